"""`fieldgen train` over several processes: settings that cannot make a run over processes, and a coordinator
that never answers, are one line, before anything trains or is written."""

from __future__ import annotations

import socket
import time

import pytest
from typer.testing import CliRunner

from fieldgen.cli import app
from fieldgen.run import distributed
from fieldgen.run.record import RunError

runner = CliRunner()


@pytest.mark.parametrize("options,phrase", [
    (["--coordinator", "localhost:1234", "--num-processes", "0", "--process-id", "0"],
     "--num-processes 0: a run needs at least one process"),
    (["--coordinator", "localhost:1234", "--num-processes", "2", "--process-id", "2"],
     "--process-id 2 is out of range: with --num-processes 2 the ids are 0 to 1"),
    (["--coordinator", "localhost:1234", "--num-processes", "2", "--process-id", "-1"], "--process-id -1 is out of range"),
    (["--coordinator", "localhost:1234"], "--num-processes, --process-id missing: a run over several processes needs"),
    (["--coordinator", "node01", "--num-processes", "2", "--process-id", "1"],
     "--coordinator node01: write it as HOST:PORT"),
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
    for variable in distributed.LAUNCHERS:
        monkeypatch.delenv(variable, raising=False)
    assert distributed.layout(None, None, None) is None
    monkeypatch.setenv("SLURM_STEP_NUM_TASKS", "1")  # a sweep's SLURM task: one process
    assert distributed.layout(None, None, None) is None
    monkeypatch.setenv("SLURM_STEP_NUM_TASKS", "4")  # srun started four
    assert distributed.layout(None, None, None) == distributed.Layout(None, None, None)
    assert distributed.layout("h:1", 2, 1) == distributed.Layout("h:1", 2, 1)


def test_a_coordinator_that_never_answers_is_one_line_after_the_timeout(tmp_path):
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    began = time.monotonic()
    with pytest.raises(RunError, match=rf"no coordinator answered at 127.0.0.1:{port} within 2 s"):
        distributed._wait_for(f"127.0.0.1:{port}", 2)
    assert 2 <= time.monotonic() - began < 10
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--coordinator", f"127.0.0.1:{port}",
                                 "--num-processes", "2", "--process-id", "1", "--coordinator-timeout", "1"])
    assert result.exit_code == 1 and result.output.startswith(f"error: no coordinator answered at 127.0.0.1:{port}")
    assert "start process 0" in result.output and len(result.output.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())
