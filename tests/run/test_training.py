"""Training runs: exact resume after an interrupt, run folders, and bad input caught before compiling."""

from __future__ import annotations

import json
import re
from pathlib import Path

import flax.struct
import jax
import numpy as np
import pytest
from typer.testing import CliRunner

from fieldgen.agents import checkpoint, crl, loop
from fieldgen.agents.buffer import gradient_steps
from fieldgen.agents.config import ConfigError
from fieldgen.agents.registry import trainer
from fieldgen.cli import app
from fieldgen.run import record

runner = CliRunner()


def unwrapped(text: str) -> str:
    """The text without whitespace: the console breaks long paths anywhere."""
    return "".join(text.split())


class Stop(Exception):
    pass


@flax.struct.dataclass
class Snapshot:
    """Stands in for a training state where only its name and its environments' fields matter."""
    name: str = flax.struct.field(pytree_node=False)
    env_state: object = flax.struct.field(pytree_node=False)
    buffer: object = flax.struct.field(pytree_node=False)


@flax.struct.dataclass
class Episodes:
    """Stands in for a batch of environments of one field: nothing of how they draw episodes to keep."""
    info: dict = flax.struct.field(pytree_node=False, default_factory=dict)


EPISODES = Episodes()


def no_opengl(*args, **kwargs):
    """Stands in for the renderer of a machine without OpenGL."""
    raise RuntimeError("no OpenGL here")


@pytest.mark.slow
def test_resume_after_interrupt_reproduces_the_uninterrupted_run(env_cache, tmp_path, tiny_crl):
    algo = crl.make_train(tiny_crl(), env_cache("point_nav"))
    full, _ = loop.run(algo, [0], 2)

    saved = {}

    def save_then_stop(ts, index):
        saved[index] = checkpoint.to_bytes(ts)
        if index == 1:
            raise Stop

    with pytest.raises(Stop):
        loop.run(algo, [0], 2, on_eval=save_then_stop)
    template = jax.eval_shape(jax.vmap(algo.start), jax.random.PRNGKey(0)[None])
    (tmp_path / "c.msgpack").write_bytes(saved[1])
    restored = checkpoint.load(tmp_path / "c.msgpack", template)
    resumed, history = loop.run(algo, [0], 2, resume=(restored, 1))
    assert [row["eval"] for row in history] == [2] and "refilled_from" not in history[0]
    for a, b in zip(jax.tree.leaves(full.nets), jax.tree.leaves(resumed.nets)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert int(full.env_steps[0]) == int(resumed.env_steps[0])

    # what a learner checkpoint keeps: no episode, no replay buffer; training goes on from it with the same
    # networks, fresh episodes and a buffer filled anew, its prefill counted in the env steps
    learned = algo.learned(restored)
    assert learned.env_state is None and learned.buffer is None and not algo.holds_environments(learned)
    environments = sum(np.asarray(x).nbytes for x in jax.tree.leaves((restored.env_state, restored.buffer)))
    assert len(saved[1]) - len(checkpoint.to_bytes(learned)) >= environments
    prefill, chunk = 800, 6 * 80  # 10 iterations of 8 envs x 10 steps fill min_replay_rows; a chunk is 6
    refilled, history = loop.run(algo, [0], 1, resume=(learned, 1))  # nothing left to train: refilled alone
    assert history == [] and algo.holds_environments(refilled) and int(refilled.buffer.size[0]) == 100
    assert int(refilled.env_steps[0]) == 1280 + prefill
    for a, b in zip(jax.tree.leaves(learned.nets), jax.tree.leaves(refilled.nets)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    trained, history = loop.run(algo, [0], 2, resume=(learned, 1))
    assert [row["eval"] for row in history] == [2] and history[0]["env_steps"] == 1280 + prefill + chunk
    assert history[0]["refilled_from"] == 1280  # its curves mark where episodes and buffer began anew
    assert all(np.isfinite(np.asarray(x)).all() for x in jax.tree.leaves(trained.nets))


@pytest.mark.slow
def test_a_run_copied_without_its_whole_checkpoint_goes_on_from_what_it_learned(tmp_path, interrupt_after_eval,
                                                                                tiny_crl_args):
    """A run folder moved without checkpoint.msgpack (gigabytes with a full replay buffer) goes on from
    learner.msgpack: it says so, and trains to its end with a buffer filled anew."""
    args = ["train", "point_nav", "--out", str(tmp_path), "--no-videos", *tiny_crl_args]
    run = tmp_path / "point_nav-crl-0"
    interrupt_after_eval(2)
    assert runner.invoke(app, args).exit_code == 130
    interrupt_after_eval(None)
    whole = (run / "checkpoint.msgpack").read_bytes()
    (run / "checkpoint.msgpack").write_bytes(whole[:len(whole) // 2])  # cut short: refused, with the way on
    refused = runner.invoke(app, ["train", "--resume", str(run)])
    assert refused.exit_code == 1 and unwrapped(f"or move checkpoint.msgpack aside: fieldgen train --resume {run} "
                                                "then goes on from learner.msgpack") in unwrapped(refused.output)
    (run / "checkpoint.msgpack").unlink()
    result = runner.invoke(app, ["train", "--resume", str(run)])
    assert result.exit_code == 0, result.output
    assert unwrapped("holds no checkpoint.msgpack: it goes on from learner.msgpack with fresh episodes and a "
                     "replay buffer filled anew by its policy (its 800 env steps count: the run ends at 2,560)") \
        in unwrapped(result.output)
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert [r["eval"] for r in rows] == [0, 1, 2] and rows[-1]["env_steps"] == 1280 + 800 + 6 * 80  # refilled
    assert [r.get("refilled_from") for r in rows] == [None, None, 1280]  # and says where from
    assert (run / "checkpoint.msgpack").exists()


def test_a_checkpoint_is_left_out_only_while_another_is_written_never_twice_in_a_row_nor_last():
    from fieldgen.run.train import skip_checkpoint

    assert skip_checkpoint(writing=True, skipped_last=False, last=False)
    assert not skip_checkpoint(writing=False, skipped_last=False, last=False)
    assert not skip_checkpoint(writing=True, skipped_last=True, last=False)
    assert not skip_checkpoint(writing=True, skipped_last=False, last=True)


@pytest.mark.slow
def test_the_whole_checkpoint_is_copied_to_the_host_in_the_writers_thread_not_the_training_one(
        tmp_path, monkeypatch, tiny_crl_args):
    """Copying gigabytes of replay buffer off the GPU held training for seconds at every evaluation: the
    training thread now takes what was learned (megabytes) and the writer copies the whole state itself."""
    import threading

    import jax
    import numpy as np

    from fieldgen.run import train as training

    copies, to_host = [], training.sharding.to_host

    def noted(tree):
        size = sum(np.asarray(leaf).nbytes for leaf in jax.tree.leaves(tree))
        copies.append((threading.current_thread().name, size))
        return to_host(tree)

    monkeypatch.setattr(training.sharding, "to_host", noted)
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--no-videos", *tiny_crl_args])
    assert result.exit_code == 0, result.output
    whole = [size for thread, size in copies if thread.startswith("fieldgen-writer")]
    held = [size for thread, size in copies if not thread.startswith("fieldgen-writer")]
    assert len(whole) == 3 and len(held) == 3  # evaluations 0, 1 and 2: a whole checkpoint and a learner each
    assert max(held) < min(whole) / 2  # the replay buffer is what the training thread no longer copies


@pytest.mark.slow
def test_a_run_whose_checkpoints_are_left_out_resumes_to_the_run_never_stopped(tmp_path, monkeypatch,
                                                                               interrupt_after_eval, tiny_crl_args):
    """With the writer always busy, every other evaluation leaves its whole checkpoint out (the learner is still
    written) and the last never does; stopped at its last evaluation, two chunks after its last whole
    checkpoint, the run goes on from that checkpoint, trains both chunks again, and ends with the metrics and
    checkpoint of a run never stopped."""
    from fieldgen.run import train as training

    args = ["--no-videos", *tiny_crl_args, "--set", "crl.num_evals=5"]
    assert runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path / "whole"), *args]).exit_code == 0
    reference = tmp_path / "whole" / "point_nav-crl-0"
    written, write_atomic, skip = [], training.write_atomic, training.skip_checkpoint

    def noted(path, data):
        written.append(path.name)
        return write_atomic(path, data)

    monkeypatch.setattr(training, "write_atomic", noted)
    monkeypatch.setattr(training, "skip_checkpoint", lambda writing, skipped_last, last: skip(True, skipped_last, last))
    interrupt_after_eval(5)  # the last: no chunk is under way, so the interrupt reaches the command's handler
    assert runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), *args]).exit_code == 130
    assert written.count("checkpoint.msgpack") == 2 and written.count("learner.msgpack") == 5  # evaluations 1, 3; 0-4
    run = tmp_path / "point_nav-crl-0"
    interrupt_after_eval(None)
    result = runner.invoke(app, ["train", "--resume", str(run)])
    assert result.exit_code == 0, result.output
    assert written.count("checkpoint.msgpack") == 3  # evaluation 4's left out again, the last one kept

    def untimed(folder):
        return [{k: v for k, v in json.loads(line).items() if k not in record.TIMINGS}
                for line in (folder / "metrics.jsonl").read_text().splitlines()]

    assert [r["eval"] for r in untimed(run)] == [0, 1, 2, 3, 4, 5] and untimed(run) == untimed(reference)
    for name in ("checkpoint.msgpack", "learner.msgpack"):
        assert (run / name).read_bytes() == (reference / name).read_bytes()


