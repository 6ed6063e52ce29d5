"""Comparing algorithms on one field: a run per algorithm (every seed of it vmapped), then one
plot of success against env steps and against wall-clock time, and a table, each over the seeds as
an interquartile mean with its bootstrap interval (fieldgen.run.summary).

The runs are ordinary run folders under the comparison's folder, so an interrupted
comparison resumes where it stopped, a run prepared here can train elsewhere
(`fieldgen train --resume`), and running the same comparison again only redraws.

Runs already trained (a sweep's, or any run folders) compare the same way from their records alone
(`recorded`, `report_recorded`): no field is loaded and nothing trains.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import Callable

import numpy as np
from rich.console import Console
from rich.table import Column, Table

import fieldgen
from fieldgen.agents import registry, sharding
from fieldgen.compile.artifact import ArtifactError
from fieldgen.files import COMPARE, Output, check_file, kind_of_blocker, named_twice, write_file
from fieldgen.run import plots, record, session, summary
from fieldgen.suggest import shell

PLOT, TABLE = "compare.png", "compare.json"


def runs(source: Path, algos: list[str], seeds: list[int], folder: Path | None, config_file: Path | None,
         sets: list[str], preset: str | None = None, **fixed) -> tuple[Path, list[session.Run]]:
    """(the comparison's folder, default runs/compare-<field>; a run per algorithm in it: an existing one,
    checked to have the same settings, or a new one). Every config is checked before anything is written."""
    if not algos:
        raise record.RunError(f"--algos names no algorithm; give one or more, comma-separated, of "
                              f"{', '.join(registry.ALGORITHMS)} (--algos crl,ppo)")
    entries = {algo: registry.trainer(algo) for algo in algos}
    if len(set(algos)) != len(algos):
        raise record.RunError(f"--algos lists an algorithm twice: {','.join(algos)}")
    try:
        env = fieldgen.make(source)
    except ArtifactError as exc:
        raise record.RunError(str(exc)) from None
    folder = folder or Path("runs") / f"compare-{env.spec.name}"
    for name in (TABLE, PLOT):  # before anything trains: files of the user's where the table and plot go
        check_file(folder / name, COMPARE)
    for item in sets:  # another algorithm's keys, unchecked and unused, would read as part of the comparison
        section = item.partition("=")[0].partition(".")[0]
        if section in registry.ALGORITHMS and section not in algos:
            raise record.RunError(f"--set {item}: '{section}' is not among the compared algorithms "
                                  f"({', '.join(algos)}); its keys apply to those runs alone: add it to --algos or "
                                  "leave the item out")
    configs = {}
    for algo, entry in entries.items():
        others = tuple(a for a in algos if a != algo)
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


# what a self-play run's evaluations measure, drawn in place of success.png's panels: metric -> (axis label,
# panel title, y limits or None)
TEAM_PANELS = {"win_vs_random": ("share won (IQM)", "matches won against a random policy", (-0.02, 1.02)),
               "elo": ("Elo (IQM)", "the newest snapshot's rating", None)}


def curves(run: session.Run, judge=None, metrics=plots.PANELS) -> dict:
    """Per evaluation: env steps, wall seconds, and each of `metrics` (default those success.png plots:
    success_any, time_at_goal, closest_distance, farthest_from_start) over the seeds (NaN in rows written before
    the metric was logged), each row judged by `judge` (default `on_field`)."""
    judge = judge or on_field
    evals = sorted({r["eval"] for r in run.rows})
    out = {"env_steps": [], "wall_seconds": [], **{metric: [] for metric in metrics}}
    for e in evals:
        rows = [r for r in run.rows if r["eval"] == e]
        out["env_steps"].append(rows[0]["env_steps"])
        out["wall_seconds"].append(rows[0].get("wall_seconds", np.nan))
        for metric in metrics:
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


def plot(runs_: list[session.Run], path: Path, title: str, labels: list[str] | None = None, judge=None,
         output: Output | None = COMPARE) -> None:
    """success_any against env steps and against wall-clock seconds, time at goal, the closest approach to the
    goal and, where measured, how far the ball moved against env steps: the interquartile mean over seeds, with
    its 95% bootstrap interval shaded.
    Each run (anything with the `rows` and `seeds` of one) is a line named by its algorithm, or by `labels`;
    each row judged by `judge` (default `on_field`); `output=None` writes the plot where it is, keeping no
    ownership record (a results folder's own plot, drawn again by its page's command)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if getattr(runs_[0], "team", False):
        return _plot_matches(runs_, path, title, labels, output)
    drawn = [curves(run, judge) for run in runs_]
    # how far the ball moved gets a fifth panel where a run measured it, the five then wrapped three a row
    moved = any(np.isfinite(v).all() for c in drawn for v in c["farthest_from_start"])
    if moved:
        fig, grid = plt.subplots(2, 3, figsize=(15, 7.6))
        fig.delaxes(grid.flat[5])
        axes = list(grid.flat[:5])
    else:
        fig, axes = plt.subplots(1, 4, figsize=(18, 3.8))
    panels = [(axes[0], "env_steps", "success_any"), (axes[1], "wall_seconds", "success_any"),
              (axes[2], "env_steps", "time_at_goal"), (axes[3], "env_steps", "closest_distance")]
    if moved:
        panels.append((axes[4], "env_steps", "farthest_from_start"))
    for k, (run, c) in enumerate(zip(runs_, drawn)):
        for ax, x, metric in panels:
            _band(ax, c[x], c[metric], labels[k] if labels else run.algo, len(run.seeds) > 1)
    over = ", level mean" if judge is over_levels else ""
    axes[0].set(xlabel="env steps", ylabel=f"success_any{over} (IQM)", ylim=(-0.02, 1.02),
                title="episodes with a success")
    axes[1].set(xlabel="wall-clock seconds (compiling, training, evaluating)", ylabel=f"success_any{over} (IQM)",
                ylim=(-0.02, 1.02), title="against time")
    axes[2].set(xlabel="env steps", ylabel=f"steps at goal per episode{over} (IQM)", title="time at goal")
    axes[3].set(xlabel="env steps", ylabel=f"distance{over} (IQM)", title="closest approach to the goal")
    if moved:
        axes[4].set(xlabel="env steps", ylabel=f"distance{over} (IQM)", title=plots.PANELS["farthest_from_start"][1])
    handles, names = axes[0].get_legend_handles_labels()  # one legend under the panels, none over the curves
    fig.legend(handles, names, loc="lower center", ncol=min(len(names), 3), fontsize=9, frameon=False)
    plots.save_figure(fig, axes, title, path, output)


