"""PPO: on-policy, clipped surrogate, GAE, value loss, entropy bonus, observation normalisation.

Actions are a Gaussian squashed by tanh into the motors' range, as brax's PPO draws them, with
a spread the policy network sets for each state (brax's choice; `spread: global` keeps one
learned log-std per action, which learned the ant fields later).
The entropy bonus is the squashed distribution's (the Gaussian's plus the expected log-slope
of tanh), which is bounded: an unsquashed Gaussian clipped by the motors lets the bonus widen
the spread without limit, and on long runs that drowned the policy in noise.

The reward is the field's dense reward (`env.step(...).reward`, the spec's
weighted terms) or, with `reward: sparse`, its success metric. A time-limit
truncation is treated as an episode end (no bootstrap from the lost final
observation, which auto-reset replaces).
"""

from __future__ import annotations

import flax.struct
import jax
import jax.numpy as jnp
import optax

from ...env.contract import DIVERGED
from .config import PPOConfig
from ..loop import Trainer, first_states
from ..networks import MLP, tanh_log_slope
from ..actor import Policy


@flax.struct.dataclass
class Normalizer:
    count: jax.Array
    mean: jax.Array
    m2: jax.Array

    def update(self, batch: jax.Array, weight: jax.Array | None = None) -> "Normalizer":
        """Chan's parallel update of the running mean and variance over the rows of `batch` whose `weight` is 1
        (all by default); a row weighing 0 is left out however large its values."""
        weight = jnp.ones(batch.shape[0]) if weight is None else weight
        kept = weight[:, None] > 0
        batch = jnp.where(kept, batch, 0.0)
        n = jnp.sum(weight)
        mean = jnp.sum(weight[:, None] * batch, 0) / jnp.maximum(n, 1.0)
        var = jnp.sum(weight[:, None] * jnp.where(kept, batch - mean, 0.0) ** 2, 0) / jnp.maximum(n, 1.0)
        total = self.count + n
        share = n / jnp.maximum(total, 1.0)
        delta = mean - self.mean
        return Normalizer(total, self.mean + delta * share, self.m2 + var * n + delta**2 * self.count * share)

    CLIP = 10.0  # normalised observations are clipped to +-CLIP

    @property
    def std(self) -> jax.Array:
        """The running standard deviation; 1 before any observation is counted, so the first rollout's
        observations pass unscaled instead of divided by the floor and clipped (saturating every action)."""
        return jnp.where(self.count > 0, jnp.sqrt(self.m2 / jnp.maximum(self.count, 1.0) + 1e-6), 1.0)

    def __call__(self, obs: jax.Array, enabled: bool) -> jax.Array:
        if not enabled:
            return obs
        return jnp.clip((obs - self.mean) / self.std, -self.CLIP, self.CLIP)


@flax.struct.dataclass
class TrainState:
    params: dict
    opt: optax.OptState
    normalizer: Normalizer
    env_state: object
    key: jax.Array
    env_steps: jax.Array


def gaussian(policy_net, spread: str, params, obs):
    """The pre-tanh Gaussian's mean and log-std: the policy network's (spread state), or its mean with the one
    learned log-std per action (spread global)."""
    out = policy_net.apply(params["policy"], obs)
    if spread == "global":
        return out, params["log_std"]
    mean, raw = jnp.split(out, 2, axis=-1)
    return mean, jnp.log(jax.nn.softplus(raw) + 1e-3)


def advantages(data, last_value, discount: float, gae_lambda: float):
    """(GAE advantages, value targets) of a rollout [steps, ...] whose `done` ends an episode (no bootstrap)."""
    def back(carry, t):
        gae, next_value = carry
        live = 1.0 - t["done"]
        delta = t["reward"] + discount * next_value * live - t["value"]
        gae = delta + discount * gae_lambda * live * gae
        return (gae, t["value"]), gae

    _, adv = jax.lax.scan(back, (jnp.zeros_like(last_value), last_value), data, reverse=True)
    return adv, adv + data["value"]


def blown_up(done: jax.Array, diverged: jax.Array) -> jax.Array:
    """[steps, ...] 1.0 on every step of a rollout's episodes that ended because their simulation blew up, from
    the episode's first step in the rollout to its last: speeds grow for several steps before the guard ends
    such an episode, and one of those steps in the observation normaliser's running variance or in a value
    target spoils the rest of a run."""
    def back(spoiled_after, t):
        ended, broke = t
        spoiled = broke | (spoiled_after & ~ended)
        return spoiled, spoiled

    _, spoiled = jax.lax.scan(back, jnp.zeros_like(done, bool)[0], (done > 0, diverged > 0), reverse=True)
    return spoiled.astype(jnp.float32)


