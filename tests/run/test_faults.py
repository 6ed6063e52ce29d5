"""Runs killed at the worst moments, and damaged run folders: every one goes on, or says exactly why not."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fieldgen.agents import loop
from fieldgen.cli import app
from fieldgen.run import record

runner = CliRunner()

# `fieldgen train` that kills itself (SIGKILL, nothing cleaned up) at one moment: "metrics N" once
# evaluation N's metrics are written and before its checkpoint is, "write N" halfway through writing
# the N-th checkpoint file this process writes; "never" runs to the end.
KILLED_AT = textwrap.dedent("""
    import os, signal, sys
    from fieldgen.agents import checkpoint
    from fieldgen.cli import app
    from fieldgen.run import record

    from fieldgen.run import train as training

    moment, at = sys.argv[1], int(sys.argv[2])
    written, real_pieces, real_metrics = [0], checkpoint.pieces, record.write_metrics
    # every evaluation writes its whole checkpoint, then what it learned: the writes counted below are those
    # (one is left out only while an earlier write is under way, a matter of timing: tests/run/test_training.py)
    training.skip_checkpoint = lambda *args: False

    def pieces(state):
        written[0] += 1
        for k, piece in enumerate(real_pieces(state)):
            if moment == "write" and written[0] == at and k == 4:
                os.kill(os.getpid(), signal.SIGKILL)
            yield piece

    def write_metrics(folder, rows):
        real_metrics(folder, rows)
        if moment == "metrics" and rows[-1]["eval"] == at:
            os.kill(os.getpid(), signal.SIGKILL)

    checkpoint.pieces, record.write_metrics = pieces, write_metrics
    app(sys.argv[3:])
