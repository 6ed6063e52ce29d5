"""fieldgen's fields in brax's registry and inside brax's training wrappers."""

from __future__ import annotations

import pytest
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


def test_brax_wrappers_count_each_step_once_and_reset_to_fresh_episodes(check_wrapped_episodes):
    """Inside brax's vmap, episode and auto-reset wrappers an episode of point_nav lasts its 100 steps (not
    50: the wrappers' step counter is brax's alone), ends truncated, and starts again somewhere new."""
    fieldgen.brax.register()
    env = envs.get_environment("point_nav")
    wrapped = training.wrap(env, episode_length=env.episode_length)
    assert wrapped.unwrapped is env and wrapped.observation_size == env.observation_size
    check_wrapped_episodes(wrapped, env.action_size)


def test_the_adapters_refuse_what_they_would_misread(tmp_path):
    """A name given where an environment goes, a spec that would replace a bundled field under brax's name, an
    episode length a made environment would ignore: each refused in words."""
    import fieldgen
    from fieldgen.brax import BraxField, register
    from fieldgen.playground import PlaygroundField

    with pytest.raises(TypeError, match="wrap an environment fieldgen.make returns, not 'point_nav'"):
        BraxField("point_nav")
    shadow = tmp_path / "shadow.yaml"
    shadow.write_text("extends: point_nav\nname: ant_nav\n")
    with pytest.raises(ValueError, match="is named ant_nav, as a bundled field is"):
        register(str(shadow))
    assert "point_nav" in register("point_nav")  # a bundled name, as make takes it
    with pytest.raises(ValueError, match="episode_length=7 for an environment already made, whose episodes are 100"):
        PlaygroundField(fieldgen.make("point_nav"), episode_length=7)