def _band(ax, xs, values, label: str, shaded: bool) -> None:
    """One run's curve on `ax`: the IQM over seeds of each point's `values`, its 95% interval shaded where
    `shaded` (several seeds)."""
    centre, low, high = np.array([over_seeds(v) for v in values]).T
    line, = ax.plot(xs, centre, marker="o", ms=3, label=label)
    if shaded:
        ax.fill_between(xs, low, high, color=line.get_color(), alpha=0.2)


def _plot_matches(runs_: list, path: Path, title: str, labels: list[str] | None, output: Output | None) -> None:
    """Self-play runs: the share of matches won against a random policy against env steps and wall-clock seconds,
    and the newest snapshot's rating against env steps, IQM over seeds with its 95% interval shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 3.8))
    panels = [(axes[0], "env_steps", "win_vs_random"), (axes[1], "wall_seconds", "win_vs_random"),
              (axes[2], "env_steps", "elo")]
    for k, run in enumerate(runs_):
        c = curves(run, metrics=TEAM_PANELS)
        for ax, x, metric in panels:
            _band(ax, c[x], c[metric], labels[k] if labels else run.algo, len(run.seeds) > 1)
    for ax, x, metric in panels:
        label, name, limits = TEAM_PANELS[metric]
        ax.set(xlabel="env steps" if x == "env_steps" else "wall-clock seconds (compiling, training, evaluating)",
               ylabel=label, title=name if x == "env_steps" else "against time", ylim=limits)
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="lower center", ncol=min(len(names), 3), fontsize=9, frameon=False)
    plots.save_figure(fig, list(axes), title, path, output)


def report(runs_: list[session.Run], folder: Path, console: Console, command: str) -> None:
    """compare.png, compare.json and the table in the terminal."""
    field = runs_[0].env.spec.name
    rows, seeds = summary_rows(runs_, command), len(runs_[0].seeds)
    write_file(folder / TABLE, (json.dumps(rows, indent=1) + "\n").encode(), COMPARE)
    each = f"{seeds} seeds each, IQM, 95% bootstrap interval shaded" if seeds > 1 else "one seed each"
    plot(runs_, folder / PLOT, f"{field}: {', '.join(r.algo for r in runs_)} ({each})")
    table = Table("algo", "env steps", "success_any (last)", "best", "time at goal", "closest", "steps/s", "wall s",
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


# -- runs already trained ---------------------------------------------------------------------------

RUN_FOLDER_HINT = "name the folders fieldgen train wrote (runs/<field>-<algo>-<seed>), each holding run.json"


def run_folders(arguments: list[str]) -> list[Path] | None:
    """What `fieldgen compare`'s arguments name: run folders (each holding run.json) to compare as they are, or
    None for one field (a YAML file, bundled name or build folder) to train on; a mix, several fields or anything
    else is RunError in one line naming the argument and what to do."""
    from fieldgen.compile.artifact import META
    from fieldgen.schema import bundled_fields

    paths = [Path(a) for a in arguments]
    runs = [p for p in paths if (p / record.RUN).is_file()]
    if runs and len(runs) == len(paths):
        _refuse_twice(runs)
        return runs

    def is_field(argument: str, path: Path) -> bool:
        return (path / META).is_file() or (path.is_file() and path.suffix in (".yaml", ".yml")) or \
            (not path.exists() and argument in bundled_fields())

    fields = [a for a, p in zip(arguments, paths) if is_field(a, p)]
    if runs and fields:
        raise record.RunError(f"{runs[0]} is a run folder and {fields[0]} a field: compare either trains on one field "
                              "(fieldgen compare FIELD --algos A,B) or compares runs already trained (fieldgen compare "
                              f"RUN RUN ...), not both; drop {fields[0]}, or name the folders of its runs")
    if len(fields) > 1:
        raise record.RunError(f"{fields[0]} and {fields[1]} are both fields: compare trains on one field at a time "
                              "(fieldgen compare FIELD --algos A,B); to set runs of several fields side by side, train "
                              "each, then compare their run folders")
    if len(paths) == 1 and (fields or not paths[0].is_dir() and not (paths[0].parent / record.RUN).is_file()):
        return None  # one field (or a name the field's own lookup refuses with the nearest names)
    for argument, path in zip(arguments, paths):
        if path in runs or argument in fields:
            continue
        if path.is_file() and (path.parent / record.RUN).is_file():
            raise record.RunError(f"{path} is a file of the run folder {path.parent}; name the folder itself "
                                  f"(fieldgen compare {shell(path.parent)} ...)")
        if path.is_dir():
            raise record.RunError(f"{path} is not a built field (no {META}) nor a run folder (no {record.RUN}): "
                                  f"compare trains on a field with --algos, or compares run folders; {RUN_FOLDER_HINT}")
        what = kind_of_blocker(path) if path.is_symlink() or path.exists() else "missing"
        raise record.RunError(f"{path} is {what}, not a run folder; {RUN_FOLDER_HINT}")
    return None


def _refuse_twice(runs: list[Path]) -> None:
    """A run named twice (as itself, through a link, or a path that leads to it) would be a line and a row twice,
    weighing as two runs that agree."""
    if twice := named_twice(runs):
        raise record.RunError(f"{twice}: each run is compared once; name it once")


@dataclasses.dataclass(frozen=True)
class Recorded:
    """A run as its folder records it (run.json and metrics.jsonl), read without its fields, networks or
    checkpoint: what a comparison of finished runs needs, and what `curves` and `plot` read (rows, seeds, algo)."""

    folder: Path
    algo: str
    seeds: list[int]
    rows: list[dict]  # each seed's rows up to the last evaluation every seed reached
    field: str  # the name of the field the run is judged on (a curriculum's last stage)
    field_digest: str  # of the resolved spec run.json records: fields alike in name can differ
    actions: str  # how its evaluations acted (registry.EVAL_ACTIONS)
    team: bool = False  # a self-play run: judged by the share of matches won against a random policy

    @property
    def metric(self) -> str:
        """What the run is judged by: success_any on its field, or for a self-play run win_vs_random."""
        return "win_vs_random" if self.team else "success_any"

    @property
    def last(self) -> dict[int, dict]:
        return last_evaluation(self.rows)

    def last_success(self) -> summary.MetricSummary:
        """The run's `metric` at the last evaluation (on the field, `on_field`), each seed's and their IQM with
        its 95% stratified bootstrap interval."""
        per_seed = {s: float(on_field(row, self.metric)) for s, row in self.last.items()}
        value, low, high = over_seeds(list(per_seed.values()))  # NaN where a seed's row lacks the metric
        return summary.MetricSummary(per_seed=per_seed, iqm=value, low=low, high=high)


def reached_by_every_seed(rows: list[dict], seeds: list[int]) -> list[dict]:
    """The rows up to the last evaluation that every seed reached: a point of a curve over seeds holds them all."""
    common = min(max(r["eval"] for r in rows if r["seed"] == s) for s in seeds)
    return [r for r in rows if r["eval"] <= common]


def last_evaluation(rows: list[dict]) -> dict[int, dict]:
    """Each seed's row at the last evaluation of `rows` (cut by `reached_by_every_seed`: one every seed reached)."""
    final = max(r["eval"] for r in rows)
    return {r["seed"]: r for r in rows if r["eval"] == final}


