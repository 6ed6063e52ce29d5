"""fieldgen's fields in brax's registry: `brax.envs.get_environment("soccer_v2")` after `register()`.

What the registry gives is a field adapted to brax's training wrappers (`brax.envs.wrappers.training.wrap`:
vmap, episode and auto-reset), `BraxField`; `BraxField(fieldgen.make(...))` adapts a field made otherwise.
Inside the wrappers an episode lasts its full length: fieldgen counts an episode's steps apart from brax's
and leaves ending it on time to brax's episode wrapper, so that brax's `truncation` is set; and brax's
auto-reset gets a fresh episode each time (its own keeps replaying the first). Wrap with
`episode_length=env.episode_length` and `action_repeat=1`: a field's control step is its own.
brax 0.14.2's own trainers call `jax.device_put_replicated`, which the JAX versions fieldgen
supports no longer have; fieldgen's trainers (fieldgen.agents) are its own.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import fieldgen.env.quiet  # noqa: F401  (before MJX and brax)
import jax.numpy as jnp
from brax import envs

from fieldgen.env.make import make
from fieldgen.schema import bundled_fields, resolve_spec_path

if TYPE_CHECKING:
    from fieldgen.env.field import FieldEnv


def _read_through(member: str) -> property:
    return property(lambda self: getattr(self.field, member), doc=f"The field's `{member}`.")


class FieldAdapter:
    """A field (`self.field`, a FieldEnv) behind another library's interface. Every member of the
    environment contract (fieldgen.env.contract) reads through to the field, as properties of the class,
    so that the adapter is an Environment wherever that is checked; every other attribute reads through too."""

    field: FieldEnv

    def __getattr__(self, name):
        if name.startswith("_") or name == "field":
            raise AttributeError(name)
        return getattr(self.field, name)

    name = _read_through("name")
    observation_size = _read_through("observation_size")
    action_size = _read_through("action_size")
    state_dim = _read_through("state_dim")
    goal_indices = _read_through("goal_indices")
    success_goal_entries = _read_through("success_goal_entries")
    success_depends_on_goal = _read_through("success_depends_on_goal")
    episode_length = _read_through("episode_length")
    observation_names = _read_through("observation_names")
    action_names = _read_through("action_names")
    goal_reached = _read_through("goal_reached")
    variant_count = _read_through("variant_count")
    reset_variant = _read_through("reset_variant")
    with_variant_weights = _read_through("with_variant_weights")
    kickoff_coordinates = _read_through("kickoff_coordinates")
    with_level_weights = _read_through("with_level_weights")
    reserve_worlds = _read_through("reserve_worlds")
    check_physics = _read_through("check_physics")


def reserved(field: FieldEnv) -> FieldEnv:
    """The field, refused on MuJoCo Warp until its capacities are reserved for a batch: another library's wrappers
    vmap it without saying how many environments they step, and Warp's contact buffer is shared by the batch."""
    from fieldgen.env.field import FieldEnv

    if not isinstance(field, FieldEnv):  # else the first reset fails on an attribute of whatever it was
        raise TypeError(f"the adapters wrap an environment fieldgen.make returns, not {field!r}: "
                        "BraxField(fieldgen.make(NAME))")
    if getattr(field, "impl", None) == "warp" and field.worlds < 2:
        raise ValueError(f"{field.name} runs on sim.backend warp, whose contact buffer is shared by every environment "
                         "stepped at once: call field.reserve_worlds(N) with that number before wrapping it, and "
                         "field.check_physics(state.info['physics_overflow']) after stepping; or use sim.backend: mjx")
    return field


class BraxField(FieldAdapter):
    """A field inside brax's training wrappers, which it finds in the state's info: brax's EpisodeWrapper
    (`steps`, which it counts and zeroes once an episode is over) and AutoResetWrapper (`first_obs` and
    `first_pipeline_state`, which it swaps in for a done step's). Outside them it steps as the field."""

    def __init__(self, field: FieldEnv):
        self.field = reserved(field)

    @property
    def unwrapped(self) -> "BraxField":
        return self

    def reset(self, rng):
        return self.field.reset(rng)

    def step(self, state, action):
        info = dict(state.info)
        under_auto_reset = "first_obs" in info
        if under_auto_reset:  # brax's auto-reset swaps observations, not info: a swapped-in episode's goal is its obs'
            info["goal"] = self.field.obs_target(state.obs)
        under_episode_wrapper = "steps" in info
        if under_episode_wrapper:  # brax's own count reads 0 once its wrappers have started a new episode
            for count in ("episode_step", "down_steps"):
                info[count] = jnp.where(info["steps"] == 0, 0, info[count])
        state, start = self.field.step_restarting(state.replace(info=info), action,
                                                  ends_on_time=not under_episode_wrapper)
        if under_auto_reset and start is not None:  # what brax's auto-reset swaps in is then a fresh episode
            first_pipeline_state, first_obs = start
            state = state.replace(info=dict(state.info, first_pipeline_state=first_pipeline_state, first_obs=first_obs))
        return state


def register(*specs: str | Path) -> list[str]:
    """Register every bundled field under its name, and each spec path or build folder given under
    the name in its spec; returns the names. Keyword arguments of `get_environment` go to FieldEnv
    (episode_length, auto_reset). Fields are compiled when first made, not here."""
    bundled = bundled_fields()
    named = dict(bundled)
    for spec in specs:
        if spec is None or not str(spec):
            raise TypeError(f"register takes spec paths, build folders or bundled names, not {spec!r}")
        path = resolve_spec_path(str(spec)) if isinstance(spec, str) else Path(spec)
        name = _name_of(path)
        if name in bundled and path.resolve() != bundled[name].resolve():  # brax would make the other field unsaid
            raise ValueError(f"{spec} is named {name}, as a bundled field is: registering it would replace that "
                             f"field under brax's name; give its spec another name")
        named[name] = path
    for name, source in named.items():
        envs.register_environment(name, lambda source=source, **kwargs: BraxField(make(source, **kwargs)))
    return list(named)


def _name_of(source: Path) -> str:
    if source.is_dir():
        from fieldgen.compile.artifact import load_artifact

        return load_artifact(source).spec.name
    from fieldgen.schema import load_spec

    return load_spec(source).name