""")


def train(tmp_path: Path, moment: str, at: int, *args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, JAX_PLATFORMS="cpu")  # with the compiled programs this test session shares
    return subprocess.run([sys.executable, "-c", KILLED_AT, moment, str(at), "train", *args], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)


def rows(run: Path) -> list[dict]:
    return [{k: v for k, v in json.loads(line).items() if k not in record.TIMINGS}
            for line in (run / "metrics.jsonl").read_text().splitlines()]


def leftovers(run: Path) -> list[str]:
    return sorted(p.name for p in run.rglob(".*.tmp"))


@pytest.mark.slow
def test_a_run_killed_at_any_moment_resumes_to_the_uninterrupted_result(tmp_path, tiny_crl_args):
    """Killed before its first checkpoint, in the middle of writing its first and a later one, and between the
    metrics and the checkpoint of one evaluation, the run resumed each time ends with the same bytes as a run
    never stopped."""
    tiny = [*tiny_crl_args, "--no-videos"]
    whole = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path / "whole"), *tiny])
    assert whole.exit_code == 0, whole.output
    run = tmp_path / "killed" / "point_nav-crl-0"

    first = train(tmp_path, "metrics", 0, "point_nav", "--out", "killed", *tiny)
    assert first.returncode == -signal.SIGKILL
    assert not (run / "checkpoint.msgpack").exists() and rows(run)[-1]["eval"] == 0

    # the same command again sets the run up anew; it is then killed halfway through its first checkpoint
    second = train(tmp_path, "write", 1, "point_nav", "--out", "killed", *tiny)
    assert second.returncode == -signal.SIGKILL, second.stderr[-3000:]
    assert not (run / "checkpoint.msgpack").exists()
    assert leftovers(run) == [n for n in leftovers(run) if n.startswith(".checkpoint.msgpack.")] != []

    # --resume starts it from the beginning too; killed halfway through its second whole checkpoint (each
    # evaluation writes the whole state, then what it learned alone), the first stays
    third = train(tmp_path, "write", 3, "--resume", str(run))
    assert third.returncode == -signal.SIGKILL, third.stderr[-3000:]
    assert (run / "checkpoint.msgpack").exists()
    assert leftovers(run) == [n for n in leftovers(run) if n.startswith(".checkpoint.msgpack.")] != []

    # from evaluation 0's checkpoint on, killed once the last evaluation's metrics are written, before its checkpoint
    fourth = train(tmp_path, "metrics", 2, "--resume", str(run))
    assert fourth.returncode == -signal.SIGKILL, fourth.stderr[-3000:]
    assert rows(run)[-1]["eval"] == 2

    last = train(tmp_path, "never", 0, "--resume", str(run))
    assert last.returncode == 0, last.stderr[-3000:]
    assert leftovers(run) == []
    reference = tmp_path / "whole" / "point_nav-crl-0"
    for name in ("checkpoint.msgpack", "learner.msgpack"):
        assert (run / name).read_bytes() == (reference / name).read_bytes()
    assert rows(run) == rows(reference)


def test_a_run_without_a_checkpoint_starts_again(tmp_path, monkeypatch, tiny_crl_args):
    """Stopped before its first checkpoint, a run folder holds no training: --resume and a new
    `fieldgen train` both start it from the beginning, and what killed writes left is cleared."""
    prepared = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--prepare", *tiny_crl_args])
    assert prepared.exit_code == 0, prepared.output
    run = tmp_path / "point_nav-crl-0"
    started = []
    def stop(*args, **kwargs):
        started.append(args[6])
        raise KeyboardInterrupt

    monkeypatch.setattr(loop, "run_staged", stop)
    for command in (["train", "--resume", str(run)], ["train", "point_nav", "--out", str(tmp_path), *tiny_crl_args]):
        (run / "metrics.jsonl").write_text(json.dumps({"eval": 0, "seed": 0, "env_steps": 800}) + "\n")
        (run / ".checkpoint.msgpack.x1y2.tmp").write_bytes(b"half a checkpoint")
        result = runner.invoke(app, command)
        assert result.exit_code == 130 and "Traceback" not in result.output, result.output
        assert started[-1] is None  # no resume point: from the beginning
        assert leftovers(run) == []


# `fieldgen train` given Ctrl-C as soon as its second program has begun compiling on its own thread
INTERRUPTED_COMPILING = textwrap.dedent("""
    import os, signal, sys
    from fieldgen.agents import programs
    from fieldgen.cli import app

    signal.signal(signal.SIGINT, signal.default_int_handler)  # even where this process was started ignoring it
    programs.SIDE_BY_SIDE = True  # as on a GPU machine
    started, real_init = [], programs.Compiling.__init__

    def init(self, *args):
        real_init(self, *args)
        started.append(self)
        if len(started) == 2:
            os.kill(os.getpid(), signal.SIGINT)

    programs.Compiling.__init__ = init
    app(sys.argv[1:])
""")


@pytest.mark.slow
def test_ctrl_c_while_programs_compile_exits_cleanly(tmp_path, tiny_crl_args):
    """Stopped while compiles run on their threads, the command says so and exits with Ctrl-C's status once
    they end, rather than aborting inside XLA."""
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    result = subprocess.run([sys.executable, "-c", INTERRUPTED_COMPILING, "train", "point_nav", "--out", "runs",
                             *tiny_crl_args, "--no-videos"],
                            cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert result.returncode == 130, result.stdout[-2000:] + result.stderr[-3000:]
    assert "interrupted; no checkpoint yet" in result.stdout
    assert "terminate called" not in result.stderr and "Traceback" not in result.stderr


# `fieldgen train` sent SIGNAL (by name) once its training has begun, as kill, a batch system ending or preempting
# the job (SIGTERM) or a closed terminal (SIGHUP) sends it
SIGNALLED_TRAINING = textwrap.dedent("""
    import os, signal, sys, time
    from fieldgen.agents import loop
    from fieldgen.cli import app

    sent = getattr(signal, sys.argv[1])

    def signalled(*args, **kwargs):
        os.kill(os.getpid(), sent)
        time.sleep(60)  # the handler acts between two bytecodes: here

    loop.run_staged = signalled
    app(sys.argv[2:])
