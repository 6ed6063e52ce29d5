"""Reward terms and success predicates, generated from the spec as JAX functions.

Terms live in one registry; each takes a `Transition` (positions before and
after one control step, the action, the target) and returns a scalar. Values
are signed so that larger is better: `control_cost` is -|a|^2, and a spec
weights it with a positive number. The reward is sum(weight * term).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import jax
import jax.numpy as jnp

from fieldgen.schema import geometry
from fieldgen.schema.models import FieldSpec, RewardTerm

MIN_SCALE_DISTANCE = 0.1  # scaled_ball_progress divides by max(distance, this)


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


TermFn = Callable[[Transition, RewardTerm], jax.Array]
TERMS: dict[str, TermFn] = {}


def term(name: str):
    def register(fn: TermFn) -> TermFn:
        TERMS[name] = fn
        return fn

    return register


def _dist(a: jax.Array, b: jax.Array) -> jax.Array:
    return jnp.linalg.norm(a[:2] - b[:2])


def _progress(before, after, goal, dt) -> jax.Array:
    return (_dist(before, goal) - _dist(after, goal)) / dt


@term("ball_progress")
def _ball_progress(t: Transition, cfg: RewardTerm) -> jax.Array:
    """Decrease of the ball's distance to the target, per second."""
    return _progress(t.ball_before, t.ball, t.target, t.dt)


@term("scaled_ball_progress")
def _scaled_ball_progress(t: Transition, cfg: RewardTerm) -> jax.Array:
    """ball_progress / ||ball - target||: progress counts more near the target."""
    return _ball_progress(t, cfg) / jnp.maximum(_dist(t.ball, t.target), MIN_SCALE_DISTANCE)


@term("agent_approaches_ball")
def _agent_approaches_ball(t: Transition, cfg: RewardTerm) -> jax.Array:
    """Decrease of the agent's distance to the ball, per second."""
    return (_dist(t.agent_before, t.ball_before) - _dist(t.agent, t.ball)) / t.dt


@term("agent_progress")
def _agent_progress(t: Transition, cfg: RewardTerm) -> jax.Array:
    """Decrease of the agent's distance to the target, per second."""
    return _progress(t.agent_before, t.agent, t.target, t.dt)


@term("upright")
def _upright(t: Transition, cfg: RewardTerm) -> jax.Array:
    """1 while the torso height lies inside the term's band."""
    lo, hi = cfg.band
    return ((t.agent[2] >= lo) & (t.agent[2] <= hi)).astype(jnp.float32)


@term("control_cost")
def _control_cost(t: Transition, cfg: RewardTerm) -> jax.Array:
    """-|a|^2: weight it positively to penalise effort."""
    return -jnp.sum(jnp.square(t.action))


def success_fn(spec: FieldSpec) -> Callable[[Transition], jax.Array]:
    """The spec's success predicate, as a float 0/1."""
    kind, radius = spec.task.success.kind, spec.task.success.radius
    if kind == "ball_near_target":
        return lambda t: (_dist(t.ball, t.target) < radius).astype(jnp.float32)
    if kind == "agent_near_target":
        return lambda t: (_dist(t.agent, t.target) < radius).astype(jnp.float32)
    return ball_in_goal_fn(spec)


def ball_in_goal_fn(spec: FieldSpec) -> Callable[[Transition], jax.Array]:
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


@dataclass(frozen=True)
class TaskFns:
    success: Callable[[Transition], jax.Array]
    terms: dict[str, Callable[[Transition], jax.Array]]  # metric name -> unweighted value
    weights: dict[str, float]

    def reward(self, values: dict[str, jax.Array]) -> jax.Array:
        return sum(self.weights[name] * values[name] for name in self.weights)


def task_fns(spec: FieldSpec) -> TaskFns:
    success = success_fn(spec)
    in_goal = ball_in_goal_fn(spec)
    terms, weights = {}, {}
    for cfg in spec.task.reward:
        name, n = cfg.term, 2
        while name in terms:  # the same term twice (say, two upright bands) keeps both
            name, n = f"{cfg.term}_{n}", n + 1
        if cfg.term == "success":
            terms[name] = success
        elif cfg.term == "ball_in_goal":
            terms[name] = in_goal
        else:
            terms[name] = (lambda fn, c: (lambda t: fn(t, c)))(TERMS[cfg.term], cfg)
        weights[name] = cfg.weight
    return TaskFns(success, terms, weights)
