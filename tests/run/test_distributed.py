"""`fieldgen train` over several processes: settings that cannot make a run over processes, and a coordinator
that never answers, are one line, before anything trains or is written; two processes on the CPU train the
run one process trains over two devices, a process killed stops the other with one line, and --resume
finishes the run."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fieldgen.cli import app
from fieldgen.run import distributed, record
from fieldgen.run.record import RunError

runner = CliRunner()


@pytest.mark.parametrize("options,phrase", [
    (["--coordinator", "localhost:1234", "--num-processes", "0", "--process-id", "0"],
     "--num-processes 0: the processes of one run is a whole number from 1 to 65,536"),
    (["--coordinator", "localhost:1234", "--num-processes", "2", "--process-id", "2"],
     "--process-id 2 is out of range: with --num-processes 2 the ids are 0 to 1"),
    (["--coordinator", "localhost:1234", "--num-processes", "2", "--process-id", "-1"], "--process-id -1: a process's id (0 to --num-processes - 1) is a whole number from 0 to 65,535"),
    (["--coordinator", "localhost:1234"], "--num-processes, --process-id missing: a run over several processes needs"),
    (["--coordinator", "node01", "--num-processes", "2", "--process-id", "1"],
     "--coordinator node01: write it as HOST:PORT"),
    (["--coordinator", "localhost:99999", "--num-processes", "1", "--process-id", "0"],
     "--coordinator localhost:99999: port 99,999 is out of range; a port is 1 to 65535"),
])
def test_process_settings_that_cannot_make_a_run_are_one_line(tmp_path, options, phrase):
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), *options])
    assert result.exit_code == 1 and result.output.startswith(f"error: {phrase}"), result.output
    assert len(result.output.strip().splitlines()) == 1 and not any(tmp_path.iterdir())


def test_the_settings_come_from_environment_variables_too(tmp_path):
    env = {"FIELDGEN_COORDINATOR": "localhost:1234", "FIELDGEN_NUM_PROCESSES": "3", "FIELDGEN_PROCESS_ID": "7"}
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path)], env=env)
    assert result.exit_code == 1 and "--process-id 7 is out of range: with --num-processes 3" in result.output


def test_a_launcher_of_several_tasks_is_joined_and_one_process_alone_is_not(monkeypatch):
    for variable in [*distributed.LAUNCHERS, *distributed.LAUNCHED["srun"], *distributed.LAUNCHED["mpirun"]]:
        monkeypatch.delenv(variable, raising=False)
    assert distributed.layout(None, None, None) is None
    monkeypatch.setenv("SLURM_STEP_NUM_TASKS", "1")  # a sweep's SLURM task: one process
    assert distributed.layout(None, None, None) is None
    monkeypatch.setenv("SLURM_STEP_NUM_TASKS", "4")  # srun started four
    for variable, value in zip(distributed.LAUNCHED["srun"], ["77", "node[01-04]", "4", "2", "0"]):
        monkeypatch.setenv(variable, value)
    assert distributed.layout(None, None, None) == distributed.Layout(None, None, None)
    assert distributed.layout("h:1", 2, 1) == distributed.Layout("h:1", 2, 1)


def test_a_launchers_task_count_left_in_the_shell_is_one_line(tmp_path, monkeypatch):
    """Before: SLURM_STEP_NUM_TASKS=2 without srun's other variables went on to JAX, which ended in a traceback."""
    for variable in [*distributed.LAUNCHERS, *distributed.LAUNCHED["srun"], *distributed.LAUNCHED["mpirun"]]:
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.setenv("SLURM_STEP_NUM_TASKS", "2")
    monkeypatch.setenv("SLURM_PROCID", "0")
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path)])
    assert result.exit_code == 1 and " ".join(result.output.split()) == (
        "error: SLURM_STEP_NUM_TASKS=2 says srun started 2 processes, but SLURM_JOB_ID, SLURM_STEP_NODELIST, "
        "SLURM_NTASKS, SLURM_LOCALID are not set, so srun did not start this one: start it with srun, give "
        "--coordinator HOST:PORT --num-processes N --process-id I, or unset SLURM_STEP_NUM_TASKS (left from another "
        "shell) to train in this process alone"), result.output
    assert not any(tmp_path.iterdir())