""")


@pytest.mark.parametrize("name", ["SIGTERM", pytest.param("SIGHUP", marks=pytest.mark.slow)])
def test_kill_or_a_jobs_end_stops_a_run_as_ctrl_c_does(tmp_path, tiny_crl_args, name):
    """SIGTERM and SIGHUP, which would kill the process without a word, end `fieldgen train` as Ctrl-C does: one
    line naming the signal and how to go on, the shell's status for it (128 + its number), the folder whole."""
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    result = subprocess.run([sys.executable, "-c", SIGNALLED_TRAINING, name, "train", "point_nav", "--out", "runs",
                             *tiny_crl_args, "--no-videos"],
                            cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert result.returncode == 128 + getattr(signal, name), result.stdout[-2000:] + result.stderr[-3000:]
    run = Path("runs") / "point_nav-crl-0"
    assert f"stopped by {name}; no checkpoint yet. Start again with: fieldgen train --resume {run}" in " ".join(
        result.stdout.split())
    assert "Traceback" not in result.stderr and leftovers(tmp_path / run) == []


def test_a_signal_the_process_was_started_ignoring_stays_ignored():
    """nohup starts a command ignoring SIGHUP, and a program running fieldgen's app may hold SIGTERM itself:
    the command takes neither, and gives back what it took (a test, a program keeps its own handlers)."""
    from fieldgen import stops

    def own(number, frame):
        pass

    before = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, *stops.AS_CTRL_C)}
    try:
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, own)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        give_back = stops.catch()
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN and signal.getsignal(signal.SIGTERM) is own
        assert signal.getsignal(signal.SIGINT) is not signal.default_int_handler  # Ctrl-C: its signal kept
        give_back()
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        assert (stops.status(), stops.said()) == (130, "interrupted")
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)


def test_a_ctrl_c_that_python_dropped_stops_at_the_next_check(monkeypatch):
    """A KeyboardInterrupt raised inside a garbage collector's callback or a `__del__` is dropped by Python, which
    prints its traceback (a run given Ctrl-C as JAX collected a buffer trained on to its end): the stop it stood
    for is kept, without the traceback, and raised at the next check, which a training loop makes between its
    chunks; other exceptions Python drops are still reported."""
    from fieldgen import stops

    dropped = []

    def reported(unraisable):
        dropped.append(unraisable.exc_type)

    monkeypatch.setattr(sys, "unraisablehook", reported)
    before = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)  # Ctrl-C's default, even in a job started ignoring it
    give_back = stops.catch()
    try:
        stops.check()  # no signal came: nothing to raise

        class Collected:
            def __del__(self):
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(10_000):  # the handler runs between these, inside __del__
                    pass

        class Broken:
            def __del__(self):
                raise ValueError("not a stop")

        Collected()
        assert dropped == []  # kept without a word
        Broken()
        assert dropped == [ValueError]
        with pytest.raises(KeyboardInterrupt):
            stops.check()
        assert (stops.status(), stops.said()) == (130, "interrupted")
        stops.catch()  # the next command starts with no stop pending
        stops.check()
    finally:
        give_back()
        signal.signal(signal.SIGINT, before)
    assert sys.unraisablehook is reported  # given back


def test_a_command_stopped_before_it_says_anything_says_that_it_was(monkeypatch, capsys):
    """typer turns a KeyboardInterrupt that reaches it into status 130 without a word; the `fieldgen` script
    says "interrupted" (here: Ctrl-C as the command line starts), and leaves every other exit as it was."""
    from fieldgen import __main__ as script
    from fieldgen import xla_cache

    def stopped():
        raise KeyboardInterrupt

    monkeypatch.setattr(sys, "argv", ["fieldgen", "validate", "point_nav"])
    monkeypatch.setattr(xla_cache, "enable", stopped)
    with pytest.raises(SystemExit) as ended:
        script.main()
    assert ended.value.code == 130 and capsys.readouterr().err == "interrupted\n"
    monkeypatch.undo()
    monkeypatch.setattr(sys, "argv", ["fieldgen", "validate", "no_such_field"])
    with pytest.raises(SystemExit) as ended:
        script.main()
    assert ended.value.code == 1 and "interrupted" not in capsys.readouterr().err


