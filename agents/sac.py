"""SAC and TD3: off-policy actor-critic with twin Q-functions, on the field's dense reward or
its sparse success, optionally with hindsight relabelling (HER).

With `her > 0` that share of sampled transitions gets a goal taken from a later state of
its own episode, and its reward is recomputed by the field's success predicate
(`env.goal_reached`): an episode that missed its goal still teaches how to reach where it
went. The replay buffer is the same trajectory buffer CRL uses, so relabelling never
crosses an episode boundary.

A step that ends in a fall (`done` without time-limit truncation) has no bootstrap; a
time-limit step, whose next observation auto-reset replaced, is left out of the loss.
TD3 (agents.td3) is this module with a deterministic actor, target policy smoothing and
delayed actor updates.
"""

from __future__ import annotations

import flax.struct
import jax
import jax.numpy as jnp
import optax

from . import buffer as replay
from .config import OffPolicyConfig, SACConfig
from .contrastive import weighted_mean
from .loop import Trainer
from .networks import MLP, Actor, sample_tanh_gaussian


@flax.struct.dataclass
class TrainState:
    """`critic` holds twin Q-functions, stacked on a leading axis of 2. Actor, critic and alpha keep
    their own optimizers: the actor steps against the critic just updated, and TD3 skips it at times."""

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
    target_actor: dict
    target_critic: dict


