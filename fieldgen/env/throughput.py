"""Env-steps per second of a batched environment: a `lax.scan` of steps under jit.

Timed after two warm-up calls, because the first call compiles and the first
call fed its own output can compile again. A team field's env step is one step of
one match, every agent acting in it.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from pathlib import Path

import jax
import jax.numpy as jnp

from fieldgen.command import fieldgen_command
from fieldgen.env.mjx_physics import OVERFLOW
from fieldgen.env.contract import agents_per_env
from fieldgen.env.team_contract import TeamEnvironment


@dataclass(frozen=True)
class Throughput:
    n_envs: int
    steps: int
    seconds: float
    agents: int = 1  # agents acting in one env

    @property
    def steps_per_second(self) -> float:
        return self.n_envs * self.steps / self.seconds

    @property
    def agent_steps_per_second(self) -> float:
        return self.steps_per_second * self.agents


def action_shape(env) -> tuple[int, ...]:
    """One env's action: [agents, action_size] for a match (team_contract), [action_size] otherwise."""
    return (agents_per_env(env), env.action_size) if isinstance(env, TeamEnvironment) else (env.action_size,)


def rollout_fn(env, n_envs: int, steps: int):
    """jit(state, key) -> state after `steps` steps of random actions in every env."""

    def run(state, key):
        def body(carry, k):
            action = jax.random.uniform(k, (n_envs, *action_shape(env)), minval=-1.0, maxval=1.0)
            return jax.vmap(env.step)(carry, action), None

        state, _ = jax.lax.scan(body, state, jax.random.split(key, steps))
        return state

    return jax.jit(run)


def measure(env, n_envs: int, steps: int = 200, repeats: int = 3, seed: int = 0) -> Throughput:
    keys = jax.random.split(jax.random.PRNGKey(seed), n_envs)
    if hasattr(env, "reserve_worlds"):  # Warp's capacities, for the batch
        env.reserve_worlds(n_envs)
    state = jax.jit(jax.vmap(env.reset))(keys)
    run = rollout_fn(env, n_envs, steps)
    key = jax.random.PRNGKey(seed + 1)
    for _ in range(2):
        key, k = jax.random.split(key)
        state = jax.block_until_ready(run(state, k))
    best = float("inf")
    for _ in range(repeats):
        key, k = jax.random.split(key)
        t0 = time.perf_counter()
        state = jax.block_until_ready(run(state, k))
        best = min(best, time.perf_counter() - t0)
    if not bool(jnp.all(jnp.isfinite(state.obs))):
        raise FloatingPointError("the rollout produced non-finite observations")
    if OVERFLOW in state.info:
        env.check_physics(state.info[OVERFLOW])
    return Throughput(n_envs, steps, best, agents_per_env(env))


def train_command(field, algo: str, out, *options: str) -> list[str]:
    """`fieldgen train FIELD --algo ALGO --out OUT OPTIONS...` in a fresh interpreter of this Python."""
    return fieldgen_command("train", str(field), "--algo", algo, "--out", str(out), *options)


def run_command(args: argparse.Namespace, out, *options: str) -> list[str]:
    """The `fieldgen train` command of a benchmark's run_arguments."""
    return train_command(args.field, args.algo, out, "--steps", str(args.steps), "--envs", str(args.envs),
                         "--set", f"{args.algo}.num_evals={args.evals}",
                         *[item for setting in args.set for item in ("--set", setting)], *options)


def run_arguments(description: str) -> argparse.ArgumentParser:
    """The options of a benchmark that trains one run: field, algorithm, steps, envs, evaluations, --json."""
    parser = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--field", default="build/soccer_v1", help="a build folder or bundled field name")
    parser.add_argument("--algo", default="crl")
    parser.add_argument("--steps", type=int, default=12_000_000)
    parser.add_argument("--envs", type=int, default=1024)
    parser.add_argument("--evals", type=int, default=4, help="evaluations (each one a checkpoint and a video)")
    parser.add_argument("--set", action="append", default=[], metavar="ALGO.KEY=VALUE",
                        help="a setting passed to fieldgen train (repeatable)")
    parser.add_argument("--json", type=Path)
    return parser