def test_ctrl_c_while_a_run_is_set_up_makes_no_run_folder(tmp_path, monkeypatch, tiny_crl_args):
    """A Ctrl-C that Python dropped while the field built (`stops.check`) ends the command before the run's
    folder is made, in a line; one landing in the setup itself says nothing was trained."""
    from fieldgen import stops
    from fieldgen.run import recipe, session

    chosen = recipe.training

    def dropped_stop(*args, **kwargs):
        stops._pending[0] = True  # as stops._stop leaves it where Python drops its KeyboardInterrupt
        return chosen(*args, **kwargs)

    monkeypatch.setattr(recipe, "training", dropped_stop)
    made = []
    monkeypatch.setattr(session, "new_run", lambda *args, **kwargs: made.append(args))
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path / "runs"), *tiny_crl_args])
    assert result.exit_code == 130 and made == [] and not (tmp_path / "runs").exists()
    assert "interrupted while setting the run up; nothing was trained" in result.output


# a `fieldgen` command given Ctrl-C a second into the first of XLA's compiles that lasts that long (JAX tells each
# program's compile start and end as it lowers and compiles it, whichever way it is jitted): "SIGINT at T" on stderr
INTERRUPTED_COMPILING_IN_XLA = textwrap.dedent("""
    import os, signal, sys, threading, time
    import jax
    from fieldgen.cli import app

    signal.signal(signal.SIGINT, signal.default_int_handler)  # even where this process was started ignoring it
    lowered, compiled, sent = [], [], threading.Event()

    def interrupt(program):
        if len(compiled) < program and not sent.is_set():  # compiles on a CPU come one after another
            sent.set()
            print(f"SIGINT at {time.time()}", file=sys.stderr, flush=True)
            os.kill(os.getpid(), signal.SIGINT)

    def listen(event, duration, **kwargs):
        if event == "/jax/core/compile/jaxpr_to_mlir_module_duration":  # lowered: its compile starts
            lowered.append(event)
            timer = threading.Timer(1, interrupt, (len(lowered),))
            timer.daemon = True
            timer.start()
        elif event == "/jax/core/compile/backend_compile_duration":
            compiled.append(event)

    jax.monitoring.register_event_duration_secs_listener(listen)
    app(sys.argv[1:])
""")


def interrupted_compiling(command: list[str], env: dict) -> subprocess.CompletedProcess:
    """The `fieldgen` command given Ctrl-C a second into a compile (INTERRUPTED_COMPILING_IN_XLA), once it has
    ended: with Ctrl-C's status, within seconds of the signal."""
    import time

    result = subprocess.run([sys.executable, "-c", INTERRUPTED_COMPILING_IN_XLA, *command], env=env,
                            capture_output=True, text=True, timeout=600)
    ended = time.time()
    assert result.returncode == 130, result.stdout[-2000:] + result.stderr[-3000:]
    interrupted = float(result.stderr.split("SIGINT at ")[1].split()[0])
    assert ended - interrupted < 5, f"Ctrl-C took {ended - interrupted:.0f} s to act"
    return result


@pytest.mark.slow
def test_ctrl_c_during_the_first_compile_acts_at_once_and_the_run_goes_on(tmp_path):
    """An ant field's first compile takes minutes on a CPU, and XLA takes no signal meanwhile: Ctrl-C still
    stops the command within seconds, saying how to go on, and both ways of going on open the run."""
    env = dict(os.environ, JAX_PLATFORMS="cpu", JAX_ENABLE_COMPILATION_CACHE="false")
    command = ["train", "ant_nav", "--preset", "cpu", "--out", str(tmp_path), "--no-videos"]
    result = interrupted_compiling(command, env)
    run = tmp_path / "ant_nav-crl-0"
    assert f"interrupted; no checkpoint yet. Start again with: fieldgen train --resume {run}" in " ".join(
        result.stdout.split())
    for again in (["train", "--resume", str(run)], command):
        prepared = runner.invoke(app, [*again, "--prepare"])
        assert prepared.exit_code == 0 and f"prepared {run}" in " ".join(prepared.output.split()), prepared.output


