"""`fieldgen sweep`: many runs from one file, on this machine's GPUs or through SLURM."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.table import Table
from rich.text import Text

from fieldgen import limits, stops
from fieldgen.cli.app import app, bounded, choice, fail, out
from fieldgen.suggest import shell
from fieldgen.sweep.plan import BACKENDS


@app.command()
def sweep(
    file: Annotated[Path, typer.Argument(metavar="SWEEP.yaml", help="the sweep file: fields, algorithms, seeds, "
                                                                    "set, grid, steps, backend")],
    status: Annotated[bool, typer.Option("--status", help="show what ran, what failed and why, and once every run "
                                                          "is done write the summary over seeds")] = False,
    dry_run: Annotated[bool, typer.Option("--dry-run", help="show the commands it would run, and run none")] = False,
    runs: Annotated[Optional[Path], typer.Option("--out", "-o", metavar="DIR",
                                                 help="the sweep's folder (default: the file's out:, else "
                                                      "runs/sweep-<file name>)")] = None,
    backend: Annotated[Optional[str], typer.Option(help="where the runs train (default: the file's backend:)",
                                                   **choice("backend", BACKENDS))] = None,
    partition: Annotated[Optional[str], typer.Option(help="slurm: the partition")] = None,
    time: Annotated[Optional[int], typer.Option(parser=bounded("--time", limits.SLURM_MINUTES), metavar="MIN",
                                                help="slurm: minutes a task runs before it is requeued")] = None,
    gpus_per_task: Annotated[Optional[int], typer.Option(parser=bounded("--gpus-per-task", limits.GPUS_PER_TASK),
                                                         metavar="N", help="slurm: GPUs of each task")] = None,
) -> None:
    """Train every combination of a sweep file's fields, algorithms, grid values and seeds, one `fieldgen train`
    run each, and summarize them over seeds (IQM with 95% bootstrap intervals) when all are done.

    Started again, a sweep skips finished runs and continues the others from their folders.

    Example: fieldgen sweep sweeps/point_nav.yaml --dry-run
    Example: fieldgen sweep sweeps/point_nav.yaml --backend slurm --partition gpu --time 120
    Example: fieldgen sweep sweeps/point_nav.yaml --status
    """
    from fieldgen.sweep import launch, plan
    from fieldgen.sweep import status as standing

    try:
        planned = plan.load(file, runs, backend=backend, partition=partition, time=time, gpus_per_task=gpus_per_task)
        plan.check_plan(planned)  # sweep.json read and checked: --status trusts it as going on does
    except plan.SweepError as exc:
        fail(str(exc))
    command = f"fieldgen sweep {shell(file)}"
    if dry_run:
        for line in launch.dry_run(planned):
            out.print(line, highlight=False, soft_wrap=True)
        return
    standing.check_outputs(planned)  # a file of the user's where the plan or the summary goes: one line, now
    if status:
        raise typer.Exit(_report(planned, standing, command))
    try:
        if planned.spec.backend == "slurm":
            jobs = launch.submit(planned)
            if jobs:
                out.print(f"submitted {len(jobs)} runs as job array {jobs[0].job_id.split('_')[0]}; follow them with: "
                          f"fieldgen sweep {shell(file)} --status", highlight=False)
            else:
                raise typer.Exit(_report(planned, standing, command))
            return
        launch.run_local(planned, lambda line: out.print(line, highlight=False))
        if not planned.folder.is_dir():
            fail(f"the sweep's folder {planned.folder} was removed while its runs trained, and with it their "
                 f"results; start the sweep again to train them anew: fieldgen sweep {shell(file)}")
    except launch.BackendError as exc:
        fail(str(exc))
    except plan.SweepError as exc:
        fail(str(exc))
    except KeyboardInterrupt:
        out.print(f"{stops.said()}; the runs keep their last checkpoints: fieldgen sweep {shell(file)} continues them",
                  soft_wrap=True)  # one line: the command stays whole to copy
        raise typer.Exit(stops.status()) from None
    raise typer.Exit(_report(planned, standing, command))


def _report(planned, standing, command: str) -> int:
    """The table of runs; once all are done, the summary over seeds, written beside them. Returns the sweep's
    exit status, as make and schedulers read it: 0 when every run is done, 1 when any failed, and
    TIME_LIMIT_STATUS (75, "try again later") while the others wait, train or stopped to go on."""
    from fieldgen.command import TIME_LIMIT_STATUS

    found = standing.states(planned)
    table = Table("run", "state", "", title=f"{planned.path}: {len(found)} runs in {planned.folder}")
    styles = {standing.DONE: "green", standing.FAILED: "red", standing.RUNNING: "cyan"}
    for s in found:
        table.add_row(s.run.id, Text(s.state, style=styles.get(s.state, "")), s.detail)
    out.print(table)
    counts = {state: sum(s.state == state for s in found) for state in dict.fromkeys(s.state for s in found)}
    out.print(", ".join(f"{n} {state}" for state, n in counts.items()), highlight=False)
    if counts.get(standing.DONE) != len(found):
        for s in found:
            if s.state == standing.FAILED:  # whole, as the table's cell may cut it
                out.print(f"{s.run.id} failed: {s.detail}", highlight=False, soft_wrap=True)
        if counts.get(standing.FAILED):
            out.print("a failed run's whole output is in "
                      f"{planned.folder / 'logs'}; fix its cause and start the sweep again to retry it", highlight=False)
            return 1
        return TIME_LIMIT_STATUS
    from fieldgen.run.record import RunError
    from fieldgen.run.summary import SummaryError

    try:
        rows, folder = standing.summarize(planned, command)
    except (SummaryError, RunError) as exc:  # no figure over values that cannot be what they claim
        fail(str(exc))
    summary = Table("field", "setting", "seeds", "success_any", "time at goal",
                    caption="IQM [95% stratified bootstrap interval] of each seed's last evaluation")
    for row in rows:
        s = row["summary"]
        summary.add_row(row["field"], row["setting"], str(len(s["success_any"]["per_seed"])),
                        standing.interval_text(s["success_any"], 3), standing.interval_text(s["time_at_goal"], 1))
    out.print(summary)
    out.print(f"summary: {folder / standing.SUMMARY}, {folder / standing.TABLE}; plots: {folder}/summary-<field>.png",
              highlight=False)
    return 0
