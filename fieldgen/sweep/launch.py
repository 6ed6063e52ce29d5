"""Running a sweep's runs: each is the `fieldgen train` command of its plan (plan.PlannedRun), started or
continued from its folder, its output kept in the sweep's logs/ with how it ended.

Two backends hand the runs out. `local` keeps a queue and gives each GPU of this machine one run at a
time (CUDA_VISIBLE_DEVICES), or, without GPUs, runs them one after another. `slurm` submits one
submitit job array; each task gives its run a `--time-limit` some minutes short of its own, so that the run
stops at an evaluation with its checkpoint written, and then requeues itself; a task preempted, or out of
time first, is requeued by submitit's checkpointing protocol. A requeued task continues from its run folder.
Starting a sweep again skips finished runs and continues the others.
"""

from __future__ import annotations

import json
import os
import queue
import shutil
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path
from typing import Callable

from fieldgen import files, stops
from fieldgen.command import TIME_LIMIT_STATUS, fieldgen_command
from fieldgen.files import SWEEP, write_atomic, write_file
from fieldgen.schema import Problem
from fieldgen.sweep.plan import PLAN, PlannedRun, PlanRecord, Sweep, SweepError, check_plan, read_plan, shell

LOGS = "logs"
SUBMITIT = "slurm"  # submitit's folder of job scripts, pickles and scheduler logs


class BackendError(Exception):
    """A backend that cannot run here (not installed, no scheduler)."""


def log_path(folder: Path, run: PlannedRun, suffix: str) -> Path:
    """The run's log (.log), start (.started) or end (.ended) record in the sweep's logs folder."""
    return folder / LOGS / (run.id.replace("/", "__") + suffix)


def finished(run: PlannedRun) -> bool:
    """Whether the run's folder holds its last evaluation."""
    from fieldgen.run import record

    try:
        num_evals = record.read_run(run.folder).config.get("num_evals")
        rows = record.read_metrics(run.folder)
    except record.RunError:
        return False
    return bool(rows) and num_evals is not None and rows[-1]["eval"] >= num_evals


def execute(folder: Path, run: PlannedRun, environment: dict | None = None,
            on_start: Callable[[subprocess.Popen], None] = lambda process: None, extra: tuple[str, ...] = ()) -> int:
    """Run `run` to its end (or to the time limit among `extra`, words added to its command) as a `fieldgen
    train` process of this interpreter, appending its output to its log; records where it ran (.started) and
    how it ended (.ended: exit status, and why it failed)."""
    if finished(run):
        return 0
    log = log_path(folder, run, ".log")
    log.parent.mkdir(parents=True, exist_ok=True)
    command = (*run.command(), *extra)
    log_path(folder, run, ".ended").unlink(missing_ok=True)
    with log.open("ab") as out:
        out.write(f"\n$ {' '.join(['fieldgen', *command])}\n".encode())
        out.flush()
        process = subprocess.Popen(fieldgen_command(*command), stdout=out, stderr=subprocess.STDOUT,
                                   stdin=subprocess.DEVNULL, env={**os.environ, **(environment or {})})
        _write_json(log_path(folder, run, ".started"), {"host": socket.gethostname(), "pid": process.pid,
                                                        "time": time.time(), "command": list(command)})
        on_start(process)
        code = process.wait()
    _write_json(log_path(folder, run, ".ended"), {"exit": code, "why": "" if code == 0 else why(log, code),
                                                  "time": time.time()})
    return code


def why(log: Path, code: int) -> str:
    """What a failed run said last: its last `error:` line, else the last line it wrote, else its signal."""
    try:
        lines = [line.strip() for line in log.read_text(errors="replace").splitlines() if line.strip()]
    except OSError:
        lines = []
    errors = [line for line in lines if line.startswith("error:")]
    if errors:
        return errors[-1]
    if code == TIME_LIMIT_STATUS:
        return "stopped at its time limit, checkpointed"
    if code < 0:
        return f"stopped by signal {-code}"
    if code == 130:
        return "interrupted (Ctrl-C); start the sweep again to continue it"
    if code - 128 in stops.AS_CTRL_C:
        return f"stopped by {signal.Signals(code - 128).name}; start the sweep again to continue it"
    return lines[-1] if lines and not lines[-1].startswith("$ ") else f"exit status {code}"


def _write_json(path: Path, data: dict) -> None:
    write_atomic(path, (json.dumps(data) + "\n").encode())