def squashed_entropy(mean, log_std, noise):
    """The squashed Gaussian's entropy per sample, its tanh part estimated at the stored samples (`noise`) moved
    with the current mean and spread (reparameterised, so it has a gradient)."""
    fresh = mean + jnp.exp(log_std) * jax.lax.stop_gradient(noise)
    gaussian = jnp.broadcast_to(log_std, mean.shape) + 0.5 * jnp.log(2 * jnp.pi * jnp.e)
    return jnp.sum(gaussian + tanh_log_slope(fresh), -1)


def networks(c: PPOConfig, action_size: int) -> tuple[MLP, MLP]:
    """The policy network (the pre-tanh mean, and per state its spread) and the value network, LeCun-initialised;
    the policy's output layer at `c.policy_out_scale`."""
    policy = MLP(c.hidden, action_size * (2 if c.spread == "state" else 1), init_scale=1.0,
                 out_scale=c.policy_out_scale)
    return policy, MLP(c.hidden, 1, init_scale=1.0)


def optimizer(c: PPOConfig) -> optax.GradientTransformation:
    """Adam after clipping the gradients' norm, over both networks together or over each apart (the policy's
    global spread, `log_std`, goes with the policy), at a constant rate or one falling linearly to zero over
    the run's updates."""
    rate = c.learning_rate if c.learning_rate_schedule == "constant" else \
        optax.linear_schedule(c.learning_rate, 0.0, max(c.updates, 1))
    step = lambda: optax.chain(optax.clip_by_global_norm(c.max_grad_norm), optax.adam(rate))  # noqa: E731
    if c.grad_clip == "together":
        return step()
    network = lambda params: {key: "value" if key == "value" else "policy" for key in params}  # noqa: E731
    return optax.multi_transform({"policy": step(), "value": step()}, network)


def exported_policy(c: PPOConfig, env, policy_params, normalizer: Normalizer) -> Policy:
    """PPO's policy network alone (as `networks` builds it for `env`'s actions), with the normaliser's statistics
    where observations are normalised; its first outputs are the mean. Self-play's learner exports the same way."""
    stats = dict(obs_mean=normalizer.mean, obs_std=normalizer.std, clip=normalizer.CLIP) \
        if c.normalize_observations else {}
    return Policy.whole(env, policy_params, c.hidden, networks(c, env.action_size)[0].out, **stats)


