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
"""

from __future__ import annotations

import argparse
import contextlib
import io
import time
from pathlib import Path

import jax

import fieldgen
from fieldgen.compile.artifact import compile_spec, load_artifact, write_artifact
from fieldgen.env.throughput import append_jsonl, measure
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
    t0 = time.perf_counter()
    state = jax.jit(jax.vmap(env.reset))(keys)
    action = jax.numpy.zeros((n_envs, env.action_size))
    jax.block_until_ready(jax.jit(jax.vmap(env.step))(state, action))
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--build", type=Path, default=Path("build"), help="folder of built fields")
    parser.add_argument("--fields", default="", help="comma-separated names; default: every built field")
    parser.add_argument("--envs", default="1024,8192,32768", help="comma-separated batch sizes")
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--backends", default="", help="comma-separated sim.backend names; default: each field's own")
    parser.add_argument("--no-reference", action="store_true", help="skip brax ant")
    parser.add_argument("--prepare", action="store_true", help="build each field for each backend and stop")
    parser.add_argument("--json", type=Path, help="append results here, one JSON object per line")
    args = parser.parse_args()
    sizes = [int(n) for n in args.envs.split(",")]
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
            reference[n] = measure(ant, n, args.steps).steps_per_second
            print(f"{'brax ant':16s} {n:>7d} envs {reference[n]:>12,.0f} steps/s   1.00x")
            append_jsonl(args.json, {"field": "brax_ant", "envs": n, "steps_per_second": reference[n]})

    for name in names:
        for backend in backends:
            env = field_env(args.build, name, backend)
            label = f"{name} ({env.spec.sim.backend})"
            contacts = contacts_per_step(env)
            compile_s = compile_seconds(env, sizes[0])
            print(f"{label}: {contacts} contacts per physics step, {env.n_substeps} physics steps per env step, "
                  f"reset+step compile {compile_s:.1f} s at {sizes[0]} envs")
            for n in sizes:
                sps = measure(env, n, args.steps).steps_per_second
                ratio = sps / reference[n] if n in reference else float("nan")
                print(f"{label:30s} {n:>7d} envs {sps:>12,.0f} steps/s   {ratio:.2f}x brax ant")
                append_jsonl(args.json, {"field": name, "backend": env.spec.sim.backend, "envs": n,
                                         "steps_per_second": sps, "ratio_to_brax_ant": ratio, "contacts": contacts,
                                         "physics_steps": env.n_substeps, "compile_seconds": compile_s})



if __name__ == "__main__":
    main()
