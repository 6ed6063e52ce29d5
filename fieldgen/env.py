"""Built field -> batched MJX environment with brax's State contract.

`reset(rng)` and `step(state, action)` are pure and jit/vmap-able. Each state
carries its own random key in `info["rng"]`; when an episode ends (the agent
falls or time runs out) `step` returns a fresh episode drawn from that key, so
auto-reset never replays an earlier start. `done` still reads 1 on that step.
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from fieldgen.compile.artifact import Artifact
from fieldgen.compile.layout import observation_layout
from fieldgen.compile.task import Transition, task_fns
from fieldgen.schema import geometry

with contextlib.redirect_stdout(io.StringIO()):  # mjx (also via brax) prints about its optional warp backend
    from brax.envs.base import State
    from mujoco import mjx


# mjx.Data fields that carry state from step to step; everything else is recomputed by the next
# mjx.step, so an auto-reset only needs to swap these.
_STATE_FIELDS = ("time", "qpos", "qvel", "act", "ctrl", "mocap_pos", "mocap_quat", "qacc_warmstart")


class FieldEnv:
    """A goal-conditioned environment: obs = concat(state, goal)."""

    def __init__(self, artifact: Artifact, episode_length: int | None = None, auto_reset: bool = True):
        self.artifact = artifact
        self.spec = spec = artifact.spec
        self.mj_model = artifact.model()
        self.sys = mjx.put_model(self.mj_model)
        self.layout = observation_layout(spec, self.mj_model)
        self.task = task_fns(spec)
        self.episode_length = episode_length or spec.episode.length
        self.auto_reset = auto_reset
        self.n_substeps = spec.episode.substeps
        self.dt = spec.episode.control_dt
        self.observation_size = self.layout.size
        self.action_size = int(self.mj_model.nu)
        self.state_dim = self.layout.state_dim
        self.goal_indices = np.array(self.layout.goal_indices)
        self.metric_names = ("success", *self.task.terms)
        key = self.mj_model.key("home")
        self._home_qpos = jnp.asarray(key.qpos)
        self._data0 = mjx.make_data(self.mj_model).replace(qpos=self._home_qpos)
        self._agent_qpos = jnp.asarray(self.layout.agent_qpos)
        self._agent_qvel = jnp.asarray(self.layout.agent_qvel)
        self._ball_qpos = jnp.asarray(self.layout.ball_qpos)
        self._ball_qvel = jnp.asarray(self.layout.ball_qvel)
        self._is_ant = spec.agent.kind == "ant"
        self._ball_z = spec.ball.radius
        self._agent_z = geometry.POINT_RADIUS

    # -- reset -------------------------------------------------------------

    def reset(self, rng: jax.Array) -> State:
        rng, episode_key = jax.random.split(rng)
        data, goal = self._fresh_episode(episode_key)
        zero = jnp.zeros(())
        info = {"rng": rng, "goal": goal, "steps": jnp.zeros((), jnp.int32), "truncation": zero,
                "episode": jnp.zeros((), jnp.int32)}
        metrics = {name: zero for name in self.metric_names}
        return State(data, self._obs(data, goal), zero, zero, metrics, info)

    def _fresh_episode(self, key: jax.Array):
        """Agent pose noise, target and ball spawn: new draws from `key`."""
        k_q, k_v, k_target, k_ball = jax.random.split(key, 4)
        noise = self.spec.agent.reset_noise
        qpos = self._home_qpos
        agent_noise = jax.random.uniform(k_q, (len(self.layout.agent_qpos),), minval=-noise.qpos, maxval=noise.qpos)
        if self._is_ant:
            agent_noise = agent_noise.at[3:7].set(0.0)  # keep the torso quaternion a unit quaternion
        qpos = qpos.at[self._agent_qpos].add(agent_noise)
        qvel = jnp.zeros(self.mj_model.nv).at[self._agent_qvel].set(
            noise.qvel * jax.random.normal(k_v, (len(self.layout.agent_qvel),)))
        target = self._sample_target(k_target)
        if self.spec.ball.enabled:
            qpos = qpos.at[self._ball_qpos[:2]].set(self._sample_ball(k_ball, target))
        data = self._data0.replace(qpos=qpos, qvel=qvel, mocap_pos=self._data0.mocap_pos.at[0, :2].set(target))
        return data, target

    def _sample_target(self, key: jax.Array) -> jax.Array:
        fixed = self.spec.target_fixed()
        if fixed is not None:
            return jnp.asarray(fixed, jnp.float32)
        t = self.spec.task.target
        k_r, k_a = jax.random.split(key)
        radius = jax.random.uniform(k_r, minval=t.radius[0], maxval=t.radius[1])
        angle = jnp.deg2rad(jax.random.uniform(k_a, minval=t.angle_deg[0], maxval=t.angle_deg[1]))
        return jnp.asarray(self.spec.agent.start) + radius * jnp.stack([jnp.cos(angle), jnp.sin(angle)])

    def _sample_ball(self, key: jax.Array, target: jax.Array) -> jax.Array:
        s = self.spec.ball.spawn
        if s.mode == "region":
            lo = jnp.array([s.x[0], s.y[0]])
            hi = jnp.array([s.x[1], s.y[1]])
            return jax.random.uniform(key, (2,), minval=lo, maxval=hi)
        start = jnp.asarray(self.spec.agent.start)
        jitter = jax.random.uniform(key, (2,), minval=-s.jitter, maxval=s.jitter)
        return start + s.fraction * (target - start) + jitter

    # -- step --------------------------------------------------------------

    def step(self, state: State, action: jax.Array) -> State:
        action = jnp.clip(action, -1.0, 1.0)
        before = state.pipeline_state
        with jax.default_matmul_precision(self.spec.sim.precision):
            data = jax.lax.fori_loop(0, self.n_substeps, lambda _, d: mjx.step(self.sys, d),
                                     before.replace(ctrl=action))
        goal = state.info["goal"]
        t = Transition(self._ball_pos(before), self._ball_pos(data), self._agent_pos(before), self._agent_pos(data),
                       goal, action, self.dt)
        metrics = {"success": self.task.success(t)}
        metrics.update({name: fn(t) for name, fn in self.task.terms.items()})
        reward = self.task.reward(metrics)
        steps = state.info["steps"] + 1
        truncated = steps >= self.episode_length
        fell = jnp.zeros((), bool)
        if self._is_ant and self.spec.episode.terminate_unhealthy:
            lo, hi = self.spec.agent.healthy_z
            z = data.qpos[self._agent_qpos[2]]
            fell = (z < lo) | (z > hi)
        done = truncated | fell
        info = dict(state.info, steps=steps, truncation=(truncated & ~fell).astype(jnp.float32))
        obs = self._obs(data, goal)
        if self.auto_reset:
            rng, key = jax.random.split(state.info["rng"])
            fresh, fresh_goal = self._fresh_episode(key)
            data = data.replace(**{f: jnp.where(done, getattr(fresh, f), getattr(data, f)) for f in _STATE_FIELDS})
            goal = jnp.where(done, fresh_goal, goal)
            obs = jnp.where(done, self._obs(fresh, fresh_goal), obs)
            info.update(rng=rng, goal=goal, steps=jnp.where(done, 0, steps),
                        episode=state.info["episode"] + done.astype(jnp.int32))
        return State(data, obs, reward, done.astype(jnp.float32), metrics, info)

    # -- views -------------------------------------------------------------

    def _obs(self, data: mjx.Data, goal: jax.Array) -> jax.Array:
        parts = [data.qpos[self._agent_qpos], data.qvel[self._agent_qvel], data.qpos[self._ball_qpos],
                 data.qvel[self._ball_qvel], goal]
        return jnp.concatenate(parts)

    def _ball_pos(self, data: mjx.Data) -> jax.Array:
        if not self.spec.ball.enabled:
            return jnp.zeros(3)
        p = data.qpos[self._ball_qpos]
        return p if p.shape[0] == 3 else jnp.append(p, self._ball_z)

    def _agent_pos(self, data: mjx.Data) -> jax.Array:
        p = data.qpos[self._agent_qpos[:3]] if self._is_ant else data.qpos[self._agent_qpos[:2]]
        return p if self._is_ant else jnp.append(p, self._agent_z)


def make(source, backend: str = "mjx", **kwargs) -> FieldEnv:
    """An environment from a FieldSpec, a YAML path, a bundled name or a build directory.

    Building from a spec needs dm_control; a build directory needs only mujoco.
    Keyword arguments (episode_length, auto_reset) go to FieldEnv.
    """
    from fieldgen.compile.artifact import compile_spec, load_artifact
    from fieldgen.schema import FieldSpec, load_spec, resolve_spec_path

    if backend != "mjx":
        raise ValueError(f"unknown backend {backend!r}; fieldgen environments run on 'mjx'")
    if isinstance(source, FieldSpec):
        return FieldEnv(compile_spec(source), **kwargs)
    path = Path(source) if isinstance(source, Path) else resolve_spec_path(str(source))
    if path.is_dir():
        return FieldEnv(load_artifact(path), **kwargs)
    return FieldEnv(compile_spec(load_spec(path)), **kwargs)