def test_the_deadline_weighs_the_longest_chunk_and_checkpoint_and_lets_an_unmeasured_chunk_run(monkeypatch):
    from fieldgen.run import train as training

    assert not training.Deadline(None, []).stop(10**6)  # no time limit
    monkeypatch.setattr(training.time, "monotonic", lambda: 1000.0)
    deadline = training.Deadline(1100.0, [])
    assert not deadline.stop(None) and deadline.needed is None  # nothing measured yet: the chunk runs
    deadline.handing += [2.0, 5.0]
    deadline.writing += [10.0]
    assert not deadline.stop(84.0) and deadline.needed == 99.0
    assert deadline.stop(86.0) and deadline.needed == 101.0 and deadline.reached
    walls = {0: 50.0, 1: 80.0, 2: 100.0, 3: 130.0}  # gaps 30, 20, 30 over two seeds' rows: their median, 30
    rows = [{"eval": e, "seed": s, "wall_seconds": w} for e, w in walls.items() for s in (0, 1)]
    assert training.Deadline(1031.0, rows).earlier_interval() == 30.0
    assert not training.Deadline(1031.0, rows).stop(None) and training.Deadline(1029.0, rows).stop(None)


@pytest.mark.parametrize("limit,hint", [("9x", ""), ("-5", ""), ("m", ""), ("2d", " (48h for 2d)")])
def test_a_time_limit_that_is_no_length_of_time_is_one_line(tmp_path, limit, hint):
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--time-limit", limit])
    said = " ".join(result.output.replace("│", " ").split())  # the words of the error's box
    assert result.exit_code == 2 and f"'{limit}' is not a length of time; write it in hours, minutes and seconds " \
        f"(h, m, s), as 570 (seconds), 9m30s, 45m or 1.5h{hint}" in said and "Traceback" not in result.output


