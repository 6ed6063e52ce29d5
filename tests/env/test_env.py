"""Episodes: fresh draws on auto-reset, truncation, divergence and falls, walls, and MJX agreeing with MuJoCo C."""

from __future__ import annotations

import functools
import os
import re
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from backends import compare_backends
import fieldgen
from fieldgen.schema import SpecError, bundled_fields, load_spec


@functools.cache
def zero_action_rollout(env, n: int):
    """A jitted n-step scan of one env with zero actions (the stacked states after each step); compiled once per
    env and length, for the tests that share it."""

    def body(state, _):
        state = env.step(state, jnp.zeros(env.action_size))
        return state, state

    return jax.jit(lambda s: jax.lax.scan(body, s, None, length=n))


def zero_action_steps(env, n: int, seed: int):
    """Step one env n times with zero actions; returns the last state and the stacked states after each step."""
    return zero_action_rollout(env, n)(env.reset(jax.random.PRNGKey(seed)))


def test_auto_reset_draws_fresh_episodes(env_cache):
    """100 consecutive one-step episodes of one env never repeat a ball start."""
    env = env_cache("point_soccer", episode_length=1)
    last, states = zero_action_steps(env, 100, seed=3)
    assert np.all(np.asarray(states.done) == 1.0)
    ball_starts = np.asarray(states.obs[:, slice(*env.layout.slices["ball_pos"])]).round(6)
    assert len({tuple(b) for b in ball_starts}) == 100
    assert int(last.info["episode"]) == 100 and int(last.info["episode_step"]) == 0


def test_auto_reset_draws_fresh_targets(env_cache):
    """100 consecutive three-step episodes of one env never repeat a target: the first episode's and the 100
    drawn on auto-reset are 101. The env and its compiled rollout are test_truncation_and_done_flags'."""
    nav = env_cache("point_nav", episode_length=3)
    last, states = zero_action_steps(nav, 300, seed=4)
    assert int(last.info["episode"]) == 100
    assert len({tuple(g) for g in np.asarray(states.info["goal"]).round(6)}) == 101


def test_truncation_and_done_flags(env_cache):
    env = env_cache("point_nav", episode_length=3)
    _, states = zero_action_steps(env, 300, seed=0)
    flags = list(zip(np.asarray(states.done)[:6].tolist(), np.asarray(states.info["truncation"])[:6].tolist()))
    assert flags == [(0, 0), (0, 0), (1, 1), (0, 0), (0, 0), (1, 1)]


def test_a_diverged_simulation_ends_its_episode_as_a_fall(write_spec):
    """A NaN or huge velocity (a blown-up MJX step) must not stay in the batch: the episode ends on that
    step with no reward, counted as a fall (not a truncation), and the next episode starts sound."""
    import fieldgen

    env = fieldgen.make(write_spec("extends: point_nav\nname: point_nav_dense\ntask:\n  reward:\n"
                                   "    - {term: success}\n    - {term: agent_progress, weight: 0.1}\n"))
    step = jax.jit(env.step)
    # not finite, beyond mujoco's own bound, and the growth before it: faster than any field moves
    for bad in (jnp.nan, jnp.inf, 2e10, 2e4):
        state = env.reset(jax.random.PRNGKey(0))
        state = state.replace(pipeline_state=state.pipeline_state.replace(qvel=jnp.full(2, bad)))
        nxt = step(state, jnp.zeros(2))
        assert float(nxt.done) == 1.0 and float(nxt.info["truncation"]) == 0.0
        assert float(nxt.reward) == 0.0 and all(float(v) == 0.0 for v in nxt.metrics.values())
        assert np.all(np.isfinite(np.asarray(nxt.obs))) and np.all(np.abs(np.asarray(nxt.pipeline_state.qvel)) < 1e3)
        assert int(nxt.info["episode"]) == 1 and int(nxt.info["diverged_episodes"]) == 1
        again = step(nxt.replace(pipeline_state=nxt.pipeline_state.replace(qvel=jnp.full(2, bad))), jnp.zeros(2))
        assert int(again.info["diverged_episodes"]) == 2  # counted over episodes, for the trainer to report
    sound = step(env.reset(jax.random.PRNGKey(0)), jnp.ones(2))
    assert float(sound.done) == 0.0 and np.isfinite(float(sound.reward))
    assert int(sound.info["diverged_episodes"]) == 0


