"""Energy functions and contrastive (InfoNCE) losses of contrastive RL.

`logits[i, j]` is the energy between the i-th state-action representation and
the j-th goal representation; the diagonal holds the positive pairs.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

ENERGIES = ("norm", "l2", "dot", "cosine")


def energy(kind: str, phi: jax.Array, psi: jax.Array, log_temperature: jax.Array | None = None,
           positives: jax.Array | None = None) -> jax.Array:
    """Pairwise energies between rows of phi [B, d] and psi [B, d] -> [B, B].

    Every pair comes from one matrix product (distances as |a|^2 + |b|^2 - 2 a.b), not from the
    [B, B, d] differences: reducing those over d is the slower at the batches CRL trains with, on a GPU
    and far more on a CPU (bench/energy_matrix.py; its timings in bench/results/). The diagonal, the
    positive pairs, whose small distances that form would round away, is `paired_energy`'s own, for every
    energy, so that the positive pairs `critic_terms` is given are the matrix's diagonal to the bit; a caller that
    has them already (`paired_energy` of the same rows) passes them as `positives`."""
    if kind not in ENERGIES:
        raise ValueError(f"unknown energy {kind!r}; choose one of {', '.join(ENERGIES)}")
    if positives is None:
        positives = paired_energy(kind, phi, psi, log_temperature)
    if kind == "cosine":
        phi, psi = _unit(phi), _unit(psi)
    cross = jnp.matmul(phi, psi.T, precision=jax.lax.Precision.HIGHEST)
    if kind == "dot":
        pairs = cross
    elif kind == "cosine":
        pairs = cross / jnp.exp(log_temperature)
    else:
        squared = jnp.maximum(jnp.sum(phi ** 2, axis=-1)[:, None] + jnp.sum(psi ** 2, axis=-1)[None, :] - 2 * cross,
                              0.0)
        pairs = -jnp.sqrt(squared + 1e-12) if kind == "norm" else -squared
    return jnp.where(jnp.eye(len(phi), dtype=bool), positives[:, None], pairs)


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


LOSSES = ("fwd_infonce", "bwd_infonce", "sym_infonce")  # over goals, over state-actions, the mean of both


def critic_terms(kind: str, logits: jax.Array, positives: jax.Array,
                 weight: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """(InfoNCE of the positive pairs, the logsumexp penalty, the accuracy), weighted means over the rows.

    The loss is the cross-entropy of each positive pair (`kind`: among its row's goals, among its column's
    state-actions, or the mean of both); the penalty, the squared log-partition over goals, keeps the logits
    from drifting; the accuracy is the share of rows whose positive pair is their most likely goal. All three
    come from one maximum and one log-partition per axis the loss needs, and the positive pairs' energies
    (`positives`, the matrix's diagonal as `energy` writes it) come as computed, not read back off the matrix:
    each reduction over the [B, B] matrix is a GPU kernel of its own at every gradient step."""
    if kind not in LOSSES:
        raise ValueError(f"unknown contrastive loss {kind!r}; choose one of {', '.join(LOSSES)}")
    row_max = jnp.max(logits, axis=1)
    over_goals = _log_partition(logits, row_max, axis=1)
    if kind == "fwd_infonce":
        per_row = over_goals - positives
    else:
        over_pairs = _log_partition(logits, jnp.max(logits, axis=0), axis=0)
        per_row = over_pairs - positives if kind == "bwd_infonce" else 0.5 * (over_goals + over_pairs) - positives
    accuracy = (positives >= row_max).astype(logits.dtype)
    return weighted_mean(per_row, weight), weighted_mean(over_goals ** 2, weight), weighted_mean(accuracy, weight)


def _log_partition(logits: jax.Array, peak: jax.Array, axis: int) -> jax.Array:
    """logsumexp along `axis`, shifted by its maximum `peak` (held constant: the gradient is the softmax)."""
    peak = jax.lax.stop_gradient(peak)
    return peak + jnp.log(jnp.sum(jnp.exp(logits - jnp.expand_dims(peak, axis)), axis=axis))


def weighted_mean(x: jax.Array, weight: jax.Array) -> jax.Array:
    return jnp.sum(x * weight) / jnp.maximum(jnp.sum(weight), 1.0)
