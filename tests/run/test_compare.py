"""`fieldgen compare`: a run per algorithm, one plot and table; rerunning only redraws."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from fieldgen.cli import app
from fieldgen.run.summary import SeedSummary

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
    assert all(r["seeds"] == 2 and r["env_steps"] == 1760 for r in table)  # 1900
    # less what does not fill an evaluation's iterations of 8 envs x 10 steps: 800 of prefill, then 2 x 6 x 80
    summaries = [SeedSummary.model_validate(r["summary"]) for r in table]
    assert all(0 <= s.success_any.low <= s.success_any.iqm <= s.success_any.high <= 1 for s in summaries)
    assert all(s.seeds == [0, 1] and s.env_steps == {0: 1760, 1: 1760} for s in summaries)
    assert [s.episodes for s in summaries] == [8, 128]  # td3's evaluations keep the default eval_envs
    assert summaries[1].command.startswith("fieldgen compare point_nav --algos crl,td3 --steps 1900 --envs 8 --seeds 2")
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


def hand_made_run(folder, algo: str, per_eval: list[list[float]], **config):
    """A finished run whose evaluations gave these success_any values, one per seed (no training: the
    plot and the table read only the rows)."""
    from types import SimpleNamespace

    from fieldgen.agents.crl import CRLConfig
    from fieldgen.run.session import Run

    seeds = list(range(len(per_eval[0])))
    rows = [{"eval": e, "seed": s, "env_steps": 1000 * e, "wall_seconds": 10.0 * e, "success_any": v,
             "time_at_goal": 100 * v, "closest_distance": 1 - v, "steps_per_second": 50.0}
            for e, values in enumerate(per_eval) for s, v in zip(seeds, values)]
    return Run(folder / f"point_nav-{algo}", algo, [SimpleNamespace(spec=SimpleNamespace(name="point_nav"))],
               CRLConfig(eval_envs=16, **config), seeds, rows)


FIVE_SEEDS = [[0.0] * 5, [0.0, 0.0, 0.0, 1.0, 0.0], [1.0] * 5]  # worked out in test_summary: IQM 0, [0, 2/3]


def test_compare_plots_the_iqm_over_seeds_with_its_interval_shaded(tmp_path, monkeypatch):
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import to_rgb

    from fieldgen.run import compare, plots

    drawn = {}
    monkeypatch.setattr(plots, "save_figure", lambda fig, axes, title, path: drawn.update(axes=axes, title=title))
    runs = [hand_made_run(tmp_path, "crl", FIVE_SEEDS), hand_made_run(tmp_path, "td3", [[0.5], [0.25], [0.75]])]
    compare.plot(runs, tmp_path / "compare.png", "title")
    success = drawn["axes"][0]
    np.testing.assert_allclose(success.lines[0].get_ydata(), [0.0, 0.0, 1.0])  # the mean would be 0.2 at 1000
    np.testing.assert_allclose(success.lines[1].get_ydata(), [0.5, 0.25, 0.75])
    bands = [c for c in success.collections if isinstance(c, PolyCollection)]
    assert len(bands) == 1  # one seed has no band
    corners = bands[0].get_paths()[0].vertices
    spans = {x: (corners[corners[:, 0] == x, 1].min(), corners[corners[:, 0] == x, 1].max()) for x in (0, 1000, 2000)}
    assert spans[0] == (0.0, 0.0) and spans[2000] == (1.0, 1.0)
    np.testing.assert_allclose(spans[1000], (0.0, 2 / 3))  # the seeds' range would be (0, 1)
    assert bands[0].get_facecolor()[0][:3] == pytest.approx(to_rgb(success.lines[0].get_color()))
    for ax in drawn["axes"][1:]:  # against time, time at goal, closest approach: each its band
        assert sum(isinstance(c, PolyCollection) for c in ax.collections) == 1


def test_compare_tables_the_iqm_and_its_interval_per_algorithm(tmp_path):
    import io

    from rich.console import Console

    from fieldgen.run import compare
    from fieldgen.run.summary import SeedSummary

    runs = [hand_made_run(tmp_path, "crl", FIVE_SEEDS[:2]),
            hand_made_run(tmp_path, "td3", [[0.0] * 5, [0.5] * 5], eval_actions="sampled")]
    printed = io.StringIO()
    compare.report(runs, tmp_path, Console(file=printed, width=200), "fieldgen compare point_nav --seeds 5")
    rows = json.loads((tmp_path / "compare.json").read_text())
    first = SeedSummary.model_validate(rows[0]["summary"])
    assert first.success_any.per_seed == {0: 0.0, 1: 0.0, 2: 0.0, 3: 1.0, 4: 0.0}  # the last evaluation
    assert (first.success_any.iqm, first.success_any.low) == (0.0, 0.0)
    assert first.success_any.high == pytest.approx(2 / 3) and first.time_at_goal.high == pytest.approx(200 / 3)
    assert first.algo == "crl" and first.fields == ["point_nav"] and first.episodes == 16
    assert first.env_steps == dict.fromkeys(range(5), 1000) and first.command == "fieldgen compare point_nav --seeds 5"
    # each summary says how its run's evaluations acted
    assert first.actions == "mean" and SeedSummary.model_validate(rows[1]["summary"]).actions == "sampled"
    assert rows[0]["best_success_any"] == 0.0 and rows[1]["best_success_any"] == 0.5  # the best IQM, not mean
    assert rows[0]["closest_distance"] == 1.0
    text = printed.getvalue()
    assert "0.00 [0.00, 0.67]" in text and "0.0 [0.0, 66.7]" in text and "0.50 [0.50, 0.50]" in text, text
    assert "over 5 seeds each: interquartile mean [95% bootstrap interval]" in text
    assert (tmp_path / "compare.png").stat().st_size > 10_000


def test_compare_of_one_seed_says_its_interval_is_its_value(tmp_path):
    import io

    from rich.console import Console

    from fieldgen.run import compare

    printed = io.StringIO()
    compare.report([hand_made_run(tmp_path, "crl", [[0.0], [0.25]])], tmp_path, Console(file=printed, width=200), "")
    row = json.loads((tmp_path / "compare.json").read_text())[0]
    assert row["summary"]["success_any"] == {"per_seed": {"0": 0.25}, "iqm": 0.25, "low": 0.25, "high": 0.25}
    assert "0.25 [0.25, 0.25]" in printed.getvalue() and "one seed each" in printed.getvalue()


def test_a_curriculum_run_is_compared_on_its_field_not_on_the_mean_over_its_variants(tmp_path):
    """A mixed or automatic curriculum's row holds success over every variant; beside a run on the field alone it
    is drawn and tabled by its last variant, the field."""
    from fieldgen.run import compare

    run = hand_made_run(tmp_path, "crl", [[0.5, 0.5]])
    for row, field in zip(run.rows, (0.0, 0.25)):
        row["variants"] = {"success_any": [1.0, field], "time_at_goal": [400.0, 100 * field],
                           "closest_distance": [0.2, 2.0], "weight": [0.5, 0.5]}
    c = compare.curves(run)
    assert c["success_any"] == [[0.0, 0.25]]
    assert c["time_at_goal"] == [[0.0, 25.0]]
    assert c["closest_distance"] == [[2.0, 2.0]]
    assert compare.curves(hand_made_run(tmp_path, "td3", [[0.5, 0.5]]))["success_any"] == [[0.5, 0.5]]
    staged = hand_made_run(tmp_path, "sac", [[0.5, 0.5]])
    for row in staged.rows:
        row.update(stage=0, last_stage_success_any=0.125)
    assert compare.curves(staged)["success_any"] == [[0.125, 0.125]]
    assert compare.curves(staged)["time_at_goal"] == [[50.0, 50.0]]  # measured on the stage it trains
