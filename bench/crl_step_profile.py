"""What one CRL gradient step and one training iteration run on the device: kernels, device time, the
busiest kernels and how many are short enough to be bound by their launch.

CRL runs with the settings `fieldgen train` gives it on the field (its preset for the field's agent,
agents/presets/crl_ant.yaml on an ant field, then --set), called as training calls it: the trainer's
chunk (here one training iteration: collect, then an epoch of gradient steps), jitted and vmapped over
one seed. After two warm-up calls, --traced iterations run under JAX's profiler and the trace's kernels
are summarised per iteration. The gradient step is no function of its own: a second trainer samples
twice the windows (`crl.windows`), and the one loop of the compiled chunk whose trip count changed with
them is the loop of gradient steps; its body's kernels (matched by the HLO instruction each traced
kernel names), divided by the steps the body runs, are one gradient step. Where the trace names no
such instruction, the difference between the two trainers' traces, divided by their difference in
gradient steps, stands in for it (hindsight sampling included), and the script says so. Each figure
comes with a reference from the same run: kernel time as a share of the traced wall time, the gradient
steps' share of the iteration's kernel time, small kernels' share of the kernel time. The compiled
chunk's fusion count is read from `jit(chunk).lower(state).compile().as_text()`.

    python bench/crl_step_profile.py --field build/ant_nav --envs 1024 --profile prof
    python bench/crl_step_profile.py --field build/ant_nav --envs 4096 --windows 64 --set crl.batch_size=256

--windows caps the windows of the two trainers compared, so that their traces hold fewer gradient steps
than the iteration's (the ant preset samples two windows per environment). On a CPU the summary reads
the host operations XLA's CPU runtime ran in place of device kernels, and says so.
"""

from __future__ import annotations

import argparse
import collections
import re
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import jax

import fieldgen
from fieldgen import xla_flags
from fieldgen.agents import buffer, loop, registry
from fieldgen.agents.config import ConfigError
from fieldgen.files import append_jsonl
from fieldgen.schema import SpecError
from kernel_trace import busy_us, device_kernels, host_ops, trace_events
from train_throughput import config_for


def kind_of(kernel: str) -> str:
    """A kernel's name without its instance number: the same kind of kernel in two compiled programs, whose
    instances are numbered apart (loop_multiply_fusion_12 and _15 are both loop_multiply_fusion)."""
    return re.sub(r"([._]\d+)+$", "", kernel)


def summary(kernels: list[dict], iterations: int, small_us: float) -> dict:
    """Per iteration: kernels, kernel time (sum of durations, us), busy time (us), small kernels (shorter than
    `small_us`) and their time, and kernel time by name and by kind."""
    by_name, by_kind = collections.Counter(), collections.Counter()
    for e in kernels:
        by_name[e["name"]] += e["dur"] / iterations
        by_kind[kind_of(e["name"])] += e["dur"] / iterations
    small = [e for e in kernels if e["dur"] < small_us]
    return {"kernels": len(kernels) / iterations, "kernel_us": sum(e["dur"] for e in kernels) / iterations,
            "busy_us": busy_us(kernels) / iterations if kernels else 0.0,
            "small_kernels": len(small) / iterations, "small_kernel_us": sum(e["dur"] for e in small) / iterations,
            "by_name": by_name, "by_kind": by_kind}


def per_step(fewer: dict, more: dict, extra_steps: int) -> dict:
    """One gradient step's share of two iterations' summaries that differ by `extra_steps` gradient steps."""
    step = {key: (more[key] - fewer[key]) / extra_steps
            for key in ("kernels", "kernel_us", "busy_us", "small_kernels", "small_kernel_us")}
    step["by_kind"] = collections.Counter({kind: (more["by_kind"][kind] - fewer["by_kind"][kind]) / extra_steps
                                           for kind in more["by_kind"]})
    return step


