"""sim.backend warp: the mjx field stepped by MuJoCo Warp's kernels (on a CPU, Warp's CPU kernels), with Warp's
capacities taken from the build and sized for the batch, and an environment that outgrows them stopped with one
line, never left to step without its contacts."""

from __future__ import annotations

import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fieldgen.agents import loop
from fieldgen.env import mjx_physics
from fieldgen.env.make import make

pytest.importorskip("warp")

NEFC, NARROWPHASE, ITERATIONS = 1, 8, 512  # mujoco_warp's OverflowType: rows beyond njmax, contacts beyond
# naconmax; solver iterations used up


def rollout(env, steps: int, n: int = 2):
    """The batch's state after `steps` control steps of a fixed action from the same fresh episodes."""
    env.reserve_worlds(n)
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), n))
    step = jax.jit(jax.vmap(env.step))
    action = jnp.full((n, env.action_size), 0.5)
    for _ in range(steps):
        state = step(state, action)
    return state


@pytest.mark.slow
@pytest.mark.parametrize("field", ["point_nav", "ant_nav", "ant_nav with elliptic cones"])
def test_warp_steps_the_field_s_own_physics_beside_jax(field, tmp_path):
    """At the fields' one solver iteration, where Warp's own start of the solve left the ant 0.1-0.5 away in some
    position after 10 control steps (bench/warp_agreement.py), the two agree to float32's rounding."""
    if field.endswith("elliptic cones"):
        field = tmp_path / "ant_nav_elliptic.yaml"
        field.write_text("extends: ant_nav\nname: ant_nav_elliptic\nsim: {cone: elliptic}\n")
        field = str(field)
    warp, jax_ = make(field, backend="warp"), make(field, backend="mjx")
    assert (warp.impl, jax_.impl) == ("warp", "jax") and warp.mj_model.opt.iterations == 1
    stepped, reference = rollout(warp, 10), rollout(jax_, 10)
    qpos = np.asarray(stepped.pipeline_state.qpos)
    assert np.all(np.isfinite(qpos)) and not np.allclose(qpos, np.asarray(warp.rules[0].home_qpos))
    assert np.max(np.abs(qpos - np.asarray(reference.pipeline_state.qpos))) < 1e-4
    assert mjx_physics.OVERFLOW not in reference.info
    warp.check_physics(stepped.info[mjx_physics.OVERFLOW])  # no capacity outgrown


@pytest.mark.slow
def test_an_environment_outgrowing_warp_s_constraint_rows_stops_training_with_one_line(monkeypatch):
    real = mjx_physics.capacities
    monkeypatch.setattr(mjx_physics, "capacities", lambda model: (real(model)[0], 1))  # one row: a contact needs more
    env = make("soccer_v1", backend="warp")
    state = rollout(env, 1)
    assert np.bitwise_or.reduce(np.asarray(state.info[mjx_physics.OVERFLOW])) & NEFC
    with pytest.raises(mjx_physics.PhysicsOverflow) as stopped:
        loop.stop_on_overflow(env, state.info[mjx_physics.OVERFLOW])  # as training reads it after each chunk
    message = str(stopped.value)
    assert "\n" not in message and message.startswith("soccer_v1: ") and "(NEFC; " in message
    assert "x 2 environments reserved, 1 constraint rows per environment" in message and "sim.backend: mjx" in message


def test_only_a_capacity_outgrown_is_an_overflow():
    env = make("point_nav", backend="warp")
    env.check_physics(0)
    env.check_physics(ITERATIONS)  # the solver's iteration limit reached: the step is whole
    with pytest.raises(mjx_physics.PhysicsOverflow, match=r"^point_nav: .*\(NARROWPHASE; 0 contacts per environment x 1 "):
        env.check_physics(NARROWPHASE | ITERATIONS)
    loop.stop_on_overflow(env, None)  # a field on JAX's implementation has no flags to read


def test_warp_data_is_sized_for_the_batch_reserved():
    env = make("soccer_v1", backend="warp")
    contacts, rows = mjx_physics.capacities(env.mj_model)
    assert contacts > 0 and rows > 0
    env.reserve_worlds(8)
    env.reserve_worlds(4)  # a smaller batch fits what is reserved
    data = env.rules[0].data0
    assert (env.worlds, data._impl.naconmax, data._impl.njmax) == (8, 8 * contacts, rows)
    assert make("soccer_v1").rules[0].impl == "jax"


