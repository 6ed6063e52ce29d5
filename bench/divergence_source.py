"""Where does a CRL run's NaN come from, the simulation or the learner?

Trains CRL one chunk at a time (the iterations between two evaluations) and after
each reports whether any environment's observation, any state held in the replay
buffer and the weights are finite, and the largest magnitude the buffer holds. It
stops after the first chunk that leaves the weights non-finite. States that blow up
before the weights do point at the simulation; weights that go first, at the learner.

    python bench/divergence_source.py --field build/ant_nav_no_ceiling --json results.jsonl
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import jax.numpy as jnp

import fieldgen
from fieldgen.agents import crl
from fieldgen.files import append_jsonl


def all_finite(tree) -> bool:
    return all(bool(jnp.all(jnp.isfinite(x))) for x in jax.tree.leaves(tree) if jnp.issubdtype(x.dtype, jnp.floating))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--field", default="build/ant_nav_no_ceiling", help="a build folder or bundled field name")
    parser.add_argument("--steps", type=int, default=10_000_000)
    parser.add_argument("--envs", type=int, default=1024)
    parser.add_argument("--windows", type=int, default=0, help="crl.windows (0: one per environment)")
    parser.add_argument("--chunks", type=int, default=20, help="chunks (crl.num_evals) the steps are cut into")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    config = crl.CRLConfig(total_steps=args.steps, num_envs=args.envs, windows=args.windows, num_evals=args.chunks)
    trainer = crl.make_train(config, fieldgen.make(args.field))
    chunk = jax.jit(trainer.chunk)
    state = jax.jit(trainer.start)(jax.random.PRNGKey(0))
    began = time.perf_counter()
    for index in range(args.chunks):
        state, metrics = chunk(state)
        held = state.buffer.data["state"]
        row = {"field": args.field, "windows": args.windows, "chunk": index, "env_steps": int(state.env_steps),
               "seconds": round(time.perf_counter() - began, 1), "weights_finite": all_finite(state.nets),
               "envs_nonfinite_obs": int(jnp.sum(~jnp.all(jnp.isfinite(state.env_state.obs), axis=1))),
               "buffer_nonfinite_rows": int(jnp.sum(~jnp.all(jnp.isfinite(held), axis=-1))),
               "buffer_max_abs": float(jnp.nanmax(jnp.abs(held))),
               **{k: float(v) for k, v in metrics.items()}}
        print(f"{row['env_steps']:>11,} steps: weights finite {row['weights_finite']}, environments with a "
              f"non-finite observation {row['envs_nonfinite_obs']}, non-finite buffer rows "
              f"{row['buffer_nonfinite_rows']}, largest |state| held {row['buffer_max_abs']:.1f}", flush=True)
        append_jsonl(args.json, row)
        if not row["weights_finite"]:
            break


if __name__ == "__main__":
    main()
