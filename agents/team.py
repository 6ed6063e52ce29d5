"""Splitting one body's actuators among independent controllers, and what each controller observes.

A controller is one actor (with its critic and entropy coefficient) that drives a part of the body:
a leg or a joint (agents.icrl).

Observation entries and actions are matched by name (`env.observation_names`,
`env.action_names`: the joint each action drives), never by position, so a change of
layout cannot silently shift what a controller sees. Every controller observes the entries
that belong to no actuated joint (the torso, the ball, the goal) and those of its own
joints (their angles and velocities); the joints of other controllers stay hidden.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

GROUPINGS = ("leg", "joint")


@dataclasses.dataclass(frozen=True)
class Team:
    observed: np.ndarray  # [controllers, entries]: the state entries each controller sees (all of them see the goal)
    actions: np.ndarray  # [controllers, actions per controller]: the action indices each controller drives
    names: tuple[str, ...]  # one per controller

    @property
    def size(self) -> int:
        return len(self.names)

    @property
    def plain(self) -> bool:
        """One controller seeing and driving everything in order: nothing to gather or scatter."""
        return self.size == 1 and (self.observed[0] == np.arange(self.observed.shape[1])).all() and \
            (self.actions[0] == np.arange(self.actions.shape[1])).all()

    def observe(self, state: jax.Array, goal: jax.Array) -> tuple[jax.Array, jax.Array]:
        """([controllers, batch, seen], [controllers, batch, goal]) from a batch of states and goals."""
        mine = state[None] if self.plain else jnp.moveaxis(state[:, self.observed], 1, 0)
        return mine, jnp.broadcast_to(goal, (self.size,) + goal.shape)

    def own_actions(self, action: jax.Array) -> jax.Array:
        """[batch, actions] -> [controllers, batch, actions per controller]."""
        return action[None] if self.plain else jnp.moveaxis(action[:, self.actions], 1, 0)

    def joint_action(self, actions: jax.Array) -> jax.Array:
        """[controllers, batch, actions per controller] -> [batch, actions], each controller's in its own slots."""
        if self.plain:
            return actions[0]
        batch = actions.shape[1]
        flat = jnp.moveaxis(actions, 0, 1).reshape(batch, -1)
        return jnp.zeros((batch, self.actions.size), actions.dtype).at[:, self.actions.reshape(-1)].set(flat)


def whole(env) -> Team:
    """One controller that sees everything and drives every actuator: plain single-agent RL."""
    return Team(np.arange(env.state_dim)[None], np.arange(env.action_size)[None], ("all",))


def split(env, grouping: str) -> Team:
    """A controller per leg (actuators `<leg>_<joint>` grouped by `<leg>`) or one per actuated joint."""
    if grouping not in GROUPINGS:
        raise ValueError(f"unknown grouping {grouping!r}; choose one of {', '.join(GROUPINGS)}")
    actions = list(env.action_names)
    groups: dict[str, list[int]] = {}
    for i, joint in enumerate(actions):
        leg = joint.rpartition("_")[0] or joint
        groups.setdefault(leg if grouping == "leg" else joint, []).append(i)
    sizes = {len(v) for v in groups.values()}
    if len(sizes) > 1:
        raise ValueError(f"agents of a {grouping} grouping must drive equally many actuators; got "
                         + ", ".join(f"{k}: {len(v)}" for k, v in groups.items()))
    owner = [name.partition(".")[0] for name in env.observation_names[:env.state_dim]]
    actuated = set(actions)
    common = [i for i, joint in enumerate(owner) if joint not in actuated]
    observed = []
    for driven in groups.values():
        own = {actions[i] for i in driven}
        mine = [i for i, joint in enumerate(owner) if joint in own]
        observed.append(sorted(common + mine))
    return Team(np.array(observed), np.array(list(groups.values())), tuple(groups))