def test_warp_variants_in_one_batch_are_refused_with_the_reason():
    from fieldgen.env.batch import batched_model

    env = make("point_nav", backend="warp")
    with pytest.raises(ValueError, match=r"point_nav: variants batched in one model \(a mixed curriculum's stages, "
                                         r"--curriculum auto's levels\) run on sim.backend mjx only"):
        batched_model([env.mj_model, env.mj_model], ["point_nav", "point_nav"], "warp")


def test_an_automatic_curriculum_of_a_warp_field_is_refused_before_anything_is_written(tmp_path):
    """Before: a traceback from the batch, after the run folder was written."""
    from typer.testing import CliRunner

    from fieldgen.cli import app

    spec = tmp_path / "point_soccer_warp.yaml"
    spec.write_text("extends: point_soccer\nname: point_soccer_warp\nsim: {backend: warp}\n")
    result = CliRunner().invoke(app, ["train", str(spec), "--curriculum", "auto", "--no-recipe", "--envs", "8",
                                      "--prepare", "--out", str(tmp_path / "runs")])
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert "variants batched in one model (a mixed curriculum's stages, --curriculum auto's levels) run on " \
           "sim.backend mjx only" in " ".join(result.output.split())
    assert not (tmp_path / "runs").exists()


def test_another_library_s_wrappers_take_a_warp_field_once_its_batch_is_reserved():
    from fieldgen.brax import BraxField

    field = make("point_nav", backend="warp")
    with pytest.raises(ValueError, match=r"^point_nav runs on sim.backend warp, .*field.reserve_worlds\(N\)"):
        BraxField(field)
    field.reserve_worlds(4)
    assert BraxField(field).field is field
    assert BraxField(make("point_nav")).field.impl == "jax"


def test_a_seed_s_carry_leaves_the_batch_s_shared_contact_buffer_unbatched():
    """agents.loop.batched_with ties every leaf of an evaluation's carry to its seed but Warp's contact buffer,
    which the whole batch of every seed shares: tied, a vmap over seeds would batch it and Warp refuse it."""
    key = jax.random.PRNGKey(3)
    tree = {"_impl": {"contact__dist": jnp.ones(6), "qpos": jnp.ones((2, 3))}, "alive": jnp.ones(2)}
    tied = jax.vmap(lambda k: loop.batched_with(k, tree))(jax.random.split(key, 4))
    assert tied["_impl"]["qpos"].shape == (4, 2, 3) and tied["alive"].shape == (4, 2)
    shared = jax.vmap(lambda k: loop.batched_with(k, tree)["_impl"]["contact__dist"], out_axes=None)(
        jax.random.split(key, 4))  # out_axes=None: refused for a leaf batched over the seeds
    np.testing.assert_array_equal(np.asarray(shared), np.ones(6))


@pytest.mark.slow
def test_ppo_trains_and_evaluates_seeds_on_warp_s_physics(tmp_path):
    """Two seeds vmapped, an evaluation batch smaller than training's, stopped and resumed: the run ends with its
    metrics."""
    import json

    from typer.testing import CliRunner

    from fieldgen.cli import app

    spec = tmp_path / "warp_soccer.yaml"
    spec.write_text("extends: point_soccer\nname: warp_soccer\nsim: {backend: warp}\n")  # with contacts
    # a time limit shorter than the first chunk stops the run after it; the resume refills its environments
    # placed as the start placed them, sized for the whole batch
    result = CliRunner().invoke(app, ["train", str(spec), "--algo", "ppo", "--steps", "4000", "--envs", "4",
                                      "--seeds", "2", "--set", "ppo.unroll_length=10", "--set",
                                      "ppo.num_minibatches=4", "--set", "ppo.num_evals=2", "--set", "ppo.eval_envs=2",
                                      "--no-videos", "--out", str(tmp_path / "runs"), "--time-limit", "0.01s"])
    assert result.exit_code == 75 and "stopped at the time limit" in result.output, result.output  # EX_TEMPFAIL
    run = tmp_path / "runs" / "warp_soccer-ppo-0to1"
    (run / "checkpoint.msgpack").unlink()  # as a run carried between machines without it: from the learner alone
    result = CliRunner().invoke(app, ["train", "--resume", str(run), "--no-videos"])
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())
    assert "goes on from learner.msgpack with fresh episodes" in said and "replay buffer" not in said  # PPO keeps none
    rows = [json.loads(line) for line in (run / "metrics.jsonl").open()]
    assert sorted((r["eval"], r["seed"]) for r in rows) == [(e, s) for e in range(3) for s in (0, 1)]


