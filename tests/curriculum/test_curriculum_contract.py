"""The curriculum contract (fieldgen.curriculum.contract): what the trainers know of curricula, on its own."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import struct

from fieldgen.curriculum.contract import adapt, start_sampling, with_episode_sampling


@struct.dataclass
class Batch:
    info: dict


WEIGHTS = np.tile(np.arange(6, dtype=np.float32).reshape(1, 2, 3) / 15, (4, 1, 1))  # 4 environments
TALLIES = np.arange(4 * 2 * 2 * 3, dtype=np.float32).reshape(4, 2, 2, 3)  # each environment's episodes since


def test_a_batch_starts_its_sampling_from_what_it_draws_by_with_no_episodes_counted():
    """start_sampling keeps the level weights once (the same in every environment) and counts of no episodes,
    with or without a leading seed axis: the episodes the environments tallied join at the next `adapt`."""
    batch = Batch({"level_weights": WEIGHTS, "level_counts": TALLIES, "rng": np.zeros((4, 2), np.uint32)})
    kept = start_sampling(batch)
    assert set(kept) == {"level_weights", "level_counts"}
    np.testing.assert_array_equal(kept["level_weights"], WEIGHTS[0])
    np.testing.assert_array_equal(kept["level_counts"], np.zeros((2, 2, 3)))
    seeds = Batch({name: np.stack([x, 2 * x]) for name, x in batch.info.items()})  # two seeds stacked
    both = start_sampling(seeds)
    np.testing.assert_array_equal(both["level_weights"][1], 2 * WEIGHTS[0])
    assert both["level_counts"].shape == (2, 2, 2, 3) and not np.any(both["level_counts"])
    variants = start_sampling(Batch({"variant_weights": np.full((4, 3), 1 / 3, np.float32)}))
    np.testing.assert_array_equal(variants["variant_weights"], np.full(3, 1 / 3, np.float32))
    assert start_sampling(Batch({"rng": batch.info["rng"]})) == {}  # one variant: nothing to keep


@dataclasses.dataclass(frozen=True)
class Levels:
    """An environment of 2 levels of 3 kick-off points each, as far as `adapt` asks of it."""

    kickoff_coordinates: np.ndarray = dataclasses.field(default_factory=lambda: np.array([[0.0, 0.5, 1.0]] * 2))

    def with_level_weights(self, state, weights, keep):
        info = state.info
        return state.replace(info=dict(info, level_weights=jnp.broadcast_to(weights, info["level_weights"].shape),
                                       level_counts=info["level_counts"] * keep))


@dataclasses.dataclass(frozen=True)
class Halving:
    """A schedule that draws each level by the episodes counted on it and keeps half of every count."""

    def next_levels(self, counts, weights, playable, key):
        assert playable.all()
        return counts[0] / jnp.sum(counts[0]), jnp.full_like(weights, 0.5)


def test_adapt_moves_the_environments_tallies_into_the_sampling_and_draws_as_the_schedule_says():
    batch = Batch({"level_weights": jnp.asarray(WEIGHTS), "level_counts": jnp.asarray(TALLIES)})
    before = {"level_counts": jnp.ones((2, 2, 3)), "level_weights": jnp.asarray(WEIGHTS[0])}
    drawn, sampling, weight, share = adapt(Halving(), Levels(), batch, before, jnp.zeros(2), jax.random.PRNGKey(0))
    counts = 1 + TALLIES.sum(axis=0)  # the sampling's and every environment's since
    np.testing.assert_allclose(sampling["level_counts"], counts / 2)
    np.testing.assert_allclose(sampling["level_weights"], counts[0] / counts[0].sum())
    np.testing.assert_allclose(drawn.info["level_weights"], np.broadcast_to(counts[0] / counts[0].sum(), WEIGHTS.shape))
    assert not np.any(drawn.info["level_counts"])  # tallied anew until the next re-weighing
    np.testing.assert_allclose(weight, (counts[0] / counts[0].sum()).sum(-1))
    assert share.shape == (10,) and float(share.sum()) == pytest.approx(1.0)


def test_a_fresh_batch_draws_as_its_sampling_says():
    """with_episode_sampling puts the sampling's weights into every environment of a fresh batch; its counts stay
    in the sampling, the environments' tallies at none."""
    kept = {"level_weights": WEIGHTS[0], "level_counts": TALLIES.sum(axis=0)}
    fresh = Batch({"level_weights": np.zeros_like(WEIGHTS), "level_counts": np.zeros_like(TALLIES),
                   "rng": np.zeros((4, 2), np.uint32)})
    put = with_episode_sampling(fresh, kept)
    np.testing.assert_array_equal(put.info["level_weights"], WEIGHTS)
    assert not np.any(put.info["level_counts"])
    np.testing.assert_array_equal(start_sampling(put)["level_weights"], kept["level_weights"])