def make_train(config: OffPolicyConfig, env, deterministic: bool = False) -> Trainer:
    """SAC, or with `deterministic` TD3 (config: agents.td3.TD3Config)."""
    c = config
    prefill_iters, iters_per_eval = replay.iterations(config)
    if iters_per_eval < 1:
        raise ValueError(f"total_steps {c.total_steps:,} leaves no training iteration between evaluations")
    state_dim, action_size, window = env.state_dim, env.action_size, env.episode_length
    goal_indices = jnp.asarray(env.goal_indices)
    windows, updates = replay.gradient_steps(config, window)
    actor = Actor(c.hidden, action_size, c.layer_norm)
    q_net = MLP(c.hidden, 1, c.layer_norm)
    twin_q = lambda params, x: jax.vmap(q_net.apply, in_axes=(0, None))(params, x)[..., 0]  # noqa: E731  [2, B]
    actor_tx, critic_tx = optax.adam(c.actor_lr), optax.adam(c.critic_lr)
    alpha_tx = optax.adam(getattr(c, "alpha_lr", 0.0))
    target_entropy = getattr(c, "target_entropy_per_action", 0.0) * action_size
    reached = jax.vmap(env.goal_reached)

    def init(key: jax.Array) -> TrainState:
        k_actor, k_q, k_env, key = jax.random.split(key, 4)
        actor_params = actor.init(k_actor, jnp.zeros((1, env.observation_size)))
        critic = jax.vmap(q_net.init, in_axes=(0, None))(jax.random.split(k_q, 2),
                                                          jnp.zeros((1, env.observation_size + action_size)))
        log_alpha = jnp.zeros(())
        env_state = jax.vmap(env.reset)(jax.random.split(k_env, c.num_envs))
        example = {"state": jnp.zeros(state_dim), "goal": jnp.zeros(len(env.goal_indices)),
                   "action": jnp.zeros(action_size), "reward": jnp.zeros(()), "fell": jnp.zeros(()),
                   "episode": jnp.zeros((), jnp.int32)}
        return TrainState(actor_params, critic, log_alpha, actor_tx.init(actor_params), critic_tx.init(critic),
                          alpha_tx.init(log_alpha), env_state, replay.init(c.max_replay_rows, c.num_envs, example),
                          key, jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32), actor_params, critic)

    def sample(actor_params, obs, key):
        """(action, log-probability): SAC's squashed Gaussian; TD3's tanh of the mean (log-prob 0)."""
        mean, log_std = actor.apply(actor_params, obs)
        if deterministic:
            return jnp.tanh(mean), jnp.zeros(mean.shape[:-1])
        return sample_tanh_gaussian(key, mean, log_std)

    def explore(actor_params, obs, key):
        if deterministic:
            noise = c.exploration_noise * jax.random.normal(key, (obs.shape[0], action_size))
            return jnp.clip(sample(actor_params, obs, key)[0] + noise, -1.0, 1.0)
        return sample(actor_params, obs, key)[0]

    def collect(ts: TrainState) -> tuple[TrainState, dict]:
        def step(env_state, key):
            action = explore(ts.actor, env_state.obs, key)
            nxt = jax.vmap(env.step)(env_state, action)
            reward = nxt.reward if c.reward == "dense" else nxt.metrics["success"]
            fell = nxt.done * (1.0 - nxt.info["truncation"])
            row = {"state": env_state.obs[:, :state_dim], "goal": env_state.obs[:, state_dim:], "action": action,
                   "reward": reward, "fell": fell, "episode": env_state.info["episode"]}
            return nxt, (row, {"train_success": nxt.metrics["success"], "train_falls": fell,
                               "train_reward": reward})

        key, k = jax.random.split(ts.key)
        env_state, (rows, stats) = jax.lax.scan(step, ts.env_state, jax.random.split(k, c.unroll_length))
        ts = ts.replace(env_state=env_state, buffer=replay.insert(ts.buffer, rows), key=key,
                        env_steps=ts.env_steps + c.num_envs * c.unroll_length)
        return ts, jax.tree.map(jnp.mean, stats)

    def transitions(ts: TrainState, key: jax.Array) -> dict:
        """updates x batch_size transitions: (obs, action, reward, next_obs, continues, weight)."""
        k_batch, k_her, k_perm = jax.random.split(key, 3)
        s = replay.hindsight_batch(ts.buffer, k_batch, windows, window, c.discount, goal_indices)
        goal, reward = s["goal"], s["reward"]
        if c.her:
            relabel = s["has_future"] & (jax.random.uniform(k_her, s["has_future"].shape) < c.her)
            goal = jnp.where(relabel[:, None], s["future_goal"], goal)
            reward = jnp.where(relabel, reached(s["next_state"], goal), reward)
        fell = s["fell"] > 0
        batch = {"obs": jnp.concatenate([s["state"], goal], -1), "action": s["action"],
                 "reward": c.reward_scale * reward, "next_obs": jnp.concatenate([s["next_state"], goal], -1),
                 "continues": 1.0 - fell, "weight": (s["has_future"] | fell).astype(jnp.float32)}
        perm = jax.random.permutation(k_perm, windows * window)[:updates * c.batch_size]
        return jax.tree.map(lambda x: x[perm].reshape((updates, c.batch_size) + x.shape[1:]), batch)

    def critic_loss(critic, ts: TrainState, mb: dict, key: jax.Array):
        next_action, next_log_prob = sample(ts.target_actor if deterministic else ts.actor, mb["next_obs"], key)
        if deterministic:  # target policy smoothing
            noise = jnp.clip(c.policy_noise * jax.random.normal(key, next_action.shape), -c.noise_clip, c.noise_clip)
            next_action = jnp.clip(next_action + noise, -1.0, 1.0)
        next_q = jnp.min(twin_q(ts.target_critic, jnp.concatenate([mb["next_obs"], next_action], -1)), axis=0)
        next_v = next_q - jnp.exp(ts.log_alpha) * next_log_prob
        target = jax.lax.stop_gradient(mb["reward"] + c.discount * mb["continues"] * next_v)
        q = twin_q(critic, jnp.concatenate([mb["obs"], mb["action"]], -1))
        loss = jnp.sum(jax.vmap(lambda x: weighted_mean((x - target) ** 2, mb["weight"]))(q))
        return loss, {"critic_loss": loss, "q": weighted_mean(q[0], mb["weight"])}

    def actor_loss(actor_params, ts: TrainState, mb: dict, key: jax.Array):
        action, log_prob = sample(actor_params, mb["obs"], key)
        q = twin_q(ts.critic, jnp.concatenate([mb["obs"], action], -1))
        q = q[0] if deterministic else jnp.min(q, axis=0)
        loss = weighted_mean(jnp.exp(ts.log_alpha) * log_prob - q, mb["weight"])
        return loss, (log_prob, {"actor_loss": loss, "entropy": -weighted_mean(log_prob, mb["weight"])})

    def alpha_loss(log_alpha, log_prob, weight):
        return weighted_mean(jnp.exp(log_alpha) * jax.lax.stop_gradient(-log_prob - target_entropy), weight)

    def polyak(target, online):
        return jax.tree.map(lambda t, o: (1 - c.tau) * t + c.tau * o, target, online)

    def update(ts: TrainState, xs) -> tuple[TrainState, dict]:
        mb, key = xs
        k_critic, k_actor = jax.random.split(key)
        (_, c_metrics), grads = jax.value_and_grad(critic_loss, has_aux=True)(ts.critic, ts, mb, k_critic)
        step, critic_opt = critic_tx.update(grads, ts.critic_opt)
        ts = ts.replace(critic=optax.apply_updates(ts.critic, step), critic_opt=critic_opt)

        def improve(ts: TrainState) -> tuple[TrainState, dict]:
            (_, (log_prob, a_metrics)), grads = jax.value_and_grad(actor_loss, has_aux=True)(ts.actor, ts, mb,
                                                                                              k_actor)
            step, actor_opt = actor_tx.update(grads, ts.actor_opt)
            ts = ts.replace(actor=optax.apply_updates(ts.actor, step), actor_opt=actor_opt)
            if not deterministic:
                grad = jax.grad(alpha_loss)(ts.log_alpha, log_prob, mb["weight"])
                step, alpha_opt = alpha_tx.update(grad, ts.alpha_opt)
                ts = ts.replace(log_alpha=optax.apply_updates(ts.log_alpha, step), alpha_opt=alpha_opt)
            if deterministic:
                ts = ts.replace(target_actor=polyak(ts.target_actor, ts.actor))
            return ts.replace(target_critic=polyak(ts.target_critic, ts.critic)), a_metrics

        if deterministic:  # delayed actor and target updates
            skip = lambda ts: (ts, {"actor_loss": jnp.nan, "entropy": jnp.zeros(())})  # noqa: E731
            ts, a_metrics = jax.lax.cond(ts.grad_steps % c.policy_delay == 0, improve, skip, ts)
        else:
            ts, a_metrics = improve(ts)
        return ts.replace(grad_steps=ts.grad_steps + 1), {**c_metrics, **a_metrics, "alpha": jnp.exp(ts.log_alpha)}

    def start(key: jax.Array) -> TrainState:
        return jax.lax.fori_loop(0, prefill_iters, lambda _, ts: collect(ts)[0], init(key))

    def chunk(ts: TrainState) -> tuple[TrainState, dict]:
        def body(ts, _):
            ts, stats = collect(ts)
            key, k_batch, k_upd = jax.random.split(ts.key, 3)
            batch = transitions(ts, k_batch)
            ts, metrics = jax.lax.scan(update, ts.replace(key=key), (batch, jax.random.split(k_upd, updates)))
            return ts, {**stats, **jax.tree.map(jnp.nanmean, metrics)}

        ts, metrics = jax.lax.scan(body, ts, None, length=iters_per_eval)
        return ts, jax.tree.map(jnp.mean, metrics)

    def act(ts: TrainState, obs: jax.Array) -> jax.Array:
        return jnp.tanh(actor.apply(ts.actor, obs)[0])

    return Trainer(config, env, start, chunk, act, {"env_state": 0, "buffer": 1})
