"""What a run shows while it trains and when it ends: a progress line with its rate and time left,
the last evaluation's statistics (live in a terminal, a plain line per evaluation elsewhere), and a
summary table."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Column, Table
from rich.text import Text

from fieldgen.run import record
from fieldgen.run.recipe import judged_elsewhere
from fieldgen.suggest import shell

if TYPE_CHECKING:
    from fieldgen.run.session import Run


class TrainingProgress(Progress):
    """One line of steps, rate and time for each run, and its evaluation statistics on a line below, so
    that neither squeezes the other out of a narrow terminal."""

    def __init__(self, console: Console):
        whole = lambda: Column(no_wrap=True)  # noqa: E731
        super().__init__(TextColumn("[bold]{task.description}", table_column=whole()), BarColumn(bar_width=12),
                         TextColumn("{task.completed:,.0f} steps {task.percentage:>3.0f}%", table_column=whole()),
                         TextColumn("{task.fields[rate]}", table_column=whole()),
                         TimeElapsedColumn(table_column=whole()), console=console, transient=False)

    def get_renderables(self):
        yield self.make_tasks_table(self.tasks)
        for task in self.tasks:
            if task.fields.get("stats"):
                yield Text("  " + task.fields["stats"], no_wrap=True, overflow="ellipsis")


class PlainProgress:
    """TrainingProgress's news as one plain line per evaluation, for output that is not a terminal (a
    batch job's log), where a live display writes nothing until the run ends."""

    def __init__(self, console: Console):
        self.console, self.task = console, {}

    def __enter__(self) -> PlainProgress:
        return self

    def __exit__(self, *exc) -> None:
        pass

    def add_task(self, description: str, **fields) -> int:
        self.task = {"description": description, **fields}
        return 0

    def update(self, task: int, **changes) -> None:
        """Prints a line where an evaluation's statistics come in."""
        self.task.update(changes)
        if "stats" in changes:
            t = self.task
            share = 100 * t["completed"] / t["total"]
            done = f"{t['description']} {t['completed']:,} of {t['total']:,} steps ({share:.0f}%)"
            self.console.print("  ".join(part for part in (done, t["rate"], t["stats"]) if part), highlight=False,
                               soft_wrap=True)


def display(console: Console) -> TrainingProgress | PlainProgress:
    return TrainingProgress(console) if console.is_terminal else PlainProgress(console)


WRITE_BOUND = 0.8  # the share of a chunk's time spent waiting on writes past which they, not training, set its pace


def waited_on_writes(row: dict, before: dict) -> tuple[float, float] | None:
    """How long `row`'s chunk (after evaluation `before`) waited on the writes of the evaluation before it
    (checkpoint, video: `write_wait_seconds`) and how long the chunk took, where the writes set its pace; else None."""
    if "steps_per_second" not in row or row["env_steps"] <= before["env_steps"]:
        return None
    chunk = (row["env_steps"] - before["env_steps"]) / row["steps_per_second"]
    wait = row.get("write_wait_seconds", 0.0)
    return (wait, chunk) if wait >= WRITE_BOUND * chunk else None


def rate(history: list[dict], total: int) -> str:
    """The last chunk's env steps/s and the time left, from the wall clock between the last two evaluations
    (chunk, evaluation, checkpoint and video together); and how long it waited on writes where they set its
    pace (the device trains while the host writes, so a chunk shorter than a write waits for it)."""
    last = history[-1]
    if "steps_per_second" not in last:
        return ""
    text = f"{last['steps_per_second']:,.0f} steps/s"
    evals = [r for r in history if r.get("seed") == last.get("seed")]
    if len(evals) > 1 and evals[-2]["env_steps"] < last["env_steps"]:
        before = evals[-2]
        if last["env_steps"] < total:
            per_step = (last["wall_seconds"] - before["wall_seconds"]) / (last["env_steps"] - before["env_steps"])
            text += f", {_duration((total - last['env_steps']) * per_step)} left"
        if (waited := waited_on_writes(last, before)) is not None:
            text += f", {waited[0]:.0f} of its {waited[1]:.0f} s waiting on writes"
    return text


def _duration(seconds: float) -> str:
    if seconds < 60:
        return "<1 min"
    return f"{seconds / 60:.0f} min" if seconds < 5400 else f"{seconds / 3600:.1f} h"


