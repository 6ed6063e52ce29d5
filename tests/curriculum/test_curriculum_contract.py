"""The curriculum contract (fieldgen.curriculum.contract): what the trainers know of curricula, on its own."""

from __future__ import annotations

import numpy as np

from fieldgen.curriculum.contract import episode_sampling, with_episode_sampling


def test_how_a_batch_draws_its_episodes_is_kept_once_and_put_back_in_every_environment():
    """episode_sampling keeps the level weights once (the same in every environment) and the counts summed,
    with or without a leading seed axis; with_episode_sampling puts them back into a fresh batch."""
    from flax import struct

    @struct.dataclass
    class Batch:
        info: dict

    weights = np.tile(np.arange(6, dtype=np.float32).reshape(1, 2, 3) / 15, (4, 1, 1))  # 4 environments
    counts = np.arange(4 * 2 * 2 * 3, dtype=np.float32).reshape(4, 2, 2, 3)
    batch = Batch({"level_weights": weights, "level_counts": counts, "rng": np.zeros((4, 2), np.uint32)})
    kept = episode_sampling(batch)
    assert set(kept) == {"level_weights", "level_counts"}
    np.testing.assert_array_equal(kept["level_weights"], weights[0])
    np.testing.assert_array_equal(kept["level_counts"], counts.sum(axis=0))
    seeds = Batch({name: np.stack([x, 2 * x]) for name, x in batch.info.items()})  # two seeds stacked
    np.testing.assert_array_equal(episode_sampling(seeds)["level_counts"][1], 2 * counts.sum(axis=0))
    fresh = Batch({"level_weights": np.zeros_like(weights), "level_counts": np.zeros_like(counts),
                   "rng": batch.info["rng"]})
    put = with_episode_sampling(fresh, kept)
    np.testing.assert_array_equal(put.info["level_weights"], weights)
    np.testing.assert_array_equal(np.asarray(put.info["level_counts"]).sum(axis=0), counts.sum(axis=0))
    assert episode_sampling(Batch({"rng": batch.info["rng"]})) == {}  # one variant: nothing to keep
