"""`fieldgen compare`: a run per algorithm, one plot and table; rerunning only redraws."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from fieldgen.cli import app

runner = CliRunner()
TD3 = ["--set", "td3.hidden=[16]", "--set", "td3.batch_size=32", "--set", "td3.unroll_length=10",
       "--set", "td3.min_replay_rows=100", "--set", "td3.max_replay_rows=400", "--set", "td3.num_evals=2",
       "--set", "td3.windows=4"]


@pytest.mark.slow
def test_compare_trains_each_algorithm_then_only_redraws(tmp_path, tiny_crl_args):
    args = ["compare", "point_nav", "--algos", "crl,td3", "--out", str(tmp_path), "--seeds", "2", *tiny_crl_args, *TD3]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    table = json.loads((tmp_path / "compare.json").read_text())
    assert [r["algo"] for r in table] == ["crl", "td3"]
    assert all(r["seeds"] == 2 and r["env_steps"] == 1760 and 0 <= r["success_any"] <= 1 for r in table)  # 1900
    # less what does not fill an evaluation's iterations of 8 envs x 10 steps: 800 of prefill, then 2 x 6 x 80
    assert all(0 <= r["closest_distance"] <= 3.0 + 1e-4 for r in table)  # targets start 3 away
    assert (tmp_path / "compare.png").stat().st_size > 10_000
    metrics = (tmp_path / "point_nav-td3-0to1" / "metrics.jsonl").read_text()
    again = runner.invoke(app, args)
    assert again.exit_code == 0 and again.output.count("already complete") == 2
    assert (tmp_path / "point_nav-td3-0to1" / "metrics.jsonl").read_text() == metrics
    changed = runner.invoke(app, [*args, "--set", "td3.policy_delay=3"])
    assert changed.exit_code == 1 and "other settings" in changed.output


@pytest.mark.parametrize("algos,phrase", [
    ("crl,crl", "lists an algorithm twice"),
    ("crl,sca", "unknown algorithm 'sca'; did you mean 'sac'?"),
])
def test_bad_comparisons_are_refused_before_anything_is_written(tmp_path, algos, phrase):
    result = runner.invoke(app, ["compare", "point_nav", "--algos", algos, "--out", str(tmp_path / "c")])
    assert result.exit_code == 1 and phrase in result.output
    assert not (tmp_path / "c").exists()
