"""How far MJX's Warp and JAX implementations part, environment by environment, and how much of it the
solver's iteration limit explains.

From the same fresh episodes and the same random actions, each implementation steps the field at each
solver iteration limit in --iterations; for every pair (Warp against JAX at one limit, and each
implementation against itself at the first and last limit) it prints, after each count of control steps in
--steps, the median, 90th percentile and largest over environments of the largest |qpos difference| in an
environment. Where Warp and JAX agree at a converged limit and part at the field's own, the parting is the
unconverged solve, not different physics. Warp starts its solve where MuJoCo does (fieldgen.env.warp_start);
--warp-start warp measures its own start instead, and --no-warm-start starts both from the unconstrained
acceleration.

    python bench/warp_agreement.py --fields ant_nav --envs 32 --iterations 1,8 --steps 1,3,10 --warp-on-cpu
"""

from __future__ import annotations

import argparse
from pathlib import Path

import jax
import numpy as np

import mujoco

from fieldgen.env.mjx_physics import capacities
from fieldgen.files import append_jsonl
from warp_vs_jax import (DEFAULT_FIELDS, Implementation, add_warp_start, load_field, physics_model, use_warp_start,
                         warp_unavailable)


def final_qpos(env, model, impl: str, reset, n: int, steps: int) -> np.ndarray:
    """Each environment's qpos after `steps` control steps of the bench's random actions (key 2)."""
    contacts, rows = capacities(model)
    run = Implementation(env, model, impl, None, contacts, rows)
    return np.asarray(run.rollout(n, steps)(run.start(reset, n), jax.random.PRNGKey(2))[0].qpos)


def started(model, cold: bool):
    """The model, its solves started from the unconstrained acceleration where `cold`."""
    if cold:
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_WARMSTART
    return model


def spread(a: np.ndarray, b: np.ndarray) -> dict[str, float]:
    """Median, 90th percentile and largest, over environments, of each environment's largest qpos gap."""
    gap = np.max(np.abs(a - b), axis=1)
    return {"median": float(np.median(gap)), "p90": float(np.quantile(gap, 0.9)), "max": float(gap.max())}


def integers(text: str, flag: str, parser) -> list[int]:
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        parser.error(f"{flag} {text!r}: write comma-separated whole numbers, e.g. 1,8")
    if min(values) < 1:
        parser.error(f"{flag} {text!r}: each number is at least 1")
    return values


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--build", type=Path, default=Path("build"), help="folder of built fields")
    parser.add_argument("--fields", default=DEFAULT_FIELDS, help="comma-separated field names or spec files")
    parser.add_argument("--envs", type=int, default=32)
    parser.add_argument("--iterations", default="1,8", help="solver iteration limits, the first compared with "
                        "the last")
    parser.add_argument("--steps", default="1,3,10", help="control steps after which positions are compared")
    parser.add_argument("--warp-on-cpu", action="store_true", help="Warp's CPU kernels where no CUDA device is")
    add_warp_start(parser)
    parser.add_argument("--no-warm-start", action="store_true", help="start both solves from the unconstrained "
                        "acceleration (MuJoCo's disable flag warmstart)")
    parser.add_argument("--json", type=Path, help="append results here, one JSON object per line")
    args = parser.parse_args()
    limits = integers(args.iterations, "--iterations", parser)
    counts = integers(args.steps, "--steps", parser)
    if args.envs < 1:
        parser.error("--envs is at least 1")
    why_not = warp_unavailable(args.warp_on_cpu)
    if why_not:
        raise SystemExit(f"error: Warp cannot run here: {why_not}")
    use_warp_start(args.warp_start)
    start = ("the unconstrained acceleration (warm start off)" if args.no_warm_start
             else {"mujoco": "MuJoCo's choice", "warp": "Warp's own start"}[args.warp_start])
    print(f"device: {jax.devices()[0].device_kind} ({jax.default_backend()}), {args.envs} envs, Warp's solve from "
          f"{start}; per-env largest |qpos gap|: median / 90% / largest")
    for name in args.fields.split(","):
        env = load_field(args.build, name)
        reset = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), args.envs))
        qpos = {(limit, impl, steps): final_qpos(env, started(physics_model(env, limit, None), args.no_warm_start),
                                                 impl, reset, args.envs, steps)
                for limit in limits for impl in ("jax", "warp") for steps in counts}
        pairs = [(f"warp vs jax, {limit} iterations", (limit, "warp"), (limit, "jax")) for limit in limits]
        if len(limits) > 1:
            pairs += [(f"{impl}, {limits[0]} vs {limits[-1]} iterations", (limits[0], impl), (limits[-1], impl))
                      for impl in ("jax", "warp")]
        for steps in counts:
            for label, a, b in pairs:
                s = spread(qpos[a + (steps,)], qpos[b + (steps,)])
                print(f"{env.name:>16s} {steps:>3d} steps  {label:<30s} {s['median']:.2e} / {s['p90']:.2e} / "
                      f"{s['max']:.2e}", flush=True)
                append_jsonl(args.json, {"field": env.name, "envs": args.envs, "steps": steps, "pair": label,
                                         "warp_start": "none" if args.no_warm_start else args.warp_start,
                                         **s, "backend": jax.default_backend()})


if __name__ == "__main__":
    main()
