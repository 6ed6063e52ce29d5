"""Executing a training run in its folder: start or resume it, show progress, checkpoint,
write metrics, plots and videos after every evaluation, and summarise at the end."""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import time
from pathlib import Path

import jax
import jax.numpy as jnp
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Column, Table
from rich.text import Text

import fieldgen
from fieldgen.agents import checkpoint, loop, registry, sharding
from fieldgen import background, curriculum, training
from fieldgen.compile.artifact import ArtifactError, write_artifact
from fieldgen.files import write_atomic
from fieldgen.compile.variants import VariantError, compile_variants
from fieldgen.curriculum.promotion import Promotion

FIELD, STAGES = "field", "stages"  # the run's own copies of its built fields: resuming needs no compiler


@dataclasses.dataclass
class Run:
    folder: Path
    algo: str
    envs: list  # one per stage; a plain run has one
    config: object
    seeds: list[int]
    rows: list[dict]
    promotion: Promotion = Promotion()
    state: object = None  # the checkpointed training state of a resumed run
    stage: int = 0  # the stage the next chunk trains on
    mixed: bool = False  # a curriculum trained all at once: every environment carries its own stage

    @property
    def finished(self) -> bool:
        return bool(self.rows) and self.rows[-1]["eval"] >= self.config.num_evals

    @property
    def env(self):
        """The field a run is judged on: its only one, or a curriculum's last stage."""
        return self.envs[-1]

    @functools.cached_property
    def trainers(self) -> list[loop.Trainer]:
        """What trains: one trainer per stage, or for a mixed run one on all stages batched together."""
        make_train = registry.trainer(self.algo).make_train
        if self.mixed:
            return [make_train(self.config, fieldgen.FieldEnv([e.artifact for e in self.envs]))]
        return [make_train(self.config, env) for env in self.envs]

    def judge(self) -> loop.Trainer:
        """The trainer evaluated on the field the run is judged on."""
        if not self.mixed:
            return self.trainers[-1]
        return registry.trainer(self.algo).make_train(self.config, self.env)


def run_name(field: str, algo: str, seeds: list[int]) -> str:
    suffix = str(seeds[0]) if len(seeds) == 1 else f"{seeds[0]}to{seeds[-1]}"
    return f"{field}-{algo}-{suffix}"


def new_run(source: Path, algo: str, seeds: list[int], config, out: Path, mixed: bool = False) -> Run:
    """A run folder for a field (a YAML file or a build folder) or a curriculum folder (staged, or mixed:
    every stage in one batch, built to one structure)."""
    promotion, name = Promotion(), None
    if curriculum.is_curriculum(source):
        try:
            c = curriculum.load(source)
            specs = c.specs()
            if mixed:
                envs = [fieldgen.FieldEnv(a) for a in compile_variants(specs)]
            else:
                envs = [fieldgen.make(s) for s in specs]
        except (curriculum.CurriculumError, VariantError) as exc:
            raise training.RunError(str(exc)) from None
        promotion, name = c.promotion, source.name + ("-mixed" if mixed else "")
        layouts = {json.dumps(e.layout.to_json()) for e in envs}
        if len(layouts) > 1:
            raise training.RunError(f"{source}: the stages' observation layouts differ; a policy cannot move between them")
    else:
        if mixed:
            raise training.RunError(f"{source} is a single field; --mixed trains the stages of a curriculum folder")
        envs = [fieldgen.make(source)]
    folder = out / run_name(name or envs[0].spec.name, algo, seeds)
    if (folder / training.RUN).exists():
        raise training.RunError(f"{folder} already holds a run; continue it with --resume {folder}, "
                                "or pick another --seed or --out")
    for env in envs:
        config.validate_env(env, sharding.device_count(), len(seeds))
    folder.mkdir(parents=True, exist_ok=True)
    dirs = [FIELD] if len(envs) == 1 else [f"{STAGES}/{k + 1:02d}" for k in range(len(envs))]
    for env, sub in zip(envs, dirs):
        write_artifact(env.artifact, folder / sub)
    training.write_run(folder, envs[-1].spec.model_dump(mode="json"), algo, config, envs[0].layout.to_json(), seeds,
                       {"fields": dirs, "promotion": dataclasses.asdict(promotion), "mixed": mixed})
    return Run(folder, algo, envs, config, seeds, [], promotion, mixed=mixed)


