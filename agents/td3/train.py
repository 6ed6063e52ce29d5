"""TD3: a deterministic actor with Gaussian exploration noise, target policy smoothing, and
actor and target updates delayed to every `policy_delay` critic steps. Off-policy, on the
field's dense reward or its success, with hindsight relabelling (agents.offpolicy)."""

from __future__ import annotations

import flax.struct
import jax
import jax.numpy as jnp

from .. import offpolicy
from .config import TD3Config
from ..contrastive import weighted_mean
from ..loop import Trainer


@flax.struct.dataclass
class TrainState(offpolicy.TrainState):
    target_actor: dict  # Polyak-averaged with the critics: the actor of their targets


def make_train(config: TD3Config, env) -> Trainer:
    c = config
    nets = offpolicy.ActorCritic(config, env)

    def new_state(**fields) -> TrainState:
        return TrainState(**fields, target_actor=fields["actor"])

    def policy(actor: dict, obs: jax.Array) -> jax.Array:
        """The action: the tanh of the actor's mean (its log-std outputs go unused)."""
        return jnp.tanh(nets.actor.apply(actor, obs)[0])

    def explore(actor: dict, obs: jax.Array, key: jax.Array) -> jax.Array:
        noise = c.exploration_noise * jax.random.normal(key, (obs.shape[0], env.action_size))
        return jnp.clip(policy(actor, obs) + noise, -1.0, 1.0)

    def actor_loss(actor: dict, ts: TrainState, mb: dict):
        loss = weighted_mean(-nets.twin_q(ts.critic, mb["obs"], policy(actor, mb["obs"]))[0], mb["weight"])
        return loss, {"actor_loss": loss}

    def improve(ts: TrainState, mb: dict) -> tuple[TrainState, dict]:
        """The delayed step: the actor against the first critic, then every target network."""
        ts, metrics = nets.step_actor(ts, lambda actor: actor_loss(actor, ts, mb))
        return ts.replace(target_actor=nets.polyak(ts.target_actor, ts.actor),
                          target_critic=nets.polyak(ts.target_critic, ts.critic)), metrics

    def update(ts: TrainState, mb: dict, k_critic: jax.Array, k_actor: jax.Array) -> tuple[TrainState, dict]:
        """The critics towards the target actor's smoothed next action; every policy_delay steps, `improve`
        (the actor is deterministic: k_actor goes unused)."""
        next_action = policy(ts.target_actor, mb["next_obs"])
        noise = jnp.clip(c.policy_noise * jax.random.normal(k_critic, next_action.shape), -c.noise_clip, c.noise_clip)
        next_action = jnp.clip(next_action + noise, -1.0, 1.0)
        ts, c_metrics = nets.step_critic(ts, mb, nets.min_q(ts.target_critic, mb["next_obs"], next_action))
        skip = lambda ts: (ts, {"actor_loss": jnp.nan})  # noqa: E731
        ts, a_metrics = jax.lax.cond(ts.grad_steps % c.policy_delay == 0, lambda ts: improve(ts, mb), skip, ts)
        return ts, {**c_metrics, **a_metrics}

    return offpolicy.trainer(nets, new_state, explore, update)
