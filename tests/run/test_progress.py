"""The end-of-run table stays whole in an 80-column terminal: no header cut to an ellipsis."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from rich.console import Console

from fieldgen import curriculum
from fieldgen.run import progress


def test_the_summary_table_keeps_every_header_whole_at_80_columns():
    rows = [{"seed": s, "eval": e, "env_steps": 9_078_784 * e, "success_any": 0.74 * e, "time_at_goal": 208.2 * e,
             "closest_distance": 9.69 - 8.66 * e, "episode_return": 208.2 * e, "steps_per_second": 20_342.0}
            for e in (0, 1) for s in (500, 501)]
    run = SimpleNamespace(rows=rows, seeds=[500, 501], folder=Path("runs/ant_nav-crl-500to502"), algo="crl",
                          envs=[None], plan=curriculum.Plan())
    console = Console(width=80, record=True)
    progress.summary(run, console)
    shown = console.export_text()
    header = " ".join(line for line in shown.splitlines() if line.startswith("┃"))  # a header may take two lines
    assert "…" not in shown
    assert all(name in header for name in ("seed", "env steps", "success_any", "time at", "goal", "closest",
                                           "return", "steps/s")), shown
