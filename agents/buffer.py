"""A trajectory replay buffer kept on the device, and hindsight goal sampling.

Rows are time steps, columns are environments: `data[name][t, env]`. A window
of consecutive rows of one environment is a piece of trajectory; the episode
counter stored with each step (`episode`) says where one episode ends, so a
hindsight goal never comes from another episode.
"""

from __future__ import annotations

import flax.struct
import jax
import jax.numpy as jnp


@flax.struct.dataclass
class Buffer:
    data: dict  # name -> [capacity, num_envs, ...]
    pos: jax.Array  # next row to write
    size: jax.Array  # rows holding data

    @property
    def capacity(self) -> int:
        return next(iter(self.data.values())).shape[0]


def init(capacity: int, num_envs: int, example: dict) -> Buffer:
    data = {k: jnp.zeros((capacity, num_envs) + jnp.shape(v), jnp.asarray(v).dtype) for k, v in example.items()}
    return Buffer(data, jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32))


def iterations(config) -> tuple[int, int]:
    """(iterations that prefill min_replay_rows, training iterations per evaluation) of an off-policy run."""
    per_iter = config.num_envs * config.unroll_length
    prefill = -(-config.min_replay_rows // config.unroll_length)
    return prefill, (config.total_steps - prefill * per_iter) // per_iter // config.num_evals


def gradient_steps(config, episode_length: int) -> tuple[int, int]:
    """(episode-long windows sampled, gradient steps) per iteration: `config.windows` windows, or
    `config.windows_per_env` per environment when it is 0, cut into batches of `config.batch_size` transitions."""
    windows = config.windows or max(1, round(config.windows_per_env * config.num_envs))
    return windows, windows * episode_length // config.batch_size


def minibatch_rows(key: jax.Array, windows: int, length: int, count: int, together: int = 1) -> jax.Array:
    """Which of the `windows` x `length` transitions `hindsight_batch` flattened fill `count` minibatch slots
    (consecutive `batch_size` slots make a minibatch), each used at most once while they last: one at a time
    from anywhere (`together` = 1, the reference's shuffle), or `together` at a time from one window. Pairs of
    one episode differ in what moved alone, so a critic must read the agent's moves to tell them apart, where
    pairs from many episodes are told apart by what stays still (a ball at rest, as it is before an ant has
    learnt to reach it)."""
    if together == 1:
        return jax.random.permutation(key, windows * length)[:count]
    k_steps, k_groups = jax.random.split(key)
    per_window = length // together
    steps = jax.vmap(lambda k: jax.random.permutation(k, length)[:per_window * together])(
        jax.random.split(k_steps, windows))
    groups = (jnp.arange(windows)[:, None] * length + steps).reshape(windows * per_window, together)
    order = jax.random.permutation(k_groups, windows * per_window)
    return groups[order[jnp.arange(count // together) % order.shape[0]]].reshape(-1)


def insert(buf: Buffer, rows: dict) -> Buffer:
    """Append rows ([T, num_envs, ...] each), overwriting the oldest once full."""
    steps = next(iter(rows.values())).shape[0]
    idx = (buf.pos + jnp.arange(steps)) % buf.capacity
    data = {k: buf.data[k].at[idx].set(rows[k]) for k in buf.data}
    return Buffer(data, (buf.pos + steps) % buf.capacity, jnp.minimum(buf.size + steps, buf.capacity))


def window(buf: Buffer, key: jax.Array, length: int, env: jax.Array) -> tuple[dict, jax.Array]:
    """Rows of environment `env` from a random start; `stored[i]` marks real rows.

    Once the buffer holds `length` rows, windows lie wholly in stored rows (as the
    reference samples them); before that they run to the newest row and are cut there.
    """
    whole = buf.size >= length
    starts = jnp.where(whole, buf.size - length + 1, jnp.maximum(buf.size, 1))
    age = jax.random.randint(key, (), 0, starts)  # 0 = oldest stored row
    start = (buf.pos - buf.size + age) % buf.capacity
    rows = (start + jnp.arange(length)) % buf.capacity
    stored = jnp.arange(length) < buf.size - age
    return {k: v[rows, env] for k, v in buf.data.items()}, stored


def future_offsets(key: jax.Array, episode: jax.Array, stored: jax.Array, gamma: float) -> tuple[jax.Array, jax.Array]:
    """For each step i of a window, an offset k >= 1 with P(k) proportional to gamma^k
    among the later steps of the same episode held in the window.

    Returns (offsets, has_future); steps with no later step in their episode get
    offset 0 and has_future False.
    """
    n = episode.shape[0]
    idx = jnp.arange(n)
    nxt_same = jnp.concatenate([episode[1:] == episode[:-1], jnp.zeros(1, bool)])
    nxt_stored = jnp.concatenate([stored[1:], jnp.zeros(1, bool)])
    last_of_run = ~(nxt_same & nxt_stored)
    run_end = jax.lax.cummin(jnp.where(last_of_run, idx, n), reverse=True)
    horizon = run_end - idx  # later steps available in the same episode
    # Inverse CDF of the geometric distribution truncated to 1..horizon.
    u = jax.random.uniform(key, (n,))
    h = jnp.maximum(horizon, 1).astype(jnp.float32)
    k = jnp.ceil(jnp.log1p(-u * (1.0 - gamma**h)) / jnp.log(gamma))
    k = jnp.clip(k, 1, h).astype(jnp.int32)
    has_future = (horizon >= 1) & stored
    return jnp.where(has_future, k, 0), has_future


def hindsight_batch(buf: Buffer, key: jax.Array, windows: int, length: int, gamma: float,
                    goal_indices: jax.Array) -> dict:
    """`windows` trajectory windows, flattened to transitions that know their own future.

    Windows come from distinct environments while there are enough (every environment once
    when `windows` equals their number, as the reference samples), then with repeats.
    Returns every stored field per step, and `future_goal` (the goal entries of a later state
    of the same episode, P(k steps later) proportional to gamma^k), `next_state` (the state
    one step later), and `has_future`: whether the episode goes on within the window, the
    condition for both (false at an episode's last step).
    """
    num_envs = next(iter(buf.data.values())).shape[1]
    k_env, k_win = jax.random.split(key)
    order = jax.random.permutation(k_env, num_envs)
    envs = order[jnp.arange(windows) % num_envs]

    def one(k, env):
        k_win, k_fut = jax.random.split(k)
        rows, stored = window(buf, k_win, length, env)
        offsets, has_future = future_offsets(k_fut, rows["episode"], stored, gamma)
        steps = jnp.arange(length)
        future = rows["state"][steps + offsets]
        later = jnp.minimum(steps + 1, length - 1)
        return {**rows, "future_goal": future[:, goal_indices], "has_future": has_future,
                "next_state": rows["state"][later]}

    batch = jax.vmap(one)(jax.random.split(k_win, windows), envs)
    return jax.tree.map(lambda x: x.reshape((-1,) + x.shape[2:]), batch)
