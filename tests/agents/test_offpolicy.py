"""SAC and TD3: the success predicate hindsight relabelling scores with, and SAC learning with it."""

from __future__ import annotations

from types import SimpleNamespace

import jax.numpy as jnp
import pytest

from fieldgen.agents import loop, sac, td3
from fieldgen.agents.config import ConfigError


def test_goal_reached_is_the_fields_success_on_any_goal(env_cache):
    point = env_cache("point_nav")  # agent_near_target, radius 0.5; the state starts with the point's x, y
    state = jnp.zeros(point.state_dim).at[:2].set(jnp.array([1.0, 2.0]))
    assert float(point.goal_reached(state, jnp.array([1.3, 2.3]))) == 1.0
    assert float(point.goal_reached(state, jnp.array([1.4, 2.4]))) == 0.0  # 0.57 away
    soccer = env_cache("soccer_v1")  # ball_near_target: the ball's x, y against the goal
    start, _ = soccer.layout.slices["ball_pos"]
    state = jnp.zeros(soccer.state_dim).at[start:start + 2].set(jnp.array([0.2, 9.8]))
    assert float(soccer.goal_reached(state, jnp.array([0.0, 10.0]))) == 1.0
    ant_there_ball_not = state.at[0:2].set(jnp.array([0.0, 10.0])).at[start:start + 2].set(jnp.array([3.0, 3.0]))
    assert float(soccer.goal_reached(ant_there_ball_not, jnp.array([0.0, 10.0]))) == 0.0


@pytest.mark.parametrize("algo", [sac.SACConfig, td3.TD3Config])
def test_hindsight_is_refused_where_the_success_ignores_the_goal(algo):
    """Told by the environment contract (`success_depends_on_goal`, `name`), not by a fieldgen spec."""
    config = algo(reward="sparse", her=0.5)
    field = SimpleNamespace(name="point_soccer", episode_length=200, success_depends_on_goal=False)
    with pytest.raises(ConfigError, match=f"{config.algo}.her needs a success that depends on the goal; "
                                          "point_soccer's does not"):
        config.validate_env(field)
    config.validate_env(SimpleNamespace(**{**vars(field), "success_depends_on_goal": True}))
    algo(reward="sparse").validate_env(field)  # without hindsight the success may ignore the goal


@pytest.mark.slow
def test_sac_with_hindsight_learns_point_nav(env_cache):
    """Sparse reward only, 80% of goals relabelled from the episode's future: from ~0 to at least 70%."""
    config = sac.SACConfig(total_steps=100_000, num_envs=16, unroll_length=25, batch_size=64, windows=64,
                           min_replay_rows=100, max_replay_rows=2000, hidden=(64, 64), num_evals=4, eval_envs=32,
                           reward="sparse", her=0.8)
    _, history = loop.run(sac.make_train(config, env_cache("point_nav")), [0], config.num_evals)
    assert history[0]["success_any"] <= 0.3
    assert history[-1]["success_any"] >= 0.7
