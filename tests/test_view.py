"""`fieldgen view`: the viewer's player steps one environment exactly as the trainers' batch steps each of theirs,
its keys pause and draw new episodes, a machine without a display gets one line, and under a virtual X display
the window shows the agent and the ball where the spec puts them."""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import sys
import textwrap
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

from fieldgen.cli import app
from fieldgen.view import NEW_EPISODE_KEY, PAUSE_KEY, Player, no_display_reason

FIELD = "point_soccer"  # agent, ball, goal and target at a fraction of the ant's cost


@pytest.fixture(scope="module")
def player(env_cache):
    """A player on FIELD whose policy always pushes towards +x and +y, so every step moves the agent."""
    env = env_cache(FIELD)
    return Player(env, lambda obs: jnp.full(env.action_size, 0.5))


def test_a_seed_given_no_number_is_one_line_with_the_range():
    result = CliRunner().invoke(app, ["view", FIELD, "--seed", "first"])
    said = " ".join(result.output.split())
    assert result.exit_code == 1 and "--seed first: a seed" in said and "4,294,967,295" in said, said


def test_no_display_is_one_line_naming_render_and_eval(monkeypatch, tmp_path):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    result = CliRunner().invoke(app, ["view", FIELD])
    assert result.exit_code == 1
    assert result.output.count("\n") == 1 and "no display here" in result.output, result.output
    assert f"fieldgen render {FIELD} -o field.png" in result.output and "fieldgen eval RUN" in result.output
    policy = tmp_path / "policy"  # an exported policy: the render advice names a field, not the policy's folder
    policy.mkdir()
    (policy / "policy.json").write_text("{}")
    said = " ".join(CliRunner().invoke(app, ["view", str(policy)]).output.split())
    assert "fieldgen render FIELD -o field.png" in said and f"render {policy}" not in said, said
    run = tmp_path / "run"  # a run set up, not trained: eval would refuse it, so the advice trains it first
    run.mkdir()
    (run / "run.json").write_text("{}")
    said = " ".join(CliRunner().invoke(app, ["view", str(run)]).output.split())
    assert f"{run} has not trained yet: `fieldgen train --resume {run}` trains it, then `fieldgen eval" in said, said
    (run / "learner.msgpack").write_bytes(b"")
    said = " ".join(CliRunner().invoke(app, ["view", str(run)]).output.split())
    assert f"`fieldgen eval {run}` writes videos of its policy" in said and "not trained" not in said, said
    assert no_display_reason({"DISPLAY": ":1"}, "linux") is None
    assert no_display_reason({"WAYLAND_DISPLAY": "wayland-0"}, "linux") is None
    assert no_display_reason({}, "darwin") is None  # there the viewer itself says why it cannot open


