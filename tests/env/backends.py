"""MJX against MuJoCo C on the same start and action sequence.

Run as a script (`python tests/env/backends.py FIELD STEPS`) it prints the largest
qpos difference, so a test can run it in a float64 JAX process.
"""

from __future__ import annotations

import sys

import jax
import jax.numpy as jnp
import mujoco
import numpy as np


def smooth_actions(steps: int, action_size: int) -> np.ndarray:
    """A fixed gait-like sequence: phase-shifted sines of amplitude 0.6."""
    t = np.arange(steps)[:, None]
    phase = np.arange(action_size)[None, :] * 2 * np.pi / max(action_size, 1)
    return (0.6 * np.sin(2 * np.pi * t / 10 + phase)).astype(np.float32)


def mujoco_c_rollout(env, state, actions) -> np.ndarray:
    model = env.mj_model
    data = mujoco.MjData(model)
    data.qpos[:] = np.asarray(state.pipeline_state.qpos)
    data.qvel[:] = np.asarray(state.pipeline_state.qvel)
    data.mocap_pos[:] = np.asarray(state.pipeline_state.mocap_pos)
    out = []
    for a in actions:
        data.ctrl[:] = a
        for _ in range(env.n_substeps):
            mujoco.mj_step(model, data)
        out.append(data.qpos.copy())
    return np.array(out)


def mjx_rollout(env, state, actions) -> np.ndarray:
    step = jax.jit(env.step)
    out = []
    for a in actions:
        state = step(state, jnp.asarray(a))
        out.append(np.asarray(state.pipeline_state.qpos))
    return np.array(out)


def compare_backends(env, steps: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    state = env.reset(jax.random.PRNGKey(seed))
    actions = smooth_actions(steps, env.action_size)
    return mjx_rollout(env, state, actions), mujoco_c_rollout(env, state, actions)


if __name__ == "__main__":
    import fieldgen

    ours, reference = compare_backends(fieldgen.make(sys.argv[1], auto_reset=False), int(sys.argv[2]))
    print(float(np.abs(ours - reference).max()))
