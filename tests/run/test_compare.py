"""`fieldgen compare`: a run per algorithm, one plot and table; rerunning only redraws."""

from __future__ import annotations

import json
import re

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
    ("", "--algos names no algorithm; give one or more, comma-separated, of crl,"),  # before: an IndexError
    (" , ", "--algos names no algorithm"),
])
def test_bad_comparisons_are_refused_before_anything_is_written(tmp_path, algos, phrase):
    result = runner.invoke(app, ["compare", "point_nav", "--algos", algos, "--out", str(tmp_path / "c")])
    assert result.exit_code == 1 and phrase in result.output
    assert not (tmp_path / "c").exists()


def test_settings_of_an_algorithm_not_compared_are_refused_not_skipped(tmp_path):
    """Skipped unread, `--set crl.foo=1` beside `--algos ppo` passed, a typo and all, as part of the comparison."""
    result = runner.invoke(app, ["compare", "point_nav", "--algos", "ppo", "--set", "crl.foo=1", "--prepare",
                                 "--out", str(tmp_path / "c")])
    assert result.exit_code == 1 and "--set crl.foo=1: 'crl' is not among the compared algorithms (ppo); its keys " \
        "apply to those runs alone" in " ".join(result.output.split()), result.output
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
    monkeypatch.setattr(plots, "save_figure",
                        lambda fig, axes, title, path, output=None: drawn.update(axes=axes, title=title))
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


def test_compare_draws_how_far_the_ball_moved_where_a_run_measured_it(tmp_path, monkeypatch):
    """Runs whose rows hold farthest_from_start get a fifth panel of it (IQM over seeds), the five wrapped three
    a row; runs without it keep the four panels."""
    from fieldgen.run import compare, plots

    drawn = {}
    monkeypatch.setattr(plots, "save_figure", lambda fig, axes, title, path, output=None: drawn.update(axes=axes))
    plain = hand_made_run(tmp_path, "crl", FIVE_SEEDS)
    compare.plot([plain], tmp_path / "compare.png", "title")
    assert len(drawn["axes"]) == 4
    moved = hand_made_run(tmp_path, "crl", FIVE_SEEDS)
    for row in moved.rows:
        row["farthest_from_start"] = 0.1 * row["eval"]
    compare.plot([moved], tmp_path / "compare.png", "title")
    assert len(drawn["axes"]) == 5 and drawn["axes"][4].get_title() == plots.PANELS["farthest_from_start"][1]
    np.testing.assert_allclose(drawn["axes"][4].lines[0].get_ydata(), [0.0, 0.1, 0.2])


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