class Clock:
    """Time that passes only when the code under test sleeps or waits for a connection."""

    def __init__(self):
        self.now, self.tries = 0.0, 0

    def sleep(self, seconds: float) -> None:
        self.now += seconds

    def refuse(self, address, timeout=None):
        self.tries += 1
        self.now += 0.01
        raise ConnectionRefusedError(111, "Connection refused")


def test_a_coordinator_that_never_answers_is_one_line_after_the_timeout(tmp_path, monkeypatch):
    port = distributed.free_port()  # nobody listens on it
    clock = Clock()
    with monkeypatch.context() as m:
        m.setattr(distributed.time, "monotonic", lambda: clock.now)
        m.setattr(distributed.time, "sleep", clock.sleep)
        m.setattr(distributed.socket, "create_connection", clock.refuse)
        with pytest.raises(RunError, match=rf"no coordinator answered at 127.0.0.1:{port} within 2 s"):
            distributed._wait_for(f"127.0.0.1:{port}", 2)
    assert clock.now > 2 and clock.tries > 1  # asked again until the timeout had passed, then gave up
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--coordinator", f"127.0.0.1:{port}",
                                 "--num-processes", "2", "--process-id", "1", "--coordinator-timeout", "1"])
    assert result.exit_code == 1 and result.output.startswith(f"error: no coordinator answered at 127.0.0.1:{port}")
    assert "start process 0" in result.output and len(result.output.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())


def test_process_0_meets_the_others_on_its_port_before_joining(monkeypatch):
    """Process 0 waits on the coordinator's port until each other process has said its id there; a connection
    that says nothing of the kind (a port scanner) is no process."""
    port = distributed.free_port()
    where = distributed.Layout(f"127.0.0.1:{port}", 3, 0)
    gathered = threading.Thread(target=distributed.gather, args=(where, 600))
    gathered.start()
    distributed._wait_for(where.coordinator, 600)  # answered, says nothing
    distributed._wait_for(where.coordinator, 600, 2)
    assert gathered.is_alive()  # process 1 has not come yet
    distributed._wait_for(where.coordinator, 600, 1)
    gathered.join(600)
    assert not gathered.is_alive()
    with socket.socket() as again:  # the port is free again for JAX's coordination service (which reuses addresses)
        again.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        again.bind(("127.0.0.1", port))
        again.listen(1)


def test_what_jax_raises_while_joining_is_one_line_naming_the_process_and_the_address(monkeypatch):
    import jax

    def refuse(*args, **kwargs):
        raise RuntimeError("DEADLINE_EXCEEDED: Barrier timed out.\n  Additional GRPC error information: ...")

    monkeypatch.setattr(distributed, "gather", lambda where, timeout: None)
    monkeypatch.setattr(distributed, "reach", lambda where, timeout: None)
    monkeypatch.setattr(jax.config, "update", lambda *args: None)
    monkeypatch.setattr(jax.distributed, "initialize", refuse)
    with pytest.raises(RunError) as refused:
        distributed.join(distributed.Layout("127.0.0.1:1234", 2, 1), 3)
    assert str(refused.value) == (
        "process 1 could not join the run's processes at 127.0.0.1:1234 within 3 s (DEADLINE_EXCEEDED: Barrier timed "
        "out. Additional GRPC error information: ...): check that every process was started with the same "
        "--coordinator and --num-processes and its own --process-id, and that the port is open between the hosts")


