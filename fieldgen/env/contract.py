"""The environment contract: all that fieldgen's trainers (fieldgen.agents) may rely on of an environment.

Any environment with these members trains; fieldgen's own (a field on MJX or on one of brax's pipelines,
several fields batched in one simulation, a field adapted to brax's or MuJoCo Playground's wrappers) are
free to change everything else. The trainers import this module, so it imports neither mujoco nor brax.
An environment may batch several variants of a field, each environment of the batch playing its own: its
last three members say how many, start an episode of a given one, and set how often each starts the
episodes to come (a plain field is one variant). Why a variant is played is the caller's business (a
curriculum's schedule); the environment only plays what it is given. A variant may also offer several
kick-off points (where the ball and the agent start): a level is a variant and one of its points; the last
two members say where each lies and set how often each level starts the episodes to come, and such an
environment counts the episodes that ended on each level (`State.info`), for the caller to weigh them by.
Physics of fixed capacities (MuJoCo Warp's) is sized for the batches a caller steps (`reserve_worlds`) and
flags what it left out (`State.info[OVERFLOW]`), which the caller hands back (`check_physics`).
"""

from __future__ import annotations

from typing import Any, Mapping, Protocol, Sequence, runtime_checkable

import jax
import jax.numpy as jnp
import numpy as np

OVERFLOW = "physics_overflow"  # State.info entry: the physics' overflow flags (int32 bits), where it has capacities
DIVERGED = "diverged_episodes"  # State.info entry: episodes ended since reset because the simulation blew up (int32)


SHARED_BY_BATCH = "contact__"  # a physics state's leaves named so are one buffer for a whole batch (Warp's contacts)


def shared_by_batch(path) -> bool:
    """Whether the state leaf at `path` (a jax.tree_util key path) belongs to the whole batch, not to one
    environment: MuJoCo Warp's contact buffer, which a vmap over environments (or seeds) must leave unbatched."""
    return SHARED_BY_BATCH in jax.tree_util.keystr(path)


def merged_overflow(flags: jax.Array) -> jax.Array:
    """Overflow flags of any shape (per environment, per flag) as one int32 of bits: set where any is set."""
    flags = flags.astype(jnp.int32)
    return jax.lax.reduce(flags, jnp.int32(0), jax.lax.bitwise_or, tuple(range(flags.ndim)))


# the observation entries of an agent's torso orientation, where it has one (an ant; a point has none)
TORSO_QUATERNION = ("root.qw", "root.qx", "root.qy", "root.qz")


def torso_entries(names: Sequence[str]) -> list[int] | None:
    """Where an observation named `names` holds the agent's torso quaternion (TORSO_QUATERNION's order), None
    where it has none (a point)."""
    names = list(names)
    return [names.index(n) for n in TORSO_QUATERNION] if set(TORSO_QUATERNION) <= set(names) else None


def up_axis_z(quat: jax.Array) -> jax.Array:
    """The world z of a body's own z axis (1 upright, -1 upside down), from its unit quaternion (w, x, y, z)."""
    _, x, y, _ = quat
    return 1.0 - 2.0 * (x * x + y * y)


@runtime_checkable
class State(Protocol):
    """One environment's state as trainers read it: a JAX pytree (brax's `State`, or MuJoCo Playground's,
    whose physics state is named differently and is none of a trainer's business). Under vmap every leaf
    gains a leading environment axis."""

    @property
    def obs(self) -> jax.Array:
        """concat(state part [state_dim], goal [observation_size - state_dim])."""

    @property
    def reward(self) -> jax.Array:
        """The step's reward: the environment's weighted reward terms."""

    @property
    def done(self) -> jax.Array:
        """1.0 on the step that ended an episode, by a fall or by time. The environment restarts on its own:
        the obs of that step is already the next episode's first."""

    @property
    def metrics(self) -> Mapping[str, jax.Array]:
        """`success` (1.0 on a step where the success holds) and every reward term, unweighted, by name."""

    @property
    def info(self) -> Mapping[str, Any]:
        """Holds at least `goal` (the target the success is judged against), `rng` (the episode's key, which
        the next episode's start is drawn from), `truncation` (1.0 where an episode ended because time ran
        out, not by a fall), `episode` (episodes ended so far: a replay buffer tells episodes apart by it)
        and `episode_step` (control steps of the current episode). Where the environment batches several
        variants it also holds `variant` (the one this environment plays) and `variant_weights` [variant_count]
        (the weights its next episodes' variants are drawn from). Where it has kick-off points
        (`Environment.kickoff_coordinates`) it also holds `level_weights` [variant_count, kickoff points], the
        weights its next episodes' levels are drawn from, and `level_counts` [2, variant_count, kickoff
        points]: the episodes that ended on each level since the caller last scaled them
        (`with_level_weights`), and of those the ones with a successful step. Where the physics has fixed
        capacities it also holds `OVERFLOW`, the flags of what it left out since the episode began."""

    def replace(self, **changes: Any) -> State:
        """The state with the named fields changed (a trainer swaps `info`, or whole episodes)."""