@pytest.mark.parametrize("limit", ["0", "0s", "0h0m", "300000h"])
def test_a_time_limit_out_of_range_is_told_the_range(tmp_path, limit):
    """Before: 0s and a limit of centuries were each 'not a length of time', which they are; the range was unsaid."""
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--time-limit", limit])
    said = " ".join(result.output.replace("│", " ").split())
    assert result.exit_code == 2 and f"'{limit}' is out of range: a time limit is above 0 and under 1,000,000,000 " \
        "seconds (some thirty years); write it in hours, minutes and seconds" in said and "Traceback" not in result.output


@pytest.mark.slow
def test_a_time_limit_stops_at_an_evaluation_and_resume_ends_as_the_run_never_stopped(tmp_path, tiny_crl_args):
    """A run from nothing trains its first chunk (nothing measured yet says how long one takes), then its time
    being up it stops there with status 75, that evaluation's whole checkpoint written; a resume whose time is
    up at once trains nothing; one without a limit ends with the metrics and files of a run never stopped."""
    args = ["--no-videos", *tiny_crl_args]
    whole = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path / "whole"), *args])
    assert whole.exit_code == 0, whole.output
    assert unwrapped("note: trains 1,760 of the 1,900 env steps asked: whole iterations of 80 (8 envs x 10 steps), "
                     "as many before each of the 2 evaluations") in unwrapped(whole.output)
    reference, run = tmp_path / "whole" / "point_nav-crl-0", tmp_path / "point_nav-crl-0"

    def untimed(folder):
        return [{k: v for k, v in json.loads(line).items() if k not in record.TIMINGS}
                for line in (folder / "metrics.jsonl").read_text().splitlines()]

    for command in (["point_nav", "--out", str(tmp_path), *args], ["--resume", str(run)]):
        result = runner.invoke(app, ["train", *command, "--time-limit", "0.01s"])
        assert result.exit_code == 75, result.output
        said = unwrapped(result.output)
        assert unwrapped("stopped at the time limit after evaluation 1 of 2 (1,280 of 1,760 env steps)") in said
        assert unwrapped(f"would not have ended in time. Continue with: fieldgen train --resume {run}") in said
        assert [r["eval"] for r in untimed(run)] == [0, 1] and (run / "checkpoint.msgpack").exists()
    result = runner.invoke(app, ["train", "--resume", str(run)])
    assert result.exit_code == 0, result.output
    assert untimed(run) == untimed(reference)
    for name in ("checkpoint.msgpack", "learner.msgpack"):
        assert (run / name).read_bytes() == (reference / name).read_bytes()


def test_an_interrupt_says_whether_a_checkpoint_was_kept(tmp_path, monkeypatch, tiny_crl_args):
    """Ctrl-C exits with 130 and tells how to go on, before and after the first checkpoint."""
    args = ["train", "point_nav", "--out", str(tmp_path), "--no-videos", *tiny_crl_args]
    run = tmp_path / "point_nav-crl-0"

    def interrupted(*args, checkpoint=False):
        if checkpoint:
            (run / "checkpoint.msgpack").write_bytes(b"")
        raise KeyboardInterrupt

    resume = ["train", "--resume", str(run)]  # the advice of the first message, followed
    for saved, phrase, command in ((False, "no checkpoint yet. Start again with", args),
                                   (True, "the last checkpoint is intact. Continue with", resume)):
        monkeypatch.setattr(loop, "run_staged", lambda *a, saved=saved, **kw: interrupted(*a, checkpoint=saved))
        result = runner.invoke(app, command)
        assert result.exit_code == 130, result.output
        assert unwrapped(f"{phrase}: fieldgen train --resume {run}") in unwrapped(result.output)


def test_a_curriculum_run_is_named_by_its_curriculum_not_its_last_stage(tmp_path, monkeypatch, tiny_crl_args):
    """Its progress and its plot name the curriculum, as it starts and as it resumes."""
    from fieldgen.run import train as training

    titles = []
    monkeypatch.setattr(training, "plot_success", lambda folder, rows, title, *_: titles.append(title))

    def one_evaluation(trainers, seeds, num_evals, schedule, progress, *args, **kwargs):  # its prefill, 800 steps
        progress(0, [{"eval": 0, "seed": 0, "env_steps": 800, "stage": 0, "success_any": 0.0, "time_at_goal": 0.0}])
        raise KeyboardInterrupt

    monkeypatch.setattr(loop, "run_staged", one_evaluation)
    run = tmp_path / "point_nav_to_far-crl-0"
    for command in (["train", str(ROOT / "curricula" / "point_nav_to_far"), "--out", str(tmp_path), "--no-videos",
                     *tiny_crl_args], ["train", "--resume", str(run), "--no-videos"]):
        result = runner.invoke(app, command)
        assert result.exit_code == 130, result.output
        assert "point_nav_to_far 800 of 1,760 steps (45%) stage 1 of 4 success 0.00" in " ".join(result.output.split())
        assert "_s04" not in result.output and titles.pop() == "point_nav_to_far: crl"


def test_resume_says_it_keeps_the_runs_own_settings(tmp_path, tiny_crl_args):
    """--steps (or any setting a run is set up with: --envs, --set, --algo, --seeds, --curriculum, --levels, a
    field, even --seed 0 said aloud) beside --resume would be ignored: refused, saying how to train on instead,
    before anything loads."""
    prepared = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--prepare", *tiny_crl_args])
    assert prepared.exit_code == 0, prepared.output
    run = tmp_path / "point_nav-crl-0"
    for extra, named in ((["--steps", "4000"], "--steps"), (["--envs", "4", "--set", "crl.repr_dim=4"], "--envs and --set"),
                         (["--curriculum", "auto", "--levels", "5", "--seeds", "3", "--algo", "sac"],
                          "--algo and --seeds and --curriculum and --levels"),
                         (["point_soccer", "--seed", "0"], "a field named beside it and --seed")):
        result = runner.invoke(app, ["train", "--resume", str(run), *extra])
        message = " ".join(result.output.split())
        assert result.exit_code == 1 and f"(its run.json: 1,900 env steps in all), which {named} cannot change" in \
            message and f"fieldgen train SPEC --init-from {run} --steps N --out DIR" in message, message


