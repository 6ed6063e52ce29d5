"""Built field -> batched MJX environment with brax's State contract.

`reset(rng)` and `step(state, action)` are pure and jit/vmap-able. Each state
carries its own random key in `info["rng"]`; when an episode ends (the agent
falls or time runs out) `step` returns a fresh episode drawn from that key, so
auto-reset never replays an earlier start. `done` still reads 1 on that step.
A physics state that has diverged also ends its episode, as a fall, so that one
blown-up simulation never reaches a learner's batch.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
from pathlib import Path
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from fieldgen.compile.artifact import Artifact
from fieldgen.compile.layout import observation_layout
from fieldgen.compile.task import Transition, fall_fn, task_fns
from fieldgen.schema import geometry

with contextlib.redirect_stdout(io.StringIO()):  # mjx (also via brax) prints about its optional warp backend
    import mujoco
    from brax.envs.base import State
    from mujoco import mjx


# mjx.Data fields that carry state from step to step; everything else is recomputed by the next
# mjx.step, so an auto-reset only needs to swap these.
_STATE_FIELDS = ("time", "qpos", "qvel", "act", "ctrl", "mocap_pos", "mocap_quat", "qacc_warmstart")


WEIGHT_FLOOR = 0.1  # every variant keeps at least this share of the weight mass (before normalising)


def sampling_weights(success: jax.Array) -> jax.Array:
    """How often to start each variant, from its success rate p: most where p(1-p) is largest
    (the variants being learnt now), a floor for the solved and the not yet reachable."""
    score = WEIGHT_FLOOR + 4.0 * success * (1.0 - success)
    return score / jnp.sum(score)


class Variant:
    """One field's episode rules: how episodes start, how a step scores, when an episode ends."""

    def __init__(self, spec, mj_model, layout, episode_length: int | None = None):
        self.spec = spec
        self.task = task_fns(spec)
        self.fell = fall_fn(spec)
        self.episode_length = episode_length or spec.episode.length
        self.home_qpos = jnp.asarray(mj_model.key("home").qpos)
        self.data0 = mjx.make_data(mj_model).replace(qpos=self.home_qpos)
        self.layout = layout
        self.is_ant = spec.agent.kind == "ant"

    def fresh_episode(self, key: jax.Array):
        """Agent pose noise, target and ball spawn: new draws from `key`."""
        k_q, k_v, k_target, k_ball = jax.random.split(key, 4)
        noise, layout = self.spec.agent.reset_noise, self.layout
        agent_noise = jax.random.uniform(k_q, (len(layout.agent_qpos),), minval=-noise.qpos, maxval=noise.qpos)
        if self.is_ant:
            agent_noise = agent_noise.at[3:7].set(0.0)  # keep the torso quaternion a unit quaternion
        qpos = self.home_qpos.at[jnp.asarray(layout.agent_qpos)].add(agent_noise)
        qvel = jnp.zeros(self.data0.qvel.shape).at[jnp.asarray(layout.agent_qvel)].set(
            noise.qvel * jax.random.normal(k_v, (len(layout.agent_qvel),)))
        target = self._sample_target(k_target)
        if self.spec.ball.enabled:
            qpos = qpos.at[jnp.asarray(layout.ball_qpos[:2])].set(self._sample_ball(k_ball, target))
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
            lo = jnp.array([s.x[0], s.y[0]])
            hi = jnp.array([s.x[1], s.y[1]])
            return jax.random.uniform(key, (2,), minval=lo, maxval=hi)
        start = jnp.asarray(self.spec.agent.start)
        jitter = jax.random.uniform(key, (2,), minval=-s.jitter, maxval=s.jitter)
        return start + s.fraction * (target - start) + jitter

    def score(self, t: Transition, names: tuple[str, ...]) -> tuple[dict, jax.Array]:
        """(metrics, reward) of one step; terms this field does not use read 0."""
        metrics = {"success": self.task.success(t)}
        metrics.update({name: self.task.terms[name](t) if name in self.task.terms else jnp.zeros(())
                        for name in names})
        return metrics, self.task.reward(metrics)

    def ended(self, data: mjx.Data, steps: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(time ran out, the agent fell)."""
        fell = jnp.zeros((), bool)
        if self.fell is not None:
            torso = data.qpos[jnp.asarray(self.layout.agent_qpos[:7])]
            fell = self.fell(torso[:3], torso[3:7])
        return steps >= self.episode_length, fell


def diverged(data: mjx.Data) -> jax.Array:
    """Whether the simulation has blown up: a position or velocity that is not finite or beyond
    mujoco's own bound (mjMAXVAL), where mujoco (not MJX) would warn and reset the data."""
    return ~(jnp.all(jnp.abs(data.qpos) < mujoco.mjMAXVAL) & jnp.all(jnp.abs(data.qvel) < mujoco.mjMAXVAL))


class FieldEnv:
    """A goal-conditioned environment: obs = concat(state, goal).

    Given several variants of a field (built to one structure by fieldgen.compile.variants),
    every environment carries its own variant (`info["variant"]`), all stepped in one
    batched simulation; each new episode draws its variant from `info["variant_weights"]`.
    """

    def __init__(self, artifacts: Artifact | Sequence[Artifact], episode_length: int | None = None,
                 auto_reset: bool = True):
        artifacts = [artifacts] if isinstance(artifacts, Artifact) else list(artifacts)
        self.artifacts = artifacts
        self.artifact = artifacts[-1]  # a mixed environment is judged on its last variant
        self.spec = spec = self.artifact.spec
        models = [a.model() for a in artifacts]
        self.mj_model = models[-1]
        self.layout = observation_layout(spec, self.mj_model)
        self.variants = [Variant(a.spec, m, self.layout, episode_length) for a, m in zip(artifacts, models)]
        _check_compatible(self.variants, models, self.layout)
        self.task = self.variants[-1].task
        self.sys, self._varying = _batched_model(models, [a.spec.name for a in artifacts])
        self.episode_length = max(v.episode_length for v in self.variants)
        self._ball_radii = jnp.asarray([v.spec.ball.radius for v in self.variants])
        self.auto_reset = auto_reset
        self.n_substeps = spec.episode.substeps
        self.dt = spec.episode.control_dt
        self.observation_size = self.layout.size
        self.action_size = int(self.mj_model.nu)
        self.state_dim = self.layout.state_dim
        self.goal_indices = np.array(self.layout.goal_indices)
        self.observation_names = self.layout.names
        self.action_names = tuple(self.mj_model.actuator(i).name for i in range(self.mj_model.nu))  # = joint names
        self.terms = tuple(dict.fromkeys(n for v in self.variants for n in v.task.terms))
        self.metric_names = ("success", *self.terms)
        self._agent_qpos = jnp.asarray(self.layout.agent_qpos)
        self._agent_qvel = jnp.asarray(self.layout.agent_qvel)
        self._ball_qpos = jnp.asarray(self.layout.ball_qpos)
        self._ball_qvel = jnp.asarray(self.layout.ball_qvel)
        self._is_ant = spec.agent.kind == "ant"
        self._agent_z = geometry.POINT_RADIUS

    @property
    def variant_count(self) -> int:
        return len(self.variants)

    @property
    def mixed(self) -> bool:
        return len(self.variants) > 1

    def adapt(self, env_state: State, metrics: dict) -> tuple[State, dict]:
        """New variant weights for the episodes to come (envs batched on axis 0), from an evaluation's
        `variant_KK_success_any`: `sampling_weights`. Returns the state and `variant_KK_weight`."""
        success = jnp.stack([metrics[f"variant_{k + 1:02d}_success_any"] for k in range(self.variant_count)])
        weights = sampling_weights(success)
        info = dict(env_state.info, variant_weights=jnp.broadcast_to(weights, env_state.info["variant_weights"].shape))
        return env_state.replace(info=info), {f"variant_{k + 1:02d}_weight": w for k, w in enumerate(weights)}

    def _each(self, variant: jax.Array, fn):
        """fn(the variant's rules), for a traced variant index (every branch runs under vmap: all are cheap)."""
        if not self.mixed:
            return fn(self.variants[0])
        return jax.lax.switch(variant, [lambda v=v: fn(v) for v in self.variants])

    def _model(self, variant: jax.Array):
        if not self._varying:
            return self.sys
        leaves, treedef = jax.tree.flatten(self.sys)
        return treedef.unflatten([x[variant] if i in self._varying else x for i, x in enumerate(leaves)])

    # -- reset -------------------------------------------------------------

    def reset(self, rng: jax.Array) -> State:
        """A fresh episode; a mixed environment draws its variant uniformly."""
        if not self.mixed:
            return self.reset_variant(rng, 0)
        rng, k_variant = jax.random.split(rng)
        return self.reset_variant(rng, jax.random.randint(k_variant, (), 0, len(self.variants)))

    def reset_variant(self, rng: jax.Array, variant) -> State:
        rng, episode_key = jax.random.split(rng)
        variant = jnp.asarray(variant, jnp.int32)
        data, goal = self._each(variant, lambda v: v.fresh_episode(episode_key))
        zero = jnp.zeros(())
        info = {"rng": rng, "goal": goal, "steps": jnp.zeros((), jnp.int32), "truncation": zero,
                "episode": jnp.zeros((), jnp.int32)}
        if self.mixed:
            n = len(self.variants)
            info.update(variant=variant, variant_weights=jnp.full(n, 1.0 / n))
        metrics = {name: zero for name in self.metric_names}
        return State(data, self._obs(data, goal), zero, zero, metrics, info)

    # -- step --------------------------------------------------------------

    def step(self, state: State, action: jax.Array) -> State:
        action = jnp.clip(action, -1.0, 1.0)
        before = state.pipeline_state
        variant = state.info.get("variant", jnp.zeros((), jnp.int32))
        sys = self._model(variant)
        with jax.default_matmul_precision(self.spec.sim.precision):
            data = jax.lax.fori_loop(0, self.n_substeps, lambda _, d: mjx.step(sys, d), before.replace(ctrl=action))
        goal = state.info["goal"]
        t = Transition(self._ball_pos(before, variant), self._ball_pos(data, variant), self._agent_pos(before),
                       self._agent_pos(data), goal, action, self.dt)
        steps = state.info["steps"] + 1
        metrics, reward, (truncated, fell) = self._each(
            variant, lambda v: (*v.score(t, self.terms), v.ended(data, steps)))
        broken = diverged(data)
        metrics, reward = jax.tree.map(lambda x: jnp.where(broken, jnp.zeros_like(x), x), (metrics, reward))
        fell = fell | broken
        done = truncated | fell
        info = dict(state.info, steps=steps, truncation=(truncated & ~fell).astype(jnp.float32))
        obs = self._obs(data, goal)
        if self.auto_reset:
            rng, key = jax.random.split(state.info["rng"])
            if self.mixed:
                key, k_variant = jax.random.split(key)
                drawn = jax.random.categorical(k_variant, jnp.log(state.info["variant_weights"]))
                variant = jnp.where(done, drawn, variant).astype(jnp.int32)
                info.update(variant=variant)
            fresh, fresh_goal = self._each(variant, lambda v: v.fresh_episode(key))
            data = data.replace(**{f: jnp.where(done, getattr(fresh, f), getattr(data, f)) for f in _STATE_FIELDS})
            goal = jnp.where(done, fresh_goal, goal)
            obs = jnp.where(done, self._obs(fresh, fresh_goal), obs)
            info.update(rng=rng, goal=goal, steps=jnp.where(done, 0, steps),
                        episode=state.info["episode"] + done.astype(jnp.int32))
        return State(data, obs, reward, done.astype(jnp.float32), metrics, info)

    def goal_reached(self, state: jax.Array, goal: jax.Array) -> jax.Array:
        """The field's success predicate (0/1) of an observation's state part and any goal: what
        hindsight relabelling scores a stored state against a goal taken from its future."""
        agent = state[:3] if self._is_ant else jnp.append(state[:2], self._agent_z)
        ball = jnp.zeros(3)
        if self.spec.ball.enabled:
            start, stop = self.layout.slices["ball_pos"]
            ball = state[start:stop] if stop - start == 3 else jnp.append(state[start:stop], self._ball_radii[-1])
        t = Transition(ball, ball, agent, agent, goal, jnp.zeros(self.action_size), self.dt)
        return self.task.success(t)

    # -- views -------------------------------------------------------------

    def _obs(self, data: mjx.Data, goal: jax.Array) -> jax.Array:
        parts = [data.qpos[self._agent_qpos], data.qvel[self._agent_qvel], data.qpos[self._ball_qpos],
                 data.qvel[self._ball_qvel], goal]
        return jnp.concatenate(parts)

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


def _check_compatible(variants: list[Variant], models, layout) -> None:
    """Variants batched together must share the observation layout, the control period and the structure."""
    first = variants[0].spec
    for v, model in zip(variants[1:], models[1:]):
        if observation_layout(v.spec, model).to_json() != layout.to_json():
            raise ValueError(f"{v.spec.name} and {first.name} observe different things; "
                             "variants trained in one batch need one observation layout")
        e, f = v.spec.episode, first.episode
        if (e.control_dt, e.substeps) != (f.control_dt, f.substeps):
            raise ValueError(f"{v.spec.name} steps {e.substeps} x {e.physics_dt} s and {first.name} "
                             f"{f.substeps} x {f.physics_dt} s; variants trained in one batch need one control period")
        if v.spec.sim.precision != first.sim.precision:
            raise ValueError(f"{v.spec.name} and {first.name} differ in sim.precision")


# Static (non-array) model fields that differ between variants but that stepping never reads:
# keyframes (each variant's home pose is read from its own MjModel) and height-field bounds.
_UNREAD_STATIC = {"key_time", "key_qpos", "key_qvel", "key_act", "key_mpos", "key_mquat", "key_ctrl",
                  "geom_rbound_hfield"}


def _batched_model(models, names: list[str]) -> tuple[object, frozenset[int]]:
    """One mjx.Model whose leaves that differ between the variants are stacked on a leading axis,
    and the indices of those leaves."""
    systems = [mjx.put_model(m) for m in models]
    first = systems[0]
    systems = [first] + [_static_like(first, s, f"{n} and {names[0]}") for s, n in zip(systems[1:], names[1:])]
    columns = zip(*(jax.tree.leaves(s) for s in systems))
    leaves, varying = [], set()
    for i, column in enumerate(columns):
        if all(np.array_equal(np.asarray(column[0]), np.asarray(c)) for c in column[1:]):
            leaves.append(column[0])
        else:
            leaves.append(jnp.stack(column))
            varying.add(i)
    return jax.tree.structure(systems[0]).unflatten(leaves), frozenset(varying)


def _static_like(first, other, which: str):
    """`other` with the unread static fields of `first`; any other static difference is an error."""
    changes = {}
    for field in dataclasses.fields(other):
        a, b = getattr(first, field.name), getattr(other, field.name)
        if dataclasses.is_dataclass(b) and not isinstance(b, type):
            b = _static_like(a, b, which)
        elif isinstance(b, jax.Array) or _same(a, b):
            continue
        elif field.name not in _UNREAD_STATIC:
            raise ValueError(f"{which} differ in the model's structure ({field.name}); variants trained in one "
                             "batch must share bodies, joints, geoms and contact settings (build them with "
                             "fieldgen.compile.variants.compile_variants)")
        else:
            b = a
        changes[field.name] = b
    return other.replace(**changes) if changes else other


def _same(a, b) -> bool:
    try:
        return bool(np.array_equal(np.asarray(a), np.asarray(b)))
    except (TypeError, ValueError):
        return a == b


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