def learned_nothing(out: Path, field: str, seed: int) -> Path:
    """A CPU-sized CRL run set up by `fieldgen train --prepare` that reads as having learned networks of zeros:
    a run `fieldgen eval` judges, without the minutes of training one."""
    from tiny_runs import as_if_learned

    result = runner.invoke(app, ["train", field, "--preset", "cpu", "--seed", str(seed), "--out", str(out),
                                 "--prepare"])
    assert result.exit_code == 0, result.output
    return as_if_learned(out / f"{field}-crl-{seed}")


@pytest.mark.slow
def test_ctrl_c_during_evals_first_compile_acts_at_once_and_writes_nothing(tmp_path):
    """`fieldgen eval` of an ant field's run compiles its evaluation for long on a CPU, and XLA takes no signal
    meanwhile: Ctrl-C still stops it within seconds, as it stops training, one run or several on another field
    alike, and leaves the run folders as they were."""
    first, second = (learned_nothing(tmp_path / "runs", "ant_nav", seed) for seed in (0, 1))
    # at XLA's usual optimization, not the tests' -O0 (conftest): a compile long enough that waiting it out shows
    flags = os.environ.get("XLA_FLAGS", "").replace("--xla_backend_optimization_level=0", "")
    env = dict(os.environ, JAX_PLATFORMS="cpu", JAX_ENABLE_COMPILATION_CACHE="false", XLA_FLAGS=flags)
    before = sorted((p, p.stat().st_mtime_ns) for p in tmp_path.rglob("*"))
    for command, judged in ((["eval", str(first)], str(first)),
                            (["eval", str(first), str(second), "--field", "ant_nav"], "2 runs on ant_nav")):
        result = interrupted_compiling(command, env)
        assert f"interrupted evaluating {judged}; nothing was written\n" in result.stdout, result.stdout
        assert "Traceback" not in result.stderr
        assert sorted((p, p.stat().st_mtime_ns) for p in tmp_path.rglob("*")) == before


@pytest.mark.slow
def test_ctrl_c_while_a_chunk_trains_acts_at_once_and_the_run_goes_on(tmp_path):
    """A chunk of training runs in XLA for a minute here (400k env steps of point_nav): Ctrl-C given a few
    seconds after the first evaluation, once its checkpoint is written, stops the command within seconds."""
    import time

    env = dict(os.environ, JAX_PLATFORMS="cpu")
    command = ["fieldgen", "train", "point_nav", "--envs", "256", "--steps", "4M", "--out", str(tmp_path),
               "--no-videos"]
    # Ctrl-C's default in the command, even where the tests were started ignoring it (a background job)
    training = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    output = ""
    while "steps (" not in output:  # the line of the first evaluation
        output += training.stdout.readline() or pytest.fail(output)
    time.sleep(5)
    training.send_signal(signal.SIGINT)
    interrupted = time.time()
    output += training.communicate(timeout=600)[0]
    assert training.returncode == 130, output
    assert time.time() - interrupted < 5, f"Ctrl-C took {time.time() - interrupted:.0f} s to act"
    run = tmp_path / "point_nav-crl-0"
    assert f"interrupted; the last checkpoint is intact. Continue with: fieldgen train --resume {run}" in " ".join(
        output.split()), output
    resumed = runner.invoke(app, ["train", "--resume", str(run), "--prepare"])
    assert resumed.exit_code == 0 and f"prepared {run}" in " ".join(resumed.output.split()), resumed.output


