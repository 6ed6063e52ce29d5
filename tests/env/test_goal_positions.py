"""Goals that name the agent's position beside the ball's (`task.goal_positions: [agent, ball]`): the
layout, what the success still judges, and a CRL run that learns from such goals."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import fieldgen
from fieldgen.agents import buffer as replay
from fieldgen.agents import crl, loop

FIELD = """name: {name}
field: {{length: 8, width: 6}}
goal: {{enabled: false}}
ball: {{radius: 0.2, mass: 0.2, joint: planar, spawn: {{x: [-0.5, 0.5], y: 1.5}}}}
agent: {{kind: point}}
episode: {{length: 50}}
task:
  target: {{kind: point, x: 0, y: 3}}
  success: {{kind: ball_near_target, radius: 0.5}}
"""


@pytest.fixture(scope="module")
def envs(tmp_path_factory):
    """The same field with the default goal (the ball's x, y) and with [agent, ball]."""
    folder = tmp_path_factory.mktemp("goal_positions")
    (folder / "ball.yaml").write_text(FIELD.format(name="ball_goal"))
    (folder / "both.yaml").write_text(FIELD.format(name="both_goal") + "  goal_positions: [agent, ball]\n")
    return fieldgen.make(str(folder / "ball.yaml")), fieldgen.make(str(folder / "both.yaml"))


def test_the_goal_names_the_agent_then_the_ball_each_at_the_target(envs):
    ball, both = envs
    agent_xy = [ball.observation_names.index(n) for n in ("agent_x.pos", "agent_y.pos")]
    np.testing.assert_array_equal(both.goal_indices, [*agent_xy, *ball.goal_indices])
    assert both.observation_size == ball.observation_size + 2 and both.state_dim == ball.state_dim
    assert both.observation_names[-4:] == ("goal.agent.x", "goal.agent.y", "goal.ball.x", "goal.ball.y")
    np.testing.assert_array_equal(both.success_goal_entries, [2, 3])
    state = jax.jit(jax.vmap(both.reset))(jax.random.split(jax.random.PRNGKey(0), 4))
    target = np.asarray(state.info["goal"])
    np.testing.assert_allclose(state.obs[:, both.state_dim:], np.concatenate([target, target], axis=1))


@pytest.mark.slow
def test_episodes_score_as_with_the_balls_goal_alone(envs):
    """Naming the agent in the goal changes what the agent is told, not the physics, reward or success;
    the evaluation's closest distance stays the ball's to the target."""
    ball, both = envs
    push = lambda obs: jnp.tile(jnp.array([0.0, 1.0]), (obs.shape[0], 1))  # noqa: E731  at the ball and target
    key = jax.random.PRNGKey(1)
    alone, _ = loop.evaluate_policy(ball, push, key, 8)
    named, _ = loop.evaluate_policy(both, push, key, 8)
    assert float(alone["success_any"]) > 0  # the pushed balls reach the target
    for name in ("success_any", "time_at_goal", "episode_return", "closest_distance"):
        assert float(named[name]) == pytest.approx(float(alone[name]), rel=1e-5, abs=1e-6), name


@pytest.mark.slow
def test_the_evaluation_measures_how_far_the_ball_moved_from_its_kick_off(envs):
    """farthest_from_start is how far what the success judges (here the ball) moved from where the episode
    began: zero while nothing touches it, the pushed ball's way where the agent walks into it."""
    ball, _ = envs
    still = lambda obs: jnp.zeros((obs.shape[0], 2))  # noqa: E731
    push = lambda obs: jnp.tile(jnp.array([0.0, 1.0]), (obs.shape[0], 1))  # noqa: E731  at the ball and target
    key = jax.random.PRNGKey(1)
    rest, _ = loop.evaluate_policy(ball, still, key, 4)
    pushed, _ = loop.evaluate_policy(ball, push, key, 4)
    assert float(rest["farthest_from_start"]) == pytest.approx(0.0, abs=1e-3)
    # the balls start 1.5 ahead of the agent and 1.5 short of the target: a push carries them past 1
    assert float(pushed["farthest_from_start"]) > 1.0


def test_hindsight_success_reads_the_balls_entries_of_a_goal(envs):
    _, both = envs
    state = jax.jit(both.reset)(jax.random.PRNGKey(2)).obs[:both.state_dim]
    agent, ball = np.asarray(state[both.goal_indices[:2]]), np.asarray(state[both.goal_indices[2:]])
    far = np.array([3.0, -2.0])
    assert float(both.goal_reached(state, jnp.concatenate([far, ball]))) == 1.0
    assert float(both.goal_reached(state, jnp.concatenate([agent, far]))) == 0.0


@pytest.mark.slow
def test_crl_trains_on_goals_of_agent_and_ball(envs, tiny_crl):
    """CRL's positive pairs, drawn from the steps it stored as it trained: each step whose episode goes on is
    paired with the agent's and the ball's x, y at a later step of that episode; the episode's last step with
    none. Its losses stay finite, and its actor reads all four goal entries."""
    _, both = envs
    config = tiny_crl()
    algo = crl.make_train(config, both)
    state, rows = loop.run(algo, [0], 2)
    assert all(np.isfinite(r["critic_loss"]) for r in rows if r["eval"])
    trained = loop.seed_slice(state, 0)
    policy = algo.export(trained)
    assert policy.observes[0][-4:] == tuple(range(both.state_dim, both.state_dim + 4))

    length, windows = both.episode_length, config.num_envs
    # TINY_CRL stored 100 rows of prefill and 2 x 6 iterations of 10: whole windows, every row a stored step
    assert int(trained.buffer.size) == 220
    sampled = jax.device_get(replay.hindsight_batch(trained.buffer, jax.random.PRNGKey(3), windows, length,
                                                    config.discount, jnp.asarray(both.goal_indices)))
    named = [both.observation_names.index(n) for n in ("agent_x.pos", "agent_y.pos", "ball.x", "ball.y")]
    states = sampled["state"].reshape(windows, length, -1)[..., named]
    episodes, positive = (sampled[k].reshape(windows, length) for k in ("episode", "has_future"))
    goals = sampled["future_goal"].reshape(windows, length, 4)
    for w in range(windows):
        for i in range(length):
            later = [j for j in range(i + 1, length) if episodes[w, j] == episodes[w, i]]
            assert positive[w, i] == bool(later), (w, i)
            if later:
                assert any(np.array_equal(goals[w, i], states[w, j]) for j in later), (w, i, goals[w, i])
    assert (episodes[:, 1:] != episodes[:, :-1]).any()  # some windows cross an episode's end
