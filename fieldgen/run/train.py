"""Training a run in its folder: the chunks between evaluations, and after each a checkpoint, the
metrics, the plot and a video, written beside training and sent to a logger (TensorBoard, W&B); a run
whose numbers stop being finite stops, and one given a deadline stops at the last evaluation before it."""

from __future__ import annotations

import contextlib
import math
import statistics
import time

import jax
import numpy as np
from rich.console import Console

from fieldgen import stops
from fieldgen.agents import checkpoint, loop, sharding
from fieldgen.agents.registry import judged_on
from fieldgen.env.mjx_physics import PhysicsOverflow
from fieldgen.files import locked, remove_leftovers, write_atomic
from fieldgen.run import background, record, session
from fieldgen.run.loggers import open_logger
from fieldgen.run.plots import plot_success
from fieldgen.run.progress import display, rate, stats, summary
from fieldgen.run.session import Run
from fieldgen.run.videos import EpisodeRecorder, video_name
from fieldgen.suggest import shell


def train(run: Run, console: Console, videos: bool = True, logger: str = "none", video_format: str | None = None,
          deadline: float | None = None) -> bool:
    """Train until the run's last evaluation, filming each in `video_format` (fieldgen.video.choose) and logging
    to `logger` (loggers.LOGGERS) too; Ctrl-C leaves the last checkpoint intact. In a run over several
    processes every process trains and only the first writes (the folder, metrics, videos, checkpoints); the
    folder is locked meanwhile by the one that writes: another command training it is refused.

    With `deadline` (a time.monotonic() instant, a job's time limit) training stops at the last evaluation
    after which the next chunk, its evaluation and the whole checkpoint written then would not all end
    before it (`Deadline`), and says how to go on: a scheduler's kill would lose the chunk under way. True
    once the run is complete, False where the deadline stopped it."""
    with locked(run.folder) if jax.process_index() == 0 else contextlib.nullcontext():
        return _train(run, console, videos, logger, video_format, Deadline(deadline, run.rows))


class Deadline:
    """Whether the next chunk fits before a deadline: the longest a chunk with its evaluation has taken (in
    this command, its first chunk left out once others are measured: `loop.longest_chunk`; else the median gap
    between the run's evaluations so far) and the longest that handing an evaluation on and writing its whole
    checkpoint took. Before anything is measured, the chunk runs."""

    def __init__(self, at: float | None, rows: list[dict]) -> None:
        self.at, self.rows = at, rows
        self.handing: list[float] = []  # seconds each on_eval held the training thread
        self.writing: list[float] = []  # seconds each whole checkpoint took to write, in the writer's thread
        self.needed: float | None = None  # what the chunk refused would have taken, by the estimate
        self.reached = False

    def earlier_interval(self) -> float | None:
        """The median gap of wall-clock time between the run's evaluations so far (earlier commands' too)."""
        walls = sorted({row["eval"]: row["wall_seconds"] for row in self.rows if "wall_seconds" in row}.items())
        gaps = [b - a for (_, a), (_, b) in zip(walls, walls[1:]) if b > a]
        return statistics.median(gaps) if gaps else None

    def stop(self, longest: float | None) -> bool:
        """loop.run_staged's `stop`: every process of a run takes process 0's answer, so that all stop at
        the same evaluation."""
        stops.check()  # a Ctrl-C dropped where it was raised stops the run here, before its next chunk
        interval = longest if longest is not None else self.earlier_interval()
        if self.at is not None and interval is not None:
            self.needed = interval + max(self.handing, default=0.0) + max(self.writing, default=0.0)
            self.reached = time.monotonic() + self.needed > self.at
        if jax.process_count() > 1:
            from jax.experimental import multihost_utils

            self.reached = bool(multihost_utils.broadcast_one_to_all(np.asarray(self.reached)))
        return self.reached

    def timed(self, job):
        """`job`, its seconds kept as a checkpoint's write time."""
        def run(*args):
            began = time.perf_counter()
            job(*args)
            self.writing.append(time.perf_counter() - began)
        return run


def restore_learner(run: Run, console: Console) -> None:
    """A complete run whose learner.msgpack is missing or damaged, while its whole checkpoint holds the end:
    `fieldgen eval` and `export` read the learner, so it is written again from the checkpoint."""
    path = run.folder / record.LEARNER
    try:
        checkpoint.load(path, *session.learner_template(run))
        return
    except checkpoint.CheckpointError:
        pass
    if path.is_dir():
        raise record.RunError(f"{path} is a folder, not what the run learned: move it aside and run fieldgen train "
                              f"--resume {run.folder} again, which writes it from {record.CHECKPOINT}")
    learned = session.learner_contents(run.trainers[0], *sharding.to_host((run.state, run.sampling)))
    write_atomic(path, checkpoint.pieces(learned))
    console.print(f"{path.name} was missing or damaged: written again from {record.CHECKPOINT}, which holds the "
                  "run's end")


