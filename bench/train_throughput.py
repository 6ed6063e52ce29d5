"""End-to-end CRL training throughput (env steps per second, updates included) on a built field.

The reference, measured in the same run, is the same environment stepped alone
with random actions at the same batch size (fieldgen.throughput): the ratio is
the share of time left to simulation once training runs beside it. Optionally
(--learn STEPS) trains for STEPS env steps and prints the success curve.

    python bench/train_throughput.py --field build/ant_nav --envs 1024,4096 --learn 10000000
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax

import fieldgen
from agents import crl
from fieldgen.throughput import append_jsonl, measure


def time_iterations(env, config: crl.CRLConfig, iterations: int) -> float:
    """Seconds per (collect + update epoch) iteration, after a warm-up call."""
    algo = crl.make_train(config, env)

    @jax.jit
    def run(ts):
        def body(ts, _):
            ts, metrics = algo.update_epoch(algo.collect(ts)[0])
            return ts, metrics["critic_loss"]

        return jax.lax.scan(body, ts, None, length=iterations)

    ts = jax.jit(lambda ts: jax.lax.fori_loop(0, 20, lambda _, t: algo.collect(t)[0], ts))(algo.init(jax.random.PRNGKey(0)))
    ts, _ = jax.block_until_ready(run(ts))
    t0 = time.perf_counter()
    jax.block_until_ready(run(ts))
    return (time.perf_counter() - t0) / iterations


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--field", type=Path, default=Path("build/ant_nav"))
    parser.add_argument("--envs", default="1024,4096")
    parser.add_argument("--iterations", type=int, default=5)
    parser.add_argument("--learn", type=int, default=0, help="env steps of a learning run at the first batch size")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    env = fieldgen.make(args.field)
    print(f"device: {jax.devices()[0].device_kind}; field {env.spec.name}; CRL defaults (2x256, repr 64, batch 256, "
          f"unroll 62, {env.episode_length} updates per iteration)")
    for n in [int(x) for x in args.envs.split(",")]:
        config = crl.CRLConfig(num_envs=n)
        sim = measure(env, n, config.unroll_length).steps_per_second
        seconds = time_iterations(env, config, args.iterations)
        sps = n * config.unroll_length / seconds
        print(f"{n:>6d} envs: {sps:>10,.0f} env steps/s with training; env alone {sim:>12,.0f}; "
              f"ratio {sps / sim:.3f}; {seconds:.2f} s per iteration")
        append_jsonl(args.json, {"field": env.spec.name, "envs": n, "train_steps_per_second": sps,
                            "env_steps_per_second": sim, "seconds_per_iteration": seconds})
    if args.learn:
        n = int(args.envs.split(",")[0])
        config = crl.CRLConfig(num_envs=n, total_steps=args.learn, num_evals=10, eval_envs=256)
        t0 = time.perf_counter()

        def progress(step, metrics):
            row = {"field": env.spec.name, "env_steps": step, "seconds": time.perf_counter() - t0, **metrics}
            print(json.dumps({k: round(v, 4) if isinstance(v, float) else v for k, v in row.items()}), flush=True)
            append_jsonl(args.json, row)

        crl.train(config, env, progress)



if __name__ == "__main__":
    main()