def field_digest(field: dict | None) -> str:
    """A short SHA-256 of a resolved field spec as run.json records it (keys sorted), '' where none is recorded."""
    if field is None:
        return ""
    return hashlib.sha256(json.dumps(field, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:12]


def recorded(folder: Path) -> Recorded:
    """The run in `folder` from its run.json and metrics.jsonl; RunError naming the file where it has no
    evaluation yet or its rows lack a seed's success."""
    saved = record.read_run(folder)
    seeds = saved.every_seed
    rows = record.read_metrics(folder, seeds)
    missing = sorted(set(seeds) - {r.get("seed") for r in rows})
    if missing and not rows and record.has_trained(folder):  # a checkpoint's own evaluation is written before it
        raise record.RunError(f"{folder / record.METRICS} holds no evaluation, yet the run has a checkpoint; the file "
                              "was edited or damaged: restore it from a copy, or leave the run out")
    if missing:
        said = "holds no evaluation yet" if not rows else f"holds no evaluation of seed {missing[0]}"
        raise record.RunError(f"{folder / record.METRICS} {said}, so {folder} has nothing to compare; train it "
                              f"first (fieldgen train --resume {shell(folder)}) or leave it out")
    rows = reached_by_every_seed(rows, seeds)
    metric = "win_vs_random" if saved.selfplay else "success_any"
    for r in rows:
        if not np.isfinite(on_field(r, metric)):
            raise record.RunError(f"{folder / record.METRICS}: evaluation {r['eval']} of seed {r['seed']} holds no "
                                  f"{metric} (edited or damaged); restore the file from a copy, or leave the run out")
    field = (saved.field or {}).get("name") or "(field not recorded)"
    return Recorded(folder, saved.algo, list(seeds), rows, str(field), field_digest(saved.field),
                    str(saved.config.get("eval_actions", "mean")), saved.selfplay)


def fields_differ(runs_: list[Recorded]) -> str:
    """One line saying which runs are of other fields than the first (by the digest of the spec each records,
    so a field edited under the same name counts), '' where all are of one field."""
    first = runs_[0]
    others = [r for r in runs_[1:] if (r.field_digest, r.field) != (first.field_digest, first.field)]
    if not others:
        return ""

    def named(run: Recorded) -> str:
        return f"{run.field} ({run.field_digest or 'no spec recorded'})"

    return (f"note: these runs are of different fields, so their success is not measured alike: {first.folder} "
            f"on {named(first)}, " + ", ".join(f"{r.folder} on {named(r)}" for r in others))


@dataclasses.dataclass(frozen=True)
class Against:
    """A run measured against another (the first named: the code before a change, as a change is measured): env
    steps a second a seed, and the in-run metric (IQM over seeds) at the env steps both reached and at the wall
    clock both reached, each run's last evaluation there."""

    steps: int  # the env steps both runs reached
    seconds: float  # the wall-clock seconds both reached, from each run's start (NaN where a run lacks them)
    rate: tuple[float, float]  # (this run, the first): env steps a second a seed, the median over its chunks
    at_steps: tuple[float, float]  # the metric at `steps`
    at_seconds: tuple[float, float]  # the metric at `seconds`


def training_rate(run: Recorded) -> float:
    """Env steps a second a seed while training: the median over the run's chunks (each evaluation's row holds its
    chunk's), NaN where no row holds one."""
    rates = [r["steps_per_second"] for r in run.rows if r["seed"] == run.seeds[0] and "steps_per_second" in r]
    return float(np.median(rates)) if rates else float("nan")


def metric_at(run: Recorded, key: str, limit: float) -> float:
    """The run's metric (IQM over seeds) at its last evaluation whose `key` (env_steps, wall_seconds) is within
    `limit`; NaN where none is."""
    evals = [r["eval"] for r in run.rows if r.get(key, np.nan) <= limit]
    if not evals:
        return float("nan")
    last = max(evals)
    return over_seeds([on_field(r, run.metric) for r in run.rows if r["eval"] == last])[0]


def against(run: Recorded, first: Recorded) -> Against:
    """`run` beside `first` at equal env steps and at equal wall clock."""
    def reach(r: Recorded, key: str) -> float:
        return max(row.get(key, np.nan) for row in r.rows)

    steps = int(min(reach(run, "env_steps"), reach(first, "env_steps")))
    seconds = min(reach(run, "wall_seconds"), reach(first, "wall_seconds"))
    return Against(steps, seconds, (training_rate(run), training_rate(first)),
                   (metric_at(run, "env_steps", steps), metric_at(first, "env_steps", steps)),
                   (metric_at(run, "wall_seconds", seconds), metric_at(first, "wall_seconds", seconds)))


def _ratio(pair: tuple[float, float], shown: Callable[[float], str]) -> str:
    """'0.693 / 0.544 = 1.27x', or without the ratio where the first is 0 or either is unknown."""
    this, first = pair
    if not (np.isfinite(this) and np.isfinite(first)):
        return "-"
    said = f"{shown(this)} / {shown(first)}"
    return said + (f" = {this / first:.2f}x" if first > 0 else "")


def report_against_first(runs_: list[Recorded], console: Console) -> None:
    """Each run after the first beside the first: env steps a second and the in-run metric at equal env steps and
    at equal wall clock, each as this run's over the first's."""
    first = runs_[0]
    table = Table(Column("run", overflow="fold"), "env steps/s a seed", "at equal env steps", "at equal wall clock",
                  title=f"against the first run, {first.folder}",
                  caption=f"{first.metric} in-run (IQM over seeds) at the last evaluation within the env steps, or the "
                          "seconds from the start, that both runs reached; this run / the first")
    for run in runs_[1:]:
        measured = against(run, first)
        clock = (f"at {measured.seconds:,.0f} s: {_ratio(measured.at_seconds, lambda v: f'{v:.3f}')}"
                 if np.isfinite(measured.seconds) else "-")
        table.add_row(str(run.folder), _ratio(measured.rate, lambda v: f"{v:,.0f}"),
                      f"at {measured.steps:,}: {_ratio(measured.at_steps, lambda v: f'{v:.3f}')}", clock)
    console.print(table)


def report_recorded(runs_: list[Recorded], plot_path: Path, console: Console) -> None:
    """The table of runs already trained (one row each: field, algorithm, seeds, env steps at the last evaluation,
    success there as IQM [95% interval] and per seed) and their curves with the bands, at `plot_path`. Self-play runs
    are judged by the matches they won against a random policy, and compare only with one another."""
    kinds = {run.team for run in runs_}
    if len(kinds) > 1:
        matched = next(r for r in runs_ if r.team)
        single = next(r for r in runs_ if not r.team)
        raise record.RunError(f"{matched.folder} is a self-play run on a team field, judged by the matches it won, "
                              f"and {single.folder} a run judged by its success: the two figures are not alike; "
                              "compare self-play runs with self-play runs and the others apart")
    team = kinds == {True}
    judged = "won vs random (last)" if team else "success_any (last)"
    what = "share of matches won against a random policy (in-run)" if team else "success_any on each run's field"
    table = Table(Column("run", overflow="fold"), Column("field", overflow="fold"), "algo", "seeds", "env steps",
                  Column(judged, no_wrap=True), "per seed", *(["Elo (newest snapshot)"] if team else []),
                  title="runs at their last evaluation",
                  caption=f"{what}: interquartile mean over seeds [95% stratified bootstrap interval]; one seed: "
                          "its value")
    for run in runs_:
        success = run.last_success()
        steps = sorted({r["env_steps"] for r in run.last.values()})
        table.add_row(str(run.folder), run.field, run.algo + registry.judged_on(run.actions), str(len(run.seeds)),
                      ", ".join(f"{s:,}" for s in steps), success.text(3),
                      ", ".join(f"{s}: {v:.3f}" for s, v in success.per_seed.items()),
                      *([", ".join(f"{s}: {row.get('elo', np.nan):,.0f}" for s, row in run.last.items())]
                        if team else []))
    console.print(table)
    if len(runs_) > 1:
        report_against_first(runs_, console)
    if differ := fields_differ(runs_):
        console.print(differ, soft_wrap=True)
    names = list(dict.fromkeys(r.field for r in runs_))
    seeds = {len(r.seeds) for r in runs_}
    bands = "IQM over seeds, 95% bootstrap interval shaded" if max(seeds) > 1 else "one seed each"
    count = f"{len(runs_)} run{'s' * (len(runs_) != 1)}"
    plot(runs_, plot_path, f"{', '.join(names)}: {count} ({bands})", labels=[str(r.folder) for r in runs_])
    console.print(f"plot: {plot_path}")
