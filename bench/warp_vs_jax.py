"""MJX's two implementations, JAX and Warp, stepping the same built scenes with the same actions.

Each field's MuJoCo model is put on the device twice, `mjx.put_model(m, impl="jax")` and
`impl="warp"` (once per --graph-modes entry), and both step a batch of --envs environments from the
same fresh episodes (the field's own resets) with the same random actions: each control step sets
ctrl and runs the field's physics steps, as fieldgen's environment does, without its rewards or
resets. Env steps per second (control steps x envs / s) are timed after two warm-up calls, best of
--repeats; the JAX row at the same batch size is the reference every Warp row is divided by. Each
Warp row also says how far it drifts from JAX (largest |qpos difference| after --agree-steps control
steps from the same start and actions) and which of Warp's overflow flags (contact or constraint
capacity, solver iterations) any environment raised in the timed run.

    fieldgen build ant_nav soccer_v1 soccer_v2 bench/fields/v2_all_contacts.yaml
    python bench/warp_vs_jax.py --envs 1024,8192,32768
    python bench/warp_vs_jax.py --fields soccer_v2 --envs 8192 --graph-modes WARP,JAX,NONE --naconmax 64 --njmax 128

Warp's contact capacity (naconmax) is shared by all environments of a batch: --naconmax gives it per
environment and defaults to every contact the JAX implementation allocates, --njmax (constraint rows
per environment) to the rows the JAX implementation allocates. Without warp-lang or a CUDA device the
Warp rows are skipped with the reason and the JAX rows still run; --warp-on-cpu runs Warp's CPU
kernels instead, to check the script and the agreement, not to time them. Warp starts its solve where MuJoCo
does (fieldgen.env.warp_start); --warp-start warp times its own start, in a process of its own:

    python bench/warp_vs_jax.py --fields v2_wide_goalie_dense --envs 8192 --impls warp --warp-start warp
    python bench/warp_vs_jax.py --fields v2_wide_goalie_dense --envs 8192 --impls warp
"""

from __future__ import annotations

import argparse
import copy
import time
from pathlib import Path

import jax
import jax.numpy as jnp

from env_throughput import field_env
from fieldgen.env import warp_start
from fieldgen.env.mjx_physics import capacities, overflow_bits, overflow_names, put_model, start_warp
from fieldgen.files import append_jsonl
from fieldgen.schema import SpecError
from fieldgen.schema.backends import BACKENDS

DEFAULT_FIELDS = "ant_nav,soccer_v1,soccer_v2,bench/fields/v2_all_contacts.yaml"


def load_field(build: Path, name: str):
    """The environment of BUILD/<name> (a spec's file name without .yaml), else built now from the
    bundled name or spec file."""
    stem = Path(name).stem if name.endswith((".yaml", ".yml")) else name
    try:
        env = field_env(build, stem if (build / stem).is_dir() else name, None)
    except SpecError as error:
        raise SystemExit(f"error: {error}") from None
    if BACKENDS[env.spec.sim.backend].brax:
        raise SystemExit(f"{name} runs on brax's {env.spec.sim.backend} pipeline; MJX's implementations step only "
                         f"the fields of {' and '.join(n for n, b in BACKENDS.items() if not b.brax)}")
    return env


def warp_unavailable(on_cpu: bool) -> str | None:
    """Why the Warp rows cannot run here, or None when they can."""
    from mujoco.mjx import warp as mjx_warp

    if not mjx_warp.WARP_INSTALLED:
        return "warp-lang is not installed"
    if jax.default_backend() != "gpu" and not on_cpu:
        return f"no CUDA device (JAX's backend is {jax.default_backend()}); --warp-on-cpu runs Warp's CPU kernels"
    return None


def add_warp_start(parser) -> None:
    """--warp-start: where Warp starts its constraint solve in this process (fieldgen.env.warp_start)."""
    parser.add_argument("--warp-start", choices=("mujoco", "warp"), default="mujoco",
                        help="MuJoCo's choice of start (fieldgen's) or Warp's own: each process steps one")


def use_warp_start(which: str) -> None:
    """Start Warp with the solve's start `which` (as --warp-start names it) before any Warp program is traced."""
    start_warp()
    if which == "warp":
        warp_start.remove()


def graph_mode(name: str):
    """Warp's CUDA-graph capture mode called `name` (warp.JaxCallableGraphMode)."""
    import warp

    try:
        return warp.JaxCallableGraphMode[name]
    except KeyError:
        raise SystemExit(f"--graph-modes: no mode {name!r}; "
                         f"choose from {', '.join(m.name for m in warp.JaxCallableGraphMode)}") from None


