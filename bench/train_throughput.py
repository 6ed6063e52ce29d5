"""End-to-end training throughput (env steps per second, updates included) on built fields.

Each algorithm runs with the settings `fieldgen train` would give it on that field (its preset for
the field's agent, e.g. agents/presets/crl_ant.yaml, then --set) and fieldgen's XLA options. The
reference, measured in the same run, is the same environment stepped alone with random actions at
the same batch size (fieldgen.env.throughput): the ratio is the share of time left to simulation
once training runs beside it. Each figure times one jitted chunk of training iterations after a
warm-up call, its state spread over the devices as `fieldgen train` spreads it (agents.sharding): by
seed when `--seeds` fill the devices evenly, else by environment. The first algorithm listed is also
the others' reference: `crl/icrl 1.20` means ICRL runs 1.2 times slower per env step than CRL. With
`--devices 1,2` each row is timed on one device and then on two, and the second is also printed as a
ratio to the first. With `--profile DIR` one more chunk of each row runs under JAX's profiler: the
trace is kept in DIR, and the device's busiest kernels are printed with their share of the chunk,
how many ran and for how long the device sat idle between them (a launch-bound program idles).

    python bench/train_throughput.py --fields build/ant_nav,build/soccer_v1 --algos crl,ppo --envs 1024,4096
    python bench/train_throughput.py --fields build/soccer_v1 --algos crl,icrl,icrl:agents=joint,sac,td3 --envs 1024
    python bench/train_throughput.py --fields build/ant_nav --algos crl,ppo --envs 4096 --devices 1,2
    python bench/train_throughput.py --fields build/ant_nav --algos crl --envs 1024 --seeds 2 --devices 1,2
    python bench/train_throughput.py --fields build/ant_nav --algos crl --envs 1024 --devices 1 --profile prof
"""

from __future__ import annotations

import argparse
import collections
import time
from pathlib import Path

import jax

import fieldgen
from fieldgen import xla_flags
from fieldgen.agents import buffer, loop, programs, registry, sharding
from fieldgen.agents.config import ReplayConfig
from fieldgen.env.throughput import measure
from fieldgen.files import append_jsonl
from fieldgen.run.train import peak_memory_mb
from kernel_trace import busy_us, device_kernels, span_us, trace_events


def config_for(entry: str, env, num_envs: int, iterations: int, sets: list[str]):
    """The config `fieldgen train` would start from on `env` (defaults, the trainer's preset for its agent,
    `--set algo.key=value`, then the entry's own `algo:key=value:...`) whose chunk (the work between two
    evaluations) is `iterations` training iterations."""
    algo, *own = entry.split(":")
    sets = [s for s in sets if s.startswith(f"{algo}.")] + [f"{algo}.{item}" for item in own]
    c = registry.trainer(algo).config.layered(sets=sets, agent=env.spec.agent.kind, num_envs=num_envs, num_evals=1)
    prefill = buffer.iterations(c)[0] if isinstance(c, ReplayConfig) else 0
    return c.model_copy(update={"total_steps": (prefill + iterations) * num_envs * c.unroll_length})


def time_chunk(trainer, seeds: int, devices: int | None = None, profile: Path | None = None) -> float:
    """Seconds for one chunk of `seeds` vmapped seeds placed on the first `devices` local devices (all by
    default) as training places them, timed after two warm-up calls (the first, and the first fed its
    own output, can both compile); with `profile`, one more chunk is traced into that folder."""
    keys = loop.seed_keys(range(seeds))
    start, shapes = programs.started(trainer, keys)  # Warp's physics sized for every environment of every seed first
    placement = sharding.training_shardings(shapes, sharding.device_mesh(devices), trainer.env_axes)
    chunk = jax.jit(jax.vmap(trainer.chunk), in_shardings=(placement,), out_shardings=(placement, None))
    state = jax.block_until_ready(jax.jit(start, out_shardings=placement)(keys))
    for _ in range(2):
        state, _ = jax.block_until_ready(chunk(state))
    t0 = time.perf_counter()
    jax.block_until_ready(chunk(state))
    seconds = time.perf_counter() - t0
    if profile:
        with jax.profiler.trace(profile, create_perfetto_trace=True):
            jax.block_until_ready(chunk(state))
    return seconds


