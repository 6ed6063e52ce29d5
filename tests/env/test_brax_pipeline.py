"""Fields on brax's pipelines keep FieldEnv's contract: the same observations, terms and episode rules,
a ball pushed the same way as under MJX, fresh draws on every auto-reset, no NaN. brax compiles slowly
on CPU, so each test builds few environments and steps them briefly; the bundled fields on brax's pipelines
step in test_contract, beside those on MJX."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import fieldgen
from fieldgen.compile.artifact import compile_spec
from fieldgen.env.brax_pipeline import PIPELINES, BraxFieldEnv, check_batchable, load_system
from fieldgen.env.make import environment
from fieldgen.schema import FieldSpec, bundled_fields, load_spec
from fieldgen.schema.backends import BACKENDS, BRAX


def pusher(backend: str) -> FieldSpec:
    """The ant beside a small puck on its front-left diagonal, just beyond the foot's reach at rest:
    straightening that leg's ankle swings the foot out into the puck."""
    return FieldSpec.model_validate({
        "name": "pusher", "field": {"length": 12, "width": 12}, "goal": {"enabled": False},
        "ball": {"radius": 0.3, "spawn": {"x": 0.92, "y": 0.92}},
        "agent": {"kind": "ant", "reset_noise": {"qpos": 0.02, "qvel": 0.0}},
        "task": {"target": {"kind": "ring", "radius": 4}}, "episode": {"length": 25, "fall": {"kind": "never"}},
        "sim": {"backend": backend}})


@pytest.fixture(scope="module")
def rollouts():
    """Per backend: the env, its start, and a jitted 20-step rollout holding the front-left ankle straight."""
    out = {}
    for backend in (b for b in BACKENDS if BACKENDS[b].mjx_impl != "warp"):  # Warp's: tests/env/test_warp.py
        env = fieldgen.make(pusher(backend))
        action = jnp.zeros(env.action_size).at[env.action_names.index("front_left_ankle")].set(-1.0)
        run = jax.jit(lambda s, env=env, a=action: jax.lax.scan(lambda s, _: (env.step(s, a), None), s, None, length=20)[0])
        out[backend] = env, env.reset(jax.random.PRNGKey(0)), run
    return out


def test_each_brax_backend_of_the_registry_steps_on_its_pipeline():
    assert tuple(PIPELINES) == BRAX and all(callable(p.step) and callable(p.init) for p in PIPELINES.values())


def test_brax_q_is_mujoco_qpos():
    artifact = compile_spec(load_spec(bundled_fields()["soccer_v2_positional"]))
    model = artifact.model()
    system = load_system(artifact.xml, model)
    assert system.q_size() == model.nq and system.qd_size() == model.nv and system.act_size() == model.nu
    np.testing.assert_allclose(system.actuator.gear, 200.0)


def test_env_class_and_timing_follow_the_spec():
    env = fieldgen.make("ant_nav_spring")
    assert isinstance(env, BraxFieldEnv) and env.backend == "spring"
    assert (env.n_substeps, env.dt) == (10, 0.05)
    assert env.observation_names == fieldgen.make("ant_nav").observation_names


@pytest.mark.slow
def test_ant_nav_spring_steps_as_brax_own_spring_ant():
    """From the same state and with the same actions, ant_nav_spring's ant moves exactly as brax's `ant` on
    the spring pipeline, the CRL reference's ant: the comparisons with the reference measure the trainer and
    the task, not a different ant."""
    from brax import envs

    env = fieldgen.make("ant_nav_spring")
    theirs = envs.get_environment("ant", backend="spring", exclude_current_positions_from_observation=False)
    ours = env.reset(jax.random.PRNGKey(0))
    state = ours.pipeline_state
    reference = theirs.reset(jax.random.PRNGKey(0)).replace(pipeline_state=theirs.pipeline_init(state.qpos, state.qvel))
    actions = jax.random.uniform(jax.random.PRNGKey(1), (20, env.action_size), minval=-1.0, maxval=1.0)

    def trajectory(e, start, q, qd):
        def step(s, a):
            s = e.step(s, a)
            return s, jnp.concatenate([q(s), qd(s)])

        return np.asarray(jax.jit(lambda s: jax.lax.scan(step, s, actions)[1])(start))

    got = trajectory(env, ours, lambda s: s.pipeline_state.qpos, lambda s: s.pipeline_state.qvel)
    want = trajectory(theirs, reference, lambda s: s.pipeline_state.q, lambda s: s.pipeline_state.qd)
    assert np.ptp(got[:, :2], axis=0).max() > 0.01  # the ant moved
    np.testing.assert_allclose(got, want, atol=1e-5)


def test_mixed_variants_on_brax_are_refused():
    artifacts = [compile_spec(load_spec(bundled_fields()[n])) for n in ("soccer_v2_positional", "soccer_v2_solid_positional")]
    for refuse in (check_batchable, environment):
        with pytest.raises(ValueError, match="on MJX only; soccer_v2_positional runs on brax's positional pipeline"):
            refuse(artifacts)


@pytest.mark.slow
def test_the_same_actions_push_the_ball_the_same_way_on_every_backend(rollouts):
    moved = {}
    for backend, (env, start, run) in rollouts.items():
        ball = np.asarray(env.layout.ball_qpos)
        moved[backend] = np.asarray(run(start).pipeline_state.qpos[ball] - start.pipeline_state.qpos[ball])
    outward = np.array([1.0, 1.0]) / np.sqrt(2)  # along the front-left leg
    for backend, d in moved.items():
        assert np.linalg.norm(d) > 0.02 and d @ outward > 0.7 * np.linalg.norm(d), (backend, moved)


@pytest.mark.slow
def test_auto_reset_draws_fresh_starts_on_every_backend(rollouts):
    for backend, (env, start, run) in rollouts.items():
        state = run(run(start))  # 40 steps: the 25-step episode ended once
        assert int(state.info["episode"]) == 1, backend
        again = run(run(env.reset(jax.random.PRNGKey(0))))
        torso = np.asarray(env.layout.agent_qpos[:7])
        fresh = run(run(state))  # and again, from the new episode's own key
        assert not np.allclose(state.info["goal"], start.info["goal"]), backend
        assert not np.allclose(fresh.info["goal"], state.info["goal"]), backend
        np.testing.assert_allclose(again.info["goal"], state.info["goal"])  # the draws come from the state's key
        assert np.all(np.isfinite(np.asarray(state.pipeline_state.qpos[torso]))), backend