def process_0(tmp_path: Path, port: int, timeout: int = 2) -> subprocess.CompletedProcess:
    """`fieldgen train` as process 0 of 2 at 127.0.0.1:PORT, in its own process (JAX's runtime may end it)."""
    return subprocess.run([sys.executable, "-m", "fieldgen", "train", "point_nav", "--out", str(tmp_path / "runs"),
                           "--coordinator", f"127.0.0.1:{port}", "--num-processes", "2", "--process-id", "0",
                           "--coordinator-timeout", str(timeout)], capture_output=True, text=True, timeout=600,
                          env={**os.environ, **distributed.only_devices("cpu", [0])})


def test_process_0_alone_ends_in_one_line_naming_the_one_missing(tmp_path):
    """Before: process 0 whose other process never started died of SIGABRT with JAX's fatal-error text."""
    port = distributed.free_port()
    done = process_0(tmp_path, port)
    assert done.returncode == 1 and " ".join(done.stderr.split()) == (
        f"error: process 0 of 2 waited 2 s at 127.0.0.1:{port} for process 1, which never came: start it with "
        f"--coordinator 127.0.0.1:{port} --num-processes 2 --process-id 1, and check that the address and the port "
        "are reachable from their hosts (or raise --coordinator-timeout)"), done.stdout + done.stderr
    assert not (tmp_path / "runs").exists()


def test_a_coordinator_port_another_program_holds_is_one_line(tmp_path):
    """Before: process 0 crashed (SIGSEGV) where its coordinator's port was taken."""
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        done = process_0(tmp_path, port)
    assert done.returncode == 1 and " ".join(done.stderr.split()) == (
        f"error: process 0 cannot start the run's coordinator at 127.0.0.1:{port}: port {port} of this host is taken "
        "(another program listens on it): choose a free port in --coordinator, the same for every process"), \
        done.stdout + done.stderr
    assert not (tmp_path / "runs").exists()


class Coordinator:
    """Stands in for the coordination service's client: the processes it hears from, those that finished."""

    def __init__(self, live: set[int] | None, finished: set[int]):
        self.live, self.finished = live, finished

    def get_live_nodes(self, processes):
        if self.live is None:
            raise RuntimeError("UNAVAILABLE: Socket closed")
        return {p: 1 for p in processes if p in self.live}

    def key_value_try_get(self, key):
        if int(key.rsplit("/", 1)[1]) not in self.finished:
            raise RuntimeError(f"NOT_FOUND: Config key {key} not found.")
        return "1"


def test_the_processes_gone_are_those_unheard_of_that_did_not_finish(monkeypatch):
    monkeypatch.setattr(distributed, "_client", lambda: Coordinator(live={0, 2}, finished={3}))
    assert distributed._gone(0, 4) == [1]
    monkeypatch.setattr(distributed, "_client", lambda: Coordinator(live=None, finished=set()))
    assert distributed._gone(1, 4) == [0]  # the coordinator itself, which lives in process 0


def test_a_process_gone_ends_this_one_with_one_sentence_naming_it(monkeypatch):
    said, exits = [], []
    monkeypatch.setattr(os, "_exit", exits.append)
    distributed._stop(said.append, [1, 3], 0, 4)
    assert said == ["processes 1, 3 of 4 stopped, so this one (process 0) stops too"] and exits == [1]
    distributed.stop_if_another_stopped(RuntimeError("Gloo AllGather failed"), said.append)  # one process: no other
    assert len(said) == 1
    distributed._stop(said.append, [0], 1, 2)
    assert said[1:] == ["process 0 of 2 (the run's coordinator) stopped, so this one (process 1) stops too"] \
        == [distributed.stopped([0], 1, 2)]  # the words a supervised process's parent says for it (below)


def test_a_stopped_process_is_worded_once_naming_the_coordinator_where_it_is_process_0():
    assert distributed.stopped([2], 0, 3) == "process 2 of 3 stopped, so this one (process 0) stops too"
    assert distributed.stopped([0, 2], 1, 4) == \
        "processes 0, 2 of 4 (process 0 is the run's coordinator) stopped, so this one (process 1) stops too"
    assert distributed.stopped([0]) == "process 0 (the run's coordinator) stopped, so this one stops too"