def test_opening_a_run_leaves_the_writes_of_its_training_alone(tmp_path, tiny_crl_args):
    """`fieldgen eval` or `compare` may open a run while it trains: the checkpoint being written stays."""
    from fieldgen.run import session

    prepared = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--prepare", *tiny_crl_args])
    assert prepared.exit_code == 0, prepared.output
    run = tmp_path / "point_nav-crl-0"
    (run / ".checkpoint.msgpack.x1y2.tmp").write_bytes(b"a checkpoint being written")
    session.open_run(run)
    assert leftovers(run) == [".checkpoint.msgpack.x1y2.tmp"]


def edit_record(run: Path, **changes) -> None:
    (run / "run.json").write_text(json.dumps({**json.loads((run / "run.json").read_text()), **changes}))


ROW = json.dumps({"eval": 0, "seed": 0, "env_steps": 800})
TORN = '{"eval": 1, "se'


@pytest.mark.parametrize("damage,phrase", [
    (lambda run: run / "run.json", "is a file, not a run folder; name the folder fieldgen train wrote"),
    (lambda run: (run / "run.json").write_text("{}"), "run.json is not a run record: it lacks algo, config, observation"),
    (lambda run: (run / "run.json").write_text("[]"), "run.json is not a run record: it holds a list of 0 items, "
     "where fieldgen train writes one JSON object"),  # before: "it lacks algo, config, observation"
    (lambda run: (run / "run.json").write_text('"x"'), "run.json is not a run record: it holds a string, where"),
    (lambda run: edit_record(run, config=[]), "run.json is not a run record: config should be a valid dictionary, not []"),
    (lambda run: edit_record(run, seeds="x"), "run.json is not a run record: seeds should be a valid list, not 'x'"),
    (lambda run: edit_record(run, seeds=[]), "run.json is not a run record: seeds should hold at least 1 item, not [] "
     "(edited or damaged)"),  # before: "seeds List should have at least 1 item after validation, not 0, not []"
    (lambda run: edit_record(run, observation={**json.loads((run / "run.json").read_text())["observation"], "size": 7}),
     "run.json records observation.size as 7, where the run's own copy of its field, "),  # before: no key, no way on
    (lambda run: edit_record(run, seeds=[0, -1], mixed="yes"), "run.json is not a run record: seeds.1 should be "
     "greater than or equal to 0, not -1; mixed should be a valid boolean, not 'yes' (edited or damaged); start the "
     "run again in a new folder"),
    (lambda run: edit_record(run, fields=["../../elsewhere"]), "run.json is not a run record: fields.0 should name a "
     "folder inside the run, such as field or stages/01, not '../../elsewhere'"),
    (lambda run: edit_record(run, promotion={"window": 1.5}), "run.json is not a run record: promotion.window "
     "should be a valid integer, not 1.5"),
    (lambda run: edit_record(run, promotion={"threshold": 5}), "run.json is not a run record: promotion.threshold "
     "should be less than or equal to 1, not 5"),  # before: read, a stage never promoted
    (lambda run: edit_record(run, seeds=[2**40]), "run.json is not a run record: seeds.0 should be less than or equal "
     "to 4294967295, not 1099511627776"),  # before: read, and its metrics rows blamed
    (lambda run: (run / "metrics.jsonl").write_text(f"{TORN}\n{ROW}\n"), "metrics.jsonl:1 is not a metrics row "
     "(not JSON); the file was edited or damaged: restore it from a copy, or start the run again in a new folder"),
    (lambda run: (run / "metrics.jsonl").write_bytes(b"\xff\xfe\n" + ROW.encode()), "metrics.jsonl:1 is not a "
     "metrics row (not JSON)"),
    (lambda run: (run / "metrics.jsonl").write_text(f'{ROW}\n{json.dumps({"eval": "0", "env_steps": 0})}\n'),
     "metrics.jsonl:2 is not a metrics row (eval should be a valid integer, not '0')"),
    (lambda run: ((run / "metrics.jsonl").write_text(ROW.replace("}", ', "promoted_to": 3}')),
                  (run / "checkpoint.msgpack").write_bytes(b"x")), "metrics.jsonl's last row puts the run at stage 4, past its "
     "last (1); the file was edited or damaged"),
    (lambda run: (run / "checkpoint.msgpack").write_bytes(b"x"), "metrics.jsonl holds no evaluation, yet the run "
     "has a checkpoint; the file was edited or damaged: restore it from a copy, or start the run again in a new "
     "folder"),
    (lambda run: ((run / "metrics.jsonl").write_text(ROW), (run / "checkpoint.msgpack").mkdir()),
     "cannot read the checkpoint"),
    (lambda run: (run / "field" / "field.json").write_text(
        (run / "field" / "field.json").read_text().replace('"length": 100', '"length": -3')),
     "field/field.json was edited or damaged (its record_sha256 is not the digest of the rest of it)"),
    (lambda run: edit_record(run, field={**json.loads((run / "run.json").read_text())["field"], "name": "other"}),
     "run.json describes another field than the run's own copy of it, "),
    (lambda run: edit_record(run, field="point_nav"), "run.json is not a run record: field should be a valid "
     "dictionary, not 'point_nav'"),
    (lambda run: (run / "run.json").write_text(json.dumps(
        {k: v for k, v in json.loads((run / "run.json").read_text()).items() if k != "field"})),
     "run.json describes another field than the run's own copy of it"),
    (lambda run: shutil.rmtree(run / "field"), "point_nav-crl-0/field is missing: the run's own copy of its field "
     "(a setup cut short, or a copy of the run that left it out); set the run up again with the fieldgen train "
     "command that made it"),
    (lambda run: edit_record(run, judged="../../elsewhere"), "run.json is not a run record: judged should name a "
     "folder inside the run, such as field or stages/01, not '../../elsewhere'"),
    (lambda run: edit_record(run, judged="judged"), "point_nav-crl-0/judged is missing: the run's own copy of the "
     "field as written, which its figures are judged on"),
    (lambda run: (run / "run.json").unlink(), "point_nav-crl-0 is not a training run: run.json is missing; name the "
     "folder fieldgen train wrote (runs/<field>-<algo>-<seed>); one whose setup was cut short is set up again by the "
     "same fieldgen train command"),
], ids=["file", "empty", "list", "string", "config", "seeds", "seeds_empty", "observation", "seeds_mixed", "fields", "promotion",
        "promotion_threshold", "seed_past_a_key", "middle", "bytes",
        "eval_text", "stage", "no_rows", "folder", "field", "other_field", "field_text", "no_field", "field_missing",
        "judged_outside", "judged_missing", "record_missing"])
