"""The replay buffer and hindsight sampler on tiny hand-made trajectories."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from fieldgen.agents import buffer


def filled(episodes: list[int], num_envs: int = 1, capacity: int = 16):
    """A buffer whose state at step t is t (one dim) and whose episode ids are given."""
    steps = len(episodes)
    example = {"state": jnp.zeros(1), "action": jnp.zeros(1), "episode": jnp.zeros((), jnp.int32)}
    buf = buffer.init(capacity, num_envs, example)
    t = jnp.arange(steps, dtype=jnp.float32)
    rows = {"state": jnp.tile(t[:, None, None], (1, num_envs, 1)),
            "action": jnp.zeros((steps, num_envs, 1)),
            "episode": jnp.tile(jnp.asarray(episodes, jnp.int32)[:, None], (1, num_envs))}
    return buffer.insert(buf, rows)


def test_insert_wraps_and_counts():
    buf = filled([0] * 10, capacity=8)
    assert int(buf.size) == 8 and int(buf.pos) == 2
    # rows 8, 9 overwrote rows 0, 1
    assert buf.data["state"][:, 0, 0].tolist() == [8, 9, 2, 3, 4, 5, 6, 7]


def test_future_offsets_stay_in_the_episode():
    episode = jnp.array([0, 0, 0, 1, 1, 2, 2, 2])
    stored = jnp.ones(8, bool)
    for seed in range(50):
        k, valid = buffer.future_offsets(jax.random.PRNGKey(seed), episode, stored, 0.9)
        k, valid = np.asarray(k), np.asarray(valid)
        assert valid.tolist() == [True, True, False, True, False, True, True, False]
        target = np.arange(8) + k
        assert np.all(np.asarray(episode)[target] == np.asarray(episode))
        assert np.all(k[valid] >= 1)


def test_future_offsets_respect_unstored_rows():
    episode = jnp.zeros(6, jnp.int32)
    stored = jnp.array([True, True, True, False, False, False])
    k, valid = buffer.future_offsets(jax.random.PRNGKey(0), episode, stored, 0.99)
    assert np.asarray(valid).tolist() == [True, True, False, False, False, False]
    assert np.all(np.arange(6)[np.asarray(valid)] + np.asarray(k)[np.asarray(valid)] <= 2)


def test_future_offsets_follow_truncated_geometric():
    gamma, n = 0.7, 5
    episode = jnp.zeros(n + 1, jnp.int32)
    keys = jax.random.split(jax.random.PRNGKey(1), 20000)
    ks = jax.vmap(lambda k: buffer.future_offsets(k, episode, jnp.ones(n + 1, bool), gamma)[0][0])(keys)
    counts = np.bincount(np.asarray(ks), minlength=n + 1)[1:] / len(keys)
    expected = gamma ** np.arange(1, n + 1)
    expected /= expected.sum()
    np.testing.assert_allclose(counts, expected, atol=0.015)


def test_hindsight_batch_goals_and_next_states_come_from_the_same_episode():
    episodes = [0, 0, 0, 0, 1, 1, 1, 2, 2, 2, 2, 2]
    buf = filled(episodes, num_envs=3)
    batch = buffer.hindsight_batch(buf, jax.random.PRNGKey(0), windows=64, length=6, gamma=0.9,
                                   goal_indices=jnp.array([0]))
    state, goal, nxt, valid = (np.asarray(batch[k]) for k in ("state", "future_goal", "next_state", "has_future"))
    ep = np.asarray(episodes)
    for i, (s, g, n, v) in enumerate(zip(state[:, 0].astype(int), goal[:, 0].astype(int), nxt[:, 0].astype(int),
                                         valid)):
        goes_on = s + 1 < len(ep) and ep[s + 1] == ep[s]
        assert v == (goes_on and i % 6 < 5)  # an episode's last step, or a window's, has no future
        if v:
            assert g > s and ep[g] == ep[s] and n == s + 1
    assert sorted(set(state[::6, 0].astype(int))) == list(range(7))  # windows began at every row they can: all cases


def test_windows_cover_every_environment_once_and_lie_in_stored_rows():
    """As the reference samples: one window per environment, wholly stored once the buffer holds one."""
    num_envs, length = 5, 4
    buf = filled([0] * 10, num_envs=num_envs, capacity=16)
    envs_state = buf.data["state"].at[:, :, 0].add(100.0 * jnp.arange(num_envs))  # env e's states are 100e + t
    buf = buf.replace(data=dict(buf.data, state=envs_state))
    for seed in range(20):
        batch = buffer.hindsight_batch(buf, jax.random.PRNGKey(seed), windows=num_envs, length=length, gamma=0.9,
                                       goal_indices=jnp.array([0]))
        state = np.asarray(batch["state"][:, 0]).reshape(num_envs, length)
        assert sorted((state[:, 0] // 100).astype(int).tolist()) == list(range(num_envs))
        assert np.all(np.diff(state, axis=1) == 1)  # consecutive stored steps: never past the newest row
        assert np.asarray(batch["has_future"]).reshape(num_envs, length)[:, :-1].all()


def test_minibatch_rows_one_at_a_time_are_the_reference_shuffle_and_in_groups_come_from_one_window():
    key = jax.random.PRNGKey(3)
    windows, length = 6, 10
    single = buffer.minibatch_rows(key, windows, length, 40)
    assert single.tolist() == jax.random.permutation(key, windows * length)[:40].tolist()  # runs sample as before
    grouped = np.asarray(buffer.minibatch_rows(key, windows, length, 48, together=4))
    assert grouped.shape == (48,) and len(set(grouped.tolist())) == 48  # each transition at most once
    window_of = (grouped // length).reshape(-1, 4)
    assert (window_of == window_of[:, :1]).all()  # four at a time from one window
    assert len(set(window_of[:, 0].tolist())) > 1  # from many windows in all
    assert ((grouped >= 0) & (grouped < windows * length)).all()
    # more slots than whole groups: the groups come round again, still four from one window
    again = np.asarray(buffer.minibatch_rows(key, windows, length, 64, together=4)).reshape(-1, 4) // length
    assert (again == again[:, :1]).all()