def test_resume_refuses_an_out_it_would_ignore(tmp_path, tiny_crl_args):
    """A resumed run goes on in its own folder: --out beside --resume (even naming the folder it is in) is
    refused the way a setting is, and nothing is written where it pointed."""
    prepared = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--prepare", *tiny_crl_args])
    assert prepared.exit_code == 0, prepared.output
    run = tmp_path / "point_nav-crl-0"
    for elsewhere in (tmp_path / "elsewhere", tmp_path):
        result = runner.invoke(app, ["train", "--resume", str(run), "--out", str(elsewhere), "--no-videos"])
        message = " ".join(result.output.split())
        assert result.exit_code == 1 and "which --out cannot change" in message and \
            f"fieldgen train SPEC --init-from {run} --steps N --out DIR" in message, message
    assert not (tmp_path / "elsewhere").exists() and not (run / record.METRICS).exists()


def test_a_full_disk_is_a_clear_error(tmp_path, monkeypatch, tiny_crl_args):
    def full(*args, **kwargs):
        raise OSError(28, "No space left on device", str(tmp_path / "point_nav-crl-0" / "checkpoint.msgpack"))

    monkeypatch.setattr(loop, "run_staged", full)
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), *tiny_crl_args])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert unwrapped("checkpoint.msgpack: No space left on device; the files already there are intact") in \
        unwrapped(result.output)
    run = tmp_path / "point_nav-crl-0"
    assert unwrapped(f"continue with fieldgen train --resume {run}") in unwrapped(result.output)


def test_a_diverged_run_stops_before_writing_its_evaluation(tmp_path, monkeypatch, tiny_crl_args):
    """NaN losses stop the run with one paragraph, and neither they nor the NaN weights reach the disk."""
    run = tmp_path / "point_nav-crl-0"

    def diverging(algos, seeds, num_evals, promotion, progress, on_eval, *args, **kwargs):
        row = {"eval": 0, "seed": 0, "env_steps": 0, "success_any": 0.0, "time_at_goal": 0.0, "episode_return": 0.0}
        progress(0, [row])
        on_eval(Snapshot("sound", EPISODES, "buffer"), 0, 0, None, {})
        progress(1, [dict(row, eval=1, env_steps=992, critic_loss=float("nan"), actor_loss=float("inf"))])
        on_eval(Snapshot("NaN", EPISODES, "buffer"), 1, 0, None, {})

    written = []
    monkeypatch.setattr(loop, "run_staged", diverging)
    monkeypatch.setattr(checkpoint, "pieces", lambda state: written.append(state) or [b"x"])
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--no-videos", *tiny_crl_args])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert unwrapped(f"training diverged: after 992 env steps (evaluation 1) seed 0's actor_loss, critic_loss are "
                     f"not finite. Nothing of that evaluation was written; {run} keeps evaluation 0's checkpoint") \
        in unwrapped(result.output)
    # whole, learned: each with how its episodes are drawn
    assert written == [(Snapshot("sound", EPISODES, "buffer"), {}), (Snapshot("sound", None, None), {})]
    assert [json.loads(line)["eval"] for line in (run / "metrics.jsonl").read_text().splitlines()] == [0]


def test_checkpoint_errors_are_clear(tmp_path, env_cache, tiny_crl):
    env = env_cache("point_nav")
    template = jax.eval_shape(crl.make_train(tiny_crl(), env).start, jax.random.PRNGKey(0))
    with pytest.raises(checkpoint.CheckpointError, match="no checkpoint"):
        checkpoint.load(tmp_path / "none.msgpack", template)
    bad = tmp_path / "bad.msgpack"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(checkpoint.CheckpointError, match="checkpoint corrupt"):
        checkpoint.load(bad, template)
    other = tmp_path / "other.msgpack"
    shapes = jax.eval_shape(crl.make_train(tiny_crl(repr_dim=4), env).start, jax.random.PRNGKey(0))
    other.write_bytes(checkpoint.to_bytes(jax.tree.map(lambda x: np.zeros(x.shape, x.dtype), shapes)))  # its shapes
    with pytest.raises(checkpoint.CheckpointError, match="config or the field's observation layout differs"):
        checkpoint.load(other, template)


