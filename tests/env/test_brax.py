"""fieldgen's fields in brax's registry and inside brax's training wrappers."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from brax import envs
from brax.envs.wrappers import training

import fieldgen.brax


def test_every_bundled_field_and_a_spec_path_are_registered(write_spec):
    path = write_spec("extends: point_nav\nname: my_nav\n")
    names = fieldgen.brax.register(path)
    assert {"soccer_v2", "point_nav", "my_nav"} <= set(names)
    env = envs.get_environment("my_nav", episode_length=30)
    assert env.spec.name == "my_nav" and env.episode_length == 30
    assert env.unwrapped is env and env.backend == "mjx" and env.mjx_model is env.sys


def test_brax_wrappers_count_each_step_once_and_reset_to_fresh_episodes():
    """Inside brax's vmap, episode and auto-reset wrappers an episode of point_nav lasts its 100 steps (not
    50: the wrappers' step counter is brax's alone), ends truncated, and starts again somewhere new."""
    fieldgen.brax.register()
    env = envs.get_environment("point_nav")
    wrapped = training.wrap(env, episode_length=env.episode_length)
    assert wrapped.unwrapped is env and wrapped.observation_size == env.observation_size
    state = jax.jit(wrapped.reset)(jax.random.split(jax.random.PRNGKey(0), 4))
    first = np.asarray(state.obs)

    def step(state, _):
        state = wrapped.step(state, jnp.zeros((4, env.action_size)))
        return state, (state.done, state.info["truncation"], state.obs)

    _, (done, truncation, obs) = jax.jit(lambda s: jax.lax.scan(step, s, None, length=250))(state)
    ends = [int(t) + 1 for t in np.flatnonzero(np.asarray(done)[:, 0])]
    assert ends == [100, 200]  # the 100th and 200th steps end an episode
    assert np.all(np.asarray(truncation)[np.asarray(ends) - 1] == 1)
    restarted = [np.asarray(obs)[t - 1] for t in ends]  # the observation a done step returns: the next episode's start
    for start in restarted:
        assert not np.allclose(start, first)  # fresh, not brax's replay of the first reset
    assert not np.allclose(restarted[0], restarted[1])