def open_run(folder: Path, load_state: bool = True) -> Run:
    """A run folder with its fields loaded from the run's own copies and (with load_state) its last
    checkpoint; without, the run's record and metrics alone, enough to report on a finished run."""
    record = training.read_run(folder)
    envs = []
    for sub in record.get("fields", [FIELD]):
        try:
            envs.append(fieldgen.make(folder / sub))
        except ArtifactError as exc:
            raise training.RunError(f"{folder / sub}: {exc}") from None
    if any(record["observation"] != env.layout.to_json() for env in envs):
        raise training.RunError(f"{folder} was trained on a different observation layout than its fields give now")
    config = registry.trainer(record["algo"]).config.layered(**record["config"])
    seeds = record.get("seeds", [config.seed])
    rows = training.read_metrics(folder)
    run = Run(folder, record["algo"], envs, config, seeds, rows, Promotion(**record.get("promotion", {})),
              mixed=record.get("mixed", False))
    if not load_state or not (folder / training.CHECKPOINT).exists() and not rows:
        return run  # only reported on, or set up by `fieldgen train --prepare` and never started
    if rows and not run.mixed:
        run.stage = rows[-1].get("promoted_to", rows[-1].get("stage", 0))
    keys = jnp.stack([jax.random.PRNGKey(s) for s in seeds])
    template = jax.eval_shape(jax.vmap(run.trainers[run.stage].start), keys)
    try:
        run.state = checkpoint.load(folder / training.CHECKPOINT, template)
    except checkpoint.CheckpointError as exc:
        raise training.RunError(str(exc)) from None
    done = int(jax.device_get(run.state.env_steps)[0])
    run.rows = [r for r in run.rows if r["env_steps"] <= done]
    return run


def on_field(run: Run, source: Path) -> Run:
    """The run with its policy judged on another field (a YAML file or build folder) that observes and
    acts alike: whether what it learnt carries over, e.g. from an easier variant to the field it stands for."""
    try:
        env = fieldgen.make(source)
    except ArtifactError as exc:
        raise training.RunError(f"{source}: {exc}") from None
    if env.layout.to_json() != run.env.layout.to_json() or env.action_size != run.env.action_size:
        raise training.RunError(
            f"{source} observes or acts differently from {run.env.spec.name}, which {run.folder} was trained on "
            f"(observation {env.observation_size} against {run.env.observation_size} values, actions "
            f"{env.action_size} against {run.env.action_size}); a policy moves only between fields of one layout")
    return dataclasses.replace(run, envs=[env], mixed=False, stage=0)


def train(run: Run, console: Console, videos: bool = True) -> None:
    """Train until the run's last evaluation; Ctrl-C leaves the last checkpoint intact."""
    config, env = run.config, run.env
    if run.state is not None and run.finished:
        console.print(f"{run.folder} is already complete ({run.rows[-1]['env_steps']:,} env steps)")
        return
    trainers = run.trainers
    recorders: dict[int, training.EpisodeRecorder] = {}
    started = time.perf_counter() - (run.rows[-1].get("wall_seconds", 0.0) if run.rows else 0.0)  # over resumes
    with TrainingProgress(console) as bar, background.Writer() as writer:
        first = run.rows[-1]["env_steps"] if run.rows else 0
        task = bar.add_task(env.spec.name, total=config.total_steps, completed=first, rate="compiling...", stats="")

        def on_eval(state, index, stage, filmed):
            writer.wait()  # one snapshot at a time in host memory; a failed write stops training here
            snapshot = jax.device_get(state)
            writer.submit(write_atomic, run.folder / training.CHECKPOINT, checkpoint.pieces(snapshot))
            if filmed is not None:  # the episode just evaluated (a mixed run films its last stage)
                filmed_stage, frames = filmed
                if filmed_stage not in recorders:
                    recorders[filmed_stage] = training.EpisodeRecorder(run.envs[-1 if run.mixed else filmed_stage])
                recorder = recorders[filmed_stage]
                writer.submit(recorder.save, run.folder, training.video_name(run.folder, index),
                              recorder.episode(frames), console)

        def progress(index, rows):
            stop_if_diverged(run, index, rows)
            memory = training.peak_memory_mb()
            for row in rows:
                row["wall_seconds"] = time.perf_counter() - started
                if memory is not None:
                    row["peak_memory_mb"] = memory
            run.rows.extend(rows)
            training.write_metrics(run.folder, run.rows)
            training.plot_success(run.folder, run.rows, f"{env.spec.name}: {run.algo}")
            bar.update(task, completed=rows[0]["env_steps"], rate=_rate(run.rows, config.total_steps),
                       stats=_stats(rows))

        resume = (run.state, run.rows[-1]["eval"], run.stage) if run.state is not None else None
        try:
            loop.run_staged(trainers, run.seeds, config.num_evals, run.promotion.ready, progress, on_eval, resume,
                            film=training.EpisodeRecorder.film if videos else None)
            done = run.rows[-1]["env_steps"]  # whole iterations can stop short of --steps
            bar.update(task, total=done, rate=_rate(run.rows, done))
        except KeyboardInterrupt:
            if writer.busy:
                console.print("finishing the checkpoint being written...")
            writer.wait()
            saved = (run.folder / training.CHECKPOINT).exists()
            console.print(f"interrupted; {'the last checkpoint is intact' if saved else 'no checkpoint yet'}. "
                          f"{'Continue' if saved else 'Start again'} with: fieldgen train --resume {run.folder}")
            raise
    summary(run, console)