def test_damaged_run_folders_are_clear_errors(tmp_path, damage, phrase, tiny_crl_args):
    """What a kill, an editor or a copy can leave in a run folder: one sentence naming the file and the key,
    never a traceback."""
    prepared = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--prepare", *tiny_crl_args])
    assert prepared.exit_code == 0, prepared.output
    run = tmp_path / "point_nav-crl-0"
    target = damage(run)  # the folder, or the path --resume is given instead
    result = runner.invoke(app, ["train", "--resume", str(target if isinstance(target, Path) else run)])
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert "".join(phrase.split()) in "".join(result.output.split()), result.output


def test_a_huge_value_in_a_record_is_quoted_by_its_start(tmp_path):
    """Before: a run.json whose algo was a list of a 5 MB text was quoted whole in the refusal."""
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"algo": ["x" * 5_000_000], "config": {}, "observation": {}}))
    with pytest.raises(record.RunError) as caught:
        record.read_run(run)
    said = str(caught.value)
    assert len(said) < 400 and "algo should be a valid string, not ['xxxx" in said, said


@pytest.mark.parametrize("torn", [TORN.encode(), b'{"eval": 1, "env_steps": "\xe2\x82'])
def test_a_torn_last_metrics_line_is_dropped(tmp_path, torn):
    """A last line cut short (mid-JSON or mid-character) is what a kill leaves: the rows before it stand."""
    from fieldgen.run import record

    (tmp_path / "metrics.jsonl").write_bytes(ROW.encode() + b"\n" + torn)
    assert [r["eval"] for r in record.read_metrics(tmp_path)] == [0]


