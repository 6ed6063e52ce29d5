"""Mixed-curriculum sampling: how often each variant starts an episode, from how well it is being learnt."""

from __future__ import annotations

import jax
import jax.numpy as jnp

WEIGHT_FLOOR = 0.1  # every variant keeps at least this share of the weight mass (before normalising)


def sampling_weights(success: jax.Array) -> jax.Array:
    """How often to start each variant, from its success rate p: most where p(1-p) is largest
    (the variants being learnt now), a floor for the solved and the not yet reachable."""
    score = WEIGHT_FLOOR + 4.0 * success * (1.0 - success)
    return score / jnp.sum(score)
