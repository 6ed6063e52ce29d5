"""The environment contract on every bundled field, on MJX and on brax's pipelines: reset and step pure under
jit+vmap, observations of the layout's size with the goal in place, finite numbers, every metric named."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from fieldgen.schema import bundled_fields, load_spec


def distinct_scenes(names: list[str]) -> list[str]:
    """One field per distinct scene and episode rule: fields that differ only in their reward terms or
    in how far their targets are drawn step the same physics through the same code (the terms are
    checked against their formulas in test_task)."""
    seen, kept = set(), []
    for name in names:
        spec = load_spec(bundled_fields()[name])
        ignored = {"name": True, "description": True, "extends": True,
                   "task": {"reward": True, "target": {"radius": True}}}
        key = repr(spec.model_dump(exclude=ignored))
        if key not in seen:
            seen.add(key)
            kept.append(name)
    return kept


ANT_FIELDS = distinct_scenes(sorted(n for n in bundled_fields() if not n.startswith("point")))


def rollout(env, n_envs=2, steps=3, seed=0):
    keys = jax.random.split(jax.random.PRNGKey(seed), n_envs)
    state = jax.jit(jax.vmap(env.reset))(keys)
    step = jax.jit(jax.vmap(env.step))
    actions = jax.random.uniform(jax.random.PRNGKey(seed + 1), (steps, n_envs, env.action_size), minval=-1, maxval=1)
    for a in actions:
        state = step(state, a)
    return state


def assert_contract(env, state, n_envs):
    assert state.obs.shape == (n_envs, env.observation_size)
    assert env.observation_size == env.state_dim + 2
    for x in (state.obs, state.reward, *state.metrics.values()):
        assert np.all(np.isfinite(np.asarray(x)))
    assert set(state.metrics) == set(env.metric_names) == {"success", *env.task.terms}
    goal_slice = slice(env.state_dim, env.state_dim + 2)
    np.testing.assert_array_equal(state.obs[:, goal_slice], state.info["goal"])


@pytest.mark.parametrize("name", ["point_nav", "point_soccer"])
def test_point_fields_step_under_jit_and_vmap(env_cache, name):
    env = env_cache(name)
    state = rollout(env, n_envs=4, steps=5)
    assert_contract(env, state, 4)
    assert int(state.info["episode_step"][0]) == 5


@pytest.mark.slow
@pytest.mark.parametrize("name", ANT_FIELDS)
def test_ant_fields_step_under_jit_and_vmap(env_cache, name):
    """The ant fields whose sim.backend names one of brax's pipelines are built and stepped here too."""
    env = env_cache(name)
    state = rollout(env, n_envs=2, steps=3)
    assert_contract(env, state, 2)
    assert env.action_size == 8