def test_native_lines_on_stderr_pass_but_the_one_held_back_and_the_call_s_result_or_error_comes_through(capfd):
    def speaks():
        os.write(2, b"Warp CUDA warning: Could not find or load the NVIDIA CUDA driver. GPU execution will not be "
                    b"available.\nsomething else native\n")
        return 7

    assert mjx_physics.without_native_line(speaks, mjx_physics.NO_CUDA_DRIVER) == 7
    assert capfd.readouterr().err == "something else native\n"

    def fails():
        os.write(2, b"a last word\n")
        raise ValueError("kept")

    with pytest.raises(ValueError, match="kept"):
        mjx_physics.without_native_line(fails, mjx_physics.NO_CUDA_DRIVER)
    os.write(2, b"after\n")  # stderr is the terminal's again
    assert capfd.readouterr().err == "a last word\nafter\n"


def test_making_a_warp_field_on_a_machine_without_nvidia_s_driver_says_nothing_of_it(tmp_path):
    code = "from fieldgen.env.make import make; make('point_nav', backend='warp').reserve_worlds(2); print('made')"
    said = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, check=False)
    assert said.returncode == 0 and said.stdout.strip() == "made", said.stderr
    assert "Warp CUDA warning" not in said.stderr


def test_a_batch_larger_than_reserved_is_refused_as_its_program_is_traced():
    """Before: a vmap over more environments than reserved stepped them with Warp's contacts left out, flagged in
    their info alone (a replay of 64 kick-offs scored in 8 of them where 56 of 64 was the policy's due)."""
    env = make("point_nav", backend="warp")
    states = jax.vmap(env.reset)(jax.random.split(jax.random.PRNGKey(0), 6))
    actions = jnp.zeros((6, env.action_size))
    with pytest.raises(mjx_physics.UnreservedBatch) as refused:
        jax.jit(jax.vmap(env.step))(states, actions)
    message = str(refused.value)
    assert "\n" not in message and message.startswith("point_nav runs on sim.backend warp")
    assert "steps 6 at once where 1 were reserved" in message and "env.reserve_worlds(6)" in message
    def nested():  # seeds x environments, their data sized for the batch reserved
        keys = jax.random.split(jax.random.PRNGKey(1), 6).reshape(2, 3, -1)
        return jax.vmap(jax.vmap(env.reset))(keys), jnp.zeros((2, 3, env.action_size))

    env.reserve_worlds(4)
    with pytest.raises(mjx_physics.UnreservedBatch, match=r"steps 6 at once where 4 were reserved"):
        jax.jit(jax.vmap(jax.vmap(env.step)))(*nested())  # the product of the two counts
    env.reserve_worlds(6)
    stepped = jax.jit(jax.vmap(jax.vmap(env.step)))(*nested())
    env.check_physics(stepped.info[mjx_physics.OVERFLOW])
    one = jax.jit(env.step)(env.reset(jax.random.PRNGKey(2)), actions[0])  # no batch: nothing to refuse
    assert one.obs.shape == (env.observation_size,)


# -- team fields: matches reserved and flagged as a single-agent field's batches ------------------------------

def test_a_team_field_on_warp_refuses_a_batch_of_matches_larger_than_reserved():
    """Before: a match had no reservation, its data sized for one, and a vmap of matches stepped them all with
    Warp's contacts left out, flagged in their info alone."""
    env = make("soccer_1v1", backend="warp")
    keys = jax.random.split(jax.random.PRNGKey(0), 6)
    actions = jax.ShapeDtypeStruct((6, len(env.agent_names), env.action_size), jnp.float32)

    def traced():  # six matches stepped once: traced, never run
        return jax.eval_shape(jax.vmap(env.step), jax.eval_shape(jax.vmap(env.reset), keys), actions)

    with pytest.raises(mjx_physics.UnreservedBatch) as refused:
        traced()
    message = str(refused.value)
    assert "\n" not in message and message.startswith("soccer_1v1 runs on sim.backend warp")
    assert "steps 6 at once where 1 were reserved" in message and "env.reserve_worlds(6)" in message
    env.reserve_worlds(6)
    assert env.worlds == 6 and env.data0._impl.naconmax == 6 * mjx_physics.capacities(env.mj_model)[0]
    assert mjx_physics.OVERFLOW in traced().info
    assert make("soccer_1v1").worlds == 1  # JAX's physics reserves nothing