def test_the_guard_spares_every_speed_and_place_a_field_reaches_and_stops_a_body_beyond_them():
    """The bound sits above what any field's motion reaches (a kicked ball, a spinning small ball, the
    farthest corner of the largest field) and below what a blow-up passes through on its way to mjMAXVAL."""
    from types import SimpleNamespace

    from fieldgen.env.field import MAX_DISTANCE, MAX_SPEED, diverged
    from fieldgen.schema.models import MAX_EXTENT

    def data(qvel=0.0, far=0.0):
        return SimpleNamespace(qpos=jnp.zeros(9), qvel=jnp.full(8, qvel), xpos=jnp.full((4, 3), far))

    assert not bool(diverged(data(qvel=3000.0, far=MAX_EXTENT)))  # a 1 cm ball rolling at 30 m/s; a corner
    assert bool(diverged(data(qvel=MAX_SPEED))) and bool(diverged(data(qvel=-MAX_SPEED)))
    assert bool(diverged(data(far=MAX_DISTANCE))) and bool(diverged(data(far=jnp.nan)))


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


def push_ball(env, velocity, steps=30):
    """Start the puck at its spawn centre with a given velocity; return its positions."""
    state = env.reset(jax.random.PRNGKey(0))
    ball = env.layout.ball_qpos
    data = state.pipeline_state
    data = data.replace(qpos=data.qpos.at[ball].set(jnp.array([0.0, 1.5])),
                        qvel=data.qvel.at[ball].set(jnp.asarray(velocity, jnp.float32)))

    def body(s, _):
        s = env.step(s, jnp.zeros(env.action_size))
        return s, s.pipeline_state.qpos[ball]

    _, path = jax.jit(lambda s: jax.lax.scan(body, s, None, length=steps))(state.replace(pipeline_state=data))
    return np.asarray(path)


def test_solid_walls_and_goalie_stop_the_ball(env_cache):
    env = env_cache("point_soccer", auto_reset=False)
    r = env.spec.ball.radius
    side = push_ball(env, [12.0, 0.0])
    assert side[:, 0].max() <= 3.0 - 0.05 - r + 0.02  # inner face of the right wall at x = 2.95
    assert side[-1, 0] < side[:, 0].max()  # it bounced back or stopped at the wall
    ahead = push_ball(env, [0.0, 8.0])
    goalie_front = 4.0 - 1.2 - 0.1
    assert ahead[:, 1].max() <= goalie_front - r + 0.02


def test_decorative_walls_let_the_ball_through(write_spec):
    import fieldgen

    spec = write_spec("extends: point_soccer\nname: ghost\nwalls: {solid: false}\nepisode: {length: 200}\n")
    env = fieldgen.make(spec, auto_reset=False)
    assert push_ball(env, [12.0, 0.0])[:, 0].max() > 3.5


FALL_RULES = {"flipped": {"kind": "flipped"}, "height_band": {"kind": "height_band", "band": [0.2, 1.0]},
              "never": {"kind": "never"}}
UPSIDE_DOWN = (0.0, 1.0, 0.0, 0.0)  # half a turn about x
TILTED_60 = (float(np.cos(np.pi / 6)), float(np.sin(np.pi / 6)), 0.0, 0.0)  # 60 degrees about x
POSES = {"upright and high": (1.6, (1.0, 0.0, 0.0, 0.0)), "upright and low": (0.15, (1.0, 0.0, 0.0, 0.0)),
         "upside down": (0.3, UPSIDE_DOWN), "tilted 60 degrees": (0.5, TILTED_60)}
FELL = {"flipped": {"upside down"}, "height_band": {"upright and high", "upright and low"}, "never": set()}


@pytest.mark.parametrize("rule", FALL_RULES)
def test_fall_rules_on_hand_set_torso_poses(env_cache, rule):
    """Each rule judges a torso set by hand: `flipped` only once it is turned over, however high or low
    a hop lands it; `height_band` (the study's) whenever it leaves the band; `never` not at all.
    The environment reads the pose from the simulation's own torso position and quaternion."""
    from fieldgen.env.rules import EpisodeRules

    env = env_cache("ant_nav")
    spec = env.spec.model_copy(update={"episode": env.spec.episode.model_validate(
        {**env.spec.episode.model_dump(), "fall": FALL_RULES[rule]})})
    rules = EpisodeRules(spec, env.mj_model, env.layout)
    data = env.reset(jax.random.PRNGKey(0)).pipeline_state
    fell = set()
    for name, (z, quat) in POSES.items():
        qpos = data.qpos.at[2].set(z).at[3:7].set(jnp.asarray(quat))
        time_up, fallen, _ = rules.ended(data.replace(qpos=qpos), jnp.asarray(1), jnp.asarray(0))
        assert not bool(time_up)
        if bool(fallen):
            fell.add(name)
    assert fell == FELL[rule]


