"""fieldgen's fields behind MuJoCo Playground's MjxEnv interface and inside its training wrappers."""

from __future__ import annotations

from mujoco_playground import MjxEnv, State, wrapper

from fieldgen.playground import PlaygroundField


def test_playground_wrappers_count_each_step_once_and_reset_to_fresh_episodes(env_cache, check_wrapped_episodes):
    """Inside Playground's vmap, episode and auto-reset wrappers an episode of point_nav lasts its 100 steps,
    ends truncated, and starts again somewhere new rather than at the first reset's start."""
    env = PlaygroundField(env_cache("point_nav"))
    assert isinstance(env, MjxEnv) and env.unwrapped is env and env.mjx_model is env.field.sys
    assert (env.action_size, env.observation_size, env.dt, env.n_substeps) == (2, 6, 0.05, 5)
    assert env.state_dim == env.field.state_dim and env.observation_names == env.field.observation_names
    wrapped = wrapper.wrap_for_brax_training(env, episode_length=env.episode_length)
    assert isinstance(check_wrapped_episodes(wrapped, env.action_size), State)


def test_playground_render_draws_its_states_through_fieldgens_renderer(env_cache):
    """Playground's render(trajectory, height, width) on its own State type, which has `data` where brax's has
    `pipeline_state`."""
    import jax

    env = PlaygroundField(env_cache("point_nav"))
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    frames = env.render([state, jax.jit(env.step)(state, jax.numpy.zeros(env.action_size))], height=64, width=80)
    assert [f.shape for f in frames] == [(64, 80, 3)] * 2
