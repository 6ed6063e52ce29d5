"""Comparing algorithms on one field: a run per algorithm (every seed of it vmapped), then one
plot of success against env steps and against wall-clock time, and a table, each over the seeds as
an interquartile mean with its bootstrap interval (fieldgen.run.summary).

The runs are ordinary run folders under the comparison's folder, so an interrupted
comparison resumes where it stopped, a run prepared here can train elsewhere
(`fieldgen train --resume`), and running the same comparison again only redraws.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

import fieldgen
from fieldgen.agents import registry, sharding
from fieldgen.compile.artifact import ArtifactError
from fieldgen.files import write_atomic
from fieldgen.run import plots, record, session, summary

PLOT, TABLE = "compare.png", "compare.json"


def runs(source: Path, algos: list[str], seeds: list[int], folder: Path | None, config_file: Path | None,
         sets: list[str], preset: str | None = None, **fixed) -> tuple[Path, list[session.Run]]:
    """(the comparison's folder, default runs/compare-<field>; a run per algorithm in it: an existing one,
    checked to have the same settings, or a new one). Every config is checked before anything is written."""
    entries = {algo: registry.trainer(algo) for algo in algos}
    if len(set(algos)) != len(algos):
        raise record.RunError(f"--algos lists an algorithm twice: {','.join(algos)}")
    try:
        env = fieldgen.make(source)
    except ArtifactError as exc:
        raise record.RunError(str(exc)) from None
    folder = folder or Path("runs") / f"compare-{env.spec.name}"
    configs = {}
    for algo, entry in entries.items():
        others = tuple(a for a in registry.ALGORITHMS if a != algo)
        configs[algo] = entry.config.layered(config_file, sets, others, env.spec.agent.kind, preset, **fixed)
        configs[algo].validate_env(env, sharding.device_count(), len(seeds))
    result = []
    for algo in algos:
        existing = folder / record.run_name(env.spec.name, algo, seeds)
        if (existing / record.RUN).exists():
            run = session.open_run(existing, load_state=False)  # a finished run needs no checkpoint to be reported
            if run.config.model_dump() != configs[algo].model_dump() or len(run.seeds) != len(seeds) \
                    or run.seeds != list(seeds):
                raise record.RunError(f"{existing} holds a {algo} run with other settings (config or seeds); "
                                        "compare into another --out, or delete it")
            if not run.finished:
                run = session.open_run(existing, to_train=True)
        else:
            run = session.new_run(source, algo, seeds, configs[algo], folder)
        result.append(run)
    return folder, result


def curves(run: session.Run, judge=None) -> dict:
    """Per evaluation: env steps, wall seconds, and each metric success.png plots (success_any, time_at_goal,
    closest_distance) over the seeds (NaN in rows written before the metric was logged), each row judged by
    `judge` (default `on_field`)."""
    judge = judge or on_field
    evals = sorted({r["eval"] for r in run.rows})
    out = {"env_steps": [], "wall_seconds": [], **{metric: [] for metric in plots.PANELS}}
    for e in evals:
        rows = [r for r in run.rows if r["eval"] == e]
        out["env_steps"].append(rows[0]["env_steps"])
        out["wall_seconds"].append(rows[0].get("wall_seconds", np.nan))
        for metric in plots.PANELS:
            out[metric].append([judge(r, metric) for r in rows])
    return out


def on_field(row: dict, metric: str) -> float:
    """`metric` of an evaluation row on the run's field itself, so that curricula compare with training on the
    field alone: a run training several variants at once (a mixed or automatic curriculum) is evaluated on all
    of them and judged on its last, the field; a staged curriculum's success is also measured on its last stage
    at every evaluation (its other metrics only on the stage it trains). NaN where the row lacks the metric."""
    variants = row.get("variants")
    if variants is not None and metric in variants:
        return variants[metric][-1]
    if metric == "success_any" and "stage" in row and "last_stage_success_any" in row:
        return row["last_stage_success_any"]
    return row.get(metric, np.nan)


def over_levels(row: dict, metric: str) -> float:
    """`metric` of an evaluation row as the mean over every level a curriculum run evaluates (the field
    included), each level weighed alike: how far along its levels a run has come while the field itself is
    still out of reach. A run of one field is its own single level (`on_field`)."""
    variants = row.get("variants")
    if variants is not None and metric in variants:
        return float(np.mean(variants[metric]))
    return on_field(row, metric)


JUDGES = {"field": on_field, "levels": over_levels}  # what a curriculum run's figure is measured on


def over_seeds(values: list) -> tuple[float, float, float]:
    """(IQM, low, high) of one evaluation's values over the seeds; NaN where a seed's row lacks the metric."""
    if not np.all(np.isfinite(values)):
        return np.nan, np.nan, np.nan
    return (summary.iqm(values), *summary.interval(values))


def summary_rows(runs_: list[session.Run], command: str) -> list[dict]:
    """One row per algorithm: its last evaluation over the seeds (a SeedSummary), the best evaluation's
    success IQM, the closest approach's IQM, the speed (the median over chunks, as the first one also compiles)."""
    table = []
    for run in runs_:
        c = curves(run)
        last = {metric: dict(zip(run.seeds, c[metric][-1])) for metric in summary.METRICS}
        seeds = summary.summarize([run.env.spec.name], run.algo, [run.folder], run.config.eval_envs,
                                  dict.fromkeys(run.seeds, c["env_steps"][-1]), last, command,
                                  actions=run.config.eval_actions)
        rates = [r["steps_per_second"] for r in run.rows if "steps_per_second" in r]
        table.append({"algo": run.algo, "seeds": len(run.seeds), "env_steps": c["env_steps"][-1],
                      "summary": seeds.model_dump(mode="json"),
                      "best_success_any": float(np.nanmax([over_seeds(v)[0] for v in c["success_any"]])),
                      "closest_distance": _finite(over_seeds(c["closest_distance"][-1])[0]),
                      "steps_per_second": float(np.median(rates)) if rates else None,  # the first chunk compiles
                      "wall_seconds": c["wall_seconds"][-1], "folder": str(run.folder)})
    return table