def physics_model(env, iterations: int | None, ls_iterations: int | None):
    """The field's MuJoCo model with the solver's iteration limits replaced where given."""
    model = copy.copy(env.mj_model)
    if iterations is not None:
        model.opt.iterations = iterations
    if ls_iterations is not None:
        model.opt.ls_iterations = ls_iterations
    return model


class Implementation:
    """One MJX implementation of one field's model, batched over environments."""

    def __init__(self, env, model, impl: str, mode=None, naconmax_per_env: int = 0, njmax: int = 0):
        self.env, self.model, self.impl = env, model, impl
        self.mjx_model = put_model(model, impl, **({"graph_mode": mode} if mode is not None else {}))
        self.mode_name = self.mjx_model.opt._impl.graph_mode.name if impl == "warp" else None
        self.naconmax_per_env, self.njmax = naconmax_per_env, njmax

    @property
    def label(self) -> str:
        return f"warp/{self.mode_name}" if self.impl == "warp" else self.impl

    def start(self, reset_state, n_envs: int):
        """Fresh data of this implementation for `n_envs` environments, in the physics state of `reset_state`
        (the field's own resets, batched)."""
        from mujoco import mjx

        sizes = ({"naconmax": self.naconmax_per_env * n_envs, "njmax": self.njmax}
                 if self.impl == "warp" else {})
        source = self.model if self.impl == "warp" else self.mjx_model  # Warp's data is built from the MjModel
        data = jax.vmap(lambda _: mjx.make_data(source, impl=self.impl, **sizes))(jnp.arange(n_envs))
        fresh = reset_state.pipeline_state
        return data.replace(qpos=fresh.qpos, qvel=fresh.qvel, mocap_pos=fresh.mocap_pos,
                            mocap_quat=fresh.mocap_quat)

    def rollout(self, n_envs: int, steps: int):
        """jit(data, key) -> (data after `steps` control steps of random actions drawn from `key`, the
        overflow flags any environment raised, the most contacts detected at once)."""
        from mujoco import mjx

        env, mjx_model, warp = self.env, self.mjx_model, self.impl == "warp"
        physics_step = jax.vmap(lambda d: mjx.step(mjx_model, d))

        def body(carry, key):
            data, overflow, contacts = carry
            action = jax.random.uniform(key, (n_envs, env.action_size), minval=-1.0, maxval=1.0)
            with jax.default_matmul_precision(env.spec.sim.precision):
                data = jax.lax.fori_loop(0, env.n_substeps, lambda _, d: physics_step(d), data.replace(ctrl=action))
            if warp:
                overflow = overflow | overflow_bits(data)
                contacts = jnp.maximum(contacts, jnp.max(data._impl.nacon).astype(jnp.int32))
            return (data, overflow, contacts), None

        def run(data, key):
            carry = (data, jnp.int32(0), jnp.int32(0))
            (data, overflow, contacts), _ = jax.lax.scan(body, carry, jax.random.split(key, steps))
            return data, overflow, contacts

        return jax.jit(run)


