"""The environment contract: pure reset/step under jit+vmap, fresh episodes, MJX agrees with MuJoCo C."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from backends import compare_backends
from fieldgen.schema import bundled_fields

ANT_FIELDS = sorted(n for n in bundled_fields() if not n.startswith("point"))


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
    assert np.all(np.isfinite(np.asarray(state.obs)))
    assert set(state.metrics) >= {"success", *env.task.terms}
    goal_slice = slice(env.state_dim, env.state_dim + 2)
    np.testing.assert_array_equal(state.obs[:, goal_slice], state.info["goal"])


@pytest.mark.parametrize("name", ["point_nav", "point_soccer"])
def test_point_fields_step_under_jit_and_vmap(env_cache, name):
    env = env_cache(name)
    state = rollout(env, n_envs=4, steps=5)
    assert_contract(env, state, 4)
    assert int(state.info["steps"][0]) == 5


@pytest.mark.slow
@pytest.mark.parametrize("name", ANT_FIELDS)
def test_ant_fields_step_under_jit_and_vmap(env_cache, name):
    env = env_cache(name)
    state = rollout(env, n_envs=2, steps=2)
    assert_contract(env, state, 2)
    assert env.action_size == 8


def test_auto_reset_draws_fresh_episodes(env_cache):
    """100 consecutive one-step episodes of one env never repeat a ball start or target."""
    env = env_cache("point_soccer", episode_length=1)
    state = env.reset(jax.random.PRNGKey(3))
    step = jax.jit(env.step)
    starts = []
    for _ in range(100):
        state = step(state, jnp.zeros(env.action_size))
        assert float(state.done) == 1.0
        starts.append(tuple(np.asarray(state.obs[4:6]).round(6)))
    assert len(set(starts)) == 100
    assert int(state.info["episode"]) == 100 and int(state.info["steps"]) == 0

    nav = env_cache("point_nav", episode_length=1)
    state = nav.reset(jax.random.PRNGKey(4))
    nav_step = jax.jit(nav.step)
    targets = set()
    for _ in range(100):
        state = nav_step(state, jnp.zeros(nav.action_size))
        targets.add(tuple(np.asarray(state.info["goal"]).round(6)))
    assert len(targets) == 100


def test_truncation_and_done_flags(env_cache):
    env = env_cache("point_nav", episode_length=3)
    state = env.reset(jax.random.PRNGKey(0))
    step = jax.jit(env.step)
    flags = []
    for _ in range(6):
        state = step(state, jnp.zeros(2))
        flags.append((float(state.done), float(state.info["truncation"])))
    assert flags == [(0, 0), (0, 0), (1, 1), (0, 0), (0, 0), (1, 1)]


def test_mjx_matches_mujoco_c_on_point_soccer(env_cache):
    """Float32 MJX against float64 MuJoCo C: 50 control steps within 1 cm."""
    ours, reference = compare_backends(env_cache("point_soccer", auto_reset=False), steps=50)
    np.testing.assert_allclose(ours, reference, atol=1e-2)


@pytest.mark.slow
def test_mjx_matches_mujoco_c_on_soccer_v2_in_float32(env_cache):
    """The ant's contacts amplify float32 rounding: the first 25 control steps agree within 5 mm / 5 mrad."""
    ours, reference = compare_backends(env_cache("soccer_v2", auto_reset=False), steps=25)
    np.testing.assert_allclose(ours, reference, atol=5e-3)


@pytest.mark.slow
def test_mjx_matches_mujoco_c_on_soccer_v2_in_float64():
    """With float64 JAX the two backends agree to 1e-6 over all 50 control steps."""
    script = Path(__file__).with_name("backends.py")
    done = subprocess.run([sys.executable, str(script), "soccer_v2", "50"], capture_output=True, text=True,
                          env={**os.environ, "JAX_ENABLE_X64": "1"}, check=True)
    assert float(done.stdout.split()[-1]) < 1e-6, done.stdout