def make_train(config: PPOConfig, env) -> Trainer:
    c = config
    iters_per_eval = c.iterations_per_eval
    if iters_per_eval < 1:
        raise ValueError(f"total_steps {c.total_steps:,} leaves no iteration between evaluations")
    policy_net, value_net = networks(c, env.action_size)
    tx = optimizer(c)
    batch = c.num_envs * c.unroll_length
    minibatch = batch // c.num_minibatches

    def init(key: jax.Array) -> TrainState:
        k_pi, k_v, k_env, key = jax.random.split(key, 4)
        obs = jnp.zeros((1, env.observation_size))
        params = {"policy": policy_net.init(k_pi, obs), "value": value_net.init(k_v, obs)}
        if c.spread == "global":
            params["log_std"] = jnp.full(env.action_size, -0.5)
        n = env.observation_size
        normalizer = Normalizer(jnp.zeros(()), jnp.zeros(n), jnp.zeros(n))
        env_state = first_states(env, c, k_env)
        return TrainState(params, tx.init(params), normalizer, env_state, key, jnp.zeros((), jnp.int32))

    def distribution(params, obs):
        return gaussian(policy_net, c.spread, params, obs)

    def log_prob(mean, log_std, noise):
        """The Gaussian's log-density of mean + std * noise before tanh: a ratio of two policies' densities
        at the same squashed action needs no more, as tanh's slope cancels."""
        return jnp.sum(-0.5 * noise**2 - log_std - 0.5 * jnp.log(2 * jnp.pi), -1)

    def drawn(mean, log_std, key):
        """An action before tanh drawn from the Gaussian, and the standard noise it was drawn with."""
        noise = jax.random.normal(key, mean.shape)
        return mean + jnp.exp(log_std) * noise, noise

    def act(ts: TrainState, obs: jax.Array, key: jax.Array | None = None) -> jax.Array:
        """The squashed mean action, or with `key` one drawn from the policy as its rollouts draw them."""
        mean, log_std = distribution(ts.params, ts.normalizer(obs, c.normalize_observations))
        return jnp.tanh(mean if key is None else drawn(mean, log_std, key)[0])

    def rollout(ts: TrainState):
        def step(env_state, key):
            obs = ts.normalizer(env_state.obs, c.normalize_observations)
            mean, log_std = distribution(ts.params, obs)
            raw, noise = drawn(mean, log_std, key)
            nxt = jax.vmap(env.step)(env_state, jnp.tanh(raw))
            reward = nxt.reward if c.reward == "dense" else nxt.metrics["success"]
            value = value_net.apply(ts.params["value"], obs)[:, 0]
            broke = (nxt.info[DIVERGED] > env_state.info[DIVERGED] if DIVERGED in nxt.info
                     else jnp.zeros_like(nxt.done, bool))
            return nxt, {"obs": env_state.obs, "raw": raw, "log_prob": log_prob(mean, log_std, noise),
                         "value": value, "reward": reward, "done": nxt.done, "success": nxt.metrics["success"],
                         "diverged": broke}

        key, k = jax.random.split(ts.key)
        env_state, data = jax.lax.scan(step, ts.env_state, jax.random.split(k, c.unroll_length))
        last = value_net.apply(ts.params["value"], ts.normalizer(env_state.obs, c.normalize_observations))[:, 0]
        return ts.replace(env_state=env_state, key=key), data, last

    def loss(params, normalizer, mb):
        """PPO's loss over the steps that `weight` keeps (a blown-up episode's weigh nothing)."""
        w = mb["weight"]
        total = jnp.maximum(w.sum(), 1.0)

        def average(x):
            return jnp.sum(w * jnp.where(w > 0, x, 0.0)) / total

        obs = normalizer(mb["obs"], c.normalize_observations)
        mean, log_std = distribution(params, obs)
        noise = (mb["raw"] - mean) / jnp.exp(log_std)
        ratio = jnp.exp(log_prob(mean, log_std, noise) - mb["log_prob"])
        centre = average(mb["adv"])
        adv = (mb["adv"] - centre) / (jnp.sqrt(average((mb["adv"] - centre) ** 2)) + 1e-8)
        surrogate = -average(jnp.minimum(ratio * adv, jnp.clip(ratio, 1 - c.clip, 1 + c.clip) * adv))
        value_loss = average((value_net.apply(params["value"], obs)[:, 0] - mb["target"]) ** 2)
        entropy = average(squashed_entropy(mean, log_std, noise))
        total = surrogate + c.value_coef * value_loss - c.entropy_coef * entropy
        return total, {"policy_loss": surrogate, "value_loss": value_loss, "entropy": entropy}

    def iteration(ts: TrainState):
        ts, data, last = rollout(ts)
        adv, target = advantages(data, last, c.discount, c.gae_lambda)
        flat = jax.tree.map(lambda x: x.reshape((batch,) + x.shape[2:]),
                            {"obs": data["obs"], "raw": data["raw"], "log_prob": data["log_prob"],
                             "adv": adv, "target": target,
                             "weight": 1.0 - blown_up(data["done"], data["diverged"])})
        normalizer = ts.normalizer.update(flat["obs"], flat["weight"])

        def epoch(carry, key):
            params, opt = carry
            perm = jax.random.permutation(key, batch)
            mbs = jax.tree.map(lambda x: x[perm].reshape((c.num_minibatches, minibatch) + x.shape[1:]), flat)

            def sgd(carry, mb):
                params, opt = carry
                (_, metrics), grads = jax.value_and_grad(loss, has_aux=True)(params, normalizer, mb)
                updates, opt = tx.update(grads, opt)
                return (optax.apply_updates(params, updates), opt), metrics

            return jax.lax.scan(sgd, (params, opt), mbs)

        key, k = jax.random.split(ts.key)
        (params, opt), metrics = jax.lax.scan(epoch, (ts.params, ts.opt), jax.random.split(k, c.update_epochs))
        stats = {"train_success": jnp.mean(data["success"]), "train_reward": jnp.mean(data["reward"])}
        ts = ts.replace(params=params, opt=opt, normalizer=normalizer, key=key, env_steps=ts.env_steps + batch)
        return ts, {**jax.tree.map(jnp.mean, metrics), **stats}

    def chunk(ts: TrainState) -> tuple[TrainState, dict]:
        ts, metrics = jax.lax.scan(lambda t, _: iteration(t), ts, None, length=iters_per_eval)
        return ts, jax.tree.map(jnp.mean, metrics)

    def export(ts: TrainState) -> Policy:
        return exported_policy(c, env, ts.params["policy"], ts.normalizer)

    return Trainer(config, env, init, lambda ts: ts, chunk, act, {"env_state": 0}, export)