def chased_matches(backend: str, n: int = 8):
    """soccer_1v1's environment and its n matches after 32 control steps in which each agent runs at the ball,
    jittered (random actions meet nothing in tens of steps); the agents reach the ball at about 25."""
    env = make("soccer_1v1", backend=backend)
    env.reserve_worlds(n)
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), n))

    def chase(state, key):
        obs = state.obs  # [matches, agents, n]: own x, y first, the ball's x, y at 4:6, each in its side's frame
        toward = jnp.clip(3.0 * (obs[..., 4:6] - obs[..., 0:2]), -1.0, 1.0)
        return jax.vmap(env.step)(state, toward + jax.random.uniform(key, toward.shape, minval=-0.3, maxval=0.3))

    step = jax.jit(chase)
    for key in jax.random.split(jax.random.PRNGKey(1), 32):
        state = step(state, key)
    return env, state


def test_team_matches_reserved_on_warp_keep_their_contacts():
    """Before: 8 matches of soccer_1v1 on Warp shared the contacts of one, and once their agents reached the
    ball every match's flags said contacts were left out (BROADPHASE). Every match now keeps its own, the ball
    struck in each."""
    env, state = chased_matches("warp")
    env.check_physics(state.info[mjx_physics.OVERFLOW])
    qpos = np.asarray(state.pipeline_state.qpos)
    assert np.all(np.linalg.norm(qpos[:, np.asarray(env.layout.ball_qpos[:2])], axis=1) > 0)


@pytest.mark.slow
def test_team_matches_on_warp_step_as_on_jax():
    """The same matches step on Warp as on JAX's implementation (whose 8-match step compiles for tens of seconds
    on a CPU)."""
    qpos = np.asarray(chased_matches("warp")[1].pipeline_state.qpos)
    np.testing.assert_allclose(qpos, np.asarray(chased_matches("mjx")[1].pipeline_state.qpos), atol=1e-4)


def test_self_play_s_programs_reserve_every_team_match_they_step_before_any_is_traced():
    """Training steps seeds x num_envs matches at once, an evaluation seeds x eval_envs: reserved for one seed's
    alone, two seeds' training is refused as it is traced; fieldgen.run.selfplay.programs reserves the larger of
    the two for every seed (all traced, none run)."""
    from fieldgen.agents.selfplay import SelfPlayConfig, make_selfplay
    from fieldgen.run import selfplay

    config = SelfPlayConfig(total_steps=1600, num_envs=4, unroll_length=10, num_minibatches=4, num_evals=2,
                            hidden=(8,), eval_envs=6)
    keys = loop.seed_keys([0, 1])
    short = make_selfplay(config, make("soccer_1v1", backend="warp"))
    short.env.reserve_worlds(config.num_envs)
    with pytest.raises(mjx_physics.UnreservedBatch, match="this program steps 8 at once where 4 were reserved"):
        jax.eval_shape(jax.vmap(short.chunk), jax.eval_shape(jax.vmap(short.init), keys))
    sp, init, chunk, judge, _ = selfplay.programs(config, make("soccer_1v1", backend="warp"), 2)
    assert sp.env.worlds == 2 * 6
    state = jax.eval_shape(init, keys)
    jax.eval_shape(chunk, state)
    _, results = jax.eval_shape(judge, state, 1, selfplay.opponents_of(1, config.league_opponents), keys)
    assert results[mjx_physics.OVERFLOW].shape == (2,)  # each seed's matches' flags, read after the evaluation


def test_a_team_match_that_outgrew_warp_s_capacity_stops_self_play_in_one_line():
    """What self-play does with the flags it reads after a chunk or an evaluation (no match stepped here)."""
    from fieldgen.run import record, selfplay

    env = make("soccer_1v1", backend="warp")
    selfplay.stop_if_overflowed(env, np.array([0, ITERATIONS]), "training")  # the solver's limit: the step is whole
    selfplay.stop_if_overflowed(make("soccer_1v1"), None, "training")  # JAX's physics flags nothing
    with pytest.raises(record.RunError) as stopped:
        selfplay.stop_if_overflowed(env, np.array([[0, NARROWPHASE], [0, 0]]), "evaluation")
    message = str(stopped.value)
    assert "\n" not in message and message.startswith("evaluation stopped: soccer_1v1: an environment outgrew MuJoCo "
                                                      "Warp's capacity (NARROWPHASE; ")
    assert message.endswith("or use sim.backend: mjx")


