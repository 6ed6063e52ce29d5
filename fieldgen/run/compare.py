"""Comparing algorithms on one field: a run per algorithm (every seed of it vmapped), then one
plot of success against env steps and against wall-clock time, and a table.

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
from fieldgen.run import plots, record, session

PLOT, TABLE = "compare.png", "compare.json"


def runs(source: Path, algos: list[str], seeds: list[int], folder: Path | None, config_file: Path | None,
         sets: list[str], **fixed) -> tuple[Path, list[session.Run]]:
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
        configs[algo] = entry.config.layered(config_file, sets, others, env.spec.agent.kind, **fixed)
        configs[algo].validate_env(env, sharding.device_count(), len(seeds))
    result = []
    for algo in algos:
        existing = folder / session.run_name(env.spec.name, algo, seeds)
        if (existing / record.RUN).exists():
            run = session.open_run(existing, load_state=False)  # a finished run needs no checkpoint to be reported
            if run.config.model_dump() != configs[algo].model_dump() or run.seeds != seeds:
                raise record.RunError(f"{existing} holds a {algo} run with other settings (config or seeds); "
                                        "compare into another --out, or delete it")
            if not run.finished:
                run = session.open_run(existing)
        else:
            run = session.new_run(source, algo, seeds, configs[algo], folder)
        result.append(run)
    return folder, result


def curves(run: session.Run) -> dict:
    """Per evaluation: env steps, wall seconds, and each metric success.png plots (success_any, time_at_goal,
    closest_distance) over the seeds (NaN in rows written before the metric was logged)."""
    evals = sorted({r["eval"] for r in run.rows})
    out = {"env_steps": [], "wall_seconds": [], **{metric: [] for metric in plots.PANELS}}
    for e in evals:
        rows = [r for r in run.rows if r["eval"] == e]
        out["env_steps"].append(rows[0]["env_steps"])
        out["wall_seconds"].append(rows[0].get("wall_seconds", np.nan))
        for metric in plots.PANELS:
            out[metric].append([r.get(metric, np.nan) for r in rows])
    return out


def summary(runs_: list[session.Run]) -> list[dict]:
    """One row per algorithm: the last evaluation (mean and spread over seeds), the best one, the speed
    (the median over chunks, as the first one also compiles)."""
    table = []
    for run in runs_:
        c = curves(run)
        last = np.asarray(c["success_any"][-1])
        rates = [r["steps_per_second"] for r in run.rows if "steps_per_second" in r]
        table.append({"algo": run.algo, "seeds": len(run.seeds), "env_steps": c["env_steps"][-1],
                      "success_any": float(last.mean()), "success_any_std": float(last.std()),
                      "best_success_any": float(max(np.mean(s) for s in c["success_any"])),
                      "time_at_goal": float(np.mean(c["time_at_goal"][-1])),
                      "closest_distance": _finite(np.mean(c["closest_distance"][-1])),
                      "steps_per_second": float(np.median(rates)) if rates else None,  # the first chunk compiles
                      "wall_seconds": c["wall_seconds"][-1], "folder": str(run.folder)})
    return table


def _finite(x: float) -> float | None:
    return None if np.isnan(x) else float(x)


def plot(runs_: list[session.Run], path: Path, title: str) -> None:
    """success_any against env steps and against wall-clock seconds, time at goal and the closest approach
    to the goal against env steps: the mean over seeds, with the seeds' range shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(18, 3.8))
    for run in runs_:
        c = curves(run)
        for ax, x, metric in ((axes[0], "env_steps", "success_any"), (axes[1], "wall_seconds", "success_any"),
                              (axes[2], "env_steps", "time_at_goal"), (axes[3], "env_steps", "closest_distance")):
            values = np.asarray(c[metric])
            line, = ax.plot(c[x], values.mean(1), marker="o", ms=3, label=run.algo)
            if values.shape[1] > 1:
                ax.fill_between(c[x], values.min(1), values.max(1), color=line.get_color(), alpha=0.2)
    axes[0].set(xlabel="env steps", ylabel="success_any", ylim=(-0.02, 1.02), title="episodes with a success")
    axes[1].set(xlabel="wall-clock seconds (compiling, training, evaluating)", ylabel="success_any", ylim=(-0.02, 1.02),
                title="against time")
    axes[2].set(xlabel="env steps", ylabel="steps at goal per episode", title="time at goal")
    axes[3].set(xlabel="env steps", ylabel="distance", title="closest approach to the goal")
    plots.save_figure(fig, axes, title, path)


def report(runs_: list[session.Run], folder: Path, console: Console) -> None:
    """compare.png, compare.json and the table in the terminal."""
    field = runs_[0].env.spec.name
    rows, seeds = summary(runs_), len(runs_[0].seeds)
    write_atomic(folder / TABLE, (json.dumps(rows, indent=1) + "\n").encode())
    plot(runs_, folder / PLOT, f"{field}: {', '.join(r.algo for r in runs_)} ({seeds} seed{'s' * (seeds > 1)} each)")
    table = Table("algo", "env steps", "success_any (last)", "best", "time_at_goal", "closest", "steps/s", "wall s",
                  title=f"{field}: {folder}")
    for r in rows:
        spread = f" ± {r['success_any_std']:.2f}" if r["seeds"] > 1 else ""
        table.add_row(r["algo"], f"{r['env_steps']:,}", f"{r['success_any']:.2f}{spread}",
                      f"{r['best_success_any']:.2f}", f"{r['time_at_goal']:.1f}",
                      "" if r["closest_distance"] is None else f"{r['closest_distance']:.2f}",
                      "" if r["steps_per_second"] is None else f"{r['steps_per_second']:,.0f}",
                      f"{r['wall_seconds']:,.0f}")
    console.print(table)
    console.print(f"plot: {folder / PLOT}; table: {folder / TABLE}")
