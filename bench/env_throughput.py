"""Env-steps per second of built fields beside brax's own `ant` (mjx), measured in the same run.

Each field steps for --steps steps in a lax.scan at every batch size, timed
after two warm-up calls (best of three). The ratio column divides by brax ant
at the same batch size. Also reports contacts per step and the JIT compile time
of reset + step.

    fieldgen build soccer_v2 soccer_v2_seed            # here, with dm_control
    python bench/env_throughput.py --fields soccer_v2,soccer_v2_seed --envs 1024,8192

--backends runs each field on each physics pipeline named (sim.backend; each
with its own default physics step). A field runs on another backend than the one
it was built for from BUILD/<name>-<backend>/, which --prepare writes here, with
dm_control, for a machine without it:

    python bench/env_throughput.py --fields ant_nav,soccer_v2 --backends mjx,spring,positional,generalized --prepare
    python bench/env_throughput.py --fields ant_nav,soccer_v2 --backends mjx,spring,positional,generalized

A team field (soccer_1v1, soccer_2v2) steps every agent of each match with random
actions [envs, agents, action_size]: its env steps are match steps, and its rows
also count agent steps (match steps x agents). --dm-control-soccer steps
dm_control's own soccer with ants, K a side, for each K named, on the CPU one
match at a time (it is not batched), in the same rows. Every row gives its
control step (control_dt) and the simulated seconds per wall second, the fair
comparison between environments whose control steps last differently long:

    fieldgen build soccer_v2 soccer_1v1 soccer_2v2
    python bench/env_throughput.py --fields soccer_v2,soccer_1v1,soccer_2v2 --envs 1,16,64 --dm-control-soccer 1,2
"""

from __future__ import annotations

import argparse
import contextlib
import io
import time
from pathlib import Path

import jax
import numpy as np

import fieldgen
from fieldgen.compile.artifact import compile_spec, load_artifact, write_artifact
from fieldgen.env.throughput import Throughput, action_shape, measure
from fieldgen.files import append_jsonl
from fieldgen.schema import load_spec, resolve_spec_path


def brax_ant():
    with contextlib.redirect_stdout(io.StringIO()):
        from brax import envs
    return envs.get_environment("ant", backend="mjx")


def contacts_per_step(env) -> int:
    with contextlib.redirect_stdout(io.StringIO()):
        from mujoco import mjx
    return int(mjx.make_data(env.mj_model)._impl.contact.dist.shape[0])


def backend_folder(build: Path, name: str, backend: str | None) -> Path:
    """Where the field built for `backend` lies: its own build folder, or <name>-<backend> beside it."""
    own = build / name
    if backend is None or (own.is_dir() and load_artifact(own).spec.sim.backend == backend):
        return own
    return build / f"{name}-{backend}"


def prepare(build: Path, name: str, backend: str | None) -> None:
    """Build the bundled field for `backend` (needs dm_control; the pipeline's own physics step where
    the spec leaves it out) where the run will look for it."""
    folder = backend_folder(build, name, backend)
    if not folder.is_dir():
        write_artifact(compile_spec(load_spec(resolve_spec_path(name), backend)), folder)
        print(f"built {folder}")


def field_env(build: Path, name: str, backend: str | None):
    """The field built for `backend`, or its bundled spec built now when no folder holds it."""
    folder = backend_folder(build, name, backend)
    return fieldgen.make(folder) if folder.is_dir() else fieldgen.make(name, backend=backend)


def compile_seconds(env, n_envs: int) -> float:
    """Wall time of the first reset + step call at this batch size (compilation dominates)."""
    keys = jax.random.split(jax.random.PRNGKey(0), n_envs)
    if hasattr(env, "reserve_worlds"):  # Warp's capacities, for the batch
        env.reserve_worlds(n_envs)
    t0 = time.perf_counter()
    state = jax.jit(jax.vmap(env.reset))(keys)
    action = jax.numpy.zeros((n_envs, *action_shape(env)))
    jax.block_until_ready(jax.jit(jax.vmap(env.step))(state, action))
    return time.perf_counter() - t0


def throughput_row(field: str, result: Throughput, control_dt: float, **details) -> dict:
    """A result row: env (match) steps/s, agent steps/s, and simulated seconds per wall second, which compares
    environments whose control steps last differently long."""
    return {"field": field, **details, "envs": result.n_envs, "steps_per_second": result.steps_per_second,
            "agents": result.agents, "agent_steps_per_second": result.agent_steps_per_second,
            "control_dt": control_dt, "simulated_seconds_per_second": result.steps_per_second * control_dt}


def dm_control_soccer(team_size: int, seed: int = 0):
    """dm_control's own soccer with ants, `team_size` a side, as `soccer.load` makes it (its control step and
    45 s matches that end at a goal)."""
    from dm_control.locomotion import soccer

    return soccer.load(team_size=team_size, walker_type=soccer.WalkerType.ANT, random_state=seed)