@pytest.mark.slow
def test_cli_run_folder_and_resume_of_a_finished_run(tmp_path, monkeypatch, tiny_crl_args):
    args = ["train", "point_nav", "--out", str(tmp_path), *tiny_crl_args]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    run = tmp_path / "point_nav-crl-0"
    assert {p.name for p in run.iterdir()} == {".fieldgen", "run.json", "metrics.jsonl", "metrics.csv", "checkpoint.msgpack",
                                               "learner.msgpack", "success.png", "videos", "field"}
    assert sorted(p.name for p in (run / "videos").iterdir()) == ["eval_000.mp4", "eval_001.mp4", "eval_002.mp4"]
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert [r["eval"] for r in rows] == [0, 1, 2] and rows[-1]["env_steps"] == 800 + 12 * 80  # prefill + 2 x 6 iterations
    # each chunk records the checkpoint work of the evaluation before it, done while it trained
    assert "write_wait_seconds" not in rows[0] and all(r["write_wait_seconds"] >= 0 for r in rows[1:])
    assert (run / "metrics.csv").read_text().splitlines()[0].startswith("eval,seed,env_steps")
    again = runner.invoke(app, args)
    assert again.exit_code == 1 and "--resume" in again.output
    loaded, load = [], checkpoint.load
    monkeypatch.setattr(checkpoint, "load", lambda path, *args: loaded.append(path.name) or load(path, *args))
    done = runner.invoke(app, ["train", "--resume", str(run)])
    assert done.exit_code == 0 and "already complete" in done.output
    assert loaded == ["learner.msgpack"]  # of the last evaluation: the whole checkpoint is not read
    prepared = runner.invoke(app, ["train", "--resume", str(run), "--prepare"])  # said prepared, to be started
    assert prepared.exit_code == 0 and "already complete" in prepared.output and "prepared" not in prepared.output
    loaded.clear()
    (run / "learner.msgpack").rename(tmp_path / "learner.msgpack")  # a kill before the last learner was written
    loaded.clear()
    done = runner.invoke(app, ["train", "--resume", str(run)])
    assert done.exit_code == 0 and "already complete" in done.output
    # none there: the whole checkpoint says where it is, and the learner that eval and export read is written again
    assert loaded == ["learner.msgpack", "checkpoint.msgpack", "learner.msgpack"]
    assert "goes on from" not in done.output and "learner.msgpack was missing or damaged" in done.output
    assert (run / "learner.msgpack").read_bytes() == (tmp_path / "learner.msgpack").read_bytes()
    (run / "learner.msgpack").write_bytes(b"cut")  # damaged alike
    assert "written again" in runner.invoke(app, ["train", "--resume", str(run)]).output
    assert (run / "learner.msgpack").read_bytes() == (tmp_path / "learner.msgpack").read_bytes()
    (run / "learner.msgpack").unlink()
    (run / "learner.msgpack").mkdir()  # not a file: said, not overwritten
    folder = runner.invoke(app, ["train", "--resume", str(run)])
    assert folder.exit_code == 1 and "is a folder, not what the run learned: move it aside" in folder.output
    (run / "learner.msgpack").rmdir()
    (tmp_path / "learner.msgpack").rename(run / "learner.msgpack")
    evaluated = runner.invoke(app, ["eval", str(run), "--episodes", "8"])
    assert evaluated.exit_code == 0, evaluated.output
    assert "success_any" in evaluated.output and "time at goal" in evaluated.output
    assert re.search(r"│ 100 +│", evaluated.output), evaluated.output  # length: point_nav's episodes never end early
    import imageio.v3 as iio

    frames = iio.imread(run / "eval.mp4", index=None)
    assert frames.shape[0] == 100 and frames.shape[1:3] == (240, 320)

    from fieldgen import render

    (run / "eval.mp4").unlink()
    monkeypatch.setattr(render, "render_rollout", no_opengl)
    blind = runner.invoke(app, ["eval", str(run), "--episodes", "8"])
    assert blind.exit_code == 0 and "Traceback" not in blind.output, blind.output
    assert "cannot render here (no OpenGL here)" in blind.output and "success_any" in blind.output
    assert (run / "eval.npz").exists() and not (run / "eval.mp4").exists()
    short = tmp_path / "point_nav_short.yaml"
    short.write_text("extends: point_nav\nname: point_nav_short\nepisode: {length: 40}\n")
    elsewhere = runner.invoke(app, ["eval", str(run), "--episodes", "8", "--field", str(short)])
    assert elsewhere.exit_code == 0, elsewhere.output
    assert "onpoint_nav_short," in unwrapped(elsewhere.output) and re.search(r"│ 40 +│", elsewhere.output)
    assert (run / "eval_point_nav_short.npz").exists()
    unlike = runner.invoke(app, ["eval", str(run), "--episodes", "8", "--field", "point_soccer"])
    assert unlike.exit_code == 1 and "observesoractsdifferentlyfrompoint_nav" in unwrapped(unlike.output)
    monkeypatch.undo()
    unnamed = runner.invoke(app, ["videos", str(run)])
    assert unnamed.exit_code == 1 and "recordsfield'point_nav_short'" in unwrapped(unnamed.output), unnamed.output
    assert "--fieldSPEC" in unwrapped(unnamed.output)
    drawn = runner.invoke(app, ["videos", str(run), "--field", str(short)])
    assert drawn.exit_code == 0 and "eval.npz" in drawn.output, drawn.output
    assert iio.imread(run / "eval.mp4", index=None).shape[0] == 100
    assert iio.imread(run / "eval_point_nav_short.mp4", index=None).shape[0] == 40


ROOT = Path(__file__).parents[2]
CONFIG_FILES = sorted([*(ROOT / "agents" / "presets").glob("*.yaml"), *(ROOT / "bench" / "configs").glob("*.yaml")])
CONFIG_FILES.remove(ROOT / "agents" / "presets" / "recipes.yaml")  # recipes by field (tests/agents/test_recipes.py)


def test_the_config_files_are_found():
    assert {p.name for p in CONFIG_FILES} >= {"crl_ant.yaml", "crl_reference.yaml"}


@pytest.mark.parametrize("path", CONFIG_FILES, ids=lambda p: p.name)
def test_bundled_config_files_hold_only_known_keys(path):
    import yaml

    from fieldgen.curriculum.section import SAMPLER
    from fieldgen.curriculum.auto import Sampler
    from fieldgen.schema.source import read_yaml

    sections = [s for s in yaml.safe_load(path.read_text()) if s != SAMPLER]  # the level sampler's: below
    for algo in sections:
        trainer(algo).config.layered(path, others=tuple(s for s in sections if s != algo))
    Sampler.configured(read_yaml(path))  # a LevelError where its sampler section holds a bad key


