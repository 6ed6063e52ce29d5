"""bench/two_processes_vs_one.py: the rate of the training chunks and the differences it reports, bad input
in one line, and the whole script on a CPU, tiny: two processes train what one process trains."""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "bench" / "two_processes_vs_one.py"
sys.path.insert(0, str(ROOT / "bench"))
import two_processes_vs_one as bench  # noqa: E402

sys.path.remove(str(ROOT / "bench"))


def test_the_rate_is_of_every_seed_over_the_chunks_after_the_first():
    rows = [{"eval": 0, "seed": s} for s in (0, 1)]
    rows += [{"eval": e, "seed": s, "steps_per_second": rate} for e, rate in ((1, 10.0), (2, 100.0), (3, 300.0))
             for s in (0, 1)]
    assert bench.chunk_rate(rows, seeds=2) == 2 * 200.0
    assert bench.chunk_rate(rows[:4], seeds=2) == 2 * 10.0  # one chunk: it alone


def test_differences_are_the_largest_of_each_metric_and_array_timings_left_out():
    one = [{"eval": 0, "loss": 1.0, "wall_seconds": 5.0, "variants": [1, 2]},
           {"eval": 1, "loss": 2.0, "steps_per_second": 10.0, "variants": [1, 2], "gone": float("nan")}]
    two = [{"eval": 0, "loss": 1.5, "wall_seconds": 9.0, "variants": [1, 2]},
           {"eval": 1, "loss": 1.75, "steps_per_second": 20.0, "variants": [1, 3], "gone": float("nan")}]
    assert bench.metric_differences(one, two) == {"eval": 0, "loss": 0.5, "variants": math.inf, "gone": 0}
    assert bench.metric_differences(one, two[:1]) == {"rows": math.inf}
    assert bench.metric_differences(one, [one[0], {**one[1], "extra": 1}])["extra"] == math.inf
    a = {"w": np.array([[1.0, 2.0]]), "b": np.zeros(3), "n": np.zeros(0)}
    b = {"w": np.array([[1.0, -2.0]]), "b": np.zeros(4), "n": np.zeros(0), "more": np.ones(1)}
    assert bench.array_differences(a, b) == {"w": 4.0, "b": math.inf, "n": 0.0, "more": math.inf}
    assert bench.largest({"w": 4.0, "n": 0.0}) == "4 (w)" and bench.largest({"n": 0.0}) == "0"


def test_the_verdict_reads_the_layouts_difference_beside_the_controls():
    same = bench.Sameness({"loss": 0.0}, {"w": 0.0}, True)
    apart = bench.Sameness({"loss": 0.5}, {"w": 2.5}, False)
    assert bench.verdict(same, None) == bench.verdict(same, apart) == "identical: yes"
    assert "--control tells" in bench.verdict(apart, None)
    assert "the split into processes changed the run" in bench.verdict(apart, same)
    assert "nor is one process trained twice (largest learner difference 2.5 (w))" in bench.verdict(apart, apart)
    assert bench.Sameness({"loss": 0.0}, {"w": 0.0}, False).identical is False  # the bytes count too
    row = apart.row()
    assert row["identical"] is False and row["learner_max_abs_difference"] == 2.5
    assert bench.Sameness({"loss": math.inf}, {"w": math.inf}, False).row()["learner_max_abs_difference"] is None


def test_a_failed_process_is_named_by_the_line_that_says_why(tmp_path):
    log = tmp_path / "p.log"
    log.write_text("ant_nav 1,000 of 2,000 steps\nF1127 20:17:03.1 client.cc:12] Check failed: ok\n"
                   "*** Check failure stack trace: ***\n    @     0x657a05  _start\n")
    assert bench.cause(log).startswith("F1127 ") and "Check failed" in bench.cause(log)
    log.write_text("Traceback (most recent call last):\n  File x\nValueError: no field\n\n")
    assert bench.cause(log) == "ValueError: no field"
    log.write_text("step 1\nkilled\n")
    assert bench.cause(log) == "killed"
    log.write_text("")
    assert bench.cause(log) == "(no output)"


WAITS_UNLESS_PROCESS_1 = ("import sys, time\n"
                          "sys.exit('error: process 1 could not start') if sys.argv[-1] == '1' else time.sleep(300)")


def test_the_process_that_fails_is_named_while_the_others_still_wait_for_it(tmp_path, monkeypatch):
    """Process 0 waits for a process 1 that died at its start (JAX aborts it only minutes later): the
    benchmark names process 1 and why, not process 0's abort or its own timeout."""
    monkeypatch.setattr(bench, "run_command", lambda args, out, *options: [sys.executable, "-c",
                                                                           WAITS_UNLESS_PROCESS_1, *options])
    args = argparse.Namespace(seeds=1, timeout=60, out=tmp_path)
    with pytest.raises(SystemExit) as stopped:
        bench.train("two processes", args, "cpu", tmp_path / "runs", tmp_path)
    assert "process 1 ended with status 1: error: process 1 could not start" in str(stopped.value)

@pytest.mark.parametrize("options, message", [
    (["--seeds", "0"], "--seeds, --envs, --steps and --evals are positive"),
    (["--field", "no_such_field", "--platform", "cpu"], "error: one process: process 0 ended with status 1: error:"),
])
def test_bad_input_is_one_clear_line(tmp_path, options, message):
    result = subprocess.run([sys.executable, str(SCRIPT), "--out", str(tmp_path), *options], capture_output=True,
                            text=True, timeout=300)
    assert result.returncode != 0 and message in result.stderr, result.stderr
    assert "Traceback" not in result.stderr and len(result.stderr.strip().splitlines()) <= 3


@pytest.mark.slow
def test_two_processes_on_a_cpu_train_what_one_process_trains(tmp_path, tiny_crl_args):
    out = tmp_path / "rows.jsonl"
    result = subprocess.run([sys.executable, str(SCRIPT), "--platform", "cpu", "--field", "point_nav", "--seeds", "2",
                             "--evals", "2", *tiny_crl_args, "--control", "--json", str(out)],
                            capture_output=True, text=True, cwd=tmp_path, timeout=1800)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "\nidentical: yes\n" in result.stdout and "checkpoint.msgpack: the same bytes" in result.stdout
    assert "two processes / one process: " in result.stdout
    one, two, again = (json.loads(line) for line in out.read_text().splitlines())
    assert again["layout"] == "one process again" and again["control"] == two["control"]
    assert two["control"]["identical"] and "one process again, against the first:" in result.stdout
    assert (one["layout"], one["processes"], one["devices_per_process"]) == ("one process", 1, [2])
    assert (two["layout"], two["processes"], two["devices_per_process"]) == ("two processes", 2, [1, 1])
    assert two["identical"] and two["checkpoint_same_bytes"] and two["learner_max_abs_difference"] == 0
    assert set(two["metrics_max_abs_difference"]) >= {"success_any", "critic_loss", "env_steps"}
    assert not any(two["metrics_max_abs_difference"].values())
    assert one["chunk_steps_per_second"] > 0 and two["chunk_steps_per_second"] > 0
    assert two["over_one_process"] == pytest.approx(two["chunk_steps_per_second"] / one["chunk_steps_per_second"])
    assert one["commands"][0].startswith("JAX_PLATFORMS=cpu XLA_FLAGS=") and "device_count=2" in one["commands"][0]
    assert [c.split("--process-id ")[1] for c in two["commands"]] == ["0", "1"]
    assert all(c in result.stdout for c in one["commands"] + two["commands"])
