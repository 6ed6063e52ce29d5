"""Contrastive RL (CRL): goal-conditioned, sparse reward, a contrastive critic.

The critic is two encoders, phi(s, a) and psi(g); their energy is trained with
InfoNCE on hindsight goals drawn from each transition's own future. The actor
is a tanh-Gaussian that maximises the energy towards its goal, with an entropy
coefficient tuned to a target entropy. Defaults follow the reference
implementation (JaxGCRL) so results compare.

`make_train(config, env)` returns the run as pure functions (agents.loop.Algorithm).
"""

from __future__ import annotations

import dataclasses

import flax.struct
import jax
import jax.numpy as jnp
import optax

from agents import buffer as replay
from agents.contrastive import energy, infonce, logsumexp_penalty, weighted_mean
from agents.loop import Algorithm, evaluate_policy
from agents.networks import MLP, Actor, sample_tanh_gaussian


@dataclasses.dataclass(frozen=True)
class CRLConfig:
    total_steps: int = 10_000_000
    num_envs: int = 1024
    unroll_length: int = 62  # env steps per environment between updates
    batch_size: int = 256  # transitions per gradient step
    windows: int = 0  # episode-long trajectory windows sampled per iteration; 0: one per environment
    # (the reference), so an iteration makes windows x episode_length / batch_size gradient steps
    min_replay_rows: int = 1000  # time rows collected before updates start
    max_replay_rows: int = 10000
    discount: float = 0.99
    actor_lr: float = 3e-4
    critic_lr: float = 3e-4
    alpha_lr: float = 3e-4
    hidden: tuple[int, ...] = (256, 256)
    repr_dim: int = 64
    layer_norm: bool = False
    energy: str = "norm"
    contrastive_loss: str = "fwd_infonce"
    logsumexp_penalty: float = 0.1
    target_entropy_per_action: float = -0.5
    num_evals: int = 10
    eval_envs: int = 128
    seed: int = 0


@flax.struct.dataclass
class TrainState:
    actor: dict
    critic: dict
    log_alpha: jax.Array
    actor_opt: optax.OptState
    critic_opt: optax.OptState
    alpha_opt: optax.OptState
    env_state: object
    buffer: replay.Buffer
    key: jax.Array
    env_steps: jax.Array
    grad_steps: jax.Array


