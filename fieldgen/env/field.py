"""Built field -> batched MJX environment with brax's State contract.

`reset(rng)` and `step(state, action)` are pure and jit/vmap-able. Each state
carries its own random key in `info["rng"]`; when an episode ends (the agent
falls or time runs out) `step` returns a fresh episode drawn from that key, so
auto-reset never replays an earlier start. `done` still reads 1 on that step.
The control steps of an episode are counted in `info["episode_step"]`. Inside
brax's and MuJoCo Playground's wrappers a field runs through an adapter
(fieldgen.brax.BraxField), which `step_restarting` serves.
A physics state that has diverged also ends its episode, as a fall, so that one
blown-up simulation never reaches a learner's batch.
"""

from __future__ import annotations

import itertools
from typing import Callable, Sequence

import fieldgen.env.quiet  # noqa: F401  (before MJX and brax)
import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from brax.envs.base import State
from mujoco import mjx

from fieldgen.cameras import CAMERAS, FOLLOW
from fieldgen.compile.artifact import Artifact
from fieldgen.compile.layout import observation_layout
from fieldgen.env import mjx_physics
from fieldgen.env.batch import batched_model, check_compatible
from fieldgen.env.contract import DIVERGED
from fieldgen.env.task import Transition
from fieldgen.env.rules import EpisodeRules
from fieldgen.schema import geometry
from fieldgen.schema.models import MAX_EXTENT


# mjx.Data fields that carry state from step to step; everything else is recomputed by the next
# mjx.step, so an auto-reset only needs to swap these.
_STATE_FIELDS = ("time", "qpos", "qvel", "act", "ctrl", "mocap_pos", "mocap_quat", "qacc_warmstart")


MAX_SPEED = 1e4  # m/s or rad/s of any degree of freedom: past a 1 cm ball rolling at 100 m/s; only a blow-up gets here
MAX_DISTANCE = 2 * MAX_EXTENT  # metres from the origin of any body: beyond every field a spec may describe


def diverged(data: mjx.Data) -> jax.Array:
    """Whether the simulation has blown up: a position that is not finite or beyond mujoco's own bound
    (mjMAXVAL), a velocity beyond MAX_SPEED or a body beyond MAX_DISTANCE. A blow-up grows for several steps
    before it reaches mjMAXVAL; a learner that saw those steps (an observation normaliser's running variance,
    a value target) stays poisoned for the rest of its run, so it is cut off where no field's motion reaches."""
    return ~(jnp.all(jnp.abs(data.qpos) < mujoco.mjMAXVAL) & jnp.all(jnp.abs(data.qvel) < MAX_SPEED)
             & jnp.all(jnp.abs(data.xpos) < MAX_DISTANCE))


def advance(sys, data: mjx.Data, ctrl: jax.Array, substeps: int, impl: str,
            guard: Callable | None = None) -> tuple[mjx.Data, jax.Array | None]:
    """The physics steps of one control step, and Warp's overflow flags they raised (None on JAX's). On Warp the
    control passes `guard` (mjx_physics.batch_guard), which refuses a batch larger than the physics was sized for."""
    if impl != "warp":
        data = data.replace(ctrl=ctrl)
        return jax.lax.fori_loop(0, substeps, lambda _, d: mjx.step(sys, d), data), None
    data = data.replace(ctrl=ctrl if guard is None else guard(ctrl))

    def one(_, carry):
        d, bits = carry
        d = mjx.step(sys, d)
        return d, bits | mjx_physics.overflow_bits(d)

    return jax.lax.fori_loop(0, substeps, one, (data, jnp.zeros((), jnp.int32)))


def restart(done: jax.Array, fresh: mjx.Data, data: mjx.Data) -> mjx.Data:
    """`fresh` where the episode is done, else `data`: only what carries from step to step is swapped."""
    return data.replace(**{f: jnp.where(done, getattr(fresh, f), getattr(data, f)) for f in _STATE_FIELDS})


