"""The automatic curriculum: levels derived from the spec alone, all trained at once, weighted by what is
being learnt now.

`levels(spec, count)` lays `count` levels on a path from the spec's easy end to the spec itself
(fieldgen.curriculum.levels): first the kick-off moves back from next to the target to the spec's own, then
the obstacles grow back to their width and place and the walls return. A level the schema refuses (its
flood fill finds no way for the ball into the goal, a start inside an obstacle...) is never played. The
levels are built to one structure and batched in one simulation, each environment playing its own level,
as a mixed curriculum is (`Auto` is a `Mixed` schedule with other weights).

`level_weights` is the sampler. A level's learnability is p(1 - p) for its success p (high where some
episodes succeed and some fail, as in Sampling For Learnability); a mixed curriculum's 0.1 + 4p(1-p) gives a
level at p = 0 a share as small as a solved one, so the frontier starves. Here the easiest level not yet
solved (the frontier) always holds FRONTIER_SHARE of the episodes, learnable levels share the rest by
p(1 - p), and the spec itself (the last level) keeps TARGET_SHARE throughout, so its success is always
learnt from as well as measured.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from fieldgen.curriculum.levels import LevelError, LevelSpace
from fieldgen.curriculum.schedule import Mixed
from fieldgen.schema import FieldSpec

LEVELS = 8  # levels on the path from the easy end to the spec, the spec included
SOLVED = 0.8  # a level at this success or above is behind the frontier
TARGET_SHARE = 0.2  # of new episodes, on the spec itself
FRONTIER_SHARE = 0.3  # of new episodes, on the easiest level not yet solved
FLOOR = 0.05  # of new episodes, spread evenly over every level but the spec: none is ever forgotten


@dataclasses.dataclass(frozen=True)
class Level:
    """One level: its coordinates on the space's axes (0 the easy end, 1 the spec) and its spec."""

    coordinates: tuple[float, ...]
    spec: FieldSpec


def path(axes: int, count: int) -> np.ndarray:
    """`count` points from every axis at 0 to every axis at 1: the kick-off (axis 0) over the first half,
    the field's geometry (the other axes) over the second; one axis moves over the whole path."""
    t = np.linspace(0.0, 1.0, count)
    if axes == 1:
        return t[:, None]
    kickoff = np.clip(2 * t, 0.0, 1.0)
    geometry = np.clip(2 * t - 1, 0.0, 1.0)
    return np.column_stack([kickoff] + [geometry] * (axes - 1))


def levels(spec: FieldSpec, count: int = LEVELS) -> list[Level]:
    """The playable levels of `spec`'s path, easiest first, the spec itself last (LevelError where the spec
    has no easy end, or too few levels are asked for)."""
    if count < 2:
        raise LevelError(f"--levels {count}: the automatic curriculum needs at least 2 levels (an easy end and "
                         "the spec itself)")
    space = LevelSpace.of(spec)
    out, seen = [], set()
    for point in path(len(space.axes), count)[:-1]:
        if not space.playable(point):
            continue
        level_spec = space.spec_at(point)
        key = level_spec.model_dump_json()
        if key not in seen:
            seen.add(key)
            out.append(Level(tuple(float(x) for x in point), level_spec))
    return out + [Level(tuple(1.0 for _ in space.axes), spec)]


def level_weights(success: jnp.ndarray) -> jnp.ndarray:
    """How often each level starts an episode next, from each level's success (the spec's last)."""
    n = success.shape[-1] - 1
    if n == 0:
        return jnp.ones_like(success)
    p = success[:-1]
    learnable = p * (1.0 - p)
    unsolved = p < SOLVED
    frontier = jnp.where(jnp.any(unsolved), jnp.argmax(unsolved), n - 1)
    at_frontier = (jnp.arange(n) == frontier).astype(success.dtype)
    total = jnp.sum(learnable)
    # learnable levels share what the frontier and the floor leave; with none learnable, the frontier takes it
    rest = jnp.where(total > 0, learnable / jnp.where(total > 0, total, 1.0), at_frontier)
    levels_ = FLOOR / n + FRONTIER_SHARE * at_frontier + (1.0 - FLOOR - FRONTIER_SHARE) * rest
    return jnp.concatenate([(1.0 - TARGET_SHARE) * levels_, jnp.full((1,), TARGET_SHARE, success.dtype)])


@dataclasses.dataclass(frozen=True)
class Auto(Mixed):
    """Every level at once, in one batched simulation, each weighted by `level_weights`."""

    def variant_weights(self, success):
        return level_weights(success)