STOP_LINE = "process 0 of 2 (the run's coordinator) stopped, so this one (process 1) stops too. Start every process again"
CHILD = f"""import os, signal, sys
for step in sys.argv[1:]:
    if step == "words":  # as fieldgen.cli.training leaves them once it knows its run
        open(os.environ["FIELDGEN_WORDS_IF_COORDINATOR_LOST"], "w").write({STOP_LINE!r})
    elif step == "watcher":  # its watcher noticed process 0 gone
        print("error: " + {STOP_LINE!r}, file=sys.stderr, flush=True)
    elif step == "jax":  # JAX's client noticed it, and ends the process with a stack trace
        print("F0000 Terminating process because the JAX distributed service detected fatal errors", file=sys.stderr)
        print("*** Check failure stack trace: ***", file=sys.stderr, flush=True)
if "jax" in sys.argv:
    os.kill(os.getpid(), signal.SIGKILL)
sys.exit(1)
"""  # a supervised child as process 0 stops: who notices it, in which order


@pytest.mark.parametrize("steps, line", [
    (["words", "watcher", "jax"], STOP_LINE),  # the watcher first, and JAX before the child has ended
    (["words", "jax", "watcher"], STOP_LINE),  # JAX first, the watcher still in time to print
    (["words", "jax"], STOP_LINE),
    (["words", "watcher"], STOP_LINE),
    (["jax"], "process 0 of 2 (the run's coordinator) stopped, so this one (process 1) stops too"),  # no words yet
], ids=["watcher-then-jax", "jax-then-watcher", "jax", "watcher", "jax-before-words"])
def test_a_supervised_process_says_process_0_stopped_once_whoever_notices_first(monkeypatch, capsys, steps, line):
    from fieldgen.run import supervisor

    monkeypatch.setattr(supervisor, "fieldgen_command", lambda *args: [sys.executable, "-c", CHILD, *steps])
    assert supervisor.supervise(1, 2) == 1
    said = capsys.readouterr().err
    assert said.splitlines() == [f"error: {line}"], said  # once, in the one wording, and no stack trace

# Two `fieldgen train` processes on the CPU, one device each, train as one run over both (their collectives go
# through gloo); the same run in one process over two devices is what they must reproduce.
def fieldgen_train(args: list[str], log: Path, devices: int = 1, python: tuple[str, ...] = ("-m", "fieldgen")
                   ) -> subprocess.Popen:
    """`fieldgen train ARGS` in its own process on `devices` CPU devices, its output in `log`."""
    env = {**os.environ, **distributed.only_devices("cpu", range(devices))}
    with log.open("w") as output:
        return subprocess.Popen([sys.executable, *python, "train", *args], stdout=output,
                                stderr=subprocess.STDOUT, env=env)


LAG_SECONDS = 45  # more than the 30 s gloo gives the other processes to join a process's first collective
COMPILES_LATE = f"""import time
from fieldgen.agents import programs
compile_, lags = programs.Compiling._compile, [{LAG_SECONDS}]
def late(self, lowered):
    time.sleep(lags.pop() if lags else 0)
    compile_(self, lowered)
programs.Compiling._compile = late
from fieldgen.cli import app
app(prog_name="fieldgen")
"""  # `fieldgen` whose first compile starts LAG_SECONDS late


def over_two_processes(args: list[str], folder: Path, logs: str = "process") -> list[subprocess.Popen]:
    """The two processes of one run, started by hand as on two hosts (process 1 first: it waits for 0)."""
    port = distributed.free_port()
    return [fieldgen_train([*args, "--coordinator", f"127.0.0.1:{port}", "--num-processes", "2", "--process-id",
                            str(i)], folder / f"{logs}{i}.log") for i in (1, 0)][::-1]


