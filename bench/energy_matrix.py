"""CRL's energy matrix and its gradient: one matrix product (fieldgen's `energy`) against the [B, B, d]
differences reduced over d (how the matrix was formed before, and how the reference implementation forms it).

Each form is timed as CRL uses it: the forward InfoNCE (the diagonal against each row's log-sum-exp)
and its gradient with respect to both encoders' outputs, jitted, best of --repeats after a warm-up.
The first form is the reference; the last columns give the product's speed as a ratio to it and the
largest difference between the two matrices.

    python bench/energy_matrix.py --batch 256,1024,2048 --kinds norm,l2
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from fieldgen.agents.contrastive import energy, paired_energy
from fieldgen.files import append_jsonl


def differences(kind: str, phi: jax.Array, psi: jax.Array) -> jax.Array:
    """Every pair's energy from the [B, B, d] differences."""
    return paired_energy(kind, phi[:, None, :], psi[None, :, :], jnp.log(1.0))


def seconds(form, kind: str, phi: jax.Array, psi: jax.Array, repeats: int) -> float:
    """Best wall time of the InfoNCE loss's value and gradient with `form`'s matrix."""
    def loss(phi, psi):
        logits = form(kind, phi, psi)
        return jnp.mean(jax.nn.logsumexp(logits, axis=1) - jnp.diagonal(logits))

    step = jax.jit(jax.value_and_grad(loss, argnums=(0, 1)))
    jax.block_until_ready(step(phi, psi))
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(step(phi, psi))
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--batch", default="256,1024,2048", help="comma-separated batch sizes")
    parser.add_argument("--dim", type=int, default=64, help="representation size (crl.repr_dim)")
    parser.add_argument("--kinds", default="norm", help="comma-separated energies")
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    print(f"device: {jax.devices()[0].device_kind}")
    rng = np.random.default_rng(0)
    for kind in args.kinds.split(","):
        for b in [int(x) for x in args.batch.split(",")]:
            phi = jnp.asarray(rng.normal(0, 1, (b, args.dim)), jnp.float32)
            psi = jnp.asarray(rng.normal(0, 1, (b, args.dim)), jnp.float32)
            before = seconds(differences, kind, phi, psi, args.repeats)
            product = seconds(energy, kind, phi, psi, args.repeats)
            gap = float(jnp.max(jnp.abs(energy(kind, phi, psi) - differences(kind, phi, psi))))
            print(f"{kind:>6s} batch {b:>5d}: differences {before * 1e6:9.1f} us, product {product * 1e6:9.1f} us, "
                  f"{before / product:5.2f}x; largest difference {gap:.2e}", flush=True)
            append_jsonl(args.json, {"kind": kind, "batch": b, "dim": args.dim, "differences_seconds": before,
                                     "product_seconds": product, "speedup": before / product, "largest_difference": gap})


if __name__ == "__main__":
    main()
