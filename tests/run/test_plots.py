"""success.png's legends and axes name a run's variants as the run does: an automatic curriculum's are levels."""

from __future__ import annotations

import pytest

from fieldgen.run import plots


def rows_of_two_variants() -> list[dict]:
    return [{"eval": e, "seed": 0, "env_steps": 1000 * (e + 1), "success_any": 0.1 * e,
             "variants": {"success_any": [0.2 * e, 0.1 * e], "weight": [0.8, 0.2]}} for e in range(3)]


@pytest.mark.parametrize("variant", ["stage", "level"])
def test_a_mixed_runs_figure_names_its_variants(tmp_path, monkeypatch, variant):
    drawn = {}
    monkeypatch.setattr(plots, "save_figure", lambda fig, axes, title, path: drawn.update(axes=axes))
    plots.plot_success(tmp_path, rows_of_two_variants(), "title", variant)
    labels = drawn["axes"][0].get_legend_handles_labels()[1]
    assert labels == [f"{variant} 1", f"{variant} 2 (last)"]
    assert drawn["axes"][1].get_ylabel() == f"{variant} (last: the field itself)"


@pytest.mark.parametrize("refilled", [True, False])
def test_a_dotted_line_marks_where_a_run_went_on_from_what_it_learned_alone(tmp_path, monkeypatch, refilled):
    drawn = {}
    monkeypatch.setattr(plots, "save_figure", lambda fig, axes, title, path: drawn.update(axes=axes))
    rows = [{"eval": e, "seed": s, "env_steps": 1000 * (e + 1), "success_any": 0.1 * e}
            for e in range(3) for s in (0, 1)]
    if refilled:
        for row in rows[4:]:
            row["refilled_from"] = 2000
    plots.plot_success(tmp_path, rows, "title")
    ax = drawn["axes"][0]
    marks = [line for line in ax.get_lines() if line.get_linestyle() == ":"]
    assert [list(line.get_xdata()) for line in marks] == ([[2000, 2000]] if refilled else [])
    assert ax.get_legend_handles_labels()[1].count("buffer refilled") == (1 if refilled else 0)


def test_env_step_counts_read_as_counts():
    assert [plots.step_count(x) for x in (0, 750, 500_000, 2_500_000, 50_000_000, 1e9)] == \
        ["0", "750", "500k", "2.5M", "50M", "1B"]


def test_six_panels_wrap_into_two_rows_of_three_with_steps_in_millions(tmp_path, monkeypatch):
    """An automatic curriculum's figure (three metrics, two heat maps, the losses) is two rows of three
    panels, each reading its env steps as counts."""
    drawn = {}
    save = plots.save_figure
    monkeypatch.setattr(plots, "save_figure", lambda fig, axes, title, path: drawn.update(fig=fig, axes=axes)
                        or save(fig, axes, title, path))
    rows = [{"eval": e, "seed": 0, "env_steps": 10_000_000 * e, "success_any": 0.1 * e, "time_at_goal": 1.0,
             "closest_distance": 2.0, "critic_loss": 1.0,
             "variants": {"success_any": [0.2, 0.1 * e], "time_at_goal": [1.0, 1.0], "closest_distance": [1.0, 1.0],
                          "weight": [0.8, 0.2], "kickoff_share": [0.5, 0.5]}} for e in range(4)]
    plots.plot_success(tmp_path, rows, "title", "level")
    axes = drawn["axes"]
    assert len(axes) == 6 and len(drawn["fig"].axes) == 6 + 2  # the panels and the heat maps' colour bars
    tops = sorted({round(ax.get_position().y1, 3) for ax in axes})
    columns = sorted({round(ax.get_position().x0, 2) for ax in axes})
    assert len(tops) == 2 and len(columns) == 3
    assert axes[0].xaxis.get_major_formatter()(20_000_000, 0) == "20M"
    assert (tmp_path / "success.png").stat().st_size > 0


def test_a_run_draws_how_far_the_ball_moved_and_a_run_of_levels_only_what_each_level_reports(tmp_path, monkeypatch):
    """farthest_from_start gets its panel where the rows hold it; a run of variants draws the metrics its
    variants report, so a top-level metric alone adds no empty panel."""
    drawn = {}
    monkeypatch.setattr(plots, "save_figure", lambda fig, axes, title, path: drawn.update(axes=axes))
    rows = [{"eval": e, "seed": 0, "env_steps": 1000 * (e + 1), "success_any": 0.1 * e, "closest_distance": 2.0,
             "farthest_from_start": 0.5 * e} for e in range(3)]
    plots.plot_success(tmp_path, rows, "title")
    assert [ax.get_title() for ax in drawn["axes"]] == ["episodes with a success", "closest approach to the goal",
                                                        "farthest moved from its start (the ball, on a ball field)"]
    assert list(drawn["axes"][2].get_lines()[0].get_ydata()) == [0.0, 0.5, 1.0]
    levels = [{**row, "variants": {"success_any": [0.2, 0.1], "weight": [0.8, 0.2]}} for row in rows]
    plots.plot_success(tmp_path, levels, "title", "level")
    assert [ax.get_title() for ax in drawn["axes"]][0] == "episodes with a success" and len(drawn["axes"]) == 2
