"""Judging a run's last checkpoint after training: its policy's episodes on the field it is judged on
(or another of the same layout), every seed at once, with one episode filmed."""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import jax

from fieldgen.agents import loop
from fieldgen.run.session import Run
from fieldgen.run.videos import EpisodeRecorder


@dataclasses.dataclass(frozen=True)
class Evaluation:
    metrics: dict  # metric -> one value per seed
    env_steps: int
    episode: dict | None  # the first seed's first episode, as EpisodeRecorder.episode gives it


def evaluate(run: Run, episodes: int, seed: int = 0, film: bool = True) -> Evaluation:
    """`episodes` evaluation episodes per seed of the run's policy, on `run.env`."""
    trainer = dataclasses.replace(run, config=run.config.model_copy(update={"eval_envs": episodes})).judged_trainer
    filming = EpisodeRecorder.film if film else None
    judged = jax.vmap(functools.partial(loop.evaluate, trainer, film=filming), in_axes=(0, None))
    metrics, frames = jax.device_get(jax.jit(judged)(run.state, jax.random.PRNGKey(seed)))
    steps = int(jax.device_get(run.state.env_steps)[0])
    episode = EpisodeRecorder(run.env).episode(loop.seed_slice(frames, 0)) if film else None
    return Evaluation(metrics, steps, episode)


def video_path(run: Run, run_dir: Path, other_field: bool) -> Path:
    """Where an evaluation's video goes, without its suffix: eval, or eval_<field> on another field."""
    return run_dir / ("eval" if not other_field else f"eval_{run.env.spec.name}")
