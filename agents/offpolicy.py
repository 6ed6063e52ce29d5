"""What SAC and TD3 share: off-policy actor-critics with twin Q-functions, on the field's dense
reward or its sparse success, optionally with hindsight relabelling (HER).

Both collect into the trajectory buffer CRL uses, so relabelling never crosses an episode
boundary: with `her > 0` that share of sampled transitions gets a goal taken from a later
state of its own episode, and its reward is recomputed by the field's success predicate
(`env.goal_reached`), so an episode that missed its goal still teaches how to reach where it
went. A step that ends in a fall (`done` without time-limit truncation) has no bootstrap; a
time-limit step, whose next observation auto-reset replaced, is left out of the loss.

Each algorithm brings what differs (agents.sac, agents.td3): how it explores, the value of the
next state its critics regress to, its actor's loss and how often it steps; `trainer` puts
them in the loop both run.
"""

from __future__ import annotations

from typing import Callable

import flax.struct
import jax
import jax.numpy as jnp
import optax

from . import buffer as replay
from .config import OffPolicyConfig
from .contrastive import weighted_mean
from .loop import Trainer, first_states
from .networks import MLP, Actor
from .actor import Policy


@flax.struct.dataclass
class TrainState:
    """What both algorithms keep; each adds its own fields. `critic` holds twin Q-functions, stacked on a
    leading axis of 2. Actor and critic keep their own optimizers: the actor steps against the critic
    just updated, and TD3 skips it at times."""

    actor: dict
    critic: dict
    actor_opt: optax.OptState
    critic_opt: optax.OptState
    env_state: object
    buffer: replay.Buffer
    key: jax.Array
    env_steps: jax.Array
    grad_steps: jax.Array
    target_critic: dict


class ActorCritic:
    """The networks both algorithms train and the steps they take with them. The actor outputs a
    tanh-Gaussian's mean and log-std (agents.networks.Actor); TD3 acts on the mean alone."""

    def __init__(self, config: OffPolicyConfig, env):
        self.config, self.env = config, env
        self.actor = Actor(config.hidden, env.action_size, config.layer_norm)
        self.q_net = MLP(config.hidden, 1, config.layer_norm)
        self.actor_tx, self.critic_tx = optax.adam(config.actor_lr), optax.adam(config.critic_lr)

    def twin_q(self, critic: dict, obs: jax.Array, action: jax.Array) -> jax.Array:
        """Both critics' values of a batch of observations and actions: [2, batch]."""
        return jax.vmap(self.q_net.apply, in_axes=(0, None))(critic, jnp.concatenate([obs, action], -1))[..., 0]

    def min_q(self, critic: dict, obs: jax.Array, action: jax.Array) -> jax.Array:
        """The smaller of the twin values, against overestimation."""
        return jnp.min(self.twin_q(critic, obs, action), axis=0)

    def step_critic(self, ts: TrainState, mb: dict, next_value: jax.Array) -> tuple[TrainState, dict]:
        """One Adam step of both critics towards reward + discount x next_value (none after a fall)."""
        c = self.config
        target = jax.lax.stop_gradient(mb["reward"] + c.discount * mb["continues"] * next_value)

        def loss(critic):
            q = self.twin_q(critic, mb["obs"], mb["action"])
            total = jnp.sum(jax.vmap(lambda x: weighted_mean((x - target) ** 2, mb["weight"]))(q))
            return total, {"critic_loss": total, "q": weighted_mean(q[0], mb["weight"])}

        (_, metrics), grads = jax.value_and_grad(loss, has_aux=True)(ts.critic)
        step, critic_opt = self.critic_tx.update(grads, ts.critic_opt)
        return ts.replace(critic=optax.apply_updates(ts.critic, step), critic_opt=critic_opt), metrics

    def step_actor(self, ts: TrainState, loss: Callable) -> tuple[TrainState, object]:
        """One Adam step of the actor down `loss(actor) -> (loss, aux)`; returns the state and aux."""
        (_, aux), grads = jax.value_and_grad(loss, has_aux=True)(ts.actor)
        step, actor_opt = self.actor_tx.update(grads, ts.actor_opt)
        return ts.replace(actor=optax.apply_updates(ts.actor, step), actor_opt=actor_opt), aux

    def polyak(self, target, online):
        """The target networks' step towards the online ones."""
        return jax.tree.map(lambda t, o: (1 - self.config.tau) * t + self.config.tau * o, target, online)


