"""SAC: a squashed-Gaussian actor that maximises the twin critics' smaller value plus its
entropy, weighted by a coefficient (alpha) tuned towards a target entropy. Off-policy, on the
field's dense reward or its success, with hindsight relabelling (agents.offpolicy)."""

from __future__ import annotations

import flax.struct
import jax
import jax.numpy as jnp
import optax

from .. import offpolicy
from .config import SACConfig
from ..contrastive import weighted_mean
from ..loop import Trainer
from ..networks import sample_tanh_gaussian


@flax.struct.dataclass
class TrainState(offpolicy.TrainState):
    log_alpha: jax.Array  # the entropy coefficient, tuned by its own optimizer
    alpha_opt: optax.OptState


def make_train(config: SACConfig, env) -> Trainer:
    c = config
    nets = offpolicy.ActorCritic(config, env)
    alpha_tx = optax.adam(c.alpha_lr)
    target_entropy = c.target_entropy_per_action * env.action_size

    def new_state(**fields) -> TrainState:
        log_alpha = jnp.zeros(())
        return TrainState(**fields, log_alpha=log_alpha, alpha_opt=alpha_tx.init(log_alpha))

    def sample(actor: dict, obs: jax.Array, key: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(action, log-probability) of the squashed Gaussian."""
        return sample_tanh_gaussian(key, *nets.actor.apply(actor, obs))

    def actor_loss(actor: dict, ts: TrainState, mb: dict, key: jax.Array):
        action, log_prob = sample(actor, mb["obs"], key)
        q = nets.min_q(ts.critic, mb["obs"], action)
        loss = weighted_mean(jnp.exp(ts.log_alpha) * log_prob - q, mb["weight"])
        return loss, (log_prob, {"actor_loss": loss, "entropy": -weighted_mean(log_prob, mb["weight"])})

    def alpha_loss(log_alpha: jax.Array, log_prob: jax.Array, weight: jax.Array) -> jax.Array:
        """Grows alpha while the policy's entropy is below the target, shrinks it above."""
        return weighted_mean(jnp.exp(log_alpha) * jax.lax.stop_gradient(-log_prob - target_entropy), weight)

    def update(ts: TrainState, mb: dict, k_critic: jax.Array, k_actor: jax.Array) -> tuple[TrainState, dict]:
        """The critics towards the soft value of the online actor's next action, then the actor, then alpha."""
        next_action, next_log_prob = sample(ts.actor, mb["next_obs"], k_critic)
        next_value = nets.min_q(ts.target_critic, mb["next_obs"], next_action) - jnp.exp(ts.log_alpha) * next_log_prob
        ts, c_metrics = nets.step_critic(ts, mb, next_value)
        ts, (log_prob, a_metrics) = nets.step_actor(ts, lambda actor: actor_loss(actor, ts, mb, k_actor))
        step, alpha_opt = alpha_tx.update(jax.grad(alpha_loss)(ts.log_alpha, log_prob, mb["weight"]), ts.alpha_opt)
        ts = ts.replace(log_alpha=optax.apply_updates(ts.log_alpha, step), alpha_opt=alpha_opt,
                        target_critic=nets.polyak(ts.target_critic, ts.critic))
        return ts, {**c_metrics, **a_metrics, "alpha": jnp.exp(ts.log_alpha)}

    return offpolicy.trainer(nets, new_state, lambda actor, obs, key: sample(actor, obs, key)[0], update)
