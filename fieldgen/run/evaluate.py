"""Judging runs' last checkpoints after training: their policies' episodes on the field they are judged on
(or another of the same layout), every seed of a run at once, with one episode filmed; and the runs of one
field and algorithm judged together, summarized over their seeds."""

from __future__ import annotations

import dataclasses
import functools
import json
from pathlib import Path

import jax

from fieldgen.agents import loop, memory, programs
from fieldgen.compile.artifact import ArtifactError, field_digest, load_artifact
from fieldgen.env.mjx_physics import OVERFLOW, PhysicsOverflow
from fieldgen.files import named_twice
from fieldgen.run import record, session, summary
from fieldgen.run.session import Run
from fieldgen.run.videos import EpisodeRecorder
from fieldgen.suggest import shell


@dataclasses.dataclass(frozen=True)
class Evaluation:
    metrics: dict  # metric -> one value per seed
    env_steps: int
    episode: dict | None  # the filmed seed's first episode, as EpisodeRecorder.episode gives it


def evaluate(run: Run, episodes: int, seed: int = 0, film: int | None = 0, actions: str | None = None) -> Evaluation:
    """`episodes` evaluation episodes per seed of the run's policy, on `run.env`, on its mean actions or (`actions`
    "sampled") on actions drawn as in training; None: as the run's own evaluations acted (its `eval_actions`).
    `film`: the place in `run.seeds` of the seed whose first episode is filmed, None for none.
    It compiles and runs as training's programs do (agents.programs), so that Ctrl-C reaches the caller at once,
    mid-compile too."""
    judging = {"eval_envs": episodes, "eval_actions": actions or run.config.eval_actions}
    trainer = dataclasses.replace(run, config=run.config.model_copy(update=judging)).judged_trainer
    programs.reserve_worlds(trainer, len(run.seeds))
    filming = EpisodeRecorder.film if film is not None else None
    judged = jax.vmap(functools.partial(loop.evaluate, trainer, film=filming),
                      in_axes=(0, None))
    key = jax.random.PRNGKey(seed)
    metrics, frames = programs.computed(programs.Compiling(jax.jit(judged), run.state, key)(run.state, key))
    try:
        loop.stop_on_overflow(trainer.env, metrics.pop(OVERFLOW, None))
    except PhysicsOverflow as exc:
        raise record.RunError(f"evaluation stopped: {exc}") from None
    steps = int(jax.device_get(run.state.env_steps)[0])
    episode = EpisodeRecorder(run.env).episode(loop.seed_slice(frames, film)) if film is not None else None
    return Evaluation(metrics, steps, episode)


def check_memory(run: Run, episodes: int) -> None:
    """Refuse (ConfigError) an evaluation whose episodes, `episodes` for each seed at once, the machine cannot hold."""
    seeds = len(run.seeds)
    memory.check(memory.episodes(run.env, episodes * seeds),
                 f"evaluating {episodes:,} episodes of each of {seeds:,} seed{'s' * (seeds > 1)} at once",
                 {memory.EPISODES: "--episodes"})


def video_path(run_dir: Path, other_field: str | None = None, seed: int | None = None) -> Path:
    """Where an evaluation's video goes, without its suffix: eval, or eval_<field> on another field, and
    _seed<S> after it where a seed to film was named."""
    name = "eval" if other_field is None else f"eval_{other_field}"
    return run_dir / (name if seed is None else f"{name}_seed{seed}")


def filmed(runs: list[Run], seed: int | None) -> tuple[int, int]:
    """Which run, and which place in its seeds, holds the training seed `seed` (None: the first run's first);
    RunError naming the seeds there are when no run trained it."""
    if seed is None:
        return 0, 0
    for k, run in enumerate(runs):
        if seed in run.seeds:
            return k, list(run.seeds).index(seed)
    there = sorted(s for run in runs for s in run.seeds)
    raise record.RunError(f"--film-seed {seed}: no run evaluated here trained seed {seed}; its seeds are "
                          f"{', '.join(map(str, there))}")


def _trained_on(run: Run) -> str:
    return " then ".join(env.spec.name for env in run.envs)


def field_digests(run: Run) -> list[str]:
    """The digest of each field the run trained on (its stages in order): what tells a user's point_nav from
    the bundled one, where names agree."""
    return [field_digest(env.spec.model_dump(mode="json")) for env in run.envs]