def record_plan(sweep: Sweep, jobs: dict[str, str] | None = None) -> None:
    """sweep.json: the sweep file, each run's command, and (slurm) each run's job id."""
    check_plan(sweep)
    try:
        sweep.folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:  # a file in the way was said as the sweep was planned: no space, or no permission
        how = "out:" if sweep.spec.out and Path(sweep.spec.out).absolute() == sweep.folder else "--out"
        raise SweepError([Problem(sweep.path, None, None, "", f"cannot set up the sweep's folder {sweep.folder}: "
                                  f"{files.way_on(sweep.folder, how, exc)}")]) from None
    path = sweep.folder / PLAN
    before = read_plan(sweep.folder) or PlanRecord(file="", backend="")
    write_file(path, (json.dumps({"file": str(sweep.path.absolute()), "backend": sweep.spec.backend,
                                  "runs": {**before.runs, **{r.id: list(r.start) for r in sweep.runs}},
                                  "jobs": {**before.jobs, **{k: str(v) for k, v in (jobs or {}).items()}}})
                      + "\n").encode(), SWEEP)


def gpus(setting) -> list[str]:
    """The GPUs the local backend gives a run each: those named, else CUDA_VISIBLE_DEVICES's, else
    nvidia-smi's; none on a machine without them."""
    if setting != "auto":
        return [str(g) for g in setting]
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    if visible is not None:
        return [g.strip() for g in visible.split(",") if g.strip() and g.strip() != "-1"]
    if shutil.which("nvidia-smi") is None:
        return []
    try:
        listed = subprocess.run(["nvidia-smi", "--query-gpu=index", "--format=csv,noheader"], capture_output=True,
                                text=True, timeout=30, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return []
    return [line.strip() for line in listed.splitlines() if line.strip()]


def run_local(sweep: Sweep, say: Callable[[str], None]) -> list[tuple[PlannedRun, int]]:
    """Every unfinished run, one per GPU at a time (one at a time without GPUs); returns each run that ran
    with its exit status. Ctrl-C reaches the runs, which keep their last checkpoint, and stops the queue."""
    record_plan(sweep)
    todo: queue.Queue = queue.Queue()
    for run in sweep.runs:
        if not finished(run):
            todo.put(run)
    slots = gpus(sweep.spec.local.gpus) or [None]
    results: list[tuple[PlannedRun, int]] = []
    stopping = threading.Event()

    def worker(gpu: str | None) -> None:
        while not stopping.is_set():
            try:
                run = todo.get_nowait()
            except queue.Empty:
                return
            where = f"GPU {gpu}" if gpu is not None else "this machine"
            say(f"{'continues' if run.command() == run.resume else 'starts'} {run.id} on {where}")
            try:
                code = execute(sweep.folder, run, None if gpu is None else {"CUDA_VISIBLE_DEVICES": gpu})
            except OSError as exc:  # its log or record could not be written: the sweep's folder is gone or full
                results.append((run, 1))
                stopping.set()  # every later run would fail alike
                say(f"{run.id} failed: cannot write {exc.filename or sweep.folder}: {exc.strerror or exc}")
                continue
            results.append((run, code))
            if code == 130:
                stopping.set()
            say(f"{run.id} {'done' if code == 0 else 'failed: ' + why(log_path(sweep.folder, run, '.log'), code)}")

    threads = [threading.Thread(target=worker, args=(gpu,), name=f"sweep-{gpu}") for gpu in slots]
    for thread in threads:
        thread.start()
    try:
        for thread in threads:
            thread.join()
    except KeyboardInterrupt:
        stopping.set()
        for thread in threads:
            thread.join()
        raise
    return results


def submitit():
    """submitit, which the slurm backend needs."""
    try:
        import submitit as module
    except ImportError:
        raise BackendError("the slurm backend needs submitit, which is not installed: pip install "
                           "'fieldgen[slurm]' (or backend: local)") from None
    return module


def time_limit(minutes: float | None) -> tuple[str, ...]:
    """The words that give a run `minutes` (none for None)."""
    return () if minutes is None else ("--time-limit", f"{minutes:g}m")


class Task:
    """One array task of the slurm backend: the run it is given, started or continued with a time limit
    short of the task's own (`run_minutes`). A run that stops at that limit has its checkpoint written, and
    the task requeues itself; a task preempted, or whose own time runs out first, is requeued by submitit
    (which calls `checkpoint` on its signal). Run again, it continues from the run folder."""

    def __init__(self, folder: Path, run_minutes: float | None = None):
        self.folder, self.run_minutes = folder, run_minutes

    def __call__(self, run: PlannedRun) -> int:
        code = execute(self.folder, run, extra=time_limit(self.run_minutes))
        if code == TIME_LIMIT_STATUS:
            requeue_this_task()
        if code != 0:
            raise RuntimeError(f"{run.id}: {why(log_path(self.folder, run, '.log'), code)}")
        return code

    def checkpoint(self, run: PlannedRun):
        """What submitit requeues: this task with its run, which goes on from its folder."""
        return submitit().helpers.DelayedSubmission(self, run)


def requeue_this_task() -> None:
    """Hand this task back to the scheduler through submitit's own path: the signal on which submitit
    checkpoints a task and requeues it (counting a time-out against the sweep's `requeues`). Outside a
    submitit job, where that signal would kill the process, it raises instead."""
    sig = getattr(signal, "SIG" + submitit().JobEnvironment.USR_SIG, None)
    if sig is None or not callable(signal.getsignal(sig)):
        raise RuntimeError("the run stopped at its time limit, and this process is no submitit task to requeue; "
                           "start the sweep again to continue it")
    os.kill(os.getpid(), sig)  # submitit's handler requeues the task and exits this process
    time.sleep(60)  # the handler runs between two bytecodes; this one waits for it
    raise RuntimeError("submitit did not requeue this task after its run stopped at its time limit")


def executor(sweep: Sweep, cluster: str | None = None):
    """A submitit executor with the sweep's slurm settings; `cluster` 'local' runs the array on this machine
    as a scheduler would (submitit's local executor), else SLURM's sbatch."""
    module = submitit()
    if cluster is None and shutil.which("sbatch") is None:
        raise BackendError("the slurm backend needs SLURM, and sbatch is not on PATH here; submit from a login "
                           "node of the cluster, or use backend: local")
    s = sweep.spec.slurm
    made = module.AutoExecutor(folder=sweep.folder / SUBMITIT, cluster=cluster, slurm_max_num_timeout=s.requeues,
                                 local_max_num_timeout=s.requeues)
    extra = {k: v for k, v in (("account", s.account), ("qos", s.qos)) if v is not None}
    made.update_parameters(name=f"sweep-{sweep.path.stem}", timeout_min=s.time, nodes=1, tasks_per_node=1,
                           gpus_per_node=s.gpus_per_task,
                           **({"cpus_per_task": s.cpus_per_task} if s.cpus_per_task else {}),
                           **({"mem_gb": s.mem_gb} if s.mem_gb else {}),
                           **({"slurm_partition": s.partition} if s.partition else {}),
                           **({"slurm_array_parallelism": s.parallel} if s.parallel else {}),
                           **({"slurm_additional_parameters": extra} if extra else {}))
    return made


def submit(sweep: Sweep, cluster: str | None = None) -> list:
    """One job array of the unfinished runs; returns the submitit jobs (empty when every run is done)."""
    made = executor(sweep, cluster)
    todo = [run for run in sweep.runs if not finished(run)]
    record_plan(sweep)
    if not todo:
        return []
    jobs = made.map_array(Task(sweep.folder, sweep.spec.slurm.run_minutes), todo)
    record_plan(sweep, {run.id: job.job_id for run, job in zip(todo, jobs)})
    return jobs


def dry_run(sweep: Sweep) -> list[str]:
    """The commands the sweep would run now, one a line (a finished run's as a comment), after how they run."""
    s = sweep.spec
    if s.backend == "slurm":
        slurm = s.slurm
        head = (f"# one SLURM job array: a task per run, {slurm.gpus_per_task} GPU(s) each, {slurm.time} min "
                f"(then requeued, up to {slurm.requeues} times)" + (f", partition {slurm.partition}" if slurm.partition else "")
                + (f"; each run stops at an evaluation {slurm.stop_before:g} min before its task's end"
                   if slurm.run_minutes else ""))
        extra = time_limit(slurm.run_minutes)
    else:
        slots = gpus(s.local.gpus)
        head = f"# a queue: one run per GPU ({', '.join(slots)})" if slots else "# one run after another (no GPU)"
        extra = ()
    lines = [head]
    for run in sweep.runs:
        if finished(run):
            lines.append(f"# done: {run.id}")
        else:
            lines.append(shell((*run.command(), *extra)))
    return lines
