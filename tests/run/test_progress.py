"""The end-of-run table stays whole in an 80-column terminal: no header cut to an ellipsis."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from rich.console import Console

from fieldgen import curriculum
from fieldgen.run import progress
from fieldgen.schema import bundled_fields, load_spec


def finished(field: str, folder: str, judged: Path | None = None):
    """A finished run of two seeds on a bundled field, as the end-of-run summary reads it; `judged`: its copy of the
    field as written, where a recipe trained it on another form of it."""
    rows = [{"seed": s, "eval": e, "env_steps": 9_078_784 * e, "success_any": 0.74 * e, "time_at_goal": 208.2 * e,
             "closest_distance": 9.69 - 8.66 * e, "episode_return": 208.2 * e, "steps_per_second": 20_342.0}
            for e in (0, 1) for s in (500, 501)]
    return SimpleNamespace(rows=rows, seeds=[500, 501], folder=Path(folder), algo="crl", envs=[None],
                           plan=curriculum.Plan(), env=SimpleNamespace(spec=load_spec(bundled_fields()[field])),
                           judged=judged)


def test_the_summary_table_keeps_every_header_whole_at_80_columns():
    run = finished("ant_nav", "runs/ant_nav-crl-500to502")
    console = Console(width=80, record=True)
    progress.summary(run, console)
    shown = console.export_text()
    header = " ".join(line for line in shown.splitlines() if line.startswith("┃"))  # a header may take two lines
    assert "…" not in shown
    assert all(name in header for name in ("seed", "env steps", "success_any", "time at", "goal", "closest",
                                           "return", "steps/s")), shown
    assert "is judged on" not in shown


def test_a_run_on_other_physics_alone_ends_with_the_command_that_judges_it_as_its_recipe_is():
    console = Console(width=400, record=True)
    progress.summary(finished("soccer_v2_dense_warp", "runs/w"), console)
    assert ("soccer_v2_dense_warp is soccer_v2_dense with sim.backend warp: its evaluations play that physics, and "
            "its recipe's figure is judged on soccer_v2_dense itself: fieldgen eval runs/w --episodes 1024 --field "
            "soccer_v2_dense") in console.export_text()


def test_a_run_its_recipe_trained_on_another_form_of_its_field_ends_with_the_command_that_judges_it_as_written():
    console = Console(width=400, record=True)
    progress.summary(finished("v2_wide_goalie", "runs/v", judged=Path("runs/v/judged")), console)
    assert ("its recipe trained it on another form of v2_wide_goalie (run.json: recipe), judged on the field as "
            "written (runs/v/judged): fieldgen eval runs/v --episodes 1024") in console.export_text()


def test_seeds_whose_simulations_blew_up_are_named_once_with_their_last_count():
    rows = [{"seed": 0, "eval": 0}, {"seed": 1, "eval": 0},
            {"seed": 0, "eval": 1, "diverged_episodes": 0.0}, {"seed": 1, "eval": 1, "diverged_episodes": 2.0},
            {"seed": 0, "eval": 2, "diverged_episodes": 0.0}, {"seed": 1, "eval": 2, "diverged_episodes": 1234.0}]
    assert progress.blown_up_line(rows, [0, 1]) == (
        "training episodes ended because the simulation blew up (fieldgen.env.diverged; none learned from): "
        "seed 1 1,234")
    assert progress.blown_up_line(rows[:3], [0, 1]) == ""  # no count, or none above zero: nothing said
