"""Energy functions and contrastive (InfoNCE) losses of contrastive RL.

`logits[i, j]` is the energy between the i-th state-action representation and
the j-th goal representation; the diagonal holds the positive pairs.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

ENERGIES = ("norm", "l2", "dot", "cosine")


def energy(kind: str, phi: jax.Array, psi: jax.Array, log_temperature: jax.Array | None = None) -> jax.Array:
    """Pairwise energies between rows of phi [B, d] and psi [B, d] -> [B, B].

    Every pair comes from one matrix product (distances as |a|^2 + |b|^2 - 2 a.b), not from the
    [B, B, d] differences: reducing those over d is the slower at the batches CRL trains with, on a GPU
    and far more on a CPU (bench/energy_matrix.py; its timings in bench/results/). The diagonal, the
    positive pairs, whose small distances that form would round away, is `paired_energy`'s own."""
    if kind not in ENERGIES:
        raise ValueError(f"unknown energy {kind!r}; choose one of {', '.join(ENERGIES)}")
    if kind == "cosine":
        phi, psi = _unit(phi), _unit(psi)
    cross = jnp.matmul(phi, psi.T, precision=jax.lax.Precision.HIGHEST)
    if kind == "dot":
        return cross
    if kind == "cosine":
        return cross / jnp.exp(log_temperature)
    squared = jnp.maximum(jnp.sum(phi ** 2, axis=-1)[:, None] + jnp.sum(psi ** 2, axis=-1)[None, :] - 2 * cross, 0.0)
    pairs = -jnp.sqrt(squared + 1e-12) if kind == "norm" else -squared
    return jnp.where(jnp.eye(len(phi), dtype=bool), paired_energy(kind, phi, psi)[:, None], pairs)


def paired_energy(kind: str, phi: jax.Array, psi: jax.Array, log_temperature: jax.Array | None = None) -> jax.Array:
    """Energy of row i of phi against row i of psi, over the last axis (broadcasting) -> [B]: the
    diagonal of `energy` without the rest of the matrix, all the actor's objective needs."""
    if kind in ("norm", "l2"):
        squared = jnp.sum((phi - psi) ** 2, axis=-1)
        return -jnp.sqrt(squared + 1e-12) if kind == "norm" else -squared
    if kind == "dot":
        return jnp.sum(phi * psi, axis=-1)
    if kind == "cosine":
        return jnp.sum(_unit(phi) * _unit(psi), axis=-1) / jnp.exp(log_temperature)
    raise ValueError(f"unknown energy {kind!r}; choose one of {', '.join(ENERGIES)}")


def _unit(x: jax.Array) -> jax.Array:
    return x / (jnp.linalg.norm(x, axis=-1, keepdims=True) + 1e-12)


def _forward(logits: jax.Array) -> jax.Array:
    return -diagonal(jax.nn.log_softmax(logits, axis=1))


def _backward(logits: jax.Array) -> jax.Array:
    return -diagonal(jax.nn.log_softmax(logits, axis=0))


# each contrastive loss by name: its value per row of the logits
PER_ROW = {"fwd_infonce": _forward, "bwd_infonce": _backward,
           "sym_infonce": lambda logits: 0.5 * (_forward(logits) + _backward(logits))}
LOSSES = tuple(PER_ROW)


def infonce(kind: str, logits: jax.Array, weight: jax.Array) -> jax.Array:
    """Cross-entropy of the diagonal: over goals (forward), over state-actions (backward), or both."""
    if kind not in PER_ROW:
        raise ValueError(f"unknown contrastive loss {kind!r}; choose one of {', '.join(LOSSES)}")
    return weighted_mean(PER_ROW[kind](logits), weight)


def diagonal(x: jax.Array) -> jax.Array:
    """The diagonal of a square matrix as a masked row sum: its gradient is then elementwise, where
    `jnp.diagonal`'s is a scatter, one more GPU kernel per gradient step."""
    return jnp.sum(x * jnp.eye(x.shape[0], dtype=x.dtype), axis=1)


def logsumexp_penalty(logits: jax.Array, weight: jax.Array) -> jax.Array:
    """Mean squared log-partition over goals: keeps the forward logits from drifting."""
    return weighted_mean(jax.nn.logsumexp(logits, axis=1) ** 2, weight)


def weighted_mean(x: jax.Array, weight: jax.Array) -> jax.Array:
    return jnp.sum(x * weight) / jnp.maximum(jnp.sum(weight), 1.0)