def top_rows(by_time: collections.Counter, total_us: float, top: int) -> list[dict]:
    """The `top` names by time (those that took any), with their time and share of `total_us`."""
    return [{"name": name, "us": us, "share": us / total_us if total_us > 0 else float("nan")}
            for name, us in by_time.most_common(top) if us > 0]


def fusion_count(hlo_text: str) -> int:
    """Fusion instructions in a compiled HLO module's text (each one a kernel, or a call, where it runs)."""
    return len(re.findall(r"\sfusion\(", hlo_text))


COMPUTATION = re.compile(r"^(?:ENTRY )?%([\w.\-]+) \(")
INSTRUCTION = re.compile(r"^\s+(?:ROOT )?%([\w.\-]+) = ")
CALLED = re.compile(r"(?:condition|body|to_apply|calls|branch_computations)=\{?([^,}]+(?:, %[^,}]+)*)")
TRIP_COUNT = re.compile(r'"known_trip_count":\{"n":"(\d+)"\}')


def hlo_loops(hlo_text: str) -> list[tuple[int, set[str]]]:
    """(known trip count, names of every instruction its body runs, nested computations included) of each
    while loop of a compiled HLO module whose trip count XLA knows."""
    instructions, calls, loops, current = {}, {}, [], None
    for line in hlo_text.splitlines():
        if (start := COMPUTATION.match(line)):
            current = start.group(1)
            instructions[current], calls[current] = set(), set()
        elif current and (instruction := INSTRUCTION.match(line)):
            instructions[current].add(instruction.group(1))
            for group in CALLED.findall(line):
                calls[current].update(name.strip().lstrip("%") for name in group.split(","))
            trips, body = TRIP_COUNT.search(line), re.search(r"body=%([\w.\-]+)", line)
            if " while(" in line and trips and body:
                loops.append((int(trips.group(1)), body.group(1)))

    def under(computation: str, seen: set[str]) -> set[str]:
        if computation in seen or computation not in instructions:
            return set()
        seen.add(computation)
        return instructions[computation].union(*(under(c, seen) for c in calls[computation]))

    return [(trips, under(body, set())) for trips, body in loops]


def unroll(trips: int, steps: int) -> int | None:
    """How many steps each iteration of a loop of `trips` iterations runs if it runs `steps` steps, the
    remainder (fewer than that) outside it; None if it cannot."""
    each = steps // trips if trips else 0
    return each if each >= 1 and steps - each * trips < each else None


def update_loop(loops: list, other_loops: list, steps: int, other_steps: int) -> tuple[set[str], int] | None:
    """(the instructions of the loop of gradient steps, gradient steps its body runs per iteration) of a compiled
    chunk, told from the other loops by a second chunk that differs only in its gradient steps per iteration:
    the one loop of its trip count that runs `steps` as the other chunk runs `other_steps` in a loop of
    another trip count, unrolled alike; None where not exactly one loop does."""
    trips = collections.Counter(t for t, _ in loops)
    others = {t for t, _ in other_loops}
    found = [t for t in trips if trips[t] == 1 and unroll(t, steps)
             and any(o != t and unroll(o, other_steps) == unroll(t, steps) for o in others)]
    if len(found) != 1:
        return None
    body = next(names for t, names in loops if t == found[0])
    return body, found[0] * unroll(found[0], steps)


@dataclass
class Profile:
    """Traced training iterations of one trainer, and its compiled chunk."""

    gradient_steps: int  # per iteration
    iterations: int  # traced
    wall_seconds: float  # per iteration, untraced
    traced_wall_seconds: float  # per iteration, under the profiler
    kernels: list  # trace events
    kind: str  # what the events are: device kernels, or a CPU's host operations
    fusions: int
    flops: float | None
    bytes_accessed: float | None
    loops: list  # (trip count, instruction names) of the compiled chunk's loops (hlo_loops)