def open_runs(folders: list[Path], field: Path | None = None) -> list[Run]:
    """The runs to judge together, each with its last checkpoint (its policy put on `field` where given, else on the
    copy of the field as written that runs keep where a recipe trained them on another form of it: `judged_copy`).
    Refused before any checkpoint loads: a folder that is not a run or has not trained, runs of another
    field or algorithm than the first's, a seed in two of them, a `field` that is a folder of fields; a summary
    is over the seeds of one recipe."""
    first, owners, copies = None, {}, []
    if twice := named_twice(folders):
        raise record.RunError(f"{twice}: each run's seeds count once in a summary; name it once")
    for folder in folders:
        run = session.open_run(folder, load_state=False)
        copies.append(run.judged)
        if not record.has_trained(folder):
            raise record.RunError(f"{folder} has no checkpoint: it has not trained yet; train it with "
                                  f"fieldgen train --resume {shell(folder)}, then evaluate it")
        first = first or run
        if (run.algo, field_digests(run)) != (first.algo, field_digests(first)):
            alike = (" (fields of one name that differ)" if _trained_on(run) == _trained_on(first)
                     and field_digests(run) != field_digests(first) else "")
            raise record.RunError(f"{folder} trained {run.algo} on {_trained_on(run)}, {first.folder} {first.algo} "
                                  f"on {_trained_on(first)}{alike}: runs evaluated together are seeds of one field "
                                  "and algorithm; evaluate them separately")
        for s in run.seeds:
            if s in owners:
                raise record.RunError(f"seed {s} is in both {owners[s]} and {folder}: each seed counts once in a "
                                      "summary; leave one of them out")
            owners[s] = folder
    if field is not None:
        session.refuse_folder_of_fields(field)
    else:
        field = judged_copy(folders, copies)
    runs = [session.open_run(folder, learned=True) for folder in folders]
    return runs if field is None else [session.on_field(run, field) for run in runs]


def judged_copy(folders: list[Path], copies: list[Path | None]) -> Path | None:
    """Where runs to judge together are judged by default: the copy of the field as written that each keeps (its
    `judged` folder, `copies`) where a recipe trained it on another form of it (the first's; refused where they
    differ), else None: where they trained."""
    if all(copy is None for copy in copies):
        return None
    if any(copy is None for copy in copies):
        alone, other = folders[copies.index(None)], folders[next(k for k, c in enumerate(copies) if c is not None)]
        raise record.RunError(f"{alone} is judged on the field it trained on, {other} on the field as written beside "
                              "another form its recipe trained on: evaluate them separately, or name the field to "
                              "judge both on: --field FIELD")
    try:
        digests = {field_digest(load_artifact(copy).spec.model_dump(mode="json")) for copy in copies}
    except ArtifactError as exc:
        raise record.RunError(f"{exc.problem}; it is a run's own copy of the field as written: restore it from a copy "
                              "of the run, or judge the run on that field by name: --field FIELD") from None
    if len(digests) > 1:
        raise record.RunError(f"{', '.join(map(str, folders))} keep different fields as written: runs evaluated "
                              "together are seeds of one field; evaluate them separately")
    return copies[0]


def summary_path(folders: list[Path], run: Run, other_field: bool, episodes: int) -> tuple[Path, Path | None]:
    """Where a summary goes by default: into the run folder for one run, beside the first for several;
    summary_<field>.json on another field, as its video is eval_<field>. A summary there of more episodes is
    kept, and this one goes beside it named with its episodes (summary_4.json, `kept_beside`), so that a quick
    look, such as a filmed episode or four, never replaces a figure of 1,024 episodes."""
    name = summary.SUMMARY if not other_field else f"summary_{run.env.spec.name}.json"
    return kept_beside((folders[0] if len(folders) == 1 else folders[0].absolute().parent) / name, episodes)


def kept_beside(path: Path, episodes: int) -> tuple[Path, Path | None]:
    """`path` for an evaluation of `episodes`, unless the file there records more ("episodes", as a summary and
    a self-play evaluation do): then that one is kept, the path beside it named with the episodes is returned
    first and the kept one second."""
    try:
        held = json.loads(path.read_bytes()).get("episodes")
    except (OSError, ValueError, AttributeError):  # none there, or none of eval's: the writer's checks decide
        return path, None
    if not isinstance(held, int) or held <= episodes:
        return path, None
    return path.with_name(f"{path.stem}_{episodes}{path.suffix}"), path


def summarize(runs: list[Run], evaluations: list[Evaluation], episodes: int, command: str,
              actions: str = "mean") -> summary.SeedSummary:
    """The runs' evaluations, seed by seed and over every seed."""
    seeds = [(s, evaluation, i) for run, evaluation in zip(runs, evaluations) for i, s in enumerate(run.seeds)]
    per_seed = {metric: {s: float(e.metrics[metric][i]) for s, e, i in seeds} for metric in summary.METRICS}
    before = {s: run.learned_before for run in runs for s in run.seeds if run.learned_before}
    return summary.summarize([runs[0].env.spec.name], runs[0].algo, [run.folder for run in runs], episodes,
                             {s: e.env_steps for s, e, _ in seeds}, per_seed, command, before, actions,
                             [field_digest(runs[0].env.spec.model_dump(mode="json"))])