@runtime_checkable
class Environment(Protocol):
    """A goal-conditioned environment, batched by the caller (jax.vmap over `reset` and `step`)."""

    def reset(self, rng: jax.Array) -> State:
        """A fresh episode drawn from `rng`; pure, jit- and vmap-able."""

    def step(self, state: State, action: jax.Array) -> State:
        """One control step with `action` [action_size] in [-1, 1]; pure, jit- and vmap-able."""

    def goal_reached(self, state: jax.Array, goal: jax.Array) -> jax.Array:
        """The success predicate (0.0 or 1.0) of an observation's state part and any goal: what hindsight
        relabelling scores a stored state with, against a goal taken from its future."""

    @property
    def name(self) -> str:
        """The environment's name, as messages to a user call it."""

    @property
    def observation_size(self) -> int:
        """Entries of `State.obs`."""

    @property
    def action_size(self) -> int:
        """Entries of an action."""

    @property
    def state_dim(self) -> int:
        """Entries of the obs' state part; the goal follows them."""

    @property
    def goal_indices(self) -> np.ndarray:
        """For each goal entry, the state entry (an index into the state part) it is compared with: the
        state a trajectory reached, read as a goal, is `state[goal_indices]`."""

    @property
    def success_goal_entries(self) -> np.ndarray:
        """The goal entries (indices into the goal) that the success reads; all of them unless the goal
        names more than the target (a target for the agent and for the ball, say)."""

    @property
    def success_depends_on_goal(self) -> bool:
        """Whether the success changes with the goal: false where it judges a fixed region (a ball in the
        goal box, wherever the goal is), which hindsight relabelling cannot use."""

    @property
    def episode_length(self) -> int:
        """Control steps after which an episode ends on time."""

    @property
    def observation_names(self) -> Sequence[str]:
        """One name per obs entry (`root.z`, `front_left_hip.vel`, `goal.x`...): trainers that split a body
        among agents pick entries by name, never by position; an agent with a torso names its orientation
        TORSO_QUATERNION."""

    @property
    def action_names(self) -> Sequence[str]:
        """One name per action entry: the joint its motor drives."""

    def reserve_worlds(self, worlds: int) -> None:
        """Size the physics for batches of up to `worlds` environments (all that one program steps at once: seeds
        x environments), before the programs that step them are traced; physics without fixed capacities needs
        nothing."""

    def check_physics(self, overflow: Any) -> None:
        """Raise where `overflow` (`State.info[OVERFLOW]` of any number of environments, of any shape, or
        `merged_overflow` of it) says an environment outgrew the physics' capacities, so that its steps left
        contacts or constraints out."""

    @property
    def variant_count(self) -> int:
        """How many variants of a field the environment batches: 1 for a plain field."""

    def reset_variant(self, rng: jax.Array, variant: jax.Array) -> State:
        """A fresh episode of variant `variant` (an index below `variant_count`), drawn from `rng`."""

    def with_variant_weights(self, state: State, weights: jax.Array) -> State:
        """`state` (a batch, environments on axis 0) drawing the variants of its next episodes from `weights`
        [variant_count], which sum to 1."""

    @property
    def kickoff_coordinates(self) -> np.ndarray:
        """[variant_count, kickoff points]: where each kick-off point of each variant lies, from the easiest
        start (0) to the field's own (1); NaN where a point is never played; each variant's last point is its
        own start, where `reset_variant` starts. No columns where the variants have no kick-off points."""

    def with_level_weights(self, state: State, weights: jax.Array, keep: jax.Array) -> State:
        """`state` (a batch) drawing the levels of its next episodes from `weights` [variant_count, kickoff
        points], which sum to 1 and are 0 where a point is not played, and its `level_counts` multiplied by
        `keep` (same shape: 1 keeps a level's counts, 0 forgets them)."""


def agents_per_env(env) -> int:
    """Agents that act in one env step: a match's every agent (a team environment names them, team_contract),
    or the one agent of any other field."""
    return len(getattr(env, "agent_names", ())) or 1