def kernel_table(profile: Path, top: int = 20) -> str:
    """The device's kernels in the newest trace under `profile`, by total time: name, calls, share of the
    time from the first kernel's start to the last one's end, and the share of that span no kernel ran."""
    kernels = device_kernels(trace_events(profile))
    if not kernels:
        return "no device kernels in the trace (a CPU backend traces host threads only)"
    total, calls = collections.Counter(), collections.Counter()
    for e in kernels:
        total[e["name"]] += e["dur"]
        calls[e["name"]] += 1
    span = span_us(kernels)
    rows = [f"{len(kernels):,} kernels in {span / 1e6:.3f} s; device idle {1 - busy_us(kernels) / span:.1%} of it"]
    rows += [f"{t / span:7.1%} {calls[name]:>8,} x {t / calls[name]:8.1f} us  {name[:100]}"
             for name, t in total.most_common(top)]
    return "\n".join(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--fields", default="build/ant_nav", help="comma-separated build folders or field names")
    parser.add_argument("--algos", default="crl,ppo", help="comma-separated, each ALGO or ALGO:KEY=VALUE:...; "
                        "the first is the others' reference")
    parser.add_argument("--envs", default="1024,4096")
    parser.add_argument("--iterations", type=int, default=4, help="training iterations per timed chunk")
    parser.add_argument("--set", action="append", default=[], metavar="ALGO.KEY=VALUE", help="config overrides")
    parser.add_argument("--devices", help="comma-separated device counts to time each row on; default: all")
    parser.add_argument("--seeds", type=int, default=1, help="seeds trained at once (vmapped); env steps count all")
    parser.add_argument("--profile", type=Path, help="trace one more chunk of each row into this folder and "
                        "print its busiest device kernels")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    xla_flags.apply()  # before JAX starts its backend, as every fieldgen command does
    counts = [int(x) for x in args.devices.split(",")] if args.devices else [sharding.device_count()]
    print(f"device: {jax.devices()[0].device_kind} x {len(jax.devices())}")
    for field in args.fields.split(","):
        env = fieldgen.make(Path(field) if Path(field).exists() else field)
        for n in [int(x) for x in args.envs.split(",")]:
            sim = measure(env, n * args.seeds, 62).steps_per_second  # as many envs as all seeds step
            algos = args.algos.split(",")
            first = {}  # the first algorithm's figure by device count
            for name in algos:
                config = config_for(name, env, n, args.iterations, args.set)
                trainer = registry.trainer(name.partition(":")[0]).make_train(config, env)
                per_iter = n * config.unroll_length
                alone = None
                for devices in counts:
                    profile = args.profile and args.profile / f"{env.spec.name}-{name}-{n}-{devices}"
                    seconds = time_chunk(trainer, args.seeds, devices, profile)
                    sps = args.seeds * args.iterations * per_iter / seconds
                    memory = peak_memory_mb()
                    first.setdefault(devices, sps)
                    alone = alone or sps
                    scaling = f"; x{devices} devices / x{counts[0]} {sps / alone:.2f}" if len(counts) > 1 else ""
                    per_seed = f" x {args.seeds} seeds" if args.seeds > 1 else ""
                    print(f"{env.spec.name:>12s} {name:>17s} {n:>6d} envs{per_seed}: {sps:>10,.0f} env steps/s "
                          f"with training; env alone {sim:>11,.0f}; ratio {sps / sim:.3f}; "
                          f"{algos[0]}/{name} {first[devices] / sps:.2f}; "
                          f"{seconds / args.iterations:.3f} s per iteration; peak memory so far "
                          f"{memory if memory is None else f'{memory:,.0f} MiB'}{scaling}", flush=True)
                    append_jsonl(args.json, {"field": env.spec.name, "algo": name, "envs": n, "seeds": args.seeds, "devices": devices,
                                             "train_steps_per_second": sps, "env_steps_per_second": sim,
                                             f"{algos[0]}_over_this": first[devices] / sps, "sets": args.set,
                                             "seconds_per_iteration": seconds / args.iterations,
                                             "peak_memory_mb": memory, "over_first_device_count": sps / alone})
                    if profile:
                        print(kernel_table(profile), flush=True)


if __name__ == "__main__":
    main()
