"""bench/warp_vs_jax.py on a CPU: the JAX rows run, the Warp rows are skipped with the reason (or, asked
for, run on Warp's CPU kernels and agree with JAX), and bad input is one line."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
import warp_vs_jax  # noqa: E402

sys.path.remove(str(ROOT / "bench"))

# one batch size, and the agreement after as many steps as a timed call: one program to compile
TINY = ["--fields", "point_nav", "--envs", "4", "--steps", "2", "--agree-steps", "2", "--repeats", "1"]


def run(tmp_path: Path, monkeypatch, capture, *options: str) -> tuple[str, list[dict]]:
    """The script's printed lines and JSON rows, run in this process (its imports and compiled programs shared)."""
    out = tmp_path / "rows.jsonl"
    monkeypatch.setattr(sys, "argv", ["warp_vs_jax.py", *options, "--build", str(tmp_path / "build"),
                                      "--json", str(out)])
    warp_vs_jax.main()
    rows = [json.loads(line) for line in out.read_text().splitlines()] if out.exists() else []
    return capture.readouterr().out, rows


def test_jax_rows_run_and_warp_rows_say_why_they_are_skipped(tmp_path, monkeypatch, capsys):
    printed, rows = run(tmp_path, monkeypatch, capsys, *TINY, "--iterations", "3", "--ls-iterations", "2")
    skipped = [line for line in printed.splitlines() if line.startswith("Warp rows skipped: ")]
    assert len(skipped) == 1 and ("no CUDA device" in skipped[0] or "warp-lang is not installed" in skipped[0])
    assert [(r["field"], r["impl"], r["envs"]) for r in rows] == [("point_nav", "jax", 4)]
    row = rows[0]
    assert row["env_steps_per_second"] > 0 and row["ratio_to_jax"] == 1.0 and row["max_qpos_difference"] is None
    assert row["steps"] == 2 and row["agree_steps"] == 2 and row["nonfinite_envs"] == 0
    assert (row["iterations"], row["ls_iterations"]) == (3, 2)  # the solver's limits as given, not the field's
    assert row["physics_steps"] >= 1 and row["backend"] == "cpu"


@pytest.mark.parametrize("options, message", [
    (["--envs", "many"], "--envs 'many': write comma-separated whole numbers"),
    (["--impls", "cpp"], "--impls takes jax and/or warp"),
    (["--fields", "no_such_field"], "no_such_field: neither a file nor a bundled field"),
])
def test_bad_input_is_one_clear_line(tmp_path, monkeypatch, capsys, options, message):
    with pytest.raises(SystemExit) as stopped:
        run(tmp_path, monkeypatch, capsys, *options)
    said = str(stopped.value.code) + capsys.readouterr().err
    assert stopped.value.code != 0 and message in said and not (tmp_path / "rows.jsonl").exists()


@pytest.mark.slow
def test_warp_on_cpu_steps_the_ant_beside_jax(tmp_path, monkeypatch, capfd):
    pytest.importorskip("warp")
    printed, rows = run(tmp_path, monkeypatch, capfd, "--fields", "ant_nav", "--envs", "2", "--steps", "3",
                        "--agree-steps", "3", "--repeats", "1", "--warp-on-cpu")
    assert [(r["impl"], r["graph_mode"]) for r in rows] == [("jax", None), ("warp", "JAX")]
    warp = rows[1]
    assert warp["env_steps_per_second"] > 0 and warp["ratio_to_jax"] > 0 and warp["nonfinite_envs"] == 0
    assert 0 < warp["max_qpos_difference"] < 0.1  # the same start and actions; the solvers differ
    assert 1 <= warp["most_contacts"] <= warp["naconmax"]
    # ant_nav's one solver iteration is flagged as reached; no contact or constraint capacity overflows
    assert set(warp["overflow"]) <= {"ITERATIONS", "LS_ITERATIONS"}
    assert "limit reached" not in printed  # Warp's kernels print no warning of their own (capfd: C's stdout too)


def test_overflow_flags_are_named():
    pytest.importorskip("warp")
    assert warp_vs_jax.overflow_names(0) == []
    assert warp_vs_jax.overflow_names(0b1001) == ["NEFC", "NARROWPHASE"]