def ended(process: subprocess.Popen, log: Path, timeout: float = 900) -> str:
    """The process's output once it has ended with exit status 0."""
    assert process.wait(timeout) == 0, log.read_text()[-3000:]
    return log.read_text()


def results(run: Path) -> tuple[list[dict], bytes, bytes]:
    """A run's metrics without their timings, its checkpoint and its learner, as written."""
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    return ([{k: v for k, v in row.items() if k not in record.TIMINGS} for row in rows],
            (run / "checkpoint.msgpack").read_bytes(), (run / "learner.msgpack").read_bytes())


@pytest.fixture(scope="module")
def two_seeds(tiny_crl_args):
    return ["point_nav", "--seeds", "2", "--no-videos", *tiny_crl_args]


@pytest.fixture(scope="module")
def one_process(tmp_path_factory, two_seeds) -> Path:
    """The tiny run of two seeds in one process over two CPU devices (a seed each)."""
    out = tmp_path_factory.mktemp("one-process")
    ended(fieldgen_train([*two_seeds, "--out", str(out)], out / "log", devices=2), out / "log")
    return out / "point_nav-crl-0to1"


@pytest.mark.slow
def test_two_processes_train_the_run_one_process_trains_over_two_devices(tmp_path, two_seeds, one_process):
    processes = over_two_processes([*two_seeds, "--out", str(tmp_path)], tmp_path)
    outputs = [ended(p, tmp_path / f"process{i}.log") for i, p in enumerate(processes)]
    run = tmp_path / "point_nav-crl-0to1"
    assert results(run) == results(one_process)
    assert json.loads((run / "run.json").read_text())["processes"]["devices_per_process"] == [1, 1]
    assert "metrics:" in outputs[0] and "metrics:" not in outputs[1]  # process 0 alone reports and writes


@pytest.mark.slow
def test_a_process_that_compiles_long_after_the_other_still_trains_the_run_with_it(tmp_path, two_seeds, one_process):
    """Process 0 (not supervised: it runs in the process started here) compiles LAG_SECONDS late; process 1
    waits for it before either calls a program, rather than failing in its first collective."""
    port = distributed.free_port()
    joined = [*two_seeds, "--out", str(tmp_path), "--coordinator", f"127.0.0.1:{port}", "--num-processes", "2"]
    later = fieldgen_train([*joined, "--process-id", "1"], tmp_path / "process1.log")
    first = fieldgen_train([*joined, "--process-id", "0"], tmp_path / "process0.log", python=("-c", COMPILES_LATE))
    for i, process in enumerate((first, later)):
        ended(process, tmp_path / f"process{i}.log")
    assert results(tmp_path / "point_nav-crl-0to1") == results(one_process)


@pytest.mark.slow
def test_a_process_killed_stops_the_other_with_one_line_and_resume_finishes_the_run(tmp_path, two_seeds,
                                                                                       one_process):
    processes = over_two_processes([*two_seeds, "--out", str(tmp_path)], tmp_path)
    run = tmp_path / "point_nav-crl-0to1"
    deadline = time.monotonic() + 900
    while not (run / "checkpoint.msgpack").exists():  # evaluation 0 is written: training goes on
        assert time.monotonic() < deadline and processes[0].poll() is None, (tmp_path / "process0.log").read_text()
        time.sleep(0.05)
    processes[1].kill()
    assert processes[0].wait(distributed.HEARTBEAT_SECONDS + 60) == 1  # no hang: the heartbeat names it
    errors = [line for line in (tmp_path / "process0.log").read_text().splitlines() if line.startswith("error")]
    assert errors == [f"error: process 1 of 2 stopped, so this one (process 0) stops too. Start every process "
                      f"again with --resume {run} to continue from its last checkpoint"]
    assert results(run)[0][-1]["eval"] < 2  # stopped before the end

    processes = over_two_processes(["--resume", str(run)], tmp_path, "resumed")
    for i, process in enumerate(processes):
        ended(process, tmp_path / f"resumed{i}.log")
    assert results(run) == results(one_process)


