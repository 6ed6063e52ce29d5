"""A trained actor as a plain network: what a policy needs to act once training is over.

Every trainer's deterministic action has one form: observations (normalised, for PPO), each
controller's entries of them picked (agents.team: ICRL's one per leg or joint, every other
algorithm's one for the whole body), an MLP per controller (agents.networks.MLP, one shared by all,
or each one's own stacked on a leading axis), the tanh of its first outputs, written into the actions
that controller drives. A `Policy` holds exactly that, so it can be saved and called without the
trainer, its optimizer states or its replay buffer.
"""

from __future__ import annotations

import flax.struct
import jax
import jax.numpy as jnp
import numpy as np

from .networks import MLP
from .team import Team


@flax.struct.dataclass
class Policy:
    params: dict  # the MLP's variables; with a leading controller axis where `per_controller`
    # per controller: the observation entries its network reads, in order, and the action each of its first
    # outputs drives
    observes: tuple[tuple[int, ...], ...] = flax.struct.field(pytree_node=False)
    drives: tuple[tuple[int, ...], ...] = flax.struct.field(pytree_node=False)
    hidden: tuple[int, ...] = flax.struct.field(pytree_node=False)
    outputs: int = flax.struct.field(pytree_node=False)  # the network's outputs: a Gaussian's mean (and spread)
    obs_mean: jax.Array | None = None  # observations are (obs - mean) / std, clipped to +-clip, before all else
    obs_std: jax.Array | None = None
    layer_norm: bool = flax.struct.field(pytree_node=False, default=False)
    skip_every: int = flax.struct.field(pytree_node=False, default=0)
    per_controller: bool = flax.struct.field(pytree_node=False, default=False)
    clip: float = flax.struct.field(pytree_node=False, default=10.0)
    matmul: str = flax.struct.field(pytree_node=False, default="float32")  # as it trained (networks.MATMULS)

    @property
    def network(self) -> MLP:
        return MLP(self.hidden, self.outputs, self.layer_norm, skip_every=self.skip_every, matmul=self.matmul)

    @classmethod
    def whole(cls, env, params: dict, hidden, outputs: int, **options) -> "Policy":
        """One network that reads every observation entry and drives every action."""
        return cls(params, (tuple(range(env.observation_size)),), (tuple(range(env.action_size)),), tuple(hidden),
                   outputs, **options)

    def __call__(self, obs: jax.Array) -> jax.Array:
        """obs [..., observation_size] -> deterministic actions [..., action_size] in [-1, 1]."""
        if obs.ndim != 2:
            return jax.vmap(self)(obs) if obs.ndim > 2 else self(obs[None])[0]
        if self.obs_mean is not None:
            obs = jnp.clip((obs - self.obs_mean) / self.obs_std, -self.clip, self.clip)
        team = Team(np.array(self.observes), np.array(self.drives), ())
        inputs = jnp.moveaxis(obs[:, team.observed], 1, 0)  # [controllers, batch, inputs]
        out = jax.vmap(self.network.apply, in_axes=(0 if self.per_controller else None, 0))(self.params, inputs)
        return team.joint_action(jnp.tanh(out[..., :team.actions.shape[1]]))
