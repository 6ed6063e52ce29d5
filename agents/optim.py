"""Adam over several parameter groups at once, as one flat vector.

A GPU runs an optimizer update per parameter leaf as its own small kernel; for
the few-hundred-wide networks of goal-conditioned RL those kernels, not the
arithmetic, set the time of a gradient step. Raveling every group into one
vector makes the whole update one kernel, with each group's learning rate kept.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optax
from jax.flatten_util import ravel_pytree


def adam_by_group(*learning_rates: float) -> optax.GradientTransformation:
    """Adam over a tuple of parameter groups (one learning rate each), elementwise equal to
    `optax.adam(rate)` applied to each group on its own."""
    adam = optax.scale_by_adam()

    def init(groups):
        if len(groups) != len(learning_rates):
            raise ValueError(f"{len(groups)} parameter groups for {len(learning_rates)} learning rates")
        return adam.init(ravel_pytree(groups)[0])

    def update(grads, state, params=None):
        flat, unravel = ravel_pytree(grads)
        sizes = [sum(leaf.size for leaf in jax.tree.leaves(group)) for group in grads]
        rates = jnp.concatenate([jnp.full(size, -rate, flat.dtype) for size, rate in zip(sizes, learning_rates)])
        step, state = adam.update(flat, state)
        return unravel(step * rates), state

    return optax.GradientTransformation(init, update)
