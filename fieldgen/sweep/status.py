"""Where a sweep stands, read from its folders alone (so it can be asked from any terminal, while the runs
train elsewhere), and once every run is done its results over seeds: for each field, algorithm and point
of the grid the interquartile mean of the seeds' last evaluation with its 95% stratified bootstrap interval
(fieldgen.run.summary), over several fields one with the fields as the strata, and a plot per field of
the learning curves (fieldgen.run.compare's)."""

from __future__ import annotations

import dataclasses
import json
import os
import socket
from pathlib import Path

from fieldgen.command import TIME_LIMIT_STATUS
from fieldgen.files import SWEEP, parsed_json, write_file
from fieldgen.run import record
from fieldgen.sweep.launch import finished, log_path
from fieldgen.sweep.plan import PlannedRun, Sweep, read_plan

SUMMARY, TABLE = "summary.json", "summary.md"
DONE, FAILED, RUNNING, STOPPED, WAITING = "done", "failed", "running", "stopped", "waiting"


@dataclasses.dataclass
class RunState:
    run: PlannedRun
    state: str  # one of DONE, FAILED, RUNNING, STOPPED, WAITING
    detail: str  # how far it got, where it runs, why it failed


def _read(path: Path) -> dict | None:
    try:
        data = parsed_json(path.read_bytes())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _alive(started: dict) -> bool | None:
    """Whether the process a run was started in still runs: None where it ran on another host."""
    if started.get("host") != socket.gethostname():
        return None
    try:
        os.kill(int(started["pid"]), 0)
    except (ProcessLookupError, KeyError, ValueError, TypeError):
        return False
    except PermissionError:
        return True
    return True


def progress(run: PlannedRun) -> str:
    """'evaluation K of N, S env steps' from the run's folder ('' before its first evaluation)."""
    try:
        rows = record.read_metrics(run.folder)
        num_evals = record.read_run(run.folder).config.get("num_evals", "?")
    except record.RunError:
        return ""
    if not rows:
        return ""
    return f"evaluation {rows[-1]['eval']} of {num_evals}, {rows[-1]['env_steps']:,} env steps"


def damaged(run: PlannedRun) -> str | None:
    """Why the run's folder cannot be read (its run.json or metrics.jsonl edited or damaged: a success rate of
    7.5, say), or None: such a run is failed, neither waiting nor done, and none of its values reach a figure."""
    if not (run.folder / record.RUN).is_file():
        return record.occupied(run.folder)
    try:
        saved = record.read_run(run.folder)
        record.read_metrics(run.folder, saved.every_seed)
    except record.RunError as exc:
        return str(exc)
    return None


def states(sweep: Sweep) -> list[RunState]:
    recorded = read_plan(sweep.folder)
    jobs = recorded.jobs if recorded is not None else {}
    out = []
    for run in sweep.runs:
        started, ended = _read(log_path(sweep.folder, run, ".started")), _read(log_path(sweep.folder, run, ".ended"))
        far = progress(run)
        if (said := damaged(run)) is not None:
            out.append(RunState(run, FAILED, said))
        elif finished(run):
            out.append(RunState(run, DONE, far))
        elif ended is not None and ended.get("exit") not in (0, None, TIME_LIMIT_STATUS):
            out.append(RunState(run, FAILED, str(ended.get("why") or f"exit status {ended.get('exit')}")))
        elif started is not None and ended is None and _alive(started) is not False:
            where = f"on {started.get('host')}" + (f" (job {jobs[run.id]})" if run.id in jobs else "")
            out.append(RunState(run, RUNNING, ", ".join(filter(None, [far, where]))))
        elif ended is not None and ended.get("exit") == TIME_LIMIT_STATUS:
            requeued = f"requeued as job {jobs[run.id]}, else " if run.id in jobs else ""
            out.append(RunState(run, STOPPED, f"{far}; stopped at its time limit, checkpointed: {requeued}"
                                              "start the sweep again to continue it"))
        elif started is not None or far:
            out.append(RunState(run, STOPPED, (far or "before its first evaluation") +
                                "; start the sweep again to continue it"))
        else:
            out.append(RunState(run, WAITING, f"job {jobs[run.id]}" if run.id in jobs else "not started"))
    return out


@dataclasses.dataclass
class Group:
    """The runs of one field, algorithm and point of the grid, one per seed: what a summary line is over."""

    field: str
    algo: str
    label: str
    runs: list[PlannedRun]
    rows: list[dict]  # every seed's metrics rows

    @property
    def seeds(self) -> list[int]:
        return [run.seed for run in self.runs]


def groups(sweep: Sweep) -> list[Group]:
    found: dict[tuple, Group] = {}
    for run in sweep.runs:
        key = (run.field, run.label)
        group = found.setdefault(key, Group(run.field, run.algo, run.label, [], []))
        group.runs.append(run)
        group.rows.extend(record.read_metrics(run.folder))
    return list(found.values())


