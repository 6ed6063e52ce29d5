"""bench/program_lowering.py: bad input in one line, and one tiny measurement on the CPU."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "bench" / "program_lowering.py"


def test_a_reference_folder_without_fieldgen_is_one_line(tmp_path):
    result = subprocess.run([sys.executable, str(SCRIPT), "--against", str(tmp_path)], capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 2 and f"--against {tmp_path}: no fieldgen installed there" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.slow
def test_each_program_of_a_tiny_run_is_lowered_and_timed(tmp_path):
    out = tmp_path / "rows.jsonl"
    result = subprocess.run([sys.executable, str(SCRIPT), "--field", "point_nav", "--envs", "8", "--json", str(out)],
                            capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [row["program"] for row in rows] == ["shapes", "start", "evaluate", "chunk"]
    assert all(row["this_seconds"] > 0 and row["this_over_against"] is None for row in rows)
    assert "round 1, this: shapes" in result.stdout