def timed(run, data, repeats: int) -> tuple[float, tuple]:
    """Best wall time of `run` after two warm-up calls (the first compiles, the first fed its own output can
    compile again), and the last call's output; every call draws fresh actions."""
    key = jax.random.PRNGKey(1)
    out = (data,)
    for _ in range(2):
        key, k = jax.random.split(key)
        out = jax.block_until_ready(run(out[0], k))
    best = float("inf")
    for _ in range(repeats):
        key, k = jax.random.split(key)
        t0 = time.perf_counter()
        out = jax.block_until_ready(run(out[0], k))
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--build", type=Path, default=Path("build"), help="folder of built fields")
    parser.add_argument("--fields", default=DEFAULT_FIELDS,
                        help="comma-separated field names or spec files, each read from BUILD/<name> when built")
    parser.add_argument("--envs", default="1024,8192,32768", help="comma-separated batch sizes")
    parser.add_argument("--steps", type=int, default=100, help="control steps per timed call")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--agree-steps", type=int, default=10,
                        help="control steps after which Warp's qpos is compared with JAX's")
    parser.add_argument("--impls", default="jax,warp", help="jax, warp or both; jax is the reference")
    parser.add_argument("--graph-modes", default="", help="comma-separated Warp graph modes, one row each "
                        "(warp.JaxCallableGraphMode: NONE, JAX, WARP, WARP_STAGED, WARP_STAGED_EX); default: "
                        "MJX's own choice for the device")
    parser.add_argument("--iterations", type=int, help="solver iterations (default: the field's)")
    parser.add_argument("--ls-iterations", type=int, help="line-search iterations (default: the field's)")
    parser.add_argument("--naconmax", type=int, help="Warp's contacts per environment (default: JAX's count)")
    parser.add_argument("--njmax", type=int, help="Warp's constraint rows per environment (default: JAX's count)")
    parser.add_argument("--warp-on-cpu", action="store_true", help="run the Warp rows on Warp's CPU kernels "
                        "where no CUDA device is (a check of the script, not a timing)")
    add_warp_start(parser)
    parser.add_argument("--json", type=Path, help="append results here, one JSON object per line")
    args = parser.parse_args()
    try:
        sizes = [int(n) for n in args.envs.split(",")]
    except ValueError:
        parser.error(f"--envs {args.envs!r}: write comma-separated whole numbers, e.g. 1024,8192")
    impls = args.impls.split(",")
    if set(impls) - {"jax", "warp"} or min(sizes) < 1 or min(args.steps, args.agree_steps, args.repeats) < 1:
        parser.error("--impls takes jax and/or warp; --envs, --steps, --agree-steps and --repeats are positive")
    why_not = warp_unavailable(args.warp_on_cpu) if "warp" in impls else None
    modes = []  # None: MJX's own choice
    if "warp" in impls and not why_not:
        use_warp_start(args.warp_start)
        modes = [graph_mode(name) for name in args.graph_modes.split(",")] if args.graph_modes else [None]
    print(f"device: {jax.devices()[0].device_kind} ({jax.default_backend()}), jax {jax.__version__}, "
          f"{args.steps}-step calls, agreement after {args.agree_steps} steps")
    if why_not:
        print(f"Warp rows skipped: {why_not}")

    for name in args.fields.split(","):
        env = load_field(args.build, name)
        model = physics_model(env, args.iterations, args.ls_iterations)
        contacts, rows = capacities(model)
        naconmax = contacts if args.naconmax is None else args.naconmax
        njmax = rows if args.njmax is None else args.njmax
        runs = [Implementation(env, model, "jax")] if "jax" in impls else []
        runs += [Implementation(env, model, "warp", mode, naconmax, njmax) for mode in modes]
        print(f"{env.name}: {env.n_substeps} physics steps per env step, solver iterations {model.opt.iterations}, "
              f"line search {model.opt.ls_iterations}; JAX allocates {contacts} contacts and {rows} constraint rows "
              f"per env; Warp gets {naconmax} contacts per env and {njmax} rows")
        for n in sizes:
            reset = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), n))
            reference_sps = reference_qpos = None
            for run in runs:
                start = run.start(reset, n)
                rollout = run.rollout(n, args.steps)
                seconds, (data, overflow, most_contacts) = timed(rollout, start, args.repeats)
                sps = n * args.steps / seconds
                agree = rollout if args.agree_steps == args.steps else run.rollout(n, args.agree_steps)
                agreed = agree(start, jax.random.PRNGKey(2))[0].qpos
                if run.impl == "jax":
                    reference_sps, reference_qpos = sps, agreed
                ratio = sps / reference_sps if reference_sps else float("nan")
                compared = run.impl == "warp" and reference_qpos is not None
                drift = float(jnp.max(jnp.abs(agreed - reference_qpos))) if compared else None
                flags = overflow_names(int(overflow)) if run.impl == "warp" else []
                nonfinite = int(jnp.sum(~jnp.all(jnp.isfinite(data.qpos), axis=1)))
                warp_part = ""
                if run.impl == "warp":
                    gap = "no jax row" if drift is None else f"{drift:.2e}"
                    warp_part = (f"; qpos vs jax after {args.agree_steps} steps {gap}; most contacts "
                                 f"{int(most_contacts)} of {naconmax * n}; overflow {','.join(flags) or 'none'}")
                print(f"{env.name:>16s} {run.label:>18s} {n:>7d} envs {sps:>13,.0f} env steps/s   "
                      f"{ratio:5.2f}x jax{warp_part}; non-finite envs {nonfinite}", flush=True)
                append_jsonl(args.json, {
                    "field": env.name, "impl": run.impl, "graph_mode": run.mode_name, "envs": n,
                    "warp_start": args.warp_start if run.impl == "warp" else None,
                    "steps": args.steps, "env_steps_per_second": sps, "ratio_to_jax": ratio,
                    "agree_steps": args.agree_steps, "max_qpos_difference": drift,
                    "overflow": flags if run.impl == "warp" else None,
                    "most_contacts": int(most_contacts) if run.impl == "warp" else None,
                    "naconmax": naconmax * n if run.impl == "warp" else None,
                    "njmax": njmax if run.impl == "warp" else None,
                    "iterations": int(model.opt.iterations), "ls_iterations": int(model.opt.ls_iterations),
                    "physics_steps": env.n_substeps, "nonfinite_envs": nonfinite,
                    "backend": jax.default_backend()})


if __name__ == "__main__":
    main()
