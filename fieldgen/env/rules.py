"""One variant's episode rules inside a batched environment: how episodes start, how a step scores,
when an episode ends. A field of one variant has one set; a batch of variants, one set each."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from mujoco import mjx

from fieldgen.env import mjx_physics
from fieldgen.env.batch import own_device
from fieldgen.env.falls import fall_fn
from fieldgen.env.task import Transition, task_fns
from fieldgen.schema.backends import mjx_impl

def ball_in_region(key: jax.Array, spawn) -> jax.Array:
    """The ball's x, y drawn uniformly in a spawn region (ball.spawn of mode region)."""
    return jax.random.uniform(key, (2,), minval=jnp.array([spawn.x[0], spawn.y[0]]),
                              maxval=jnp.array([spawn.x[1], spawn.y[1]]))


class EpisodeRules:
    """One variant's episode rules: how episodes start, how a step scores, when an episode ends."""

    def __init__(self, spec, mj_model, layout, episode_length: int | None = None):
        self.spec = spec
        self.task = task_fns(spec)
        self.fell = fall_fn(spec)
        self.episode_length = episode_length or spec.episode.length
        self.home_qpos = jnp.asarray(mj_model.key("home").qpos)
        self.mj_model, self.impl = mj_model, mjx_impl(spec) or "jax"  # brax's pipelines start from JAX's data
        self.reserve(1)
        self.layout = layout
        self.is_ant = spec.agent.kind == "ant"

    def reserve(self, worlds: int) -> None:
        """Episodes start from data sized for batches of `worlds` environments (Warp's capacities)."""
        self.data0 = mjx_physics.home_data(self.mj_model, self.impl, own_device(), worlds, self.spec.name)

    def fresh_episode(self, key: jax.Array, kickoff: jax.Array | None = None):
        """Agent pose noise, target and ball spawn: new draws from `key`. With `kickoff` (the ball's spawn
        region's corners x0, y0, x1, y1 and the agent's start x, y), the episode starts there instead of
        where the spec starts it: a start moved changes no compiled program."""
        k_q, k_v, k_target, k_ball = jax.random.split(key, 4)
        noise, layout = self.spec.agent.reset_noise, self.layout
        agent_noise = jax.random.uniform(k_q, (len(layout.agent_qpos),), minval=-noise.qpos, maxval=noise.qpos)
        if self.is_ant:
            agent_noise = agent_noise.at[3:7].set(0.0)  # keep the torso quaternion a unit quaternion
        home = self.home_qpos if kickoff is None else \
            self.home_qpos.at[jnp.asarray(layout.agent_qpos[:2])].set(kickoff[4:6])
        qpos = home.at[jnp.asarray(layout.agent_qpos)].add(agent_noise)
        qvel = jnp.zeros(self.data0.qvel.shape).at[jnp.asarray(layout.agent_qvel)].set(
            noise.qvel * jax.random.normal(k_v, (len(layout.agent_qvel),)))
        target = self._sample_target(k_target)
        if self.spec.ball.enabled:
            ball = self._sample_ball(k_ball, target) if kickoff is None else \
                jax.random.uniform(k_ball, (2,), minval=kickoff[0:2], maxval=kickoff[2:4])
            qpos = qpos.at[jnp.asarray(layout.ball_qpos[:2])].set(ball)
        data = self.data0.replace(qpos=qpos, qvel=qvel, mocap_pos=self.data0.mocap_pos.at[0, :2].set(target))
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
            return ball_in_region(key, s)
        start = jnp.asarray(self.spec.agent.start)
        jitter = jax.random.uniform(key, (2,), minval=-s.jitter, maxval=s.jitter)
        return start + s.fraction * (target - start) + jitter

    def score(self, t: Transition, names: tuple[str, ...]) -> tuple[dict, jax.Array]:
        """(metrics, reward) of one step; terms this field does not use read 0."""
        metrics = {"success": self.task.success(t)}
        metrics.update({name: self.task.terms[name](t) if name in self.task.terms else jnp.zeros(())
                        for name in names})
        return metrics, self.task.reward(metrics)

    def ended(self, data: mjx.Data, steps: jax.Array, down: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
        """(time ran out, the agent fell, control steps it has now been down in a row), given the steps it
        had been down before this one."""
        if self.fell is None:
            return steps >= self.episode_length, jnp.zeros((), bool), jnp.zeros((), jnp.int32)
        is_down, grace = self.fell
        torso = data.qpos[jnp.asarray(self.layout.agent_qpos[:7])]
        down = jnp.where(is_down(torso[:3], torso[3:7]), down + 1, 0).astype(jnp.int32)
        return steps >= self.episode_length, down > grace, down