def measure_dm_control(env, steps: int, repeats: int = 3, seed: int = 0) -> Throughput:
    """One dm_control match stepped `steps` times with random actions within each action spec's bounds, best of
    `repeats` after a warm-up rollout. A match that ends restarts inside the timing, as a field's env does."""
    rng = np.random.default_rng(seed)
    specs = env.action_spec()
    env.reset()
    best = float("inf")
    for rollout in range(repeats + 1):  # rollout 0 warms up
        actions = [rng.uniform(spec.minimum, spec.maximum, (steps, *spec.shape)) for spec in specs]
        t0 = time.perf_counter()
        for t in range(steps):
            if env.step([a[t] for a in actions]).last():
                env.reset()
        if rollout:
            best = min(best, time.perf_counter() - t0)
    return Throughput(1, steps, best, len(specs))


def ratio_to_reference(steps_per_second: float, reference: float | None) -> float | None:
    """Steps/s over brax ant's at the same batch size; None (null in JSON, "-" printed) where brax ant was not
    measured."""
    return None if reference is None else steps_per_second / reference


def report(label: str, row: dict) -> None:
    ratio = row.get("ratio_to_brax_ant")
    ratio_text = "-" if ratio is None else f"{ratio:.2f}x brax ant"
    print(f"{label:30s} {row['envs']:>7d} envs {row['steps_per_second']:>12,.0f} steps/s   {ratio_text:14s}   "
          f"{row['agent_steps_per_second']:>12,.0f} agent steps/s ({row['agents']} agents)   "
          f"{row['simulated_seconds_per_second']:>10,.0f} simulated s/s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--build", type=Path, default=Path("build"), help="folder of built fields")
    parser.add_argument("--fields", default="", help="comma-separated names; default: every built field")
    parser.add_argument("--envs", default="1024,8192,32768", help="comma-separated batch sizes")
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--backends", default="", help="comma-separated sim.backend names; default: each field's own")
    parser.add_argument("--no-reference", action="store_true", help="skip brax ant")
    parser.add_argument("--dm-control-soccer", default="", metavar="TEAM_SIZES",
                        help="comma-separated agents a side: also step dm_control's soccer with ants (CPU, one match)")
    parser.add_argument("--prepare", action="store_true", help="build each field for each backend and stop")
    parser.add_argument("--json", type=Path, help="append results here, one JSON object per line")
    args = parser.parse_args()
    sizes = [int(n) for n in args.envs.split(",")]
    team_sizes = [int(k) for k in args.dm_control_soccer.split(",")] if args.dm_control_soccer else []
    names = args.fields.split(",") if args.fields else sorted(p.parent.name for p in args.build.glob("*/field.json"))
    backends = args.backends.split(",") if args.backends else [None]
    if args.prepare:
        for name in names:
            for backend in backends:
                prepare(args.build, name, backend)
        return
    print(f"device: {jax.devices()[0].device_kind}, jax {jax.__version__}, {args.steps}-step rollouts")

    reference = {}
    if not args.no_reference:
        ant = brax_ant()
        for n in sizes:
            row = throughput_row("brax_ant", measure(ant, n, args.steps), float(ant.dt), ratio_to_brax_ant=1.0)
            reference[n] = row["steps_per_second"]
            report("brax ant", row)
            append_jsonl(args.json, row)

    for name in names:
        for backend in backends:
            env = field_env(args.build, name, backend)
            label = f"{name} ({env.spec.sim.backend})"
            contacts = contacts_per_step(env)
            compile_s = compile_seconds(env, sizes[0])
            print(f"{label}: {contacts} contacts per physics step, {env.n_substeps} physics steps per env step, "
                  f"reset+step compile {compile_s:.1f} s at {sizes[0]} envs")
            for n in sizes:
                result = measure(env, n, args.steps)
                row = throughput_row(name, result, env.dt, backend=env.spec.sim.backend,
                                     ratio_to_brax_ant=ratio_to_reference(result.steps_per_second, reference.get(n)),
                                     contacts=contacts, physics_steps=env.n_substeps, compile_seconds=compile_s)
                report(label, row)
                append_jsonl(args.json, row)

    for team_size in team_sizes:
        env = dm_control_soccer(team_size)
        control_dt = env.control_timestep()
        result = measure_dm_control(env, args.steps)
        row = throughput_row(f"dm_control_soccer_{team_size}v{team_size}", result, control_dt,
                             backend="dm_control (mujoco, CPU)",
                             ratio_to_brax_ant=ratio_to_reference(result.steps_per_second, reference.get(1)),
                             physics_steps=round(control_dt / env.physics.timestep()))
        report(f"dm_control soccer {team_size}v{team_size} (ants)", row)
        append_jsonl(args.json, row)


if __name__ == "__main__":
    main()
