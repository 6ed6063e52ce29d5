"""The team environment contract: what a trainer of a match (self-play, several agents) may rely on of a field
with `teams`. It extends nothing of the single-agent contract (contract.py), which the single-agent trainers
know alone: a team field is no goal-conditioned environment, and those trainers refuse it (`refuse_team`).

Agents come in one order, the home side's then the away side's (home0, home1, away0, away1), and every agent
observes and acts in its own side's frame, in which it attacks along +y (the away side's is the field's turned
half a turn), so that one policy plays either side. Rewards, success and the terms come per side: [home, away].
Like contract.py, this module imports neither mujoco nor brax.
"""

from __future__ import annotations

from typing import Any, Mapping, Protocol, Sequence, runtime_checkable

import jax
import numpy as np


@runtime_checkable
class TeamState(Protocol):
    """One match's state: a JAX pytree; under vmap every leaf gains a leading environment axis."""

    @property
    def obs(self) -> jax.Array:
        """[agents, observation_size]: each agent's observation in its side's frame."""

    @property
    def reward(self) -> jax.Array:
        """[2]: each side's weighted reward terms (home, away)."""

    @property
    def done(self) -> jax.Array:
        """1.0 on the step that ended the episode, for both sides: a goal, or time out. The environment restarts on
        its own: the obs of that step is already the next episode's first."""

    @property
    def metrics(self) -> Mapping[str, jax.Array]:
        """[2] per name: `success` (1.0 on the step the side scored) and every reward term, unweighted."""

    @property
    def info(self) -> Mapping[str, Any]:
        """Holds at least `rng`, `truncation` (1.0 where the episode ended because time ran out), `episode`
        (episodes ended so far) and `episode_step`; on physics of fixed capacities also contract.py's `OVERFLOW`,
        the flags of what it left out since it was reset."""

    def replace(self, **changes: Any) -> TeamState:
        """The state with the named fields changed."""


@runtime_checkable
class TeamEnvironment(Protocol):
    """A match between two sides, batched by the caller (jax.vmap over `reset` and `step`)."""

    def reset(self, rng: jax.Array) -> TeamState:
        """A fresh episode drawn from `rng`; pure, jit- and vmap-able."""

    def step(self, state: TeamState, actions: jax.Array) -> TeamState:
        """One control step with `actions` [agents, action_size] in [-1, 1], each in its agent's side's frame."""

    @property
    def name(self) -> str:
        """The field's name."""

    @property
    def agent_names(self) -> Sequence[str]:
        """home0, ..., away0, ...: the order of `TeamState.obs` and of the actions."""

    @property
    def agent_sides(self) -> np.ndarray:
        """[agents]: each agent's side, 0 home or 1 away: its index into every per-side array."""

    @property
    def observation_size(self) -> int:
        """Entries of one agent's observation."""

    @property
    def action_size(self) -> int:
        """Entries of one agent's action."""

    @property
    def episode_length(self) -> int:
        """Control steps after which an episode ends on time."""

    @property
    def observation_names(self) -> Sequence[str]:
        """One name per entry of an agent's observation (`agent_x.pos`, `ball.x`, `opponent0.vy`...)."""

    @property
    def action_names(self) -> Sequence[str]:
        """One name per entry of an agent's action: the joint its motor drives, without the agent's prefix."""

    @property
    def zero_sum_terms(self) -> Sequence[str]:
        """The reward terms whose values for the two sides sum to zero on every step."""

    def reserve_worlds(self, worlds: int) -> None:
        """Size the physics for batches of up to `worlds` matches (all that one program steps at once: seeds x
        matches), before the programs that step them are traced, as a single-agent environment's
        (contract.Environment.reserve_worlds)."""

    def check_physics(self, overflow: Any) -> None:
        """Raise where `overflow` (`TeamState.info[OVERFLOW]` of any number of matches, or `merged_overflow` of it)
        says a match outgrew the physics' capacities, as a single-agent environment's."""


def refuse_team(env: Any, what: str) -> None:
    """Raise ValueError, one line, where `env` is a match: `what` (a single-agent trainer, say) plays one agent."""
    if isinstance(env, TeamEnvironment):
        raise ValueError(f"{env.name} is a team field ({', '.join(env.agent_names)}); {what} plays one agent on a "
                         "goal-conditioned field: give it a field without teams")
