"""ball_endings: where a policy leaves the ball, episode by episode, summed up in one line."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
import ball_endings  # noqa: E402

sys.path.remove(str(ROOT / "bench"))


def row(scored: bool, closest: float, start: list[float], final: list[float]) -> dict:
    return {"episode": 0, "scored": scored, "closest": closest, "start": start, "final": final}


def test_the_report_counts_scored_near_and_farther_episodes_and_the_cells_they_end_in():
    rows = [row(True, 0.2, [0, 5], [0.1, 20.2]),
            row(False, 0.9, [0, 5], [0.8, 20.4]),          # near the target, not within the radius
            row(False, 7.0, [0, 5], [1.2, 13.2]),          # against the goalie's face
            row(False, 7.0, [0.5, 5], [0.6, 13.1]),
            row(False, 15.0, [0, 5], [0.2, 5.1])]          # never moved
    assert ball_endings.report(rows, near=1.5) == (
        "5 episodes: 1 scored, 1 came within 1.5 m of the target without scoring, 3 ended farther (1 of them "
        "within 0.5 m of where the ball started); where the ball ends in episodes without a score (1 m cells): "
        "(1, 13) x2, (1, 20) x1, (0, 5) x1")


def test_a_policy_of_a_field_without_a_ball_is_one_line(tmp_path):
    (tmp_path / "policy.json").write_text(json.dumps({"observation_names": ["root.x", "root.y", "goal.x"]}))
    with pytest.raises(SystemExit, match="observes no ball"):
        ball_endings.endings(tmp_path, "point_nav", episodes=2, seed=0)


def test_the_report_says_how_many_misses_saw_an_agent_with_a_torso_upside_down_and_when():
    rows = [dict(row(True, 0.2, [0, 5], [0.1, 20.2]), upside_down_at=None),
            dict(row(False, 15.0, [0, 5], [0.0, 5.0]), upside_down_at=30),
            dict(row(False, 7.0, [0, 5], [0.6, 13.1]), upside_down_at=None),
            dict(row(False, 9.0, [0, 5], [0.2, 11.0]), upside_down_at=400)]
    assert ball_endings.report(rows, near=1.5).endswith(
        "; 2 of the 3 without a score saw the agent upside down (first at step 30, median 215)")
    assert "upside down" not in ball_endings.report([row(False, 7.0, [0, 5], [0.6, 13.1])], near=1.5)


def test_first_step_counts_from_one_and_is_none_where_nothing_holds():
    import numpy as np

    assert ball_endings.first_step(np.array([False, False, True, True])) == 3
    assert ball_endings.first_step(np.zeros(4, bool)) is None


def test_median_where_reads_only_the_flagged_steps():
    import numpy as np

    assert ball_endings.median_where(np.array([0.5, -0.2, -0.4, 0.6]), np.array([False, True, True, False])) == -0.3
    assert ball_endings.median_where(np.array([0.5]), np.array([False])) is None