def profile_trainer(name: str, trainer, iterations: int, folder: Path) -> Profile:
    """One seed's chunk run as training runs it (jitted, vmapped over seeds): compiled, warmed up, one call
    timed, then `iterations` calls traced into folder/name."""
    keys = loop.seed_keys(range(1))
    state = jax.block_until_ready(jax.jit(jax.vmap(trainer.start))(keys))
    chunk = jax.jit(jax.vmap(trainer.chunk))
    compiled = chunk.lower(state).compile()
    cost = compiled.cost_analysis()
    cost = (cost[0] if isinstance(cost, (list, tuple)) else cost) or {}
    for _ in range(2):
        state, _ = jax.block_until_ready(compiled(state))
    t0 = time.perf_counter()
    state, _ = jax.block_until_ready(compiled(state))
    wall = time.perf_counter() - t0
    with jax.profiler.trace(folder / name, create_perfetto_trace=True):
        t0 = time.perf_counter()
        for _ in range(iterations):
            state, _ = jax.block_until_ready(compiled(state))
        traced = (time.perf_counter() - t0) / iterations
    events = trace_events(folder / name)
    kernels, kind = device_kernels(events), "device kernels"
    if not kernels:
        kernels, kind = host_ops(events), "CPU host operations (no device kernels in the trace)"
    _, updates = buffer.gradient_steps(trainer.config, trainer.env.episode_length)
    text = compiled.as_text()
    return Profile(updates, iterations, wall, traced, kernels, kind, fusion_count(text), cost.get("flops"),
                   cost.get("bytes accessed"), hlo_loops(text))