@pytest.mark.slow
def test_a_team_field_on_warp_trains_by_self_play_and_is_judged_with_every_match_s_contacts(tmp_path):
    """Two seeds of the tiny self-play run (matches of 40 steps: Warp's CPU kernels are slow), each program's
    matches reserved (seeds x matches) and their flags read after every chunk and evaluation, then judged: the run
    ends, its matches' flags clear. Before: the matches shared one match's contacts, and training went on without
    a word."""
    from typer.testing import CliRunner

    from fieldgen.cli import app
    from fieldgen.run import selfplay
    from tiny_runs import TINY_SELFPLAY

    spec = tmp_path / "soccer_1v1_warp.yaml"
    spec.write_text("extends: soccer_1v1\nname: soccer_1v1_warp\nsim: {backend: warp}\nepisode: {length: 40}\n")
    result = CliRunner().invoke(app, ["train", str(spec), "--seeds", "2", "--no-videos",
                                      "--out", str(tmp_path / "runs"), *TINY_SELFPLAY])
    assert result.exit_code == 0, result.output
    run = selfplay.open_run(tmp_path / "runs" / "soccer_1v1_warp-ppo-0to1")
    assert [(r["eval"], r["seed"]) for r in run.rows] == [(i, s) for i in range(4) for s in (0, 1)]
    assert run.algorithm.env.worlds == 2 * 8  # seeds x the larger of training's and evaluation's matches
    run.env.check_physics(run.state.env_state.info[mjx_physics.OVERFLOW])  # every training match's, kept
    result = CliRunner().invoke(app, ["eval", str(run.folder), "--no-video"])
    assert result.exit_code == 0 and "Elo ratings" in result.output, result.output


@pytest.mark.parametrize("cone", ["pyramidal", "elliptic"])
def test_warp_s_solve_starts_from_the_cheaper_of_the_warm_start_and_the_unconstrained_acceleration(cone):
    """MuJoCo's choice (fieldgen.env.warp_start): a warm start at the converged solution is kept, one far from it
    gives way to the unconstrained acceleration, world by world."""
    import mujoco
    from mujoco.mjx.third_party import mujoco_warp as mjwarp

    from fieldgen.env import warp_start

    mjm = make("ant_nav", backend="warp").mj_model
    mjm.opt.cone = {"pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL, "elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC}[cone]
    mjd = mujoco.MjData(mjm)
    mjd.qpos[:] = mjm.key("home").qpos
    mjd.qpos[2] -= 0.05  # pressed into the floor: contacts push back
    mjm.opt.iterations, mjm.opt.ls_iterations = 100, 50
    mujoco.mj_forward(mjm, mjd)
    solved = mjd.qacc.copy()
    mjm.opt.iterations, mjm.opt.ls_iterations = 1, 4
    mjx_physics.start_warp()
    m, d = mjwarp.put_model(mjm), mjwarp.put_data(mjm, mjd, nworld=2)
    assert warp_start.covers(m)
    mjwarp.forward(m, d)
    assert int(d.nefc.numpy()[0]) > 0
    d.qacc_warmstart.assign(np.stack([solved, solved + 1e3]).astype(np.float32))
    start = warp_start.mujoco_start(m, d).qacc_warmstart.numpy()
    np.testing.assert_array_equal(start[0], solved.astype(np.float32))
    np.testing.assert_array_equal(start[1], d.qacc_smooth.numpy()[1])


def test_warp_s_solve_is_wrapped_once_a_process_and_can_be_given_back():
    """Starting Warp wraps its solve once however often a field starts it; `remove` gives Warp's own start back (the
    benches' --warp-start warp) and `install` wraps it again."""
    from mujoco.mjx.third_party.mujoco_warp._src import solver

    from fieldgen.env import warp_start

    mjx_physics.start_warp()
    wrapped = solver._solve
    assert getattr(wrapped, warp_start.PATCHED) and not getattr(wrapped.__wrapped__, warp_start.PATCHED, False)
    warp_start.install()
    assert solver._solve is wrapped
    try:
        warp_start.remove()
        assert solver._solve is wrapped.__wrapped__
        warp_start.remove()
        assert solver._solve is wrapped.__wrapped__
    finally:
        warp_start.install()
    assert getattr(solver._solve, warp_start.PATCHED) and solver._solve.__wrapped__ is wrapped.__wrapped__
