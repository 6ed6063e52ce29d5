"""An environment from whatever names a field: a FieldSpec, a YAML path, a bundled name or a build folder."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the physics loads when an environment is made, not with fieldgen.env
    from fieldgen.env.field import FieldEnv


def make(source, backend: str | None = None, **kwargs) -> FieldEnv:
    """An environment from a FieldSpec, a YAML path, a bundled name or a build directory, stepped by
    the physics its spec names (sim.backend), or by `backend` in its place. A field with teams gives a
    match (fieldgen.env.team.TeamFieldEnv, the contract of fieldgen.env.team_contract).

    Building from a spec needs dm_control; a build directory needs only mujoco, and runs on the
    backend it was built for. Keyword arguments (episode_length, auto_reset) go to FieldEnv.
    """
    from fieldgen.compile.artifact import compile_spec, load_artifact
    from fieldgen.schema import FieldSpec, load_spec, resolve_spec_path

    check_options(**kwargs)
    if isinstance(source, FieldSpec):
        spec = source if backend is None else load_spec(source, backend)
        return environment(compile_spec(spec), **kwargs)
    if not isinstance(source, (str, Path)) or not str(source):
        raise TypeError(f"fieldgen.make takes a FieldSpec, a YAML file, a bundled field's name or a build folder, "
                        f"not {source!r}")
    path = Path(source) if isinstance(source, Path) else resolve_spec_path(str(source))
    if path.is_dir():
        artifact = load_artifact(path)
        if backend not in (None, artifact.spec.sim.backend):
            raise ValueError(f"{path} was built for sim.backend {artifact.spec.sim.backend}; build its spec with "
                             f"sim.backend: {backend}, or make the spec itself with backend={backend!r}")
        return environment(artifact, **kwargs)
    return environment(compile_spec(load_spec(path, backend)), **kwargs)


def check_options(episode_length=None, auto_reset=True, **others) -> None:
    """Refuse an episode length or auto_reset that would be taken as something else (0 read as the spec's length,
    a negative one ending every step, "no" read as true)."""
    import numbers

    if episode_length is not None and (isinstance(episode_length, bool)
                                       or not isinstance(episode_length, numbers.Integral) or episode_length < 1):
        raise ValueError(f"episode_length={episode_length!r}: give a whole number of control steps, 1 or more, or "
                         "None for the spec's own (episode.length)")
    if not isinstance(auto_reset, bool):
        raise ValueError(f"auto_reset={auto_reset!r}: give True (a done step starts the next episode) or False")


def environment(artifacts, **kwargs) -> FieldEnv:
    """The environment of built fields, on the physics their spec names."""
    from fieldgen.env.brax_pipeline import BraxFieldEnv, check_batchable
    from fieldgen.env.field import FieldEnv
    from fieldgen.schema.backends import mjx_impl

    if isinstance(artifacts, (list, tuple)):
        check_batchable(artifacts)
        if len(artifacts) > 1 and any(a.spec.teams is not None for a in artifacts):
            raise ValueError(f"{artifacts[-1].spec.name}: team fields play one field at a time, not variants in one batch")
        if len(artifacts) > 1:
            return FieldEnv(artifacts, **kwargs)
        artifacts = artifacts[0]
    if artifacts.spec.teams is not None:  # a match: fieldgen.env.team_contract's environment
        from fieldgen.env.team import TeamFieldEnv

        return TeamFieldEnv(artifacts, **kwargs)
    if mjx_impl(artifacts.spec):
        return FieldEnv(artifacts, **kwargs)
    return BraxFieldEnv(artifacts, **kwargs)
