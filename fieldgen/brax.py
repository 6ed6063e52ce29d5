"""fieldgen's fields in brax's registry: `brax.envs.get_environment("soccer_v2")` after `register()`.

brax's training wrappers (`brax.envs.wrappers.training.wrap`: vmap, episode and auto-reset) work on
these environments: fieldgen counts an episode's steps apart from brax's, and hands brax's
auto-reset a fresh episode each time (brax's own keeps replaying the first). Wrap with
`episode_length=env.episode_length` and `action_repeat=1`: a field's control step is its own.
brax 0.14.2's own trainers call `jax.device_put_replicated`, which the JAX versions fieldgen
supports no longer have; fieldgen's trainers (fieldgen.agents) are its own.
"""

from __future__ import annotations

from pathlib import Path

from brax import envs

from fieldgen.env.make import make
from fieldgen.schema import bundled_fields


def register(*specs: str | Path) -> list[str]:
    """Register every bundled field under its name, and each spec path or build folder given under
    the name in its spec; returns the names. Keyword arguments of `get_environment` go to FieldEnv
    (episode_length, auto_reset). Fields are compiled when first made, not here."""
    named = {name: path for name, path in bundled_fields().items()}
    for spec in specs:
        named[_name_of(Path(spec))] = Path(spec)
    for name, source in named.items():
        envs.register_environment(name, lambda source=source, **kwargs: make(source, **kwargs))
    return list(named)


def _name_of(source: Path) -> str:
    if source.is_dir():
        from fieldgen.compile.artifact import load_artifact

        return load_artifact(source).spec.name
    from fieldgen.schema import load_spec

    return load_spec(source).name
