"""End-to-end training throughput (env steps per second, updates included) on built fields.

The reference, measured in the same run, is the same environment stepped alone
with random actions at the same batch size (fieldgen.throughput): the ratio is
the share of time left to simulation once training runs beside it. Each figure
times one jitted chunk of training iterations after a warm-up call.

    python bench/train_throughput.py --fields build/ant_nav,build/soccer_v1 --algos crl,ppo --envs 1024,4096
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import jax

import fieldgen
from agents import crl, ppo
from fieldgen.throughput import append_jsonl, measure
from fieldgen.training import peak_memory_mb


def config_for(algo: str, num_envs: int, iterations: int):
    """A config whose chunk (the work between two evaluations) is `iterations` training iterations."""
    if algo == "crl":
        c = crl.CRLConfig(num_envs=num_envs, num_evals=1)
        prefill, _ = crl.iterations(c)
        return dataclasses.replace(c, total_steps=(prefill + iterations) * num_envs * c.unroll_length)
    c = ppo.PPOConfig(num_envs=num_envs, num_evals=1)
    return dataclasses.replace(c, total_steps=iterations * num_envs * c.unroll_length)


def time_chunk(algo, key) -> float:
    """Seconds for one chunk, timed after two warm-up calls (the first, and the first fed its own output,
    can both compile)."""
    chunk = jax.jit(algo.chunk)
    state = jax.block_until_ready(jax.jit(algo.start)(key))
    for _ in range(2):
        state, _ = jax.block_until_ready(chunk(state))
    t0 = time.perf_counter()
    jax.block_until_ready(chunk(state))
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--fields", default="build/ant_nav", help="comma-separated build folders or field names")
    parser.add_argument("--algos", default="crl,ppo")
    parser.add_argument("--envs", default="1024,4096")
    parser.add_argument("--iterations", type=int, default=4, help="training iterations per timed chunk")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    print(f"device: {jax.devices()[0].device_kind} x {len(jax.devices())}")
    for field in args.fields.split(","):
        env = fieldgen.make(Path(field) if Path(field).exists() else field)
        for n in [int(x) for x in args.envs.split(",")]:
            sim = measure(env, n, 62).steps_per_second
            for name in args.algos.split(","):
                config = config_for(name, n, args.iterations)
                algo = {"crl": crl, "ppo": ppo}[name].make_train(config, env)
                per_iter = n * config.unroll_length
                seconds = time_chunk(algo, jax.random.PRNGKey(0))
                sps = args.iterations * per_iter / seconds
                memory = peak_memory_mb()
                print(f"{env.spec.name:>12s} {name:>4s} {n:>6d} envs: {sps:>10,.0f} env steps/s with training; "
                      f"env alone {sim:>11,.0f}; ratio {sps / sim:.3f}; "
                      f"{seconds / args.iterations:.3f} s per iteration; peak memory so far "
                      f"{memory if memory is None else f'{memory:,.0f} MiB'}", flush=True)
                append_jsonl(args.json, {"field": env.spec.name, "algo": name, "envs": n,
                                         "train_steps_per_second": sps, "env_steps_per_second": sim,
                                         "seconds_per_iteration": seconds / args.iterations,
                                         "peak_memory_mb": memory})


if __name__ == "__main__":
    main()