def _train(run: Run, console: Console, videos: bool, logger: str, video_format: str | None,
           deadline: Deadline) -> bool:
    writes = jax.process_index() == 0
    if not writes:  # it films all the same: every process runs the same programs
        console, logger = Console(quiet=True), "none"
    else:
        remove_leftovers(run.folder)  # of writes killed midway; here, not on opening, which `fieldgen eval` does mid-run
    config, env = run.config, run.env
    if run.state is not None and run.finished:
        if writes and not run.refills:  # its state read from the whole checkpoint: the learner was not readable
            restore_learner(run, console)
        console.print(f"{run.folder} is already complete ({run.rows[-1]['env_steps']:,} env steps)")
        return True
    trainers = run.trainers
    recorders: dict[int, EpisodeRecorder] = {}
    started = time.perf_counter() - (run.rows[-1].get("wall_seconds", 0.0) if run.rows else 0.0)  # over resumes
    log = open_logger(logger, run.folder, run.seeds, {"algo": run.algo, "field": env.spec.name,
                                                       **run.config.model_dump()})
    with contextlib.closing(log), display(console) as bar, background.Writer() as writer:
        first = run.rows[-1]["env_steps"] if run.rows else 0
        if not run.rows and config.short_of_asked():
            console.print(config.short_of_asked(), soft_wrap=True)
        ending = [ends_at(run)]  # where the run ends, as its rows come in
        task = bar.add_task(run.label, total=ending[0], completed=first, rate="compiling...", stats="")

        waited = []  # seconds the last on_eval held the training thread: they fall in the next chunk's time
        skipped = [False]  # whether the last evaluation's whole checkpoint was left out

        def on_eval(state, index, stage, filmed, sampling):
            began = time.perf_counter()
            skipped[0] = skip_checkpoint(writer.busy, skipped[0], index == config.num_evals or deadline.reached)
            whole = None
            if not skipped[0]:
                writer.wait()  # one snapshot at a time in host memory; a failed write stops training here
                whole = session.checkpoint_contents(state, sampling)
                if jax.process_count() > 1:  # every process gathers it, together, here
                    whole = sharding.to_host(whole)
            learned = sharding.to_host(session.learner_contents(trainers[0], state, sampling))  # megabytes
            waited[:] = [time.perf_counter() - began]
            deadline.handing.append(waited[0])
            if not writes:
                return
            if whole is not None:
                writer.submit(deadline.timed(write_whole), run.folder / record.CHECKPOINT, [whole])
            writer.submit(write_atomic, run.folder / record.LEARNER, checkpoint.pieces(learned))
            if filmed is not None:  # the episode just evaluated (a mixed run films its last stage)
                filmed_stage, frames = filmed
                if filmed_stage not in recorders:
                    recorders[filmed_stage] = EpisodeRecorder(run.envs[-1 if run.plan.mixed else filmed_stage],
                                                              fmt=video_format)
                recorder = recorders[filmed_stage]
                writer.submit(film, recorder, video_name(run.folder, index), recorder.episode(frames),
                              run.rows[-1]["env_steps"])

        def film(recorder, name, episode, env_steps):
            """Draw the episode; a video drawn goes to the logger too."""
            if recorder.save(run.folder, name, episode, console) is not None:
                log.video(name.with_suffix(f".{recorder.fmt}"), env_steps)

        def progress(index, rows):
            stop_if_diverged(run, index, rows)
            memory = peak_memory_mb()
            for row in rows:
                if waited and "steps_per_second" in row:  # the writes waited on while this row's chunk trained
                    row["write_wait_seconds"] = waited[0]
                if memory is not None:
                    row["peak_memory_mb"] = memory
            run.rows.extend(rows)
            if not writes:
                return
            record.write_metrics(run.folder, run.rows)
            plot_success(run.folder, run.rows, f"{run.label}: {run.algo}{judged_on(config.eval_actions)}",
                         run.plan.variant_name)
            log.rows(rows)
            ending[0] = config.ends_at(rows[0]["eval"], rows[0]["env_steps"])
            bar.update(task, completed=rows[0]["env_steps"], total=ending[0], rate=rate(run.rows, ending[0]),
                       stats=stats(rows, len(run.envs)))

        # a run started from another's networks (--init-from) goes on from "evaluation -1": it evaluates them first
        resume = (run.state, run.rows[-1]["eval"] if run.rows else -1, run.stage) if run.state is not None else None
        try:
            stops.check()  # a Ctrl-C dropped while the run was opened: nothing to train
            loop.run_staged(trainers, run.seeds, config.num_evals, run.plan.schedule, progress, on_eval, resume,
                            film=EpisodeRecorder.film if videos else None, sampling=run.sampling,
                            stop=deadline.stop, clock=started)
            if not deadline.reached:
                done = run.rows[-1]["env_steps"]
                bar.update(task, total=done, rate=rate(run.rows, done))
        except PhysicsOverflow as exc:
            raise record.RunError(f"training stopped: {exc}") from None
        except KeyboardInterrupt:
            if writer.busy:
                console.print("finishing the checkpoint being written...")
            writer.wait()
            saved = record.has_trained(run.folder)
            console.print(f"{stops.said()}; {'the last checkpoint is intact' if saved else 'no checkpoint yet'}. "
                          f"{'Continue' if saved else 'Start again'} with: fieldgen train --resume {shell(run.folder)}",
                          soft_wrap=True)  # one line: the command stays whole to copy
            raise
    summary(run, console)
    if deadline.reached:
        last = run.rows[-1] if run.rows else {"eval": -1, "env_steps": 0}
        took = "" if deadline.needed is None else f" (about {deadline.needed:.0f} s)"  # a process told by process 0
        console.print(f"stopped at the time limit after evaluation {last['eval']} of {config.num_evals} "
                      f"({last['env_steps']:,} of {ending[0]:,} env steps): the next chunk with its "
                      f"evaluation and checkpoint{took} would not have ended in time. "
                      f"Continue with: fieldgen train --resume {shell(run.folder)}", soft_wrap=True)
    return not deadline.reached


