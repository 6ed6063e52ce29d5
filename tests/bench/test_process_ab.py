"""bench/process_ab.py: arms parsed and applied to the environment, medians and ratios per benchmark row,
bad input in one line, and the whole script on a CPU, tiny."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "bench" / "process_ab.py"
sys.path.insert(0, str(ROOT / "bench"))
import process_ab as bench  # noqa: E402

sys.path.remove(str(ROOT / "bench"))


def test_an_arm_is_a_name_and_its_variables():
    assert bench.arm("default:") == ("default", {})
    assert bench.arm(" graphs : XLA_FLAGS=--a=1,B  N=2") == ("graphs", {"XLA_FLAGS": "--a=1,B", "N": "2"})
    for bad in ("no colon", ": X=1", "x: NOVALUE", "x: 1X=2"):
        with pytest.raises(argparse.ArgumentTypeError):
            bench.arm(bad)


def test_xla_flags_and_the_path_add_to_the_environment_other_variables_replace():
    base = {"XLA_FLAGS": "--old=1", "PYTHONPATH": "/site", "N": "1"}
    env = bench.environment({"XLA_FLAGS": "--new=2", "PYTHONPATH": "/before", "N": "2"}, base)
    assert env["XLA_FLAGS"] == "--old=1 --new=2" and env["PYTHONPATH"] == os.pathsep.join(["/before", "/site"])
    assert env["N"] == "2" and base["N"] == "1"
    assert bench.environment({"XLA_FLAGS": "--new=2"}, {})["XLA_FLAGS"] == "--new=2"


def test_each_row_is_the_median_over_rounds():
    row = {"field": "f", "algo": "crl", "envs": 8, "seeds": 1, "devices": 1}
    rows = [{**row, "train_steps_per_second": r} for r in (10.0, 30.0, 20.0)]
    rows.append({**row, "envs": 16, "train_steps_per_second": 5.0})
    assert bench.medians(rows) == {("f", "crl", 8, 1, 1): 20.0, ("f", "crl", 16, 1, 1): 5.0}


@pytest.mark.parametrize("options, message", [
    (["--arm", "a:"], "compare at least two --arm"),
    (["--arm", "a:", "--arm", "a: X=1"], "--arm names repeat"),
    (["--arm", "a: X"], "is not KEY=VALUE"),
    (["--arm", "a:", "--arm", "b:", "--", "--json", "x"], "give --json before '--'"),
    (["--arm", "a:", "--arm", "b:", "--", "--fields", "no_such_field"], "arm 'a', round 1: train_throughput ended"),
])
def test_bad_input_is_one_clear_line(options, message):
    result = subprocess.run([sys.executable, str(SCRIPT), *options], capture_output=True, text=True, timeout=300)
    assert result.returncode != 0 and message in result.stderr, result.stderr
    assert "Traceback" not in result.stderr


def test_a_stop_reports_the_rounds_that_ended_and_exits_130(tmp_path, monkeypatch, capsys):
    """A time limit's TERM in round 2 (here the arm raising as the handler does): round 1's rates are the
    table and the rows, marked incomplete."""
    done = []

    def run_arm(name, variables, arguments, folder, round_):
        if round_ == 1 and name == "other":
            raise KeyboardInterrupt
        done.append((name, round_))
        return [{"field": "f", "algo": "crl", "envs": 8, "seeds": 1, "devices": 1,
                 "train_steps_per_second": 100.0 if name == "reference" else 150.0 + round_}]

    monkeypatch.setattr(bench, "run_arm", run_arm)
    out = tmp_path / "ab.jsonl"
    monkeypatch.setattr(sys, "argv", ["process_ab.py", "--arm", "reference:", "--arm", "other: A=1", "--arm",
                                      "third: B=1", "--rounds", "2", "--json", str(out), "--", "--envs", "8"])
    with pytest.raises(SystemExit) as stopped:
        bench.main()
    assert stopped.value.code == 130
    assert done == [("reference", 0), ("other", 0), ("third", 0), ("reference", 1)]
    said = capsys.readouterr().out
    assert "stopped in round 2, arm 'other'" in said
    rows = {row["arm"]: row for row in map(json.loads, out.read_text().splitlines())}
    assert rows["other"]["rounds"] == 1 and rows["other"]["over_reference"] == 1.5
    assert rows["reference"]["rounds"] == 2 and not any(row["complete"] for row in rows.values())


@pytest.mark.slow
def test_two_arms_on_a_cpu_are_timed_in_turn_and_compared(tmp_path):
    out = tmp_path / "ab.jsonl"
    result = subprocess.run([sys.executable, str(SCRIPT), "--arm", "reference:", "--arm", "other: FIELDGEN_AB_ARM=1",
                             "--rounds", "1", "--json", str(out), "--", "--fields", "point_nav", "--algos", "crl",
                             "--envs", "8", "--iterations", "1", "--set", "crl.hidden=[32,32]",
                             "--set", "crl.min_replay_rows=100", "--set", "crl.max_replay_rows=400"],
                            capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr[-3000:]
    lines = result.stdout.splitlines()
    assert [line.split(",")[0] for line in lines if line.startswith("round ")] == ["round 1", "round 1"]
    reference, other = (json.loads(line) for line in out.read_text().splitlines())
    assert (reference["arm"], reference["over_reference"], reference["complete"]) == ("reference", 1.0, True)
    assert other["variables"] == {"FIELDGEN_AB_ARM": "1"} and other["train_steps_per_second"] > 0
    assert other["over_reference"] == pytest.approx(other["train_steps_per_second"] / reference["train_steps_per_second"])