@pytest.mark.slow
def test_processes_stop_at_process_0s_time_limit_together_and_resume_finishes_the_run(tmp_path, two_seeds,
                                                                                    one_process):
    """Process 1 has no limit of its own; process 0's is up after the first chunk: both stop at that evaluation
    (exit 75, no hang in a collective the other never joins), and both resumed end the run as one process."""
    port = distributed.free_port()
    joined = ["--coordinator", f"127.0.0.1:{port}", "--num-processes", "2"]
    processes = [fieldgen_train([*two_seeds, "--out", str(tmp_path), *joined, "--process-id", str(i), *limit],
                                tmp_path / f"process{i}.log") for i, limit in ((1, []), (0, ["--time-limit", "0.01s"]))][::-1]
    for i, process in enumerate(processes):
        assert process.wait(900) == 75, (tmp_path / f"process{i}.log").read_text()[-3000:]
    run = tmp_path / "point_nav-crl-0to1"
    assert [row["eval"] for row in results(run)[0]] == [0, 0, 1, 1]
    assert "stopped at the time limit after evaluation 1 of 2" in " ".join((tmp_path / "process0.log").read_text().split())
    processes = over_two_processes(["--resume", str(run)], tmp_path, "resumed")
    for i, process in enumerate(processes):
        ended(process, tmp_path / f"resumed{i}.log")
    assert results(run) == results(one_process)


@pytest.mark.slow
def test_the_coordinator_killed_stops_the_other_with_one_line_naming_it(tmp_path, two_seeds):
    """Process 0 holds the coordination service, and JAX ends the others at once when it dies: process 1 says
    so in one line, with how to go on, and no stack trace."""
    processes = over_two_processes([*two_seeds, "--out", str(tmp_path)], tmp_path)
    run = tmp_path / "point_nav-crl-0to1"
    deadline = time.monotonic() + 900
    while not (run / "checkpoint.msgpack").exists():
        assert time.monotonic() < deadline and processes[1].poll() is None, (tmp_path / "process1.log").read_text()
        time.sleep(0.05)
    processes[0].kill()
    assert processes[1].wait(distributed.HEARTBEAT_SECONDS + 60) == 1, (tmp_path / "process1.log").read_text()
    log = (tmp_path / "process1.log").read_text()
    told = [line for line in log.splitlines() if line.startswith("error") or "stopped" in line]
    assert told == [f"error: process 0 of 2 (the run's coordinator) stopped, so this one (process 1) stops too. "
                    f"Start every process again with --resume {run} to continue from its last checkpoint"], log
    assert "stack trace" not in log and "Traceback" not in log and "Terminating process" not in log, log


def test_only_processes_other_than_the_coordinator_train_in_a_supervised_child(monkeypatch):
    from fieldgen.run import supervisor

    for variable in (supervisor.WORDS, *supervisor.RANKS):
        monkeypatch.delenv(variable, raising=False)
    assert supervisor.needed(1) and not supervisor.needed(0)
    assert not supervisor.needed(None)  # a launcher's process of unknown rank: as JAX alone would run it
    monkeypatch.setenv("SLURM_PROCID", "3")
    assert supervisor.needed(None)
    monkeypatch.setenv("SLURM_PROCID", "0")
    assert not supervisor.needed(None)
    monkeypatch.setenv(supervisor.WORDS, "/tmp/words")  # the child itself
    assert not supervisor.needed(1)


def test_a_supervised_command_gives_back_the_signal_handlers_it_took(monkeypatch):
    """The parent ignores Ctrl-C while its child trains; once the child is done, whoever called the app (a test,
    a program) has its own handlers again, and the processes it starts later can be stopped by SIGINT."""
    import signal
    import sys

    from fieldgen.run import supervisor

    before = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    monkeypatch.setattr(sys, "argv", ["fieldgen", "--help"])
    assert supervisor.supervise() == 0
    assert {sig: signal.getsignal(sig) for sig in before} == before
