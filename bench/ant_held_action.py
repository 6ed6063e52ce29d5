"""Does the ant travel under an action held constant? brax's generalized pipeline against MJX.

CRL learns brax's ant on the generalized pipeline but not on MJX (bench/crl_on_brax_ant.py),
though random-action rollouts look alike. This holds each of N random actions for T control
steps from the same start and reports the share of ants that stay upright (torso z in
0.2..1.0), their median displacement, and their median speed over the second half. The
generalized pipeline is the reference; a ratio far from 1 says the physics differ in a way
that matters: an ant that drifts under any held action needs no gait to reach a target.

    python bench/ant_held_action.py --envs 256 --steps 200
"""

from __future__ import annotations

import argparse
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from brax import envs

import fieldgen
from fieldgen.files import append_jsonl


def brax_rollout(backend: str):
    """actions [T, 8] -> torso positions [T, 3] of brax's ant from its initial pose, without noise."""
    env = envs.get_environment("ant", backend=backend)
    q0, qd0 = env.sys.init_q, jnp.zeros(env.sys.qd_size())

    def rollout(actions):
        def step(state, a):
            state = env.pipeline_step(state, a)
            return state, state.q[:3]

        return jax.lax.scan(step, env.pipeline_init(q0, qd0), actions)[1]

    return rollout


def field_rollout(source: str):
    """The same for a fieldgen ant field (its own start pose and reset noise)."""
    env = fieldgen.make(source, auto_reset=False)

    def rollout(actions):
        def step(state, a):
            state = env.step(state, a)
            return state, state.pipeline_state.qpos[:3]

        return jax.lax.scan(step, env.reset(jax.random.PRNGKey(0)), actions)[1]

    return rollout


def measure(rollout, actions: jax.Array, dt: float) -> dict:
    torso = np.asarray(jax.jit(jax.vmap(rollout))(actions))  # [N, T, 3]
    upright = ((torso[:, :, 2] > 0.2) & (torso[:, :, 2] < 1.0)).all(axis=1)
    shift = np.linalg.norm(torso[:, -1, :2] - torso[:, 0, :2], axis=1)
    half = torso.shape[1] // 2
    speed = np.linalg.norm(torso[:, -1, :2] - torso[:, half, :2], axis=1) / ((torso.shape[1] - 1 - half) * dt)
    return {"upright": float(upright.mean()), "displacement_m": float(np.median(shift[upright])),
            "late_speed_m_s": float(np.median(speed[upright]))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", type=int, default=256, help="random held actions")
    parser.add_argument("--steps", type=int, default=200, help="control steps each is held")
    parser.add_argument("--field", default="ant_nav")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    held = jax.random.uniform(jax.random.PRNGKey(3), (args.envs, 1, 8), minval=-1, maxval=1)
    actions = jnp.repeat(held, args.steps, axis=1)
    rollouts = {"brax generalized": brax_rollout("generalized"), "brax mjx": brax_rollout("mjx"),
                f"fieldgen {args.field}": field_rollout(args.field)}
    reference = None
    for name, rollout in rollouts.items():
        result = measure(rollout, actions, dt=0.05)
        reference = reference or result
        print(f"{name:>20s}: upright {result['upright']:.2f}; upright ants moved {result['displacement_m']:.2f} m "
              f"(x{result['displacement_m'] / reference['displacement_m']:.2f} of generalized), late speed "
              f"{result['late_speed_m_s']:.3f} m/s", flush=True)
        append_jsonl(args.json, {"backend": name, "envs": args.envs, "steps": args.steps, **result})


if __name__ == "__main__":
    main()