def report(what: str, figures: dict, rows: list[dict], reference: str, ratio: float) -> list[str]:
    """The printed lines of one summary."""
    share = figures["small_kernel_us"] / figures["kernel_us"] if figures["kernel_us"] > 0 else float("nan")
    lines = [f"{what}: {figures['kernels']:,.1f} kernels, {figures['kernel_us']:,.1f} us of kernel time "
             f"({figures['busy_us']:,.1f} us busy); {reference} {ratio:.3f}; {figures['small_kernels']:,.1f} "
             f"small kernels, {share:.1%} of the kernel time"]
    return lines + [f"  {row['share']:7.1%} {row['us']:10.1f} us  {row['name'][:100]}" for row in rows]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--field", default="build/ant_nav", help="a build folder or field name")
    parser.add_argument("--envs", type=int, default=1024)
    parser.add_argument("--windows", type=int, default=256, help="windows of the two trainers compared for the "
                        "gradient step, at most the iteration's own; the second samples twice as many")
    parser.add_argument("--traced", type=int, default=1, help="iterations traced after the warm-up")
    parser.add_argument("--small-us", type=float, default=5.0, help="a kernel shorter than this (µs) is small")
    parser.add_argument("--top", type=int, default=10, help="kernels listed by time")
    parser.add_argument("--set", action="append", default=[], metavar="crl.KEY=VALUE", help="config overrides")
    parser.add_argument("--profile", type=Path, help="keep the traces in this folder (default: a temporary one)")
    parser.add_argument("--json", type=Path, help="append the two summaries here, one JSON object per line")
    args = parser.parse_args()
    if min(args.envs, args.traced, args.top, args.windows) < 1:
        parser.error("--envs, --traced, --top and --windows are positive")
    xla_flags.apply()  # before JAX starts its backend, as every fieldgen command does
    crl = registry.trainer("crl")
    try:
        env = fieldgen.make(Path(args.field) if Path(args.field).exists() else args.field)
        iteration_config = config_for("crl", env, args.envs, 1, args.set)
        own_windows = buffer.gradient_steps(iteration_config, env.episode_length)[0]
        windows = min(args.windows, own_windows)
        pair_configs = {w: config_for(f"crl:windows={w}", env, args.envs, 1, args.set)
                        for w in (windows, 2 * windows)}
        for config in (iteration_config, *pair_configs.values()):
            config.validate_env(env)  # as training checks its settings against the field
    except (SpecError, ConfigError) as error:
        raise SystemExit(f"error: {error}") from None
    preset = crl.config.preset(env.spec.agent.kind)
    print(f"backend: {jax.default_backend()} ({jax.devices()[0].device_kind}); CRL on {env.name}, {args.envs} envs, "
          f"preset {preset or 'none'}, {args.traced} traced iterations")

    fewer, more = (buffer.gradient_steps(c, env.episode_length)[1] for c in pair_configs.values())
    if more <= fewer:
        raise SystemExit(f"{windows} and {2 * windows} windows of {env.episode_length} steps make as many gradient "
                         f"steps; raise --windows")

    with tempfile.TemporaryDirectory() as scratch:
        folder = args.profile or Path(scratch)
        iteration = profile_trainer("iteration", crl.make_train(iteration_config, env), args.traced, folder)
        pair = [iteration if w == own_windows else
                profile_trainer(f"windows_{w}", crl.make_train(config, env), args.traced, folder)
                for w, config in pair_configs.items()]
    print(f"profiled: {iteration.kind}; compiled chunk: {iteration.fusions} fusions, "
          f"{iteration.flops or 0:,.0f} flops, {iteration.bytes_accessed or 0:,.0f} bytes accessed")
    whole = summary(iteration.kernels, iteration.iterations, args.small_us)
    whole_rows = top_rows(whole["by_name"], whole["kernel_us"], args.top)
    found = update_loop(pair[0].loops, pair[1].loops, fewer, more)
    in_loop = [e for e in pair[0].kernels if found and e.get("args", {}).get("hlo_op") in found[0]]
    if in_loop:
        method = f"the kernels of the compiled loop of gradient steps, {found[1]} steps of {fewer} per iteration"
        step = summary(in_loop, pair[0].iterations * found[1], args.small_us)
        step_rows = top_rows(step["by_name"], step["kernel_us"], args.top)
    else:
        method = (f"the difference of {fewer} and {more} per iteration, hindsight sampling included, kernels by "
                  f"kind (no traced kernel names an instruction of a loop whose trip count changed with them)")
        step = per_step(*(summary(p.kernels, p.iterations, args.small_us) for p in pair), more - fewer)
        step_rows = top_rows(step["by_kind"], step["kernel_us"], args.top)
    busy_share = whole["busy_us"] / 1e6 / iteration.traced_wall_seconds
    steps_share = iteration.gradient_steps * step["kernel_us"] / whole["kernel_us"] if whole["kernel_us"] > 0 else 0.0
    print("\n".join(report(f"one iteration ({iteration.gradient_steps} gradient steps; "
                           f"{iteration.wall_seconds * 1e3:,.1f} ms wall, {iteration.traced_wall_seconds * 1e3:,.1f} "
                           f"ms traced)", whole, whole_rows, "busy share of the traced wall time", busy_share)))
    print("\n".join(report(f"one gradient step (from {method})", step, step_rows,
                           "gradient steps' share of the iteration's kernel time", steps_share)))
    if step["kernel_us"] <= 0:
        print("the gradient steps' difference is below the traces' noise: trace more iterations or raise --windows")
    common = {"field": env.name, "envs": args.envs, "backend": jax.default_backend(), "profiled": iteration.kind,
              "small_below_us": args.small_us, "sets": args.set}
    figures = ("kernels", "kernel_us", "busy_us", "small_kernels", "small_kernel_us")
    append_jsonl(args.json, {**common, "part": "iteration", "gradient_steps": iteration.gradient_steps,
                             "wall_seconds": iteration.wall_seconds,
                             "traced_wall_seconds": iteration.traced_wall_seconds,
                             "busy_share_of_traced_wall": busy_share, "fusions": iteration.fusions,
                             "flops": iteration.flops, "bytes_accessed": iteration.bytes_accessed,
                             **{k: whole[k] for k in figures}, "top": whole_rows})
    append_jsonl(args.json, {**common, "part": "gradient_step", "windows": [windows, 2 * windows],
                             "gradient_steps": [fewer, more], "method": method,
                             "share_of_iteration": steps_share, **{k: step[k] for k in figures}, "top": step_rows})


if __name__ == "__main__":
    main()