def test_a_flipped_rule_with_a_smaller_tilt_ends_sooner():
    from fieldgen.env.contract import up_axis_z

    assert float(up_axis_z(jnp.asarray(TILTED_60))) == pytest.approx(0.5, abs=1e-6)
    assert float(up_axis_z(jnp.asarray(UPSIDE_DOWN))) == pytest.approx(-1.0)
    spec = load_spec(bundled_fields()["ant_nav"])
    from fieldgen.env.falls import fall_fn

    def flipped(**rule):
        return spec.model_copy(update={"episode": spec.episode.model_validate(
            {**spec.episode.model_dump(), "fall": {"kind": "flipped", **rule}})})

    assert bool(fall_fn(flipped(tilt_deg=45))[0](jnp.asarray([0.0, 0.0, 0.5]), jnp.asarray(TILTED_60)))
    assert not bool(fall_fn(flipped())[0](jnp.asarray([0.0, 0.0, 0.5]), jnp.asarray(TILTED_60)))


def test_ant_fields_end_on_time_unless_they_name_a_rule():
    """Bundled ant fields end episodes only when time runs out (the rule CRL learns the MJX ant under);
    soccer_v2_seed keeps the study's band, as it reproduces the study's scene."""
    specs = {name: load_spec(path) for name, path in bundled_fields().items()}
    assert specs["ant_nav"].episode.fall.kind == "never"
    assert specs["soccer_v2"].episode.fall.kind == "never"
    assert specs["soccer_v2_seed"].episode.fall.model_dump() == {"kind": "height_band", "band": (0.2, 1.0)}


def test_a_flipped_ant_with_grace_falls_only_once_it_stays_over(env_cache):
    """With grace_steps 2 an ant may lie turned over for two steps and right itself; the third ends it."""
    from fieldgen.env.rules import EpisodeRules

    env = env_cache("ant_nav")
    spec = env.spec.model_copy(update={"episode": env.spec.episode.model_validate(
        {**env.spec.episode.model_dump(), "fall": {"kind": "flipped", "grace_steps": 2}})})
    rules = EpisodeRules(spec, env.mj_model, env.layout)
    data = env.reset(jax.random.PRNGKey(0)).pipeline_state
    over = data.replace(qpos=data.qpos.at[3:7].set(jnp.asarray(UPSIDE_DOWN)))
    down, fell = jnp.asarray(0), []
    for pose in (over, over, data, over, over, over):
        _, fallen, down = rules.ended(pose, jnp.asarray(1), down)
        fell.append(bool(fallen))
    assert fell == [False, False, False, False, False, True]


@pytest.mark.parametrize("action", [jnp.ones(1), jnp.zeros(3), jnp.zeros((4, 2))])
def test_a_step_refuses_an_action_of_another_shape(env_cache, action):
    """A short action would be spread over every motor, a batch stepped without vmap fail deep in MJX."""
    env = env_cache("point_nav")
    state = env.reset(jax.random.PRNGKey(0))
    with pytest.raises(ValueError, match=re.escape(f"an action of shape {tuple(action.shape)}: point_nav takes (2,) "
                                                   "a step")):
        env.step(state, action)



def test_a_step_outside_jit_refuses_an_action_holding_nan_naming_its_motors(env_cache):
    """Before: the physics blew up and the episode ended as a fall, unsaid; under jit it still does (the divergence
    guard), where no value can be looked at."""
    env = env_cache("point_nav")
    state = env.reset(jax.random.PRNGKey(0))
    with pytest.raises(ValueError, match=re.escape(f"an action holding NaN or infinite values (for "
                                                   f"{env.action_names[1]}): the physics would blow up")):
        env.step(state, jnp.array([0.0, jnp.nan]))
    stepped = jax.jit(env.step)(state, jnp.array([0.0, jnp.nan]))  # traced: ended as a fall, as documented
    assert bool(stepped.done)

@pytest.mark.parametrize("source,options,phrase", [
    ("point_nva", {}, "point_nva: neither a file nor a bundled field; did you mean 'point_nav'? `fieldgen list`"),
    (None, {}, "fieldgen.make takes a FieldSpec, a YAML file, a bundled field's name or a build folder, not None"),
    ("", {}, "not ''"),
    ("point_nav", {"episode_length": 0}, "episode_length=0: give a whole number of control steps, 1 or more"),
    ("point_nav", {"episode_length": 2.5}, "episode_length=2.5"),
    ("point_nav", {"auto_reset": "no"}, "auto_reset='no': give True"),
    ("point_nav", {"kickoffs": [1, 2, 3]}, "point_nav: kickoffs come with kickoff_coordinates"),
])
def test_make_refuses_what_it_would_take_for_something_else(source, options, phrase):
    with pytest.raises((ValueError, TypeError, SpecError), match=re.escape(phrase)):
        fieldgen.make(source, **options)
