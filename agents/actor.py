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
    # the entries of an observation (its last axis), which a call is checked against; 0 where it was not told
    observation_size: int = flax.struct.field(pytree_node=False, default=0)

    def check(self, obs: jax.Array) -> None:
        """Refuse observations a policy would otherwise read wrongly: JAX clamps an index past the end, so a
        short or long last axis (or a batch given the wrong way round) would act on the wrong entries unsaid."""
        size = self.observation_size or max(max(o) for o in self.observes) + 1
        exact = bool(self.observation_size)
        last = obs.shape[-1] if obs.ndim else None
        if last is None or (last != size if exact else last < size):
            raise ValueError(f"observations of shape {tuple(obs.shape)}: this policy reads "
                             f"{'' if exact else 'at least '}{size} entries a step, the last axis ([..., {size}]; "
                             f"a batch, if any, before it)")
        if not (jnp.issubdtype(obs.dtype, jnp.floating) or jnp.issubdtype(obs.dtype, jnp.integer)):
            raise ValueError(f"observations of dtype {obs.dtype}: this policy reads real numbers (float32)")
        if not isinstance(obs, jax.core.Tracer):  # values to look at: a call outside jit
            bad = ~np.isfinite(np.asarray(obs, np.float32)).reshape(-1, last)
            if bad.any():
                rows, entries = np.nonzero(bad.any(-1))[0], np.nonzero(bad.any(0))[0]
                raise ValueError(f"observations hold NaN or infinite values (row{'s' * (len(rows) > 1)} "
                                 f"{_listed(rows)} of {len(bad)}, entr{'ies' if len(entries) > 1 else 'y'} "
                                 f"{_listed(entries)}): the actions of a network given them are NaN")

    @property
    def network(self) -> MLP:
        return MLP(self.hidden, self.outputs, self.layer_norm, skip_every=self.skip_every, matmul=self.matmul)

    @classmethod
    def whole(cls, env, params: dict, hidden, outputs: int, **options) -> "Policy":
        """One network that reads every observation entry and drives every action."""
        return cls(params, (tuple(range(env.observation_size)),), (tuple(range(env.action_size)),), tuple(hidden),
                   outputs, observation_size=env.observation_size, **options)

    def __call__(self, obs: jax.Array) -> jax.Array:
        """obs [..., observation_size] -> deterministic actions [..., action_size] in [-1, 1]."""
        obs = jnp.asarray(obs)
        if obs.ndim <= 2:  # the outermost call, and the 2-D one it comes down to
            self.check(obs)
        if obs.ndim != 2:
            return jax.vmap(self)(obs) if obs.ndim > 2 else self(obs[None])[0]
        if obs.shape[0] == 0:  # an empty batch acts not at all (the network would divide by its size)
            return jnp.zeros((0, sum(map(len, self.drives))), jnp.float32)
        if self.obs_mean is not None:
            obs = jnp.clip((obs - self.obs_mean) / self.obs_std, -self.clip, self.clip)
        team = Team(np.array(self.observes), np.array(self.drives), ())
        inputs = jnp.moveaxis(obs[:, team.observed], 1, 0)  # [controllers, batch, inputs]
        out = jax.vmap(self.network.apply, in_axes=(0 if self.per_controller else None, 0))(self.params, inputs)
        return team.joint_action(jnp.tanh(out[..., :team.actions.shape[1]]))


def _listed(indices, most: int = 5) -> str:
    """'0, 3, 7' or '0, 3, 7, 8, 9 and 12 more'."""
    shown = ", ".join(str(int(i)) for i in indices[:most])
    return shown + (f" and {len(indices) - most} more" if len(indices) > most else "")