@pytest.mark.slow
def test_a_step_observes_what_the_batched_environment_observes(player):
    env = player.env
    player.new_episode()
    before = player.state
    player.paused = False
    player.tick()
    batched = jax.jit(jax.vmap(env.step))(jax.tree.map(lambda x: x[None], before), jnp.full((1, env.action_size), 0.5))
    np.testing.assert_allclose(np.asarray(player.state.obs), np.asarray(batched.obs[0]), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(float(player.state.reward), float(batched.reward[0]), rtol=1e-6, atol=1e-6)
    assert not np.allclose(np.asarray(player.state.obs), np.asarray(before.obs))  # the policy's action moved it

    import mujoco

    data = mujoco.MjData(env.mj_model)
    player.show(env.mj_model, data)
    np.testing.assert_array_equal(data.qpos, np.asarray(player.state.pipeline_state.qpos))
    target = data.mocap_pos[0][:2]
    np.testing.assert_allclose(target, np.asarray(player.state.info["goal"]), atol=1e-6)  # the target is the goal


def test_keys_pause_and_draw_a_new_episode(player):
    player.new_episode()
    player.paused = False
    player.tick()
    stepped = player.state
    assert int(stepped.info["episode_step"]) == 1
    player.on_key(PAUSE_KEY)
    player.tick()
    assert player.paused and player.state is stepped  # paused: nothing steps
    player.on_key(ord("A"))  # not ours: the viewer's own keys are left to it
    assert player.paused and not player.new_episode_asked
    player.on_key(NEW_EPISODE_KEY)
    player.tick()
    fresh = player.state
    assert int(fresh.info["episode_step"]) == 0 and not player.new_episode_asked
    assert not np.allclose(np.asarray(fresh.obs), np.asarray(stepped.obs))  # a new draw, not the old start again
    player.on_key(PAUSE_KEY)
    player.tick()
    assert not player.paused and int(player.state.info["episode_step"]) == 1


def viewed(monkeypatch, source) -> list:
    """`fieldgen view SOURCE` with a display said to be there and the window left out: what it would have played,
    as (environment, act) pairs."""
    import fieldgen.view

    shown = []
    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.setattr(fieldgen.view, "Player", lambda env, act: shown.append((env, act)) or "player")
    monkeypatch.setattr(fieldgen.view, "open_viewer", lambda player, camera: "window")
    monkeypatch.setattr(fieldgen.view, "play", lambda handle, player, camera: None)
    result = CliRunner().invoke(app, ["view", str(source)])
    assert result.exit_code == 0, result.output
    return shown


@pytest.mark.parametrize("args,phrase", [
    (["point_nv"], "'point_nv' is neither a file, a folder nor a bundled field; did you mean 'point_nav'?"),
    ([FIELD, "--seed", "3"], f"--seed picks one of a run's seeds; {FIELD} is not a run folder"),
    ([FIELD, "--field", "point_nav"], f"--field names the field a policy plays on; {FIELD} is a field itself"),
], ids=["no_such_field", "seed_of_a_field", "field_of_a_field"])
def test_without_a_display_a_mistaken_argument_is_said_rather_than_advice_to_render_it(monkeypatch, args, phrase):
    """The display was looked for first: a field that is not there got advice to render it, an option the source
    does not take went unsaid."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    result = CliRunner().invoke(app, ["view", *args])
    assert result.exit_code == 1 and phrase in " ".join(result.output.split()), result.output
    assert "no display here" not in result.output


def test_an_exported_policy_plays_on_the_field_it_names_and_no_other(tmp_path, monkeypatch, env_cache):
    from fieldgen.agents.actor import Policy
    from fieldgen.policy_folder import describe, save_policy

    env = env_cache(FIELD)
    policy = Policy.whole(env, None, (8,), env.action_size)
    policy = policy.replace(params=policy.network.init(jax.random.PRNGKey(0), jnp.zeros((1, env.observation_size))))
    folder = tmp_path / "policy"
    save_policy(policy, describe(policy, env.observation_names, env.action_names, algorithm="crl", field=FIELD,
                                 seed=0, env_steps=0), folder)
    shown = viewed(monkeypatch, folder)
    (played_on, act), = shown
    assert played_on.spec.name == FIELD
    assert np.asarray(act(jnp.zeros(env.observation_size))).shape == (env.action_size,)
    result = CliRunner().invoke(app, ["view", str(folder), "--field", "point_nav"])
    assert result.exit_code == 1 and "observes or acts differently from point_nav" in result.output, result.output
    assert result.output.count("\n") == 1


def test_a_run_its_recipe_trained_on_the_dense_reward_plays_on_the_field_as_written(tmp_path, monkeypatch,
                                                                                       tiny_crl_args):
    from tiny_runs import as_if_learned

    from fieldgen.agents import recipes

    path = tmp_path / "recipes.yaml"
    path.write_text("point_nav:\n  algo: crl\n  reward: dense\n")
    monkeypatch.setattr(recipes.read, "__defaults__", (path,))
    result = CliRunner().invoke(app, ["train", "point_nav", "--prepare", "--out", str(tmp_path), *tiny_crl_args])
    assert result.exit_code == 0, result.output
    run = as_if_learned(tmp_path / "point_nav-crl-0")
    (run / "metrics.jsonl").write_text(json.dumps({"eval": 0, "seed": 0, "env_steps": 0, "success_any": 0.0}) + "\n")
    (env, _), = viewed(monkeypatch, run)
    assert [term.term for term in env.spec.task.reward] == ["success"]  # point_nav's own, not the dense terms


def test_a_self_play_run_plays_every_agent_of_both_sides_on_its_own_field(tmp_path, monkeypatch):
    """A self-play run's learner (its checkpoint, here its first state) drives each agent on that agent's own
    observation; the corner says each side's reward and goal; --field is refused, as the run plays its field alone."""
    from fieldgen import files
    from fieldgen.agents import checkpoint, loop
    from fieldgen.run import record, selfplay

    result = CliRunner().invoke(app, ["train", "soccer_1v1", "--steps", "2400", "--envs", "8", "--set",
                                      "ppo.unroll_length=10", "--set", "ppo.num_evals=3", "--set", "ppo.eval_envs=8",
                                      "--set", "ppo.num_minibatches=4",
                                      "--prepare", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    folder = tmp_path / "soccer_1v1-ppo-0"
    run = selfplay.open_run(folder)
    template = jax.eval_shape(jax.vmap(run.algorithm.init), loop.seed_keys(run.seeds))  # traced, not run
    state = jax.tree.map(lambda x: np.zeros(x.shape, x.dtype), template)
    files.write_atomic(folder / record.CHECKPOINT, checkpoint.pieces(state))
    (folder / record.METRICS).write_text(json.dumps({"eval": 0, "seed": 0, "env_steps": 0, "win_vs_random": 0.0,
                                                     "success_any": 0.0, "elo": 1000.0,
                                                     "league": {"random": {"win": 0, "draw": 8, "loss": 0}},
                                                     "ratings": {"random": 1000.0, "0": 1000.0}}) + "\n")
    shown = viewed(monkeypatch, folder)
    (env, act), = shown
    agents = len(env.agent_names)
    assert env.spec.name == "soccer_1v1" and agents == 2
    assert np.asarray(act(jnp.zeros((agents, env.observation_size)))).shape == (agents, env.action_size)
    result = CliRunner().invoke(app, ["view", str(folder), "--field", "soccer_2v2"])
    assert result.exit_code == 1 and "is a self-play run: it plays on its own team field alone" in result.output

    player = Player(env, act)  # at the kick-off: a step would compile the match's physics, seconds on a CPU
    field, step = player.status()[1].splitlines()[:2]
    assert field == "soccer_1v1, its policy on both sides"
    assert step == "0 of 400, reward home 0.000 away 0.000, goal home 0 away 0"


WINDOW = textwrap.dedent("""
    import json, os, shutil, sys
    import fieldgen, mujoco
    from fieldgen.view import Player, open_viewer, play

    env = fieldgen.make(sys.argv[1])
    player = Player(env)
    player.paused = True  # the kick-off, held still
    handle = open_viewer(player, "top", panels=False)
    play(handle, player, "top", seconds=1.5)
    shutil.copy(sys.argv[2], sys.argv[3])  # Xvfb's screen as it is now, the window open on it
    model, data, view = env.mj_model, handle.d, handle.viewport
    print(json.dumps({"size": [view.width, view.height], "camera": model.cam_pos[model.cam("top").id].tolist(),
                      "fovy": float(model.cam_fovy[model.cam("top").id]),
                      "at": {g: data.geom_xpos[model.geom(g).id].tolist() for g in ("agent", "ball")},
                      "rgba": {g: model.geom_rgba[model.geom(g).id].tolist() for g in ("agent", "ball")}}), flush=True)
    os._exit(0)  # the window goes with the process: closing it first races the viewer's thread mid-frame
""")


def xwd_rgb(path: Path) -> np.ndarray:
    """The RGB pixels of an XWD image of a 24-bit TrueColor screen, as Xvfb's -fbdir keeps it."""
    blob = path.read_bytes()
    header = struct.unpack(">25I", blob[:100])
    header_size, height, byte_order, bits, line, ncolors = (header[i] for i in (0, 5, 7, 11, 12, 19))
    assert bits == 32, f"expected 32 bits a pixel, not {bits}"
    start = header_size + 12 * ncolors
    pixels = np.frombuffer(blob[start:start + line * height], np.uint8).reshape(height, line // 4, 4)
    return pixels[..., [2, 1, 0]] if byte_order == 0 else pixels[..., [1, 2, 3]]


@pytest.fixture
def virtual_display(tmp_path):
    """(DISPLAY, the file Xvfb keeps its screen in) of an Xvfb server on a free display, stopped afterwards."""
    if shutil.which("Xvfb") is None:
        pytest.skip("Xvfb is not installed (Debian and Ubuntu: apt-get install xvfb)")
    server = subprocess.Popen(["Xvfb", "-displayfd", "1", "-screen", "0", "1024x768x24", "-fbdir", str(tmp_path),
                               "-nolisten", "tcp"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        number = server.stdout.readline().strip()
        if not number:
            pytest.skip("Xvfb did not start")
        yield f":{number}", tmp_path / "Xvfb_screen0"
    finally:
        server.terminate()
        server.wait(timeout=10)


def test_the_window_shows_the_agent_and_the_ball_where_the_spec_puts_them(virtual_display, tmp_path):
    from fieldgen.schema import load_spec, resolve_spec_path

    display, screen = virtual_display
    shot = tmp_path / "shot.xwd"
    env = {**os.environ, "DISPLAY": display, "MUJOCO_GL": "glfw"}
    env.pop("WAYLAND_DISPLAY", None)
    done = subprocess.run([sys.executable, "-c", WINDOW, FIELD, str(screen), str(shot)], env=env, capture_output=True,
                          text=True, timeout=180)
    assert done.returncode == 0, done.stderr[-3000:]
    shown = json.loads(done.stdout.strip().splitlines()[-1])
    spec = load_spec(resolve_spec_path(FIELD))
    agent, ball = np.array(shown["at"]["agent"]), np.array(shown["at"]["ball"])
    noise = spec.agent.reset_noise.qpos
    assert np.all(np.abs(agent[:2] - spec.agent.start) <= noise + 1e-6)
    for (low, high), at in zip((spec.ball.spawn.x, spec.ball.spawn.y), ball[:2]):
        assert low - 1e-6 <= at <= high + 1e-6

    image = xwd_rgb(shot).astype(float)
    width, height = shown["size"]
    (cx, cy, _), scale = shown["camera"], height / shown["fovy"]  # the top view: orthographic, fovy metres high
    for geom, (x, y, _) in shown["at"].items():
        col, row = round(width / 2 + (x - cx) * scale), round(height / 2 - (y - cy) * scale)
        seen = image[row - 4:row + 5, col - 4:col + 5].reshape(-1, 3).mean(axis=0)
        colour = 255 * np.array(shown["rgba"][geom][:3])
        assert np.abs(seen - colour).max() < 40, f"{geom} at pixel ({col}, {row}) looks {seen}, not {colour}"


def test_a_folder_of_none_of_what_view_plays_is_told_the_three_it_could_be(tmp_path, monkeypatch):
    """Before: told only that it was no built field, as if fieldgen build were the only way on."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    (tmp_path / "notes.txt").write_text("a user's folder\n")
    for extra in ([], ["--field", "point_nav"]):
        result = CliRunner().invoke(app, ["view", str(tmp_path), *extra])
        said = " ".join(result.output.split())
        assert result.exit_code == 1 and "holds nothing fieldgen view plays: no field.json" in said, result.output
        assert "run.json (a run fieldgen train wrote) or policy.json (a policy fieldgen export wrote)" in said
    assert (tmp_path / "notes.txt").read_text() == "a user's folder\n"
