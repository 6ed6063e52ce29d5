"""Reward terms and success predicates, generated from the spec as JAX functions.

The terms are named in fieldgen/schema/terms.py; here each name gets its implementation, a
function of a `Transition` (positions before and after one control step, the action, the target)
that returns a scalar, and this module refuses to import unless the two cover the same names.
Values are signed so that larger is better: `control_cost` is -|a|^2, and a spec weights it with a
positive number. The reward is sum(weight * term).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import jax
import jax.numpy as jnp

from fieldgen.env.paths import way_to_target
from fieldgen.schema import geometry
from fieldgen.schema.models import FieldSpec, RewardTerm
from fieldgen.schema.terms import TERMS

MIN_SCALE_DISTANCE = 0.1  # scaled_ball_progress and scaled_ball_path_progress divide by max(distance, this)


@dataclass(frozen=True)
class Transition:
    """What reward and success functions see of one control step (built inside jit)."""

    ball_before: jax.Array  # (3,) world position; zeros when the field has no ball
    ball: jax.Array
    agent_before: jax.Array  # (3,) torso or point position
    agent: jax.Array
    target: jax.Array  # (2,)
    action: jax.Array
    dt: float


TermFn = Callable[[Transition], jax.Array]
BuildTerm = Callable[[FieldSpec, RewardTerm], TermFn]  # (the spec, the term's entry in it) -> the term
IMPLEMENTATIONS: dict[str, BuildTerm] = {}  # by the names of TERMS, each once


def builds(name: str):
    """Registers a function that builds the term `name` for a spec, refusing a name TERMS lacks."""

    def register(build: BuildTerm) -> BuildTerm:
        if name not in TERMS:
            raise ValueError(f"'{name}' is no reward term of fieldgen/schema/terms.py; name it there first")
        if name in IMPLEMENTATIONS:
            raise ValueError(f"reward term '{name}' is implemented twice")
        IMPLEMENTATIONS[name] = build
        return build

    return register


def term(name: str):
    """Registers fn(transition, the term's entry in the spec) as the term `name`."""

    def register(fn: Callable[[Transition, RewardTerm], jax.Array]):
        builds(name)(lambda spec, cfg: lambda t: fn(t, cfg))
        return fn

    return register


def _dist(a: jax.Array, b: jax.Array) -> jax.Array:
    return jnp.linalg.norm(a[:2] - b[:2])


def progress(before, after, goal, dt) -> jax.Array:
    """Decrease of the distance from a point to `goal` on the field's plane, per second."""
    return (_dist(before, goal) - _dist(after, goal)) / dt


@term("ball_progress")
def _ball_progress(t: Transition, cfg: RewardTerm) -> jax.Array:
    """Decrease of the ball's distance to the target, per second."""
    return progress(t.ball_before, t.ball, t.target, t.dt)


@term("scaled_ball_progress")
def _scaled_ball_progress(t: Transition, cfg: RewardTerm) -> jax.Array:
    """ball_progress / ||ball - target||: progress counts more near the target."""
    return _ball_progress(t, cfg) / jnp.maximum(_dist(t.ball, t.target), MIN_SCALE_DISTANCE)


@builds("ball_path_progress")
def _ball_path_progress(spec: FieldSpec, cfg: RewardTerm) -> TermFn:
    """Decrease of the ball's shortest way to the target around the solid obstacles, per second: a ball
    pushed round a goalie's end progresses, one pushed against the goalie does not."""
    way = way_to_target(spec)
    return lambda t: (way(t.ball_before, t.target) - way(t.ball, t.target)) / t.dt


@builds("scaled_ball_path_progress")
def _scaled_ball_path_progress(spec: FieldSpec, cfg: RewardTerm) -> TermFn:
    """ball_path_progress / the ball's way to the target, as scaled_ball_progress is to ball_progress: the last
    metre to the target counts as much as the ten before it, and pushing the ball on past the target costs as
    much."""
    path_progress, way = _ball_path_progress(spec, cfg), way_to_target(spec)
    return lambda t: path_progress(t) / jnp.maximum(way(t.ball, t.target), MIN_SCALE_DISTANCE)


@term("agent_approaches_ball")
def _agent_approaches_ball(t: Transition, cfg: RewardTerm) -> jax.Array:
    """Decrease of the agent's distance to the ball, per second."""
    return (_dist(t.agent_before, t.ball_before) - _dist(t.agent, t.ball)) / t.dt


@builds("agent_behind_ball")
def _agent_behind_ball(spec: FieldSpec, cfg: RewardTerm) -> TermFn:
    """Approach to the point behind the ball on its way to the target, so that the agent's pushes send the
    ball along that way: the way's slope at the ball points back along it (away from the next corner of the
    way round a goalie, or from the target where nothing stands between)."""
    way = way_to_target(spec)
    slope = jax.grad(way)
    body = geometry.ANT_TORSO_RADIUS if spec.agent.kind == "ant" else geometry.POINT_RADIUS
    behind = spec.ball.radius + body

    def push_point(ball: jax.Array, target: jax.Array) -> jax.Array:
        back = jnp.nan_to_num(slope(ball[:2], target[:2]))  # no slope where the ball sits on the target
        return ball[:2] + behind * back / jnp.maximum(jnp.linalg.norm(back), 1e-6)

    return lambda t: (_dist(t.agent_before, push_point(t.ball_before, t.target))
                      - _dist(t.agent, push_point(t.ball, t.target))) / t.dt


@term("agent_progress")
def _agent_progress(t: Transition, cfg: RewardTerm) -> jax.Array:
    """Decrease of the agent's distance to the target, per second."""
    return progress(t.agent_before, t.agent, t.target, t.dt)


@term("upright")
def _upright(t: Transition, cfg: RewardTerm) -> jax.Array:
    """1 while the torso height lies inside the term's band."""
    lo, hi = cfg.band
    return ((t.agent[2] >= lo) & (t.agent[2] <= hi)).astype(jnp.float32)


@term("control_cost")
def _control_cost(t: Transition, cfg: RewardTerm) -> jax.Array:
    """-|a|^2: weight it positively to penalise effort."""
    return -jnp.sum(jnp.square(t.action))


def success_fn(spec: FieldSpec) -> TermFn:
    """The spec's success predicate, as a float 0/1."""
    kind, radius = spec.task.success.kind, spec.task.success.radius
    if kind == "ball_near_target":
        return lambda t: (_dist(t.ball, t.target) < radius).astype(jnp.float32)
    if kind == "agent_near_target":
        return lambda t: (_dist(t.agent, t.target) < radius).astype(jnp.float32)
    return ball_in_goal_fn(spec)


def ball_in_goal_fn(spec: FieldSpec) -> TermFn:
    """The ball's centre inside the goal box."""
    region = geometry.goal_region(spec)
    if region is None:
        return lambda t: jnp.zeros((), jnp.float32)
    x0, x1, y0, y1 = region.xy_bounds()
    top = 2 * region.half[2]

    def inside(t: Transition) -> jax.Array:
        b = t.ball
        return ((b[0] >= x0) & (b[0] <= x1) & (b[1] >= y0) & (b[1] <= y1) & (b[2] <= top)).astype(jnp.float32)

    return inside


@builds("success")
def _success(spec: FieldSpec, cfg: RewardTerm) -> TermFn:
    """The success predicate as a term: the sparse reward."""
    return success_fn(spec)


@builds("ball_in_goal")
def _ball_in_goal(spec: FieldSpec, cfg: RewardTerm) -> TermFn:
    """The ball in the goal box, whatever the success predicate judges."""
    return ball_in_goal_fn(spec)


@dataclass(frozen=True)
class TaskFns:
    success: TermFn
    terms: dict[str, TermFn]  # metric name -> unweighted value
    weights: dict[str, float]

    def reward(self, values: dict[str, jax.Array]) -> jax.Array:
        return sum(self.weights[name] * values[name] for name in self.weights)


def task_fns(spec: FieldSpec) -> TaskFns:
    terms, weights = {}, {}
    for cfg in spec.task.reward:
        name, n = cfg.term, 2
        while name in terms:  # the same term twice (say, two upright bands) keeps both
            name, n = f"{cfg.term}_{n}", n + 1
        terms[name] = IMPLEMENTATIONS[cfg.term](spec, cfg)
        weights[name] = cfg.weight
    return TaskFns(success_fn(spec), terms, weights)


def _check_every_term_implemented() -> None:
    """Called as this module loads, so that a term named in TERMS but implemented nowhere fails at once,
    not when a spec first uses it."""
    missing = [name for name in TERMS if name not in IMPLEMENTATIONS]
    if missing:
        raise ImportError(f"reward terms named in fieldgen/schema/terms.py without an implementation in "
                          f"{__name__}: {', '.join(missing)}")


_check_every_term_implemented()