def iterations(config: CRLConfig) -> tuple[int, int]:
    """(prefill iterations, training iterations per evaluation) of a run."""
    per_iter = config.num_envs * config.unroll_length
    prefill = -(-config.min_replay_rows // config.unroll_length)
    return prefill, (config.total_steps - prefill * per_iter) // per_iter // config.num_evals


def gradient_steps(config: CRLConfig, episode_length: int) -> tuple[int, int]:
    """(windows sampled, gradient steps) per iteration."""
    windows = config.windows or config.num_envs
    return windows, windows * episode_length // config.batch_size


def make_train(config: CRLConfig, env) -> Algorithm:
    c = config
    prefill_iters, iters_per_eval = iterations(config)
    if iters_per_eval < 1:
        raise ValueError(f"total_steps {c.total_steps:,} leaves no training iteration between evaluations")
    state_dim, action_size = env.state_dim, env.action_size
    goal_indices = jnp.asarray(env.goal_indices)
    window = env.episode_length
    windows, updates = gradient_steps(config, window)
    actor = Actor(c.hidden, action_size, c.layer_norm)
    sa_encoder = MLP(c.hidden, c.repr_dim, c.layer_norm)
    g_encoder = MLP(c.hidden, c.repr_dim, c.layer_norm)
    actor_tx, critic_tx, alpha_tx = optax.adam(c.actor_lr), optax.adam(c.critic_lr), optax.adam(c.alpha_lr)
    target_entropy = c.target_entropy_per_action * action_size

    def init(key: jax.Array) -> TrainState:
        k_actor, k_sa, k_g, k_env, key = jax.random.split(key, 5)
        actor_params = actor.init(k_actor, jnp.zeros((1, env.observation_size)))
        critic_params = {
            "sa": sa_encoder.init(k_sa, jnp.zeros((1, state_dim + action_size))),
            "g": g_encoder.init(k_g, jnp.zeros((1, len(env.goal_indices)))),
            "log_temperature": jnp.zeros(()),
        }
        log_alpha = jnp.zeros(())
        env_state = jax.vmap(env.reset)(jax.random.split(k_env, c.num_envs))
        example = {"state": jnp.zeros(state_dim), "action": jnp.zeros(action_size),
                   "episode": jnp.zeros((), jnp.int32)}
        return TrainState(actor_params, critic_params, log_alpha, actor_tx.init(actor_params),
                          critic_tx.init(critic_params), alpha_tx.init(log_alpha), env_state,
                          replay.init(c.max_replay_rows, c.num_envs, example), key,
                          jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32))

    def policy(actor_params, obs, key=None):
        """A sampled action, or the mean action when key is None."""
        mean, log_std = actor.apply(actor_params, obs)
        if key is None:
            return jnp.tanh(mean)
        return sample_tanh_gaussian(key, mean, log_std)[0]

    def collect(ts: TrainState) -> tuple[TrainState, dict]:
        """unroll_length steps of every environment, appended to the buffer; returns step statistics."""

        def step(carry, key):
            env_state = carry
            action = policy(ts.actor, env_state.obs, key)
            row = {"state": env_state.obs[:, :state_dim], "action": action, "episode": env_state.info["episode"]}
            nxt = jax.vmap(env.step)(env_state, action)
            fell = nxt.done * (1.0 - nxt.info["truncation"])
            return nxt, (row, {"train_success": nxt.metrics["success"], "train_falls": fell})

        key, k = jax.random.split(ts.key)
        env_state, (rows, stats) = jax.lax.scan(step, ts.env_state, jax.random.split(k, c.unroll_length))
        ts = ts.replace(env_state=env_state, buffer=replay.insert(ts.buffer, rows), key=key,
                        env_steps=ts.env_steps + c.num_envs * c.unroll_length)
        return ts, jax.tree.map(jnp.mean, stats)

    def critic_loss(critic_params, batch):
        phi = sa_encoder.apply(critic_params["sa"], jnp.concatenate([batch["state"], batch["action"]], -1))
        psi = g_encoder.apply(critic_params["g"], batch["goal"])
        logits = energy(c.energy, phi, psi, critic_params["log_temperature"])
        w = batch["weight"]
        contrastive = infonce(c.contrastive_loss, logits, w)
        loss = contrastive + c.logsumexp_penalty * logsumexp_penalty(logits, w)
        accuracy = weighted_mean((jnp.argmax(logits, axis=1) == jnp.arange(len(w))).astype(jnp.float32), w)
        return loss, {"critic_loss": loss, "contrastive_loss": contrastive, "critic_accuracy": accuracy}

    def actor_loss(actor_params, critic_params, log_alpha, batch, key):
        obs = jnp.concatenate([batch["state"], batch["goal"]], -1)
        mean, log_std = actor.apply(actor_params, obs)
        action, log_prob = sample_tanh_gaussian(key, mean, log_std)
        phi = sa_encoder.apply(critic_params["sa"], jnp.concatenate([batch["state"], action], -1))
        psi = g_encoder.apply(critic_params["g"], batch["goal"])
        q = jnp.diagonal(energy(c.energy, phi, psi, critic_params["log_temperature"]))
        alpha = jnp.exp(log_alpha)
        loss = weighted_mean(alpha * log_prob - q, batch["weight"])
        return loss, (log_prob, {"actor_loss": loss, "entropy": -jnp.mean(log_prob)})

    def alpha_loss(log_alpha, log_prob, weight):
        """alpha * (entropy - target): alpha grows while the policy is below its target entropy."""
        return weighted_mean(jnp.exp(log_alpha) * jax.lax.stop_gradient(-log_prob - target_entropy), weight)

    def update(ts: TrainState, batch: dict, key: jax.Array) -> tuple[TrainState, dict]:
        (_, (log_prob, a_metrics)), a_grads = jax.value_and_grad(actor_loss, has_aux=True)(
            ts.actor, ts.critic, ts.log_alpha, batch, key)
        updates, actor_opt = actor_tx.update(a_grads, ts.actor_opt)
        actor_params = optax.apply_updates(ts.actor, updates)
        alpha_grad = jax.grad(alpha_loss)(ts.log_alpha, log_prob, batch["weight"])
        updates, alpha_opt = alpha_tx.update(alpha_grad, ts.alpha_opt)
        log_alpha = optax.apply_updates(ts.log_alpha, updates)
        (_, c_metrics), c_grads = jax.value_and_grad(critic_loss, has_aux=True)(ts.critic, batch)
        updates, critic_opt = critic_tx.update(c_grads, ts.critic_opt)
        critic_params = optax.apply_updates(ts.critic, updates)
        ts = ts.replace(actor=actor_params, critic=critic_params, log_alpha=log_alpha, actor_opt=actor_opt,
                        critic_opt=critic_opt, alpha_opt=alpha_opt, grad_steps=ts.grad_steps + 1)
        return ts, {**a_metrics, **c_metrics, "alpha": jnp.exp(log_alpha)}

    def update_epoch(ts: TrainState) -> tuple[TrainState, dict]:
        """Windows from the buffer, hindsight goals, then one pass of shuffled minibatch updates."""
        key, k_batch, k_perm, k_upd = jax.random.split(ts.key, 4)
        batch = replay.hindsight_batch(ts.buffer, k_batch, windows, window, c.discount, goal_indices)
        perm = jax.random.permutation(k_perm, windows * window)[:updates * c.batch_size]
        batch = jax.tree.map(lambda x: x[perm].reshape((updates, c.batch_size) + x.shape[1:]), batch)

        def body(ts, xs):
            minibatch, k = xs
            return update(ts, minibatch, k)

        ts, metrics = jax.lax.scan(body, ts.replace(key=key), (batch, jax.random.split(k_upd, updates)))
        return ts, jax.tree.map(jnp.mean, metrics)

    def start(key: jax.Array) -> TrainState:
        return jax.lax.fori_loop(0, prefill_iters, lambda _, ts: collect(ts)[0], init(key))

    def chunk(ts: TrainState) -> tuple[TrainState, dict]:
        def body(ts, _):
            ts, stats = collect(ts)
            ts, metrics = update_epoch(ts)
            return ts, {**stats, **metrics}

        ts, metrics = jax.lax.scan(body, ts, None, length=iters_per_eval)
        return ts, jax.tree.map(jnp.mean, metrics)

    def act(ts: TrainState, obs: jax.Array) -> jax.Array:
        return policy(ts.actor, obs)

    def evaluate(ts: TrainState, key: jax.Array) -> dict:
        return evaluate_policy(env, lambda obs: act(ts, obs), key, c.eval_envs)

    return Algorithm(config, env, start, chunk, evaluate, act, {"env_state": 0, "buffer": 1})