def stats(rows: list[dict], stages: int = 1) -> str:
    """The progress line's figures of one evaluation (its rows, a seed each), for a run of `stages` stages."""
    mean = lambda key: sum(r[key] for r in rows) / len(rows)  # noqa: E731
    text = f"success {mean('success_any'):.2f}  at goal {mean('time_at_goal'):.1f}"
    if "variants" in rows[0]:
        text += f"  last stage {mean('last_stage_success_any'):.2f}"
    if "stage" in rows[0]:
        text = f"stage {rows[0].get('promoted_to', rows[0]['stage']) + 1} of {stages}  " + text
    for name in ("critic_loss", "actor_loss", "policy_loss", "value_loss"):
        if name in rows[0]:
            text += f"  {name.removesuffix('_loss')} {mean(name):.3f}"
    return text


def blown_up_line(rows: list[dict], seeds) -> str:
    """One line naming each seed whose training episodes were ended by a blown-up simulation (its last row's
    `diverged_episodes`), or '' where none was: the learner never saw those steps, but a field or setting that
    blows up often is worth a look."""
    counts = {}
    for row in rows:
        if row.get("diverged_episodes"):
            counts[row["seed"]] = int(row["diverged_episodes"])
    if not counts:
        return ""
    said = ", ".join(f"seed {seed} {counts[seed]:,}" for seed in seeds if seed in counts)
    return f"training episodes ended because the simulation blew up (fieldgen.env.diverged; none learned from): {said}"


def summary(run: Run, console: Console) -> None:
    """The last evaluation of every seed against the untrained one, and where the files are."""
    table = Table("seed", "env steps", "success_any", "time at goal", "closest", "return", "steps/s",
                  title=str(run.folder))
    for seed in run.seeds:
        mine = [r for r in run.rows if r.get("seed", seed) == seed]
        first, last = mine[0], mine[-1]
        closest = " -> ".join(f"{r['closest_distance']:.2f}" for r in (first, last) if "closest_distance" in r)
        table.add_row(str(seed), f"{last['env_steps']:,}",
                      f"{first['success_any']:.2f} -> {last['success_any']:.2f}",
                      f"{first['time_at_goal']:.1f} -> {last['time_at_goal']:.1f}", closest,
                      f"{last['episode_return']:.1f}",
                      f"{last['steps_per_second']:,.0f}" if "steps_per_second" in last else "")
    console.print(table)
    mine = [r for r in run.rows if r.get("seed", run.seeds[0]) == run.seeds[0]]
    bound = sum(waited_on_writes(row, before) is not None for before, row in zip(mine, mine[1:]))
    if bound:
        console.print(f"{bound} of {len(mine) - 1} chunks waited most of their time on the writes of the evaluation "
                      f"before them (checkpoint, video): fewer evaluations (--set {run.algo}.num_evals=N) or "
                      "--no-videos train faster")
    for row in run.rows:
        if "promoted_to" in row and row["seed"] == run.seeds[0]:
            name = run.envs[row["promoted_to"]].spec.name
            console.print(f"promoted to stage {row['promoted_to'] + 1} ({name}) at {row['env_steps']:,} env steps")
    if run.plan.mixed:
        last = run.rows[-1]
        variants = last["variants"]
        console.print("success_any per stage at the end: " + ", ".join(
            f"{i}. {p:.2f} (weight {w:.2f})" for i, (p, w) in enumerate(zip(variants["success_any"], variants["weight"]), 1)))
        console.print(f"success_any on the last stage ({run.env.spec.name}): {last['last_stage_success_any']:.2f}")
    elif len(run.envs) > 1:
        last = run.rows[-1]
        console.print(f"reached stage {last.get('promoted_to', last['stage']) + 1} of {len(run.envs)}; success_any on "
                      f"the last stage ({run.env.spec.name}): {last['last_stage_success_any']:.2f}")
    blown = blown_up_line(run.rows, run.seeds)
    if blown:
        console.print(blown)
    memory = run.rows[-1].get("peak_memory_mb")
    if memory is not None:
        console.print(f"peak device memory: {memory:,.0f} MiB")
    console.print(f"metrics: {run.folder / record.CSV}; plot: {run.folder / record.PLOT}")
    elsewhere = judged_elsewhere(run.env.spec, [run.folder])
    if elsewhere is not None:
        console.print(elsewhere, soft_wrap=True)
    if run.judged is not None:
        console.print(f"its recipe trained it on another form of {run.env.spec.name} (run.json: recipe), judged on "
                      f"the field as written ({run.judged}): fieldgen eval {shell(run.folder)} --episodes 1024",
                      soft_wrap=True)