def test_a_run_folder_that_cannot_be_written_is_one_sentence(tmp_path, monkeypatch, tiny_crl_args):
    """A read-only --out (simulated: tests may run as root) or a full disk when a run is set up."""
    from fieldgen import files

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(files.tempfile, "mkstemp", refuse)
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), *tiny_crl_args])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert "".join(f"cannot set up the run folder {tmp_path / 'point_nav-crl-0'}: Permission denied; fix the "
                   "folder's permissions or choose another --out".split()) in "".join(result.output.split())


def test_a_checkpoint_and_metrics_that_disagree_are_refused(tmp_path, tiny_crl_args):
    """The checkpoint is written after its evaluation's metrics, so its env steps are those of the last row kept;
    metrics.jsonl with that row removed (or from another moment of the run) would resume from the wrong evaluation."""
    import jax
    import numpy as np

    from fieldgen.agents import checkpoint
    from fieldgen.files import write_atomic
    from fieldgen.run import session

    prepared = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--prepare", *tiny_crl_args])
    assert prepared.exit_code == 0, prepared.output
    run = tmp_path / "point_nav-crl-0"
    trainer = session.open_run(run).trainers[0]
    template = jax.eval_shape(jax.vmap(trainer.start), loop.seed_keys([0]))
    state = jax.tree.map(lambda s: np.zeros(s.shape, s.dtype), template).replace(env_steps=np.array([1280], np.int32))
    write_atomic(run / "checkpoint.msgpack", checkpoint.pieces(state))
    rows = [json.dumps({"eval": e, "seed": 0, "env_steps": steps}) for e, steps in enumerate((800, 1280, 1760))]
    (run / "metrics.jsonl").write_text("\n".join(rows) + "\n")  # the third: written before a kill, dropped
    assert [r["eval"] for r in session.open_run(run).rows] == [0, 1]
    for kept, said in ((rows[:1], "its last evaluation at or before them is at 800"), (rows[2:], "none is at or before them")):
        (run / "metrics.jsonl").write_text("\n".join(kept) + "\n")
        result = runner.invoke(app, ["train", "--resume", str(run)])
        assert result.exit_code == 1 and "Traceback" not in result.output, result.output
        assert "".join(f"checkpoint.msgpack holds the run at 1,280 env steps, but {run / 'metrics.jsonl'} has no "
                       f"evaluation there ({said}): the two disagree".split()) in "".join(result.output.split())


def test_a_kick_off_point_edited_to_nan_in_run_json_is_refused_where_it_is_read(tmp_path):
    """Before: the NaN was trained on (a ball spawned at NaN); now run.json is refused in one line naming the key."""
    from typer.testing import CliRunner

    from fieldgen.cli import app

    cli = CliRunner()
    prepared = cli.invoke(app, ["train", "point_soccer", "--curriculum", "auto", "--preset", "cpu", "--steps", "40000",
                                "--prepare", "--out", str(tmp_path)])
    assert prepared.exit_code == 0, prepared.output
    run = tmp_path / "point_soccer-auto-crl-0"
    kept = json.loads((run / "run.json").read_text())
    level, point = next((i, j) for i, points in enumerate(kept["kickoffs"]) for j, p in enumerate(points) if p)
    kept["kickoffs"][level][point][1] = float("nan")
    (run / "run.json").write_text(json.dumps(kept))
    result = cli.invoke(app, ["train", "--resume", str(run)])
    said = " ".join(result.output.split())
    assert result.exit_code == 1 and "Traceback" not in said, said
    assert f"kickoffs.{level}.{point}.1 should be a finite number, not nan" in said and "run.json" in said, said