def summarize(sweep: Sweep, command: str) -> tuple[list[dict], Path]:
    """summary.json (each group's SeedSummary, and over the fields each setting's), summary.md (the table) and
    summary-<field>.png; returns the table's lines as dicts and the folder they are in."""
    from fieldgen.run import compare, summary

    table, by_setting, found = [], {}, groups(sweep)
    for group in found:
        last = {}
        for run in group.runs:
            rows = record.read_metrics(run.folder)
            last[run.seed] = rows[-1]
        config = record.read_run(group.runs[0].folder).config  # one setting's: judged alike
        result = summary.summarize([group.field], group.algo, [r.folder for r in group.runs],
                                   config.get("eval_envs", 1), {s: int(row["env_steps"]) for s, row in last.items()},
                                   {m: {s: float(compare.on_field(row, m)) for s, row in last.items()}
                                    for m in summary.METRICS}, command, actions=config.get("eval_actions", "mean"),
                                   field_digests=[one_field(group)])
        table.append({"field": group.field, "setting": group.label, "point": group.runs[0].point,
                      "summary": result.model_dump(mode="json")})
        by_setting.setdefault(group.label, []).append(result)
    over_fields = []
    if len({g.field for g in found}) > 1:
        for label, results in by_setting.items():
            entry = {"setting": label, "fields": [r.fields[0] for r in results]}
            for metric in summary.METRICS:
                tasks = [list(getattr(r, metric).per_seed.values()) for r in results]
                low, high = summary.interval(*tasks)
                entry[metric] = {"iqm": summary.iqm(*tasks), "low": low, "high": high}
            over_fields.append(entry)
    write_file(sweep.folder / SUMMARY, (json.dumps({"command": command, "groups": table,
                                                    "over_fields": over_fields}, indent=1) + "\n").encode(), SWEEP)
    write_file(sweep.folder / TABLE, markdown(table, over_fields).encode(), SWEEP)
    for field in dict.fromkeys(g.field for g in found):
        chosen = [g for g in found if g.field == field]
        seeds = len(chosen[0].seeds)
        each = f"{seeds} seeds each, IQM, 95% bootstrap interval shaded" if seeds > 1 else "one seed each"
        compare.plot(chosen, sweep.folder / f"summary-{field}.png", f"{field}: sweep {sweep.path.stem} ({each})",
                     labels=[g.label for g in chosen], output=SWEEP)
    return table, sweep.folder


def check_outputs(sweep: Sweep) -> None:
    """Before anything trains: refuse (files.NotOurs) a sweep whose folder holds, where its plan and summary go,
    files the sweep did not write (a folder of the user's that `out:` reaches)."""
    from fieldgen.files import check_file
    from fieldgen.sweep.plan import PLAN

    names = [PLAN, SUMMARY, TABLE, *(f"summary-{field}.png" for field in dict.fromkeys(r.field for r in sweep.runs))]
    for name in names:
        check_file(sweep.folder / name, SWEEP)


def one_field(group: Group) -> str:
    """The digest of the field every seed of `group` was judged on (summary.SummaryError where the seeds' fields
    differ: the field's file was edited between them, and seeds of two fields are not one figure)."""
    from fieldgen.compile.artifact import field_digest
    from fieldgen.run.summary import SummaryError

    digests = {}
    for run in group.runs:
        field = record.read_run(run.folder).field
        if field is None:
            raise SummaryError(f"no summary of {group.field} ({group.label}): {run.folder / record.RUN} does not "
                               "record the field it trained on; start that run again in the sweep")
        digests.setdefault(field_digest(field), []).append(run.folder)
    if len(digests) > 1:
        (one, *_), (other, *_) = list(digests.values())[0], list(digests.values())[-1]
        raise SummaryError(f"no summary of {group.field} ({group.label}): {one} and {other} trained on fields of "
                           "that name that differ (its file was edited between their runs); train the seeds of a "
                           "setting on one field: move the odd runs aside and start the sweep again")
    return next(iter(digests))


def interval_text(entry: dict, digits: int) -> str:
    return f"{entry['iqm']:.{digits}f} [{entry['low']:.{digits}f}, {entry['high']:.{digits}f}]"


def markdown(table: list[dict], over_fields: list[dict]) -> str:
    """The results as a Markdown table: IQM [95% interval] over seeds of each field and setting."""
    lines = ["| field | setting | seeds | env steps | success_any | time_at_goal |", "|---|---|---|---|---|---|"]
    for row in table:
        s = row["summary"]
        steps = sorted(set(s["env_steps"].values()))
        lines.append(f"| {row['field']} | {row['setting']} | {len(s['success_any']['per_seed'])} | "
                     f"{steps[-1]:,} | {interval_text(s['success_any'], 3)} | {interval_text(s['time_at_goal'], 1)} |")
    if over_fields:
        lines += ["", "Over the fields (each field a stratum of the bootstrap):", "",
                  "| setting | fields | success_any | time_at_goal |", "|---|---|---|---|"]
        lines += [f"| {e['setting']} | {', '.join(e['fields'])} | {interval_text(e['success_any'], 3)} | "
                  f"{interval_text(e['time_at_goal'], 1)} |" for e in over_fields]
    return "\n".join(lines) + "\n\nIQM [95% stratified bootstrap interval] of each seed's last evaluation.\n"