def _finite(x: float) -> float | None:
    return None if np.isnan(x) else float(x)


def plot(runs_: list[session.Run], path: Path, title: str, labels: list[str] | None = None, judge=None) -> None:
    """success_any against env steps and against wall-clock seconds, time at goal and the closest approach
    to the goal against env steps: the interquartile mean over seeds, with its 95% bootstrap interval shaded.
    Each run (anything with the `rows` and `seeds` of one) is a line named by its algorithm, or by `labels`;
    each row judged by `judge` (default `on_field`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(18, 3.8))
    for k, run in enumerate(runs_):
        c = curves(run, judge)
        for ax, x, metric in ((axes[0], "env_steps", "success_any"), (axes[1], "wall_seconds", "success_any"),
                              (axes[2], "env_steps", "time_at_goal"), (axes[3], "env_steps", "closest_distance")):
            centre, low, high = np.array([over_seeds(v) for v in c[metric]]).T
            line, = ax.plot(c[x], centre, marker="o", ms=3, label=labels[k] if labels else run.algo)
            if len(run.seeds) > 1:
                ax.fill_between(c[x], low, high, color=line.get_color(), alpha=0.2)
    over = ", level mean" if judge is over_levels else ""
    axes[0].set(xlabel="env steps", ylabel=f"success_any{over} (IQM)", ylim=(-0.02, 1.02),
                title="episodes with a success")
    axes[1].set(xlabel="wall-clock seconds (compiling, training, evaluating)", ylabel=f"success_any{over} (IQM)",
                ylim=(-0.02, 1.02), title="against time")
    axes[2].set(xlabel="env steps", ylabel=f"steps at goal per episode{over} (IQM)", title="time at goal")
    axes[3].set(xlabel="env steps", ylabel=f"distance{over} (IQM)", title="closest approach to the goal")
    handles, names = axes[0].get_legend_handles_labels()  # one legend under the panels, none over the curves
    fig.legend(handles, names, loc="lower center", ncol=min(len(names), 3), fontsize=9, frameon=False)
    plots.save_figure(fig, axes, title, path)


def report(runs_: list[session.Run], folder: Path, console: Console, command: str) -> None:
    """compare.png, compare.json and the table in the terminal."""
    field = runs_[0].env.spec.name
    rows, seeds = summary_rows(runs_, command), len(runs_[0].seeds)
    write_atomic(folder / TABLE, (json.dumps(rows, indent=1) + "\n").encode())
    each = f"{seeds} seeds each, IQM, 95% bootstrap interval shaded" if seeds > 1 else "one seed each"
    plot(runs_, folder / PLOT, f"{field}: {', '.join(r.algo for r in runs_)} ({each})")
    table = Table("algo", "env steps", "success_any (last)", "best", "time_at_goal", "closest", "steps/s", "wall s",
                  title=f"{field}: {folder}",
                  caption=f"over {seeds} seeds each: interquartile mean [95% bootstrap interval]"
                  if seeds > 1 else "one seed each: its value [an interval of one seed is the value alone]")
    for r in rows:
        last = summary.SeedSummary.model_validate(r["summary"])
        table.add_row(r["algo"], f"{r['env_steps']:,}", last.success_any.text(2), f"{r['best_success_any']:.2f}",
                      last.time_at_goal.text(1),
                      "" if r["closest_distance"] is None else f"{r['closest_distance']:.2f}",
                      "" if r["steps_per_second"] is None else f"{r['steps_per_second']:,.0f}",
                      f"{r['wall_seconds']:,.0f}")
    console.print(table)
    console.print(f"plot: {folder / PLOT}; table: {folder / TABLE}")