@pytest.mark.parametrize("args,phrase", [
    (["--algo", "crll"], "unknown algorithm 'crll'; did you mean 'crl'?"),
    (["--set", "crl.repr_dimm=3"], "unknown config key 'repr_dimm'; did you mean 'repr_dim'?"),
    (["--set", "repr_dim=3"], "write crl.KEY=VALUE"),
    (["--set", "ppo.num_evals=2"], "ppo.* sets ppo's settings, and this run trains crl; write crl.KEY=VALUE (e.g. "
                                   "crl.batch_size=256), or train ppo with --algo ppo"),
    (["--set", "crl.layer_norm=maybe"], "crl.layer_norm must be true or false, not 'maybe'"),
    (["--set", "crl.batch_size=true"], "crl.batch_size must be a whole number, not true"),  # as written
    (["--set", "crl.batch_size=0"], "crl.batch_size must be greater than 0, not 0"),
    (["--set", "crl.batch_size="], "--set crl.batch_size=: crl.batch_size must be a whole number, not left empty"),
    (["--set", "crl.actor_lr=~"], "crl.actor_lr must be a number, not left empty"),  # YAML's null, once "not None"
    (["--set", "crl.batch_size=-64"], "crl.batch_size must be greater than 0, not -64"),
    (["--set", "crl.num_evals=0"], "crl.num_evals must be greater than 0, not 0"),
    (["--set", "crl.eval_envs=0"], "crl.eval_envs must be greater than 0, not 0"),
    (["--set", "crl.actor_lr=.nan"], "crl.actor_lr must be a finite number, not nan"),
    (["--set", "crl.critic_lr=-0.001"], "crl.critic_lr must be greater than 0, not -0.001"),
    (["--set", "crl.discount=1"], "crl.discount must be less than 1, not 1"),
    (["--set", "crl.hidden=[256,0]"], "crl.hidden must be a list of layer widths, each greater than 0, not [256, 0]"),
    (["--set", "crl.hidden=64,64"], "crl.hidden must be a list of layer widths, whole numbers above 0, not '64,64'; "
                                    "write it as a list, [64,64]"),
    (["--set", "crl.hidden=[1e400]"], "crl.hidden must be a list of layer widths, whole numbers above 0, not [inf]"),
    (["--steps", "100"], "100 env steps (--steps or crl.total_steps) are too few"),
    (["--algo", "ppo", "--set", "ppo.total_steps=1.5k"], "1,500 env steps (--steps or ppo.total_steps) are too few"),
    (["--set", "crl.energy=cos"], "--set crl.energy=cos: unknown energy 'cos'; choose one of norm,"),
    (["--algo", "ppo", "--set", "ppo.num_minibatches=3", "--set", "ppo.unroll_length=10"], "does not divide"),
    (["--algo", "ppo", "--set", "ppo.reward=shaped"], "unknown reward 'shaped'"),
    (["--algo", "ppo", "--set", "ppo.spread=wide"], "unknown ppo.spread 'wide'; choose global"),
    (["--algo", "sca"], "did you mean 'sac'?"),
    (["--algo", "sac", "--set", "sac.her=0.8"], "set sac.reward=sparse"),
    (["--algo", "td3", "--set", "td3.her=1.5"], "td3.her must be at most 1, not 1.5"),
    (["--algo", "icrl", "--set", "icrl.agents=arm"], "icrl.agents: unknown grouping 'arm'"),
    (["--algo", "ppo", "--set", "num_minibatches=3"], "write ppo.KEY=VALUE, e.g. ppo.num_minibatches=32"),
    (["--set", "crl.zzzzqq=3"], "unknown config key 'zzzzqq'. Keys: total_steps,"),
])
def test_bad_training_input_is_reported_before_compiling(tmp_path, args, phrase):
    result = runner.invoke(app, ["train", "point_nav", "--envs", "8", "--out", str(tmp_path), *args])
    assert result.exit_code == 1
    assert phrase in result.output and "Traceback" not in result.output


def test_envs_must_split_over_the_devices_unless_the_seeds_do(env_cache, tiny_crl):
    env, config = env_cache("point_nav"), tiny_crl(num_envs=9, batch_size=9, total_steps=20000)
    config.validate_env(env, devices=2, seeds=2)  # a seed per device: each keeps all 9 environments
    config.validate_env(env, devices=2, seeds=4)
    for seeds in (1, 3):
        with pytest.raises(ConfigError, match="num_envs 9 does not split evenly over the 2 devices;"):
            config.validate_env(env, devices=2, seeds=seeds)


def test_config_file_and_precedence(tmp_path):
    file = tmp_path / "c.yaml"
    file.write_text("crl: {repr_dim: 32, batch_size: 128}\n")
    config = crl.CRLConfig.layered(file, ["crl.repr_dim=16"], num_envs=4)
    assert (config.repr_dim, config.batch_size, config.num_envs) == (16, 128, 4)
    file.write_text("ppo: {}\n")
    with pytest.raises(ConfigError, match="one section, 'crl:'"):
        crl.CRLConfig.layered(file)
    # a section this run does not read is named with its line, and what it is for
    file.write_text("crl:\n  repr_dim: 32\nppo:\n  lr: 1\n")
    with pytest.raises(ConfigError) as caught:
        crl.CRLConfig.layered(file)
    assert str(caught.value).startswith(f"{file}:3: section 'ppo:' is not read by this run; it sets ppo's "
                                        "settings and this run trains crl (train ppo with --algo ppo)")
    file.write_text("crl:\n  repr_dim: 32\ncrll:\n  x: 1\n")
    with pytest.raises(ConfigError, match=r":3: section 'crll:' is not read by this run \(did you mean 'crl'\?\)"):
        crl.CRLConfig.layered(file)
    file.write_text("crl: [64, 64]\n")  # the section itself is not a mapping
    with pytest.raises(ConfigError) as caught:
        crl.CRLConfig.layered(file)
    assert str(caught.value).startswith(f"{file}:1: 'crl:' holds [64, 64] where its config keys go")
    file.write_text("# a config file's problems name its line\ncrl:\n  repr_dim: 32\n\n  batch_size: -64\n")
    with pytest.raises(ConfigError) as caught:
        crl.CRLConfig.layered(file)
    assert str(caught.value) == f"{file}:5: crl.batch_size must be greater than 0, not -64"
    file.write_text("crl:\n  eval_actions: drawn\n")  # a value outside a key's choices: where, and the choices
    with pytest.raises(ConfigError) as caught:
        crl.CRLConfig.layered(file)
    assert str(caught.value) == f"{file}:2: unknown eval_actions 'drawn'; choose one of mean, sampled"


