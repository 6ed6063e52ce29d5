"""bench/warp_agreement.py: the spread of per-environment gaps on hand-made positions, bad input as one line,
and (slow) Warp's CPU kernels agreeing with JAX once the solver converges."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
import warp_agreement  # noqa: E402

sys.path.remove(str(ROOT / "bench"))


def test_the_spread_is_over_each_environments_largest_gap():
    a = np.zeros((4, 3))
    b = np.array([[0.0, 0.1, -0.2], [0.0, 0.0, 0.0], [0.4, 0.0, 0.0], [0.0, -0.3, 0.0]])
    s = warp_agreement.spread(a, b)  # per env: 0.2, 0, 0.4, 0.3
    assert s["max"] == pytest.approx(0.4) and s["median"] == pytest.approx(0.25)
    assert s["p90"] == pytest.approx(np.quantile([0.2, 0.0, 0.4, 0.3], 0.9))


@pytest.mark.parametrize("options, message", [
    (["--iterations", "one"], "--iterations 'one': write comma-separated whole numbers"),
    (["--steps", "0,3"], "--steps '0,3': each number is at least 1"),
    (["--envs", "0"], "--envs is at least 1"),
])
def test_bad_input_is_one_clear_line(monkeypatch, capsys, options, message):
    monkeypatch.setattr(sys, "argv", ["warp_agreement.py", *options])
    with pytest.raises(SystemExit) as stopped:
        warp_agreement.main()
    assert stopped.value.code != 0 and message in capsys.readouterr().err


@pytest.mark.slow
def test_warp_on_cpu_agrees_with_jax_once_the_solver_converges(tmp_path, monkeypatch):
    pytest.importorskip("warp")
    out = tmp_path / "rows.jsonl"
    monkeypatch.setattr(sys, "argv", ["warp_agreement.py", "--build", str(tmp_path / "build"), "--fields", "point_nav",
                                      "--envs", "2", "--iterations", "1,20", "--steps", "2", "--warp-on-cpu",
                                      "--json", str(out)])
    warp_agreement.main()
    rows = {r["pair"]: r for r in map(json.loads, out.read_text().splitlines())}
    assert set(rows) == {"warp vs jax, 1 iterations", "warp vs jax, 20 iterations", "jax, 1 vs 20 iterations",
                         "warp, 1 vs 20 iterations"}
    assert rows["warp vs jax, 20 iterations"]["max"] < 1e-4
