"""Adam over several parameter groups at once, as one flat vector.

A GPU runs an optimizer update per parameter leaf as its own small kernel; for
the few-hundred-wide networks of goal-conditioned RL those kernels, not the
arithmetic, set the time of a gradient step. Raveling every group into one
vector makes the whole update one kernel, with each group's learning rate kept.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import optax
from jax.flatten_util import ravel_pytree


def adam_by_group(*learning_rates) -> optax.GradientTransformation:
    """Adam over a tuple of parameter groups (one learning rate each), elementwise equal to
    `optax.adam(rate)` applied to each group on its own.

    A rate may also be an array: it then runs along the leading axes of its group's leaves, for
    groups that stack several networks on a leading axis, each with its own learning rate."""
    adam = optax.scale_by_adam()

    def init(groups):
        if len(groups) != len(learning_rates):
            raise ValueError(f"{len(groups)} parameter groups for {len(learning_rates)} learning rates")
        return adam.init(ravel_pytree(groups)[0])

    def update(grads, state, params=None):
        flat, unravel = ravel_pytree(grads)
        rates = [jax.tree.map(functools.partial(_spread, -jnp.asarray(rate, flat.dtype)), group)
                 for group, rate in zip(grads, learning_rates)]
        step, state = adam.update(flat, state)
        return unravel(step * ravel_pytree(rates)[0]), state

    return optax.GradientTransformation(init, update)


def _spread(rate: jax.Array, leaf: jax.Array) -> jax.Array:
    """A rate over a leaf's leading axes, broadcast to the whole leaf."""
    return jnp.broadcast_to(rate.reshape(rate.shape + (1,) * (leaf.ndim - rate.ndim)), leaf.shape)