class FieldEnv(mjx_physics.SizedForBatch):
    """A goal-conditioned environment: obs = concat(state, goal).

    Given several variants of a field (built to one structure by fieldgen.compile.variants),
    every environment carries its own variant (`info["variant"]`), all stepped in one
    batched simulation; each new episode draws its variant from `info["variant_weights"]`,
    which whoever trains sets (`with_variant_weights`): the environment plays the variants it
    is given and knows nothing of why they were chosen.

    Given `kickoffs` as well ([variant, point] -> the ball's spawn region x0, y0, x1, y1 and the agent's
    start x, y; NaN where a point is not played, the last point of each variant its own start), an episode
    starts from a level, a variant and one of its kick-off points (`info["kickoff"]`), drawn from
    `info["level_weights"]` [variant, point] (`with_level_weights`); every environment counts the episodes
    that ended on each level and those that succeeded (`info["level_counts"]`), which the trainer reads.
    """

    def __init__(self, artifacts: Artifact | Sequence[Artifact], episode_length: int | None = None,
                 auto_reset: bool = True, kickoffs: np.ndarray | None = None, kickoff_coordinates=None):
        artifacts = [artifacts] if isinstance(artifacts, Artifact) else list(artifacts)
        self.artifacts = artifacts
        self.artifact = artifacts[-1]  # an environment of several variants is judged on its last
        self.spec = spec = self.artifact.spec
        models = [a.model() for a in artifacts]
        self.mj_models = models  # one a variant, for drawing its states
        self.mj_model = models[-1]
        self.layout = observation_layout(spec, self.mj_model)
        self.rules = [EpisodeRules(a.spec, m, self.layout, episode_length) for a, m in zip(artifacts, models)]
        check_compatible(self.rules, models, self.layout)
        self.task = self.rules[-1].task
        self.impl = self.rules[-1].impl  # MJX's implementation (sim.backend mjx: jax, warp: warp)
        self.sys, self._varying = batched_model(models, [a.spec.name for a in artifacts], self.impl)
        self.episode_length = max(r.episode_length for r in self.rules)
        self._ball_radii = jnp.asarray([r.spec.ball.radius for r in self.rules])
        self.auto_reset = auto_reset
        self.n_substeps = spec.episode.substeps
        self.dt = spec.episode.control_dt
        self.observation_size = self.layout.size
        self.action_size = int(self.mj_model.nu)
        self.state_dim = self.layout.state_dim
        self.goal_indices = np.array(self.layout.goal_indices)
        self.success_goal_entries = np.array(self.layout.success_goal_entries)
        self.observation_names = self.layout.names
        self.action_names = tuple(self.mj_model.actuator(i).name for i in range(self.mj_model.nu))  # = joint names
        self.name = spec.name
        self.success_depends_on_goal = spec.task.success.kind != "ball_in_goal"  # the goal box, wherever the goal is
        self.terms = tuple(dict.fromkeys(n for r in self.rules for n in r.task.terms))
        self.metric_names = ("success", *self.terms)
        self._agent_qpos = jnp.asarray(self.layout.agent_qpos)
        self._agent_qvel = jnp.asarray(self.layout.agent_qvel)
        self._ball_qpos = jnp.asarray(self.layout.ball_qpos)
        self._ball_qvel = jnp.asarray(self.layout.ball_qvel)
        self._is_ant = spec.agent.kind == "ant"
        self._agent_z = geometry.POINT_RADIUS
        self._kickoffs, self.kickoff_coordinates = None, np.zeros((self.variant_count, 0))
        if kickoffs is not None:
            self._set_kickoffs(np.asarray(kickoffs, np.float32), kickoff_coordinates)

    def _set_kickoffs(self, kickoffs: np.ndarray, coordinates) -> None:
        coordinates = np.asarray(coordinates if coordinates is not None else np.nan, np.float64)
        if coordinates.ndim != 2:
            raise ValueError(f"{self.name}: kickoffs come with kickoff_coordinates, each variant's place of each "
                             f"point on the kick-off axis ([variants, points]), not {coordinates.shape}")
        shape = (self.variant_count, coordinates.shape[-1], 6)
        if kickoffs.shape != shape or coordinates.shape != shape[:2]:
            raise ValueError(f"{self.name}: kick-off tables of shape {kickoffs.shape} and {coordinates.shape} for "
                             f"{self.variant_count} variants; they should be {shape} and {shape[:2]}")
        playable = np.all(np.isfinite(kickoffs), axis=-1) & np.isfinite(coordinates)
        if not np.all(playable[:, -1]):
            raise ValueError(f"{self.name}: each variant's last kick-off point is its own start, always played")
        # an unplayed point is never drawn; its row holds the variant's own start so no NaN reaches the physics
        self._kickoffs = jnp.asarray(np.where(playable[..., None], kickoffs, kickoffs[:, -1:]))
        self.kickoff_coordinates = np.where(playable, coordinates, np.nan)

    # -- what brax's wrappers and MuJoCo Playground users reach for ----------------

    backend = "mjx"  # MJX, of either implementation (`impl`)

    @property
    def unwrapped(self) -> "FieldEnv":
        return self

    @property
    def mjx_model(self):
        """The mjx.Model stepped (leaves that differ between variants stacked on a leading axis)."""
        return self.sys

    def render(self, trajectory: Sequence[State], height: int = 240, width: int | None = None,
               camera: str = FOLLOW) -> list[np.ndarray]:
        """RGB frames [height, width, 3] of a trajectory of unbatched states, each drawn in its own variant's
        field, its arguments in brax's order; `width` defaults to the camera's own aspect
        (fieldgen.render.RenderError where no OpenGL is)."""
        from fieldgen.render import render_rollout

        states = [trajectory] if isinstance(trajectory, State) else list(trajectory)
        if not states:
            raise ValueError("render takes a trajectory of one state or more; it was given none")
        if camera not in CAMERAS:
            raise ValueError(f"camera {camera!r}: a field carries the cameras {', '.join(CAMERAS)}")
        limit = self.mj_model.vis.global_
        for name, size, most in (("height", height, limit.offheight), ("width", width, limit.offwidth)):
            if size is not None and not (isinstance(size, (int, np.integer)) and 16 <= size <= most):
                across = "high" if name == "height" else "wide"
                raise ValueError(f"{name}={size!r}: frames are 16 to {most} pixels {across} (the field's offscreen "
                                 f"buffer)")
        nq = self.mj_model.nq
        for i, s in enumerate(states):
            shape = np.shape(s.pipeline_state.qpos)
            if shape != (nq,):
                raise ValueError(f"state {i} holds positions of shape {shape}: render draws unbatched states "
                                 f"({nq},); take environment j of a batch with jax.tree.map(lambda x: x[j], state)")
        frames = []
        # consecutive states of one variant share a renderer
        for variant, run in itertools.groupby(states, key=lambda s: int(s.info.get("variant", 0))):
            run = list(run)
            qpos = np.stack([np.asarray(s.pipeline_state.qpos) for s in run])
            mocap = np.stack([np.asarray(s.pipeline_state.mocap_pos) for s in run])
            frames += render_rollout(self.mj_models[variant], qpos, mocap, camera, height, width)
        return frames

    def _size_for(self, worlds: int) -> None:
        for rules in self.rules:
            rules.reserve(worlds)

    @property
    def variant_count(self) -> int:
        """How many variants this environment batches (1 for a plain field)."""
        return len(self.rules)

    @property
    def kickoff_count(self) -> int:
        """Kick-off points of each variant an episode may start from (0: each variant's own start alone)."""
        return self.kickoff_coordinates.shape[1]

    def with_variant_weights(self, env_state: State, weights: jax.Array) -> State:
        """`env_state` (environments batched on axis 0) drawing its next episodes' variants from `weights`,
        each from its own start; a field of one variant plays it whatever the weights."""
        if self.variant_count == 1:
            return env_state
        if self.kickoff_count:
            own = jnp.zeros((self.variant_count, self.kickoff_count)).at[:, -1].set(weights)
            return self.with_level_weights(env_state, own, jnp.ones_like(own))
        shape = env_state.info["variant_weights"].shape
        return env_state.replace(info=dict(env_state.info, variant_weights=jnp.broadcast_to(weights, shape)))

    def with_level_weights(self, env_state: State, weights: jax.Array, keep: jax.Array) -> State:
        """`env_state` (a batch) drawing its next episodes' levels from `weights` [variant, kick-off point],
        its episode counts scaled by `keep` (same shape: 0 forgets a level's, 1 keeps them)."""
        info = env_state.info
        return env_state.replace(info=dict(info, level_weights=jnp.broadcast_to(weights, info["level_weights"].shape),
                                           level_counts=info["level_counts"] * keep))

    def _by_variant(self, variant: jax.Array, fn):
        """fn(the variant's episode rules), for a traced variant index (every branch runs under vmap: all are cheap)."""
        if self.variant_count == 1:
            return fn(self.rules[0])
        return jax.lax.switch(variant, [lambda r=r: fn(r) for r in self.rules])

    def _model(self, variant: jax.Array):
        if not self._varying:
            return self.sys
        leaves, treedef = jax.tree.flatten(self.sys)
        return treedef.unflatten([x[variant] if i in self._varying else x for i, x in enumerate(leaves)])

    # -- reset -------------------------------------------------------------

    def reset(self, rng: jax.Array) -> State:
        """A fresh episode; with several variants, of one drawn uniformly."""
        if self.variant_count == 1:
            return self.reset_variant(rng, 0)
        rng, k_variant = jax.random.split(rng)
        return self.reset_variant(rng, jax.random.randint(k_variant, (), 0, self.variant_count))

    def reset_variant(self, rng: jax.Array, variant, kickoff=None) -> State:
        """A fresh episode of `variant`, from its kick-off point `kickoff` (by default its own start)."""
        rng, episode_key = jax.random.split(rng)
        variant = jnp.asarray(variant, jnp.int32)
        if self.kickoff_count:
            kickoff = jnp.asarray(self.kickoff_count - 1 if kickoff is None else kickoff, jnp.int32)
        data, goal = self._fresh(variant, episode_key, kickoff)
        zero = jnp.zeros(())
        info = {"rng": rng, "goal": goal, "episode_step": jnp.zeros((), jnp.int32),
                "down_steps": jnp.zeros((), jnp.int32),
                "truncation": zero,
                "episode": jnp.zeros((), jnp.int32), DIVERGED: jnp.zeros((), jnp.int32)}
        if self.kickoff_count:
            levels = (self.variant_count, self.kickoff_count)
            info.update(variant=variant, kickoff=kickoff, succeeded=zero,
                        level_weights=jnp.zeros(levels).at[:, -1].set(1.0 / self.variant_count),
                        level_counts=jnp.zeros((2, *levels)))
        elif self.variant_count > 1:
            n = self.variant_count
            info.update(variant=variant, variant_weights=jnp.full(n, 1.0 / n))
        if self.impl == "warp":
            info[mjx_physics.OVERFLOW] = jnp.zeros((), jnp.int32)
        metrics = {name: zero for name in self.metric_names}
        return State(data, self._obs(data, goal), zero, zero, metrics, info)

    # -- step --------------------------------------------------------------

    def step(self, state: State, action: jax.Array) -> State:
        return self.step_restarting(state, action)[0]

    def step_restarting(self, state: State, action: jax.Array, ends_on_time: bool = True) -> tuple[State, tuple | None]:
        """`step`, and the start of the fresh episode it drew (physics state, obs), which a done step restarts
        from: what an auto-reset wrapper outside should swap in (None without auto_reset). With
        `ends_on_time=False` episodes end only by a fall, a wrapper outside ending them on time."""
        action = jnp.asarray(action)
        if action.shape != (self.action_size,):  # else broadcast over the motors, or an error deep in MJX
            raise ValueError(f"an action of shape {tuple(action.shape)}: {self.spec.name} takes ({self.action_size},) "
                             f"a step, one entry per motor ({self.action_size} = action_size); step a batch of "
                             f"environments with jax.vmap(env.step)")
        if not isinstance(action, jax.core.Tracer) and not bool(jnp.all(jnp.isfinite(action))):  # a call outside jit
            motors = ", ".join(self.action_names[i] for i in np.flatnonzero(~np.isfinite(np.asarray(action))))
            raise ValueError(f"an action holding NaN or infinite values (for {motors}): the physics would blow up, "
                             f"and the episode end as a fall")
        action = jnp.clip(action, -1.0, 1.0)
        before = state.pipeline_state
        variant = state.info.get("variant", jnp.zeros((), jnp.int32))
        sys = self._model(variant)
        with jax.default_matmul_precision(self.spec.sim.precision):
            data, overflow = self._advance(sys, before, action)
        goal = state.info["goal"]
        t = Transition(self._ball_pos(before, variant), self._ball_pos(data, variant), self._agent_pos(before),
                       self._agent_pos(data), goal, action, self.dt)
        steps, down_steps = state.info["episode_step"], state.info["down_steps"]
        steps = steps + 1
        metrics, reward, (truncated, fell, down) = self._by_variant(
            variant, lambda r: (*r.score(t, self.terms), r.ended(data, steps, down_steps)))
        if not ends_on_time:
            truncated = jnp.zeros_like(truncated)
        broken = diverged(data)
        metrics, reward = jax.tree.map(lambda x: jnp.where(broken, jnp.zeros_like(x), x), (metrics, reward))
        fell = fell | broken
        done = truncated | fell
        info = dict(state.info, episode_step=steps, down_steps=down, truncation=(truncated & ~fell).astype(jnp.float32))
        info[DIVERGED] = state.info[DIVERGED] + broken.astype(jnp.int32)  # kept over episodes, as OVERFLOW
        if overflow is not None:  # kept over episodes: the trainer reads it after each chunk
            info[mjx_physics.OVERFLOW] = state.info[mjx_physics.OVERFLOW] | overflow
        kickoff = state.info.get("kickoff")
        if self.kickoff_count:
            info.update(self._counted(state.info, variant, kickoff, metrics["success"], done))
        obs = self._obs(data, goal)
        start = None
        if self.auto_reset:
            rng, key = jax.random.split(state.info["rng"])
            if self.kickoff_count:
                key, k_level = jax.random.split(key)
                drawn = jax.random.categorical(k_level, jnp.log(state.info["level_weights"]).ravel())
                variant = jnp.where(done, drawn // self.kickoff_count, variant).astype(jnp.int32)
                kickoff = jnp.where(done, drawn % self.kickoff_count, kickoff).astype(jnp.int32)
                info.update(variant=variant, kickoff=kickoff)
            elif self.variant_count > 1:
                key, k_variant = jax.random.split(key)
                drawn = jax.random.categorical(k_variant, jnp.log(state.info["variant_weights"]))
                variant = jnp.where(done, drawn, variant).astype(jnp.int32)
                info.update(variant=variant)
            fresh, fresh_goal = self._fresh(variant, key, kickoff)
            fresh_obs = self._obs(fresh, fresh_goal)
            data = self._restart(done, fresh, data)
            goal = jnp.where(done, fresh_goal, goal)
            obs = jnp.where(done, fresh_obs, obs)
            info.update(rng=rng, goal=goal, episode_step=jnp.where(done, 0, steps), down_steps=jnp.where(done, 0, down),
                        episode=state.info["episode"] + done.astype(jnp.int32))
            start = self._restart(jnp.ones_like(done), fresh, data), fresh_obs
        return State(data, obs, reward, done.astype(jnp.float32), metrics, info), start

    def goal_reached(self, state: jax.Array, goal: jax.Array, variant=None) -> jax.Array:
        """The field's success predicate (0/1) of an observation's state part and any goal: what
        hindsight relabelling scores a stored state against a goal taken from its future. Judged by
        `variant`'s own rule and ball, as `step` judges it; by default the last variant's, the one a
        environment of several variants is judged on."""
        variant = jnp.asarray(self.variant_count - 1 if variant is None else variant, jnp.int32)
        goal = self._target(goal)
        agent = state[:3] if self._is_ant else jnp.append(state[:2], self._agent_z)
        ball = jnp.zeros(3)
        if self.spec.ball.enabled:
            start, stop = self.layout.slices["ball_pos"]
            ball = state[start:stop] if stop - start == 3 else jnp.append(state[start:stop], self._ball_radii[variant])
        t = Transition(ball, ball, agent, agent, goal, jnp.zeros(self.action_size), self.dt)
        return self._by_variant(variant, lambda r: r.task.success(t))

    # -- physics (brax_pipeline.BraxFieldEnv steps brax's pipelines instead) --

    def _fresh(self, variant: jax.Array, key: jax.Array, kickoff: jax.Array | None = None):
        """(physics state, goal) of a new episode of `variant` (from its kick-off point `kickoff`, where the
        field has kick-off points), drawn from `key`."""
        if not self.kickoff_count:
            return self._by_variant(variant, lambda r: r.fresh_episode(key))
        start = self._kickoffs[variant, kickoff]
        return self._by_variant(variant, lambda r: r.fresh_episode(key, start))

    def _counted(self, info: dict, variant: jax.Array, kickoff: jax.Array, success: jax.Array, done: jax.Array) -> dict:
        """The episode's success so far, and the level counts with an episode that ended now added to its level's."""
        succeeded = jnp.maximum(info["succeeded"], success)
        ended = done.astype(jnp.float32)
        counts = info["level_counts"].at[:, variant, kickoff].add(jnp.stack([ended, ended * succeeded]))
        return {"succeeded": jnp.where(done, 0.0, succeeded), "level_counts": counts}

    def _advance(self, sys, data: mjx.Data, action: jax.Array) -> tuple[mjx.Data, jax.Array | None]:
        return advance(sys, data, action, self.n_substeps, self.impl, self._guard)

    def _restart(self, done: jax.Array, fresh: mjx.Data, data: mjx.Data) -> mjx.Data:
        return restart(done, fresh, data)

    # -- views -------------------------------------------------------------

    def _obs(self, data: mjx.Data, target: jax.Array) -> jax.Array:
        """The state, then the goal: the target for each of the spec's goal positions."""
        goal = jnp.tile(target, len(self.goal_indices) // 2)
        parts = [data.qpos[self._agent_qpos], data.qvel[self._agent_qvel], data.qpos[self._ball_qpos],
                 data.qvel[self._ball_qvel], goal]
        return jnp.concatenate(parts)

    def obs_target(self, obs: jax.Array) -> jax.Array:
        """The target an observation's goal names: all that is left of an episode's goal where a wrapper swaps in
        another episode's observation and keeps the info (brax's auto-reset)."""
        return self._target(obs[self.state_dim:])

    def _target(self, goal: jax.Array) -> jax.Array:
        """The target point in a goal: the entries the success predicate reads."""
        first = int(self.success_goal_entries[0])
        return goal[..., first:first + 2]

    def _ball_pos(self, data: mjx.Data, variant: jax.Array) -> jax.Array:
        if not self.spec.ball.enabled:
            return jnp.zeros(3)
        p = data.qpos[self._ball_qpos]
        if p.shape[0] == 3:
            return p
        return jnp.append(p, self._ball_radii[variant])

    def _agent_pos(self, data: mjx.Data) -> jax.Array:
        p = data.qpos[self._agent_qpos[:3]] if self._is_ant else data.qpos[self._agent_qpos[:2]]
        return p if self._is_ant else jnp.append(p, self._agent_z)


