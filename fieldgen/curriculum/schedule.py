"""How a run moves through a curriculum's variants: the answers to what the training loop asks after
each evaluation (fieldgen.curriculum.contract.Schedule), and which environments its trainers get.

A staged run trains one variant (a stage) at a time and moves on when the curriculum's promotion rule
is met; a mixed run trains every variant at once, each environment of the batch playing its own, and
re-weights how often each starts an episode from how well it is being learnt. The trainers know
neither: they ask `next_stage` and `variant_weights`, and the environment plays what it is given."""

from __future__ import annotations

import dataclasses
from typing import Sequence

import jax
import jax.numpy as jnp

from fieldgen.curriculum.contract import OneStage
from fieldgen.curriculum.promotion import Promotion

WEIGHT_FLOOR = 0.1  # every variant keeps at least this share of the weight mass (before normalising)


def sampling_weights(success: jax.Array) -> jax.Array:
    """How often to start each variant, from its success rate p: most where p(1-p) is largest
    (the variants being learnt now), a floor for the solved and the not yet reachable."""
    score = WEIGHT_FLOOR + 4.0 * success * (1.0 - success)
    return score / jnp.sum(score)


@dataclasses.dataclass(frozen=True)
class Staged:
    """One stage after another: move on once `promotion` is met on the stage being trained."""

    promotion: Promotion = Promotion()

    def next_stage(self, history: list[dict], stage: int, stages: int) -> int:
        return stage + 1 if stage < stages - 1 and self.promotion.ready(history, stage) else stage

    variant_weights = staticmethod(OneStage().variant_weights)  # one variant per stage: drawn evenly

    def stage_environments(self, specs: Sequence) -> list:
        """Each stage's environment, built as its spec alone says."""
        import fieldgen

        return [fieldgen.make(spec) for spec in specs]

    def environments(self, envs: Sequence) -> list:
        """What the trainers train on: one environment per stage, in turn."""
        return list(envs)


@dataclasses.dataclass(frozen=True)
class Mixed:
    """Every stage at once, in one batched simulation, each weighted by `sampling_weights`."""

    def next_stage(self, history: list[dict], stage: int, stages: int) -> int:
        return stage

    def variant_weights(self, success: jax.Array) -> jax.Array:
        return sampling_weights(success)

    def stage_environments(self, specs: Sequence) -> list:
        """Each stage's environment, every stage built to one structure so that one simulation batches them."""
        from fieldgen.compile.variants import compile_variants
        from fieldgen.env.brax_pipeline import check_batchable
        from fieldgen.env.make import environment

        artifacts = compile_variants(list(specs))
        check_batchable(artifacts)
        return [environment(a) for a in artifacts]

    def environments(self, envs: Sequence) -> list:
        """What the trainer trains on: one environment batching every stage's variant."""
        from fieldgen.env.make import environment

        return [environment([e.artifact for e in envs])] if len(envs) > 1 else list(envs)