def run_folder(folder, per_eval: list[list[float]], algo: str = "crl", seeds: list[int] | None = None,
               field: dict | None = None):
    """A run folder as `fieldgen train` leaves it for reading (run.json, metrics.jsonl; no fields, no checkpoint):
    its evaluations gave these success_any values, one per seed."""
    from fieldgen.schema import load_spec, resolve_spec_path

    seeds = seeds or list(range(len(per_eval[0])))
    field = field or load_spec(resolve_spec_path("point_nav")).model_dump(mode="json")
    folder.mkdir(parents=True)
    (folder / "run.json").write_text(json.dumps({
        "field": field, "algo": algo, "observation": {}, "seeds": seeds, "fields": ["field"],
        "config": {"seed": seeds[0], "eval_envs": 16, "eval_actions": "mean", "num_evals": len(per_eval) - 1}}))
    rows = [{"eval": e, "seed": s, "env_steps": 1000 * e, "wall_seconds": 10.0 * e, "success_any": v,
             "time_at_goal": 100 * v, "closest_distance": 1 - v, "steps_per_second": 50.0}
            for e, values in enumerate(per_eval) for s, v in zip(seeds, values)]
    (folder / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


def test_compare_of_run_folders_tables_each_runs_last_evaluation_and_draws_the_bands(tmp_path):
    import io

    from rich.console import Console

    from fieldgen.run import compare, summary

    crl = run_folder(tmp_path / "point_nav-crl-0to4", [[0.0] * 5, [0.2, 1.0, 0.4, 0.8, 0.6]])
    sac = run_folder(tmp_path / "point_nav-sac-10to13", [[0.0] * 4, [0.9, 0.1, 0.3, 0.2]], "sac", [10, 11, 12, 13])
    printed = io.StringIO()
    compare.report_recorded([compare.recorded(crl), compare.recorded(sac)], tmp_path / "both.png",
                            Console(file=printed, width=400))
    runs_table = printed.getvalue().split("against the first run")[0]  # the second table measures sac against crl
    lines = {line.split("│")[1].strip(): [cell.strip() for cell in line.split("│")[2:-1]]
             for line in runs_table.splitlines() if line.count("│") > 3 and "point_nav-" in line}
    # five seeds: the IQM is the mean of the middle three, (0.4 + 0.6 + 0.8) / 3; four: of the middle two
    low, high = summary.interval([0.2, 1.0, 0.4, 0.8, 0.6])
    assert lines[str(crl)] == ["point_nav", "crl", "5", "1,000", f"0.600 [{low:.3f}, {high:.3f}]",
                               "0: 0.200, 1: 1.000, 2: 0.400, 3: 0.800, 4: 0.600"]
    assert 0.2 < low < 0.6 < high < 1.0
    assert lines[str(sac)][:5] == ["point_nav", "sac", "4", "1,000", lines[str(sac)][4]]
    assert lines[str(sac)][4].startswith("0.250 [") and lines[str(sac)][5].startswith("10: 0.900, 11: 0.100")
    assert "different fields" not in printed.getvalue()
    assert (tmp_path / "both.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "both.png").stat().st_size > 10_000


def test_fieldgen_compare_of_run_folders_prints_the_table_and_writes_the_plot(tmp_path):
    crl = run_folder(tmp_path / "point_nav-crl-0to4", [[0.0] * 5, [0.2, 1.0, 0.4, 0.8, 0.6]])
    sac = run_folder(tmp_path / "point_nav-sac-0to3", [[0.0] * 4, [0.9, 0.1, 0.3, 0.2]], "sac")
    plot = tmp_path / "plots" / "both.png"
    plot.parent.mkdir()
    result = runner.invoke(app, ["compare", str(crl), str(sac), "-o", str(plot)])
    assert result.exit_code == 0, result.output
    text = "".join(result.output.split())  # a narrow console folds the cells anywhere
    assert "0.600[" in text and "0.250[" in text and f"plot:{plot}" in text
    assert plot.stat().st_size > 10_000


def test_compare_of_run_folders_draws_the_last_evaluation_every_seed_reached(tmp_path):
    """A seed one evaluation ahead (a run copied mid-write) is cut back to the others', as a point holds them all."""
    from fieldgen.run import compare

    folder = run_folder(tmp_path / "point_nav-crl-0to1", [[0.0, 0.0], [0.5, 0.25]])
    with (folder / "metrics.jsonl").open("a") as f:
        f.write(json.dumps({"eval": 2, "seed": 0, "env_steps": 2000, "success_any": 1.0}) + "\n")
    run = compare.recorded(folder)
    assert run.last_success().per_seed == {0: 0.5, 1: 0.25}
    assert compare.curves(run)["env_steps"] == [0, 1000]


def test_compare_of_runs_of_different_fields_says_so_in_one_line(tmp_path):
    """By the digest of the spec each run records: a field edited under the same name is another field."""
    from fieldgen.schema import load_spec, resolve_spec_path

    spec = load_spec(resolve_spec_path("point_nav")).model_dump(mode="json")
    wider = json.loads(json.dumps(spec))
    wider["field"]["width"] += 2
    first = run_folder(tmp_path / "a", [[0.5]], field=spec)
    same = run_folder(tmp_path / "b", [[0.5]], field=json.loads(json.dumps(spec)))
    other = run_folder(tmp_path / "c", [[0.5]], field=wider)
    result = runner.invoke(app, ["compare", str(first), str(same), "-o", str(tmp_path / "same.png")])
    assert result.exit_code == 0 and "different fields" not in result.output, result.output
    result = runner.invoke(app, ["compare", str(first), str(same), str(other), "-o", str(tmp_path / "c.png")],
                           env={"COLUMNS": "400"})
    assert result.exit_code == 0, result.output
    [note] = [line for line in result.output.splitlines() if "different fields" in line]
    assert f"{other} on point_nav (" in note and str(same) not in note
    assert (tmp_path / "c.png").is_file()


def test_compare_refuses_a_mix_and_folders_that_are_not_runs_in_one_line(tmp_path):
    run = run_folder(tmp_path / "point_nav-crl-0", [[0.0], [0.5]])
    empty = tmp_path / "empty"
    empty.mkdir()
    prepared = run_folder(tmp_path / "prepared", [[0.0]])
    (prepared / "metrics.jsonl").unlink()
    emptied = run_folder(tmp_path / "emptied", [[0.0]])  # trained, its evaluations emptied: resume refuses it too
    (emptied / "metrics.jsonl").write_text("")
    (emptied / "checkpoint.msgpack").write_bytes(b"x")
    cases = [([str(run), str(emptied)], f"{emptied / 'metrics.jsonl'} holds no evaluation, yet the run has a "
                                        "checkpoint; the file was edited or damaged"),
             ([str(run), "point_nav"], f"{run} is a run folder and point_nav a field"),
             ([str(run), str(run / "metrics.jsonl")], f"{run / 'metrics.jsonl'} is a file of the run folder {run}"),
             ([str(run / "run.json")], f"{run / 'run.json'} is a file of the run folder {run}"),
             ([str(run), str(empty)], f"{empty} is not a built field (no field.json) nor a run folder (no run.json)"),
             ([str(run), str(tmp_path / "gone")], f"{tmp_path / 'gone'} is missing, not a run folder"),
             ([str(run), str(prepared)], f"{prepared / 'metrics.jsonl'} holds no evaluation yet"),
             (["point_nav", "point_soccer"], "point_nav and point_soccer are both fields"),
             ([str(run), "--steps", "1000", "--seeds", "2"], "--steps and --seeds set up new runs on a field"),
             ([str(run), "-o", str(tmp_path / "plot.svg")], "the plot is a PNG"),
             ([str(run), "-o", str(tmp_path / "nowhere" / "p.png")], f"there is no folder {tmp_path / 'nowhere'}"),
             ([str(run), "-o", str(run / "run.json" / "p.png")],  # before: "there is no folder ...; make it"
              f"{run / 'run.json'} is a file, not a folder; move it aside or choose another -o")]
    for args, phrase in cases:
        result = runner.invoke(app, ["compare", *args], env={"COLUMNS": "400"})
        assert result.exit_code == 1 and "Traceback" not in result.output, (args, result.output)
        assert result.output.startswith("error: ") and phrase in result.output, (args, result.output)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["emptied", "empty", "point_nav-crl-0", "prepared"]


def test_a_damaged_metrics_row_is_named_by_its_line_in_the_file_blank_lines_counted(tmp_path):
    """Blank lines were left out of the count, so the line named was another than the one to mend."""
    run = run_folder(tmp_path / "point_nav-crl-0to1", [[0.0, 0.0], [0.5, 0.25]])
    rows = (run / "metrics.jsonl").read_text().splitlines()
    rows[2] = rows[2].replace('"success_any": 0.5', '"success_any": 5')
    (run / "metrics.jsonl").write_text("\n\n" + "\n".join(rows) + "\n")
    result = runner.invoke(app, ["compare", str(run), "-o", str(tmp_path / "c.png")], env={"COLUMNS": "400"})
    assert result.exit_code == 1, result.output
    assert result.output.startswith(f"error: {run / 'metrics.jsonl'}:5 is not a metrics row (success_any is 5,")


def test_a_metrics_row_of_an_evaluation_and_seed_already_read_is_refused_not_counted_twice(tmp_path):
    """The curve's point was the IQM over three values of two seeds, the table's over two."""
    run = run_folder(tmp_path / "point_nav-crl-0to1", [[0.0, 0.0], [0.5, 0.25]])
    rows = (run / "metrics.jsonl").read_text().splitlines()
    (run / "metrics.jsonl").write_text("\n".join([*rows, rows[-1].replace("0.25", "1.0")]) + "\n")
    result = runner.invoke(app, ["compare", str(run), "-o", str(tmp_path / "c.png")], env={"COLUMNS": "400"})
    assert result.exit_code == 1, result.output
    assert result.output.startswith(f"error: {run / 'metrics.jsonl'}:5 is not a metrics row (evaluation 1 of seed 1 "
                                    "is at line 4 already)"), result.output


def test_a_run_json_without_seeds_whose_config_seed_is_no_seed_is_blamed_not_its_metrics(tmp_path):
    """The run's seed was then the config's -1, and the first metrics row was refused for not being of it."""
    run = run_folder(tmp_path / "point_nav-crl-0", [[0.0], [0.5]])
    saved = json.loads((run / "run.json").read_text())
    del saved["seeds"]
    saved["config"]["seed"] = -1
    (run / "run.json").write_text(json.dumps(saved))
    result = runner.invoke(app, ["compare", str(run), "-o", str(tmp_path / "c.png")], env={"COLUMNS": "400"})
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert result.output.startswith(f"error: {run / 'run.json'} is not a run record: config.seed, the run's seed "
                                    "where it lists no seeds, should be a whole number from 0 up, not -1"), result.output


def test_a_run_named_twice_is_refused_as_itself_or_through_a_link(tmp_path):
    """Each name was a line and a row of its own, the run weighing as two that agree."""
    run = run_folder(tmp_path / "point_nav-crl-0", [[0.0], [0.5]])
    other = run_folder(tmp_path / "point_nav-sac-0", [[0.0], [0.25]], "sac")
    (tmp_path / "link").symlink_to(run)
    for args, phrase in [([run, run], f"{run} is named twice:"),
                         ([run, other, tmp_path / "link"], f"{run} is named twice (also as {tmp_path / 'link'})")]:
        result = runner.invoke(app, ["compare", *map(str, args), "-o", str(tmp_path / "c.png")], env={"COLUMNS": "400"})
        assert result.exit_code == 1 and result.output.startswith(f"error: {phrase}"), result.output
    assert not (tmp_path / "c.png").exists()


@pytest.mark.parametrize("edit, phrase", [
    ({"wall_seconds": "x"}, "wall_seconds is 'x', not a number"),
    ({"steps_per_second": -5.0}, "steps_per_second is -5.0, outside its range"),
    ({"seed": True}, "seed should be a valid integer"),
    ({"seed": None}, "it lacks seed")], ids=["wall", "rate", "seed-bool", "no-seed"])
def test_a_metrics_row_whose_timing_or_seed_is_edited_is_refused_at_its_line(tmp_path, edit, phrase):
    """Each was a TypeError or KeyError traceback from the plot (a timing that is no number, a last row without its
    seed), or a row counted as another seed's (true is 1 to Python)."""
    run = run_folder(tmp_path / "point_nav-crl-0to1", [[0.0, 0.0], [0.5, 0.25]])
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    rows[-1].update(edit)
    rows[-1] = {k: v for k, v in rows[-1].items() if v is not None}
    (run / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    result = runner.invoke(app, ["compare", str(run), "-o", str(tmp_path / "c.png")], env={"COLUMNS": "400"})
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert f"{run / 'metrics.jsonl'}:4 is not a metrics row ({phrase}" in result.output
    assert not (tmp_path / "c.png").exists()


def test_compare_of_run_folders_writes_compare_png_in_a_folder_dash_o_names(tmp_path):
    run = run_folder(tmp_path / "point_nav-crl-0", [[0.0], [0.5]])
    result = runner.invoke(app, ["compare", str(run), "-o", str(tmp_path)], env={"COLUMNS": "250"})
    assert result.exit_code == 0, result.output
    assert (tmp_path / "compare.png").is_file() and "0.500 [0.500, 0.500]" in result.output


def team_run_folder(folder, per_eval: list[list[float]], seeds: list[int]):
    """A self-play run folder for reading: each evaluation's share of matches won against a random policy per
    seed, and the newest snapshot's rating rising with it."""
    from fieldgen.schema import load_spec, resolve_spec_path

    folder.mkdir(parents=True)
    (folder / "run.json").write_text(json.dumps({
        "field": load_spec(resolve_spec_path("soccer_1v1")).model_dump(mode="json"), "algo": "ppo",
        "observation": {}, "seeds": seeds, "fields": ["field"], "selfplay": True,
        "config": {"seed": seeds[0], "eval_envs": 128, "eval_actions": "mean", "num_evals": len(per_eval) - 1}}))
    rows = [{"eval": e, "seed": s, "env_steps": 1000 * e, "wall_seconds": 10.0 * e, "win_vs_random": v,
             "draw_vs_random": 1 - v, "loss_vs_random": 0.0, "success_any": v, "elo": 1000 + 500 * v}
            for e, values in enumerate(per_eval) for s, v in zip(seeds, values)]
    (folder / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


def test_self_play_runs_compare_by_matches_won_and_ratings_and_never_beside_single_agent_runs(tmp_path):
    team = team_run_folder(tmp_path / "soccer_1v1-ppo-0to2", [[0.0] * 3, [0.5, 1.0, 0.75]], [0, 1, 2])
    import io

    from rich.console import Console

    from fieldgen.run import compare

    plot, printed = tmp_path / "team.png", io.StringIO()
    compare.report_recorded([compare.recorded(team)], plot, Console(file=printed, width=400))
    [row] = [line for line in printed.getvalue().splitlines() if "soccer_1v1-ppo-0to2" in line and "│" in line]
    cells = [cell.strip() for cell in row.split("│")[1:-1]]
    assert cells[5].startswith("0.750 [") and cells[6] == "0: 0.500, 1: 1.000, 2: 0.750"
    assert cells[7] == "0: 1,250, 1: 1,500, 2: 1,375"
    assert "won vs random (last)" in printed.getvalue() and "success_any" not in printed.getvalue()
    assert plot.stat().st_size > 10_000
    single = run_folder(tmp_path / "point_nav-crl-0", [[0.0], [0.5]])
    mixed = runner.invoke(app, ["compare", str(team), str(single), "-o", str(tmp_path / "mixed.png")],
                          env={"COLUMNS": "400"})
    assert mixed.exit_code == 1 and "Traceback" not in mixed.output, mixed.output
    assert mixed.output.startswith(f"error: {team} is a self-play run on a team field") and str(single) in mixed.output
    assert not (tmp_path / "mixed.png").exists()


def test_runs_after_the_first_are_measured_against_it_in_env_steps_a_second_and_at_equal_steps_and_clock(tmp_path):
    """As a change is measured against the code before it: a run twice as fast a seed, at equal env steps (2,000,
    the most both reached) 0.9 against 0.5, at equal wall clock (15 s) 1.0 against the first's 0.4 at 10 s."""
    import io

    from rich.console import Console

    from fieldgen.run import compare

    first = run_folder(tmp_path / "before", [[0.0] * 3, [0.2, 0.4, 0.6], [0.5, 0.5, 0.5]])
    faster = run_folder(tmp_path / "after", [[0.0] * 3, [0.4, 0.8, 0.6], [0.9, 0.9, 0.9], [1.0, 1.0, 1.0]])
    rows = [json.loads(line) for line in (faster / "metrics.jsonl").read_text().splitlines()]
    for row in rows:
        row.update(wall_seconds=5.0 * row["eval"], steps_per_second=100.0)
    (faster / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    measured = compare.against(compare.recorded(faster), compare.recorded(first))
    assert (measured.steps, measured.seconds, measured.rate) == (2000, 15.0, (100.0, 50.0))
    assert measured.at_steps == pytest.approx((0.9, 0.5)) and measured.at_seconds == pytest.approx((1.0, 0.4))
    printed = io.StringIO()
    compare.report_recorded([compare.recorded(first), compare.recorded(faster)], tmp_path / "both.png",
                            Console(file=printed, width=300))
    said = printed.getvalue()
    assert f"against the first run, {first}" in said and "100 / 50 = 2.00x" in said
    assert "at 2,000: 0.900 / 0.500 = 1.80x" in said and "at 15 s: 1.000 / 0.400 = 2.50x" in said
    assert compare._ratio((0.3, 0.0), str) == "0.3 / 0.0" and compare._ratio((0.3, float("nan")), str) == "-"


def test_a_run_json_whose_evaluation_actions_were_edited_is_refused_not_read_as_mean(tmp_path):
    """Before: an eval_actions fieldgen never writes was tabled as a run judged on its mean actions."""
    run = run_folder(tmp_path / "point_nav-crl-0", [[0.0], [0.5]])
    saved = json.loads((run / "run.json").read_text())
    saved["config"]["eval_actions"] = "weird"
    (run / "run.json").write_text(json.dumps(saved))
    result = runner.invoke(app, ["compare", str(run)])
    assert result.exit_code == 1 and f"{run / 'run.json'} is not a run record: config.eval_actions should be one " \
        "of mean, sampled, not 'weird'" in " ".join(result.output.split()), result.output


def test_a_seed_whose_env_steps_fall_between_evaluations_is_refused_at_the_later_row(tmp_path):
    """Before: rows of two runs joined, or a number edited, were drawn as a curve running back on itself."""
    from fieldgen.run import record

    run = run_folder(tmp_path / "point_nav-crl-0to1", [[0.0, 0.0], [0.5, 0.5], [0.6, 0.6]])
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    rows[5]["env_steps"] = 500  # seed 1's evaluation 2, below its evaluation 1's 1,000
    (run / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    with pytest.raises(record.RunError, match=re.escape(f"{run / 'metrics.jsonl'}:6 is not a metrics row (evaluation 2 "
                                                        "of seed 1 is at 500 env steps, fewer than evaluation 1's "
                                                        "1,000)")):
        record.read_metrics(run, [0, 1])
