"""win_share: each seed's share of matches won against the random policy, for a self-play results page."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
import win_share  # noqa: E402

sys.path.remove(str(ROOT / "bench"))


def row(seed: int, steps: int, win: float, draw: float, loss: float) -> dict:
    return {"seed": seed, "eval": steps, "env_steps": steps, "win_vs_random": win, "draw_vs_random": draw,
            "loss_vs_random": loss}


def test_each_seed_gets_its_share_won_in_env_step_order():
    rows = [row(1, 20, 0.5, 0.5, 0.0), row(0, 20, 0.25, 0.5, 0.25), row(0, 0, 0.0, 1.0, 0.0),
            row(1, 0, 0.0, 1.0, 0.0)]
    shares = win_share.win_shares(rows)
    assert list(shares) == [0, 1]
    assert shares[0] == ([0, 20], [0.0, 0.25])
    assert shares[1] == ([0, 20], [0.0, 0.5])
    assert win_share.win_shares([row(0, 5, 3, 1, 0)])[0][1] == [pytest.approx(0.75)]  # counts as well as shares


def test_the_plot_is_written_with_a_panel_per_setting(tmp_path):
    rows = [row(0, 0, 0.0, 1.0, 0.0), row(0, 10, 0.9, 0.1, 0.0)]
    win_share.draw({"": rows}, tmp_path / "w.png", "title", 0.9)
    assert (tmp_path / "w.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    from PIL import Image

    win_share.draw({"a": rows, "b": rows}, tmp_path / "two.png", "title", None)
    assert Image.open(tmp_path / "two.png").width > 1.5 * Image.open(tmp_path / "w.png").width
