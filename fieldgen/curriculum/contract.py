"""The curriculum contract: all that fieldgen's trainers (fieldgen.agents) know of curricula, beside the
environment contract (fieldgen.env.contract), the one module of fieldgen it imports.

After each evaluation the training loop asks a `Schedule` which stage trains next and has `adapt` re-weigh how
an environment of several variants draws its next episodes; a run on one environment has `OneStage`. How a
batch draws its episodes and what decides it (its sampling: `start_sampling`, the weights and the episodes
counted on each level) is all of its state that outlives the episodes: a pytree of its own, which the loop
carries beside the training state and hands to `adapt`, and which checkpoints and `learner.msgpack` keep, so
that a run going on from there draws as before (`with_episode_sampling`). Which schedules there are, and how
their weights are worked out, is the rest of this package's business (schedule.py, auto.py); the trainers know
only what is here.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol

import jax
import jax.numpy as jnp
import numpy as np

from fieldgen.env.contract import Environment

LEVEL_STREAM = 0x1E7E1  # a schedule's choice of levels: fold_in(the training state's key, LEVEL_STREAM)
KICKOFF_BINS = 10  # a row's share of new episodes by kick-off: bins evenly from the easiest start to the field's own


class Schedule(Protocol):
    """What the loop asks a curriculum after each evaluation (fieldgen.curriculum.schedule answers). Schedules
    are hashable: compiled programs are kept by them."""

    def next_stage(self, history: list[dict], stage: int, stages: int) -> int:
        """The stage (an index into the loop's trainers) the next chunk trains on, given every row so far."""

    def variant_weights(self, success: jax.Array) -> jax.Array:
        """How often each variant of an environment of several starts an episode, from an evaluation's
        success_any on each; pure and jittable."""

    def next_levels(self, counts: jax.Array, weights: jax.Array, playable: np.ndarray,
                    key: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Asked instead of `variant_weights` where the environment has kick-off points: (how often each level
        starts an episode next, how much of each level's episode counts to keep) [variant, point], from the
        training episodes counted on each level ([2, variant, point]: ended, succeeded), the weights so far
        and which levels are `playable`; pure and jittable, `key` for any random choice."""


@dataclasses.dataclass(frozen=True)
class OneStage:
    """The schedule of a run on one environment: it never moves, and its variants (if any) are drawn evenly."""

    def next_stage(self, history: list[dict], stage: int, stages: int) -> int:
        return stage

    def variant_weights(self, success: jax.Array) -> jax.Array:
        return jnp.full_like(success, 1.0 / success.shape[-1])


def adapt(schedule: Schedule, env: Environment, env_state, sampling: dict, success: jax.Array,
          key: jax.Array) -> tuple[object, dict, jax.Array, jax.Array | None]:
    """A batch of `env`'s environments (on axis 0) and its `sampling` (`start_sampling`, one seed's) after an
    evaluation whose success_any on each variant is `success`: (the batch drawing its next episodes as `schedule`
    says, the sampling that goes on with it, each variant's weight, the weights' share by kick-off in KICKOFF_BINS
    bins or None). Its variants are re-weighted by the schedule's `variant_weights` of `success`, or, where the
    environment has kick-off points, its levels by the schedule's `next_levels` of the training episodes counted
    on each (the sampling's, and those the environments tallied since, which move into the sampling), drawn with
    `key` (the training state's, on a stream of its own)."""
    coordinates = env.kickoff_coordinates
    if not coordinates.shape[1]:
        weights = schedule.variant_weights(success)
        return env.with_variant_weights(env_state, weights), dict(sampling, variant_weights=weights), weights, None
    counts = sampling["level_counts"] + jnp.sum(env_state.info["level_counts"], axis=0)  # over the batch
    levels, keep = schedule.next_levels(counts, sampling["level_weights"], np.isfinite(coordinates),
                                        jax.random.fold_in(key, LEVEL_STREAM))
    bins = np.clip(np.floor(np.nan_to_num(coordinates) * KICKOFF_BINS), 0, KICKOFF_BINS - 1).astype(int)
    share = jnp.zeros(KICKOFF_BINS).at[bins.ravel()].add(levels.ravel())
    drawn = env.with_level_weights(env_state, levels, jnp.zeros_like(keep))  # their tallies start again
    return drawn, {"level_counts": counts * keep, "level_weights": levels}, jnp.sum(levels, axis=-1), share


# what a batch of environments draws its next episodes with: info entry -> its environment axis, counted from the
# end so that a leading seed axis changes nothing (the same in every environment: the first is read)
WEIGHTS = {"level_weights": -3, "variant_weights": -2}
COUNTS = "level_counts"  # the episodes ended on each level ([2, variant, point]: ended, succeeded)


def start_sampling(env_state) -> dict:
    """A batch of environments' sampling: all of its state that outlives the episodes, which the loop carries
    beside the training state and `adapt` moves on. It is the weights the batch draws its variants or levels
    with and, with kick-off points, the training episodes counted on each level, older ones counting for less
    (none here: those the environments tallied join at the next `adapt`). Checkpoints and `learner.msgpack` keep
    it beside what was learned, so a run going on from there (agents.loop.run_staged's `sampling`) draws its
    levels as before instead of starting its curriculum over. Empty for an environment of one variant. Host or
    device arrays, with or without a leading seed axis."""
    kept = {}
    for name, axis in WEIGHTS.items():
        if name in env_state.info:
            kept[name] = env_state.info[name][(..., 0) + (slice(None),) * (-axis - 1)]
            if name == "level_weights":
                counts = env_state.info[COUNTS]
                kept[COUNTS] = jnp.zeros(counts.shape[:-4] + counts.shape[-3:], counts.dtype)
    return kept


def level_sampling_shapes(seeds: int, variants: int, points: int) -> dict:
    """The shapes of the sampling (`start_sampling`) of `seeds` seeds' batches of an environment with kick-off
    points (`variants` levels of `points` each): how `learner.msgpack`'s last part is read without the trainer."""
    return {"level_counts": jax.ShapeDtypeStruct((seeds, 2, variants, points), jnp.float32),
            "level_weights": jax.ShapeDtypeStruct((seeds, variants, points), jnp.float32)}


def with_episode_sampling(env_state, sampling: dict):
    """One seed's batch of fresh environments (on axis 0) drawing its episodes as `sampling` (`start_sampling`,
    as `adapt` moved it on) says: its weights in every environment (its counts stay in the sampling)."""
    info = dict(env_state.info)
    for name in WEIGHTS:
        if name in sampling:
            info[name] = jnp.broadcast_to(sampling[name], info[name].shape)
    return env_state.replace(info=info)