def trainer(nets: ActorCritic, new_state: Callable, explore: Callable, update: Callable) -> Trainer:
    """The loop both algorithms run around their own pieces.

    new_state(**fields) -> the algorithm's TrainState from the shared fields; explore(actor, obs, key) ->
    the actions that collect; update(ts, minibatch, critic key, actor key) -> (ts, metrics), one gradient
    step (a metric that is NaN at a step, as TD3's actor loss between its delayed steps, is averaged
    over the steps where it is not)."""
    c, env = nets.config, nets.env
    prefill_iters, iters_per_eval = replay.iterations(c)
    if iters_per_eval < 1:
        raise ValueError(f"total_steps {c.total_steps:,} leaves no training iteration between evaluations")
    state_dim, action_size, window = env.state_dim, env.action_size, env.episode_length
    goal_indices = jnp.asarray(env.goal_indices)
    windows, updates = replay.gradient_steps(c, window)
    reached = jax.vmap(env.goal_reached)

    def init(key: jax.Array) -> TrainState:
        k_actor, k_q, k_env, key = jax.random.split(key, 4)
        actor = nets.actor.init(k_actor, jnp.zeros((1, env.observation_size)))
        critic = jax.vmap(nets.q_net.init, in_axes=(0, None))(jax.random.split(k_q, 2),
                                                               jnp.zeros((1, env.observation_size + action_size)))
        env_state = first_states(env, c, k_env)
        example = {"state": jnp.zeros(state_dim), "goal": jnp.zeros(len(env.goal_indices)),
                   "action": jnp.zeros(action_size), "reward": jnp.zeros(()), "fell": jnp.zeros(()),
                   "episode": jnp.zeros((), jnp.int32)}
        return new_state(actor=actor, critic=critic, actor_opt=nets.actor_tx.init(actor),
                         critic_opt=nets.critic_tx.init(critic), env_state=env_state,
                         buffer=replay.init(c.max_replay_rows, c.num_envs, example), key=key,
                         env_steps=jnp.zeros((), jnp.int32), grad_steps=jnp.zeros((), jnp.int32),
                         target_critic=critic)

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

    def gradient_step(ts: TrainState, xs) -> tuple[TrainState, dict]:
        mb, key = xs
        k_critic, k_actor = jax.random.split(key)
        ts, metrics = update(ts, mb, k_critic, k_actor)
        return ts.replace(grad_steps=ts.grad_steps + 1), metrics

    def prefill(ts: TrainState) -> TrainState:
        return jax.lax.fori_loop(0, prefill_iters, lambda _, ts: collect(ts)[0], ts)

    def chunk(ts: TrainState) -> tuple[TrainState, dict]:
        def body(ts, _):
            ts, stats = collect(ts)
            key, k_batch, k_upd = jax.random.split(ts.key, 3)
            batch = transitions(ts, k_batch)
            ts, metrics = jax.lax.scan(gradient_step, ts.replace(key=key), (batch, jax.random.split(k_upd, updates)))
            return ts, {**stats, **jax.tree.map(jnp.nanmean, metrics)}

        ts, metrics = jax.lax.scan(body, ts, None, length=iters_per_eval)
        return ts, jax.tree.map(jnp.mean, metrics)

    def act(ts: TrainState, obs: jax.Array, key: jax.Array | None = None) -> jax.Array:
        """The squashed mean action, or with `key` the action training explores with."""
        if key is not None:
            return explore(ts.actor, obs, key)
        return jnp.tanh(nets.actor.apply(ts.actor, obs)[0])

    def export(ts: TrainState) -> Policy:
        """The actor's MLP alone: its first outputs are the mean, its last the log-std."""
        return Policy.whole(env, {"params": ts.actor["params"]["MLP_0"]}, c.hidden, 2 * action_size,
                            layer_norm=c.layer_norm)

    return Trainer(c, env, init, prefill, chunk, act, {"env_state": 0, "buffer": 1}, export)