def stop_if_diverged(run: Run, index: int, rows: list[dict]) -> None:
    """Stop a run whose metrics are no longer finite, before its metrics or checkpoint are written:
    weights that are NaN never recover, and the checkpoint already on disk is still a sound one."""
    for row in rows:
        bad = sorted(k for k, v in row.items() if isinstance(v, float) and not math.isfinite(v))
        if bad:
            kept = f"evaluation {index - 1}'s checkpoint and metrics" if index > 0 else "no checkpoint"
            raise training.RunError(
                f"training diverged: after {row['env_steps']:,} env steps (evaluation {index}) seed {row['seed']}'s "
                f"{', '.join(bad)} {'is' if len(bad) == 1 else 'are'} not finite. Nothing of that evaluation was "
                f"written; {run.folder} keeps {kept}. Train again with smaller learning rates (--set) "
                f"or another --seed")


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


def _rate(history: list[dict], total: int) -> str:
    """The last chunk's env steps/s and the time left, from the wall clock between the last two evaluations
    (chunk, evaluation, checkpoint and video together)."""
    last = history[-1]
    if "steps_per_second" not in last:
        return ""
    text = f"{last['steps_per_second']:,.0f} steps/s"
    evals = [r for r in history if r.get("seed") == last.get("seed")]
    if len(evals) > 1 and evals[-2]["env_steps"] < last["env_steps"] < total:
        before = evals[-2]
        per_step = (last["wall_seconds"] - before["wall_seconds"]) / (last["env_steps"] - before["env_steps"])
        text += f", {_duration((total - last['env_steps']) * per_step)} left"
    return text


def _duration(seconds: float) -> str:
    if seconds < 60:
        return "<1 min"
    return f"{seconds / 60:.0f} min" if seconds < 5400 else f"{seconds / 3600:.1f} h"


def _stats(rows: list[dict]) -> str:
    mean = lambda key: sum(r[key] for r in rows) / len(rows)  # noqa: E731
    text = f"success {mean('success_any'):.2f}  at goal {mean('time_at_goal'):.1f}"
    if "variants" in rows[0]:
        text += f"  last stage {mean('last_stage_success_any'):.2f}"
    if "stage" in rows[0]:
        text = f"stage {rows[0].get('promoted_to', rows[0]['stage']) + 1}  " + text
    for name in ("critic_loss", "actor_loss", "policy_loss", "value_loss"):
        if name in rows[0]:
            text += f"  {name.removesuffix('_loss')} {mean(name):.3f}"
    return text


def summary(run: Run, console: Console) -> None:
    """The last evaluation of every seed against the untrained one, and where the files are."""
    table = Table("seed", "env steps", "success_any", "time_at_goal", "closest", "return", "steps/s",
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
    for row in run.rows:
        if "promoted_to" in row and row["seed"] == run.seeds[0]:
            name = run.envs[row["promoted_to"]].spec.name
            console.print(f"promoted to stage {row['promoted_to'] + 1} ({name}) at {row['env_steps']:,} env steps")
    if run.mixed:
        last = run.rows[-1]
        variants = last["variants"]
        console.print("success_any per stage at the end: " + ", ".join(
            f"{i}. {p:.2f} (weight {w:.2f})" for i, (p, w) in enumerate(zip(variants["success_any"], variants["weight"]), 1)))
        console.print(f"success_any on the last stage ({run.env.spec.name}): {last['last_stage_success_any']:.2f}")
    elif len(run.envs) > 1:
        last = run.rows[-1]
        console.print(f"reached stage {last.get('promoted_to', last['stage']) + 1} of {len(run.envs)}; success_any on "
                      f"the last stage ({run.env.spec.name}): {last['last_stage_success_any']:.2f}")
    memory = run.rows[-1].get("peak_memory_mb")
    if memory is not None:
        console.print(f"peak device memory: {memory:,.0f} MiB")
    console.print(f"metrics: {run.folder / training.CSV}; plot: {run.folder / training.PLOT}")