def test_ant_fields_get_the_ant_preset_under_a_config_file_and_set(tmp_path):
    """CRL on an ant field starts from agents/presets/crl_ant.yaml; a config file and --set still win;
    a point field, and trainers without a preset, keep their defaults."""
    from fieldgen.agents.sac import SACConfig

    ant = crl.CRLConfig.layered(agent="ant")
    assert (ant.hidden, ant.skip_every, ant.matmul, ant.layer_norm, ant.windows_per_env, ant.batch_size) == (
        (256,) * 9, 4, "bfloat16", True, 1.0, 1024)
    # the reference's one window per environment: 1,024 at 1,024 envs, 16 at a test's 16
    assert gradient_steps(ant, 1001) == (1024, 1001)
    assert gradient_steps(crl.CRLConfig.layered(agent="ant", num_envs=16), 1001) == (16, 15)
    assert gradient_steps(crl.CRLConfig.layered(agent="ant", sets=["crl.windows=100"]), 1001) == (100, 97)
    assert crl.CRLConfig.layered(agent="point") == crl.CRLConfig.layered() == crl.CRLConfig()
    assert SACConfig.preset("ant") is None
    file = tmp_path / "c.yaml"
    file.write_text("crl: {batch_size: 256}\n")
    mine = crl.CRLConfig.layered(file, ["crl.layer_norm=false"], agent="ant")
    assert (mine.batch_size, mine.layer_norm, mine.windows_per_env) == (256, False, 1.0)
    reference = ROOT / "bench" / "configs" / "crl_reference.yaml"
    assert crl.CRLConfig.layered(reference, agent="ant") == crl.CRLConfig()  # the reference's settings, back
    narrow = crl.CRLConfig.layered(ROOT / "bench" / "configs" / "crl_ant_width256.yaml", agent="ant")
    assert (narrow.hidden, narrow.matmul, narrow.windows_per_env) == ((256,) * 4, "float32", 2.0)
    wide = crl.CRLConfig.layered(ROOT / "bench" / "configs" / "crl_ant_wide1024.yaml", agent="ant")
    assert (wide.hidden, wide.skip_every, wide.windows_per_env) == ((1024,) * 4, 0, 2.0)  # the former preset
    soccer = crl.CRLConfig.layered(ROOT / "bench" / "configs" / "crl_soccer_auto.yaml", agent="ant")
    assert (soccer.hidden, soccer.skip_every, soccer.windows_per_env) == ((256,) * 4, 0, 2.0)  # as it was measured
    assert (soccer.actor_lr, soccer.critic_lr, soccer.alpha_lr) == (1e-3, 1e-3, crl.CRLConfig().alpha_lr)
    from fieldgen.curriculum.auto import Sampler
    from fieldgen.schema.source import read_yaml

    sampled = Sampler.configured(read_yaml(ROOT / "bench" / "configs" / "crl_soccer_auto.yaml"))
    assert sampled == Sampler(replaced=8)  # its level sampler as measured, the rest at the defaults


def test_hidden_layers_that_form_no_residual_block_under_the_ant_preset_are_refused_naming_the_way_out(tmp_path):
    """The ant preset's residual blocks need 1 + 4k layers of one width: other layers given with --set are
    refused before the run is set up, naming skip_every=0."""
    result = runner.invoke(app, ["train", "ant_nav", "--set", "crl.hidden=[256,256]", "--out", str(tmp_path),
                                 "--prepare"])
    assert result.exit_code != 0 and "Traceback" not in result.output
    assert ("crl.skip_every 4: residual blocks of 4 layers need 1 + a multiple of 4 hidden layers of one width, "
            "not [256, 256]; crl.skip_every=0 builds plain layers") in " ".join(result.output.split())
    assert not (tmp_path / "ant_nav-crl-0").exists()
    plain = runner.invoke(app, ["train", "ant_nav", "--set", "crl.hidden=[256,256]", "--set", "crl.skip_every=0",
                                "--out", str(tmp_path), "--prepare"])
    assert plain.exit_code == 0, plain.output


def test_the_cpu_preset_sizes_training_and_its_evaluations_for_a_laptop(tmp_path, env_cache):
    """`--preset cpu` layers CPU-sized settings, evaluation included, over the field's agent preset for every
    trainer, under a config file and --set; each fits an ant soccer field, and `fieldgen train` records it."""
    from fieldgen.agents.registry import ALGORITHMS

    soccer = env_cache("soccer_v2")
    for algo in ALGORITHMS:
        config = trainer(algo).config.layered(agent="ant", preset="cpu")
        assert (config.num_envs, config.eval_envs, config.hidden, config.total_steps) == (16, 16, (64, 64), 200_000)
        config.validate_env(soccer)
    mine = crl.CRLConfig.layered(agent="ant", preset="cpu", sets=["crl.num_envs=32"])
    assert (mine.layer_norm, mine.batch_size, mine.windows_per_env, mine.num_envs) == (True, 256, 1.0, 32)
    assert mine.matmul == "float32"  # the ant preset's bfloat16 products are a GPU's gain
    with pytest.raises(ConfigError, match="unknown preset 'cpus'; did you mean 'cpu'"):
        crl.CRLConfig.layered(preset="cpus")
    result = runner.invoke(app, ["train", "ant_nav", "--preset", "cpu", "--out", str(tmp_path), "--prepare"])
    assert result.exit_code == 0, result.output
    assert "starts from crl_ant.yaml then cpu.yaml (--preset)" in " ".join(result.output.split())
    saved = json.loads((tmp_path / "ant_nav-crl-0" / "run.json").read_text())["config"]
    assert (saved["num_envs"], saved["eval_envs"], saved["layer_norm"]) == (16, 16, True)


