"""success.png: a run's success, time at goal, closest approach, how far what the success judges moved and
the training losses against env steps, and the figure conventions every fieldgen plot shares."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from fieldgen.files import Output, write_atomic, write_file
from fieldgen.run.record import PLOT


PANELS_PER_ROW = 3

# metric -> (axis label, panel title, y limits or None); a panel is drawn where the rows have the metric
PANELS = {"success_any": ("success_any", "episodes with a success", (-0.02, 1.02)),
          "time_at_goal": ("steps at goal per episode", "time at goal", None),
          "closest_distance": ("distance", "closest approach to the goal", None),
          "farthest_from_start": ("distance", "farthest moved from its start (the ball, on a ball field)", None)}


def plot_success(run_dir: Path, rows: list[dict], title: str, variant: str = "stage") -> None:
    """success_any, time_at_goal, closest_distance and farthest_from_start against env steps: one line per seed; for a
    staged curriculum one colour per stage and a line for the last stage; for a mixed one a line per stage.
    A run of several variants (a mixed or automatic curriculum) also draws which share of new episodes each
    stage was given after each evaluation, and one whose levels start from kick-off points (an automatic
    curriculum's level buffer) which share went to each stretch of the kick-off. A last panel holds the
    training losses (each `*_loss` of the rows, mean over seeds) once training has begun. A dotted line marks
    where a run went on from what it learned alone (`refilled_from`): its episodes and buffer began anew there.
    `variant` names a variant of a mixed run in the legends ("level" for an automatic curriculum's)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # a run of variants draws what each variant reports (VariantResults), the others what any row holds
    metrics = [m for m in PANELS if (m in rows[0]["variants"] if "variants" in rows[0] else any(m in r for r in rows))]
    losses = list(dict.fromkeys(k for r in rows for k in r if k.endswith("_loss")))
    weighted = "weight" in rows[0].get("variants", {})
    kickoffs = "kickoff_share" in rows[0].get("variants", {})
    count = len(metrics) + weighted + kickoffs + bool(losses)
    # losses begin after the first evaluation; panels wrap at PANELS_PER_ROW, so that a figure of six panels
    # is read at the width of three
    columns = min(count, PANELS_PER_ROW)
    fig, grid = plt.subplots(-(-count // columns), columns, figsize=(5 * columns, 3.6 * -(-count // columns)),
                             sharex=True, squeeze=False)
    axes = list(grid.flat[:count])
    for spare in grid.flat[count:]:
        fig.delaxes(spare)
    panels = dict(zip(metrics, axes))
    if "variants" in rows[0]:
        _plot_variants(panels, rows, variant)
    else:
        _plot_groups(panels, rows)
    refills = sorted({r["refilled_from"] for r in rows if "refilled_from" in r})
    for metric, ax in panels.items():
        label, name, limits = PANELS[metric]
        ax.set(xlabel="env steps", ylabel=label, title=name, ylim=limits)
        for n, steps in enumerate(refills):
            ax.axvline(steps, color="grey", ls=":", label=None if n else "buffer refilled")
    if weighted:
        _plot_weights(fig, axes[len(metrics)], rows, variant=variant)
    if kickoffs:
        _plot_weights(fig, axes[len(metrics) + 1], rows, "kickoff_share")
    if losses:
        _plot_losses(axes[-1], rows, losses)
    save_figure(fig, axes, title, run_dir / PLOT)


def _plot_losses(ax, rows: list[dict], losses: list[str]) -> None:
    """Each loss's mean over seeds (no evaluation before training has one)."""
    for name in losses:
        steps = sorted({r["env_steps"] for r in rows if name in r})
        ax.plot(steps, [np.mean([r[name] for r in rows if r["env_steps"] == s and name in r]) for s in steps],
                marker="o", label=name.removesuffix("_loss"))
    ax.set(xlabel="env steps", ylabel="loss", title="training losses")


def _plot_weights(fig, ax, rows: list[dict], key: str = "weight", variant: str = "stage") -> None:
    """Each stage's share of the new episodes after each evaluation (mean over seeds), as a heat map: where a
    mixed or automatic curriculum put its training over time, the last stage (the field itself) on top; with
    `key` "kickoff_share", each stretch of the kick-off's share, from the easiest start up to the field's own."""
    steps = sorted({r["env_steps"] for r in rows})
    shares = np.array([np.mean([r["variants"][key] for r in rows if r["env_steps"] == s], axis=0)
                       for s in steps]).T  # [stage or kick-off stretch, evaluation]
    edges = np.concatenate([[steps[0]], (np.array(steps[1:]) + steps[:-1]) / 2, [steps[-1]]]) if len(steps) > 1 \
        else np.array([steps[0] - 0.5, steps[0] + 0.5])
    rows_at = np.arange(shares.shape[0] + 1) + 0.5 if key == "weight" else np.linspace(0, 1, shares.shape[0] + 1)
    mesh = ax.pcolormesh(edges, rows_at, shares, cmap="viridis", vmin=0, vmax=max(float(shares.max()), 1e-9))
    fig.colorbar(mesh, ax=ax, label="share of new episodes")
    if key == "weight":
        ax.set(xlabel="env steps", ylabel=f"{variant} (last: the field itself)", title="where episodes go",
               yticks=np.arange(1, shares.shape[0] + 1))
    else:
        ax.set(xlabel="env steps", ylabel="kick-off (0: easy end, 1: the field's)",
               title="where episodes start")
    ax.grid(False)


def save_figure(fig, axes, title: str, path: Path, output: Output | None = None) -> None:
    """Grids, a legend on each panel with labelled lines unless the figure has a legend of its own (then room for
    it under the panels), the title; then the PNG, written atomically (as `output.command` where the figure goes
    where files of the user's may be: write_file; a run's own success.png otherwise)."""
    import matplotlib.pyplot as plt

    from matplotlib.ticker import FuncFormatter, MaxNLocator

    for ax in axes:
        ax.grid(alpha=0.3)
        if ax.get_xlabel() == "env steps":  # 20M, not 2 under an offset of 1e7
            ax.xaxis.set_major_locator(MaxNLocator(nbins=6))
            ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: step_count(x)))
            ax.tick_params(axis="x", labelbottom=True)
        if ax.get_legend_handles_labels()[0] and not fig.legends:
            ax.legend(fontsize=8)
    fig.suptitle(title)
    room = 0.0  # a legend of the whole figure sits under the panels
    if fig.legends:
        renderer = fig.canvas.get_renderer()
        room = max(legend.get_window_extent(renderer).height for legend in fig.legends) / fig.bbox.height
    fig.tight_layout(rect=(0, room, 1, 1))
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    if output is None:
        write_atomic(path, buf.getvalue())
    else:
        write_file(path, buf.getvalue(), output)


def step_count(steps: float) -> str:
    """An env-step count as a tick reads it: 0, 500k, 2.5M, 1B."""
    for scale, suffix in ((1e9, "B"), (1e6, "M"), (1e3, "k")):
        if abs(steps) >= scale:
            return f"{steps / scale:.4g}{suffix}"
    return f"{steps:.4g}"


def _series(rows: list[dict], metric: str) -> tuple[list, list]:
    """(env steps, values) of the rows that have the metric (a run resumed from older code may lack it)."""
    have = [r for r in rows if metric in r]
    return [r["env_steps"] for r in have], [r[metric] for r in have]


def _plot_groups(panels: dict, rows: list[dict]) -> None:
    """A line per seed, or the points of each stage of a staged run and its last stage's line."""
    staged = "stage" in rows[0]
    groups = list(dict.fromkeys(r["stage"] if staged else r.get("seed", 0) for r in rows))
    for group in groups:
        mine = [r for r in rows if (r["stage"] if staged else r.get("seed", 0)) == group]
        label = f"stage {group + 1}" if staged else (f"seed {group}" if len(groups) > 1 else None)
        for metric, ax in panels.items():
            ax.plot(*_series(mine, metric), marker="o", ls="" if staged else "-", label=label)
    if staged:
        panels["success_any"].plot(*_series(rows, "last_stage_success_any"), color="black", label="last stage")


def _plot_variants(panels: dict, rows: list[dict], variant: str) -> None:
    """A mixed run: one line per stage or level (mean over seeds), the last in black."""
    count = len(rows[0]["variants"]["success_any"])
    steps = sorted({r["env_steps"] for r in rows})
    for k in range(count):
        last = k == count - 1
        style = {"color": "black", "lw": 2} if last else {}
        for metric, ax in panels.items():
            values = [np.mean([r["variants"][metric][k] for r in rows if r["env_steps"] == s]) for s in steps]
            ax.plot(steps, values, marker="o", label=f"{variant} {k + 1}" + (" (last)" if last else ""), **style)