def ends_at(run: Run) -> int:
    """The env steps `run` ends at, from where it stands: past its config's trained_steps by each buffer it filled
    anew on a resume from what it learned alone, the one about to be filled included."""
    if not run.rows:
        return run.config.trained_steps
    last = run.rows[-1]
    refill = run.config.steps_at(0) if run.refills and not run.finished else 0  # PPO's: none
    return run.config.ends_at(last["eval"], last["env_steps"]) + refill


def write_whole(path, held: list) -> None:
    """Write the whole checkpoint, copying it to the host here, in the writer's thread: training's next chunk
    starts meanwhile (a chunk makes a new state; the one evaluated stays as it was until copied). `held` holds
    the state alone, emptied once copied so that its device memory is freed while the write goes on."""
    contents = sharding.to_host(held.pop())
    write_atomic(path, checkpoint.pieces(contents))


def skip_checkpoint(writing: bool, skipped_last: bool, last: bool) -> bool:
    """Whether an evaluation leaves its whole checkpoint (replay buffer included, gigabytes) out and writes
    what was learned alone: only while the writer is still busy with an earlier write that training would
    otherwise wait for, never twice in a row (a resume goes on from the last whole checkpoint, exactly, and
    trains again the chunks after it, whose rows it drops), never at the run's end, and
    never across processes, which must all gather the same state at the same evaluation."""
    return writing and not skipped_last and not last and jax.process_count() == 1


def stop_if_diverged(run: Run, index: int, rows: list[dict]) -> None:
    """Stop a run whose metrics are no longer finite, before its metrics or checkpoint are written:
    weights that are NaN never recover, and the checkpoint already on disk is still a sound one."""
    for row in rows:
        bad = sorted(k for k, v in row.items() if isinstance(v, float) and not math.isfinite(v))
        if bad:
            kept = f"evaluation {index - 1}'s checkpoint and metrics" if index > 0 else "no checkpoint"
            raise record.RunError(
                f"training diverged: after {row['env_steps']:,} env steps (evaluation {index}) seed {row['seed']}'s "
                f"{', '.join(bad)} {'is' if len(bad) == 1 else 'are'} not finite. Nothing of that evaluation was "
                f"written; {run.folder} keeps {kept}. Train again with smaller learning rates (--set) "
                f"or another --seed")


def peak_memory_mb() -> float | None:
    """The largest peak of bytes in use over the local devices, where the backend reports it (GPUs do)."""
    peaks = [(d.memory_stats() or {}).get("peak_bytes_in_use") for d in jax.local_devices()]
    peaks = [p for p in peaks if p is not None]
    return max(peaks) / 2**20 if peaks else None