def test_a_config_comes_back_from_its_run_json_record(tiny_crl):
    """run.json keeps the config as JSON (tuples become lists); read back, it is the same hashable value."""
    config = tiny_crl(hidden=(32, 16), layer_norm=True)
    again = crl.CRLConfig.layered(**json.loads(json.dumps(config.model_dump())))
    assert again == config and hash(again) == hash(config) and again.hidden == (32, 16)


@pytest.mark.slow
def test_a_machine_that_cannot_render_keeps_episodes_for_fieldgen_videos(tmp_path, monkeypatch, tiny_crl_args):
    import imageio.v3 as iio
    import jax.numpy as jnp
    from rich.console import Console

    from fieldgen import render
    from fieldgen.run import record, session, videos

    prepared = runner.invoke(app, ["train", "point_nav", "--prepare", "--out", str(tmp_path), *tiny_crl_args])
    assert prepared.exit_code == 0, prepared.output
    run_dir = tmp_path / "point_nav-crl-0"
    nothing = runner.invoke(app, ["videos", str(run_dir)])
    assert nothing.exit_code == 1 and "holds no eval_NNN.npz" in nothing.output

    env = session.open_run(run_dir, load_state=False).env
    recorder = videos.EpisodeRecorder(env)
    hold = lambda obs: jnp.full((obs.shape[0], env.action_size), 0.5)  # noqa: E731

    monkeypatch.setattr(render, "render_rollout", no_opengl)
    console = Console(record=True, width=200)
    for index in (0, 1):
        _, filmed = loop.evaluate_policy(env, hold, jax.random.PRNGKey(index), 2, videos.EpisodeRecorder.film)
        recorder.save(run_dir, videos.video_name(run_dir, index), recorder.episode(filmed), console)
    folder = run_dir / record.VIDEOS
    assert sorted(p.name for p in folder.iterdir()) == ["eval_000.npz", "eval_001.npz"]
    assert console.export_text().count("cannot render here (no OpenGL here)") == 1
    monkeypatch.undo()

    drawn = runner.invoke(app, ["videos", str(run_dir)])
    assert drawn.exit_code == 0, drawn.output
    with np.load(folder / "eval_000.npz") as kept:
        frames = len(kept["qpos"])
        assert kept["qpos"][-1, 0] > kept["qpos"][0, 0] + 0.5  # the held action moved the point along +x
    assert iio.imread(folder / "eval_000.mp4", index=None).shape[0] == frames
    assert "already drawn" in runner.invoke(app, ["videos", str(run_dir)]).output
    gifs = runner.invoke(app, ["videos", str(run_dir), "--video-format", "gif"])  # beside the MP4s
    assert gifs.exit_code == 0 and "already drawn" not in gifs.output, gifs.output
    assert iio.imread(folder / "eval_000.gif", index=None).shape[0] == -(-frames // 2)  # 20 frames/s drawn at 10
    (folder / "eval_001.mp4").unlink()
    (folder / "eval_001.npz").write_bytes(b"truncated")
    broken = runner.invoke(app, ["videos", str(run_dir)])
    assert broken.exit_code == 1 and "eval_001.npz is not an episode kept by fieldgen train" in broken.output


def test_progress_tells_the_time_left_from_the_last_two_evaluations():
    from fieldgen.run.progress import rate as _rate

    rows = [{"seed": 0, "env_steps": 0, "wall_seconds": 5.0},
            {"seed": 0, "env_steps": 1_000_000, "wall_seconds": 65.0, "steps_per_second": 25_000.0},
            {"seed": 0, "env_steps": 2_000_000, "wall_seconds": 185.0, "steps_per_second": 20_000.0}]
    assert _rate(rows[:1], 10_000_000) == ""  # the untrained evaluation: nothing timed yet
    assert _rate(rows[:2], 10_000_000) == "25,000 steps/s, 9 min left"  # 9M steps at 60 s per million
    assert _rate(rows, 10_000_000) == "20,000 steps/s, 16 min left"  # 8M at 120 s per million
    assert _rate(rows, 2_000_000) == "20,000 steps/s"  # done
    waiting = [*rows[:2], {**rows[2], "write_wait_seconds": 40.0}]  # of the chunk's 50 s
    assert _rate(waiting, 2_000_000) == "20,000 steps/s, 40 of its 50 s waiting on writes"
    assert _rate([*rows[:2], {**rows[2], "write_wait_seconds": 39.0}], 2_000_000) == "20,000 steps/s"
    from fieldgen.run.progress import waited_on_writes

    assert waited_on_writes(waiting[2], rows[1]) == (40.0, 50.0) and waited_on_writes(rows[2], rows[1]) is None
    assert waited_on_writes(rows[0], rows[0]) is None  # the untrained evaluation: no chunk


def test_a_staged_runs_progress_says_its_stage_of_how_many():
    from fieldgen.run.progress import stats

    rows = [{"success_any": 0.5, "time_at_goal": 10.0, "stage": 1, "critic_loss": 1.0},
            {"success_any": 0.25, "time_at_goal": 20.0, "stage": 1, "critic_loss": 2.0}]
    assert stats(rows, 4) == "stage 2 of 4  success 0.38  at goal 15.0  critic 1.500"
    rows[0]["promoted_to"] = 2
    assert stats(rows, 4).startswith("stage 3 of 4  ")
    assert stats([{"success_any": 1.0, "time_at_goal": 0.0}]) == "success 1.00  at goal 0.0"
