"""The ball's shortest way to the target around the field's solid obstacles, as a JAX function.

Straight-line progress pays a ball pushed against a goalie that stands between it and the target as well
as one pushed past it: the learner meets a wall of reward exactly where it must go sideways. Measured
along the shortest way around the obstacles instead, every step round the goalie's end is progress.

The way is the shortest path through a visibility graph: the ball, the target and the four corners of
each solid obstacle grown by the ball's radius (the ball's centre cannot come nearer its faces), joined
where the straight segment between two of them crosses no grown obstacle. The corners' edges among
themselves are fixed and found once; every step finds the ball's and the target's, then relaxes the
corners' ways to the target K times for K corners (Bellman and Ford).
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from fieldgen.schema import geometry
from fieldgen.schema.models import FieldSpec

BLOCKING_RADII = 0.9  # a segment is blocked inside an obstacle grown by this many ball radii: a ball pressed
# against a face (its centre one radius out, or a little nearer in contact) still sees past it
CORNER_RADII = 1.1  # the detour's corners stand this many ball radii out from the faces, outside the blocking box
TOUCH = 1e-6  # a segment shorter than this inside a blocking box grazes it and is not blocked

Way = Callable[[jax.Array, jax.Array], jax.Array]  # (ball xy or xyz, target xy) -> length of the way


def solid_boxes(spec: FieldSpec) -> list[tuple[float, float, float, float]]:
    """(x0, x1, y0, y1) of each solid obstacle, before growing."""
    return [box.xy_bounds() for box in geometry.obstacles(spec) if box.solid]


def blocked(a: jax.Array, b: jax.Array, boxes: jax.Array) -> jax.Array:
    """Whether the segment a-b (each [..., 2]) runs through the inside of any box (boxes [n, 4] as x0, x1,
    y0, y1): Liang and Barsky's clipping, for all segments and boxes at once. [...] bool."""
    a, b = a[..., None, :], b[..., None, :]  # [..., 1, 2] against the boxes' [n]
    d = b - a
    low = jnp.stack([boxes[:, 0], boxes[:, 2]], -1)  # [n, 2]
    high = jnp.stack([boxes[:, 1], boxes[:, 3]], -1)
    moving = jnp.abs(d) > 0
    step = jnp.where(moving, d, 1.0)
    t_low, t_high = (low - a) / step, (high - a) / step
    inside_slab = (a > low) & (a < high)  # for a segment parallel to this axis
    enter = jnp.where(moving, jnp.minimum(t_low, t_high), jnp.where(inside_slab, -jnp.inf, jnp.inf))
    leave = jnp.where(moving, jnp.maximum(t_low, t_high), jnp.where(inside_slab, jnp.inf, -jnp.inf))
    enter = jnp.maximum(jnp.max(enter, -1), 0.0)
    leave = jnp.minimum(jnp.min(leave, -1), 1.0)
    length = jnp.linalg.norm(d[..., 0, :], axis=-1)[..., None]
    return jnp.any((leave - enter) * length > TOUCH, -1)


def edges(a: jax.Array, b: jax.Array, boxes: jax.Array) -> jax.Array:
    """The length of each segment a-b (broadcast together, [..., 2]), or infinity where it is blocked."""
    a, b = jnp.broadcast_arrays(a, b)
    return jnp.where(blocked(a, b, boxes), jnp.inf, jnp.linalg.norm(a - b, axis=-1))


def way_to_target(spec: FieldSpec) -> Way:
    """The length of the ball's shortest way to a target around the spec's solid obstacles; the straight
    distance where the field has none (or where no way around exists, which a sound field never has)."""
    boxes = solid_boxes(spec)
    straight = lambda ball, target: jnp.linalg.norm(ball[:2] - target[:2])  # noqa: E731
    if not boxes:
        return straight
    r = spec.ball.radius
    grown = lambda box, by: (box[0] - by, box[1] + by, box[2] - by, box[3] + by)  # noqa: E731
    blocking = jnp.asarray([grown(b, BLOCKING_RADII * r) for b in boxes], jnp.float32)
    corners = jnp.asarray(np.asarray([(x, y) for b in boxes for x in grown(b, CORNER_RADII * r)[:2]
                                      for y in grown(b, CORNER_RADII * r)[2:]], np.float32))
    between_corners = edges(corners[:, None], corners[None, :], blocking)  # [K, K]: the same on every step
    relaxations = len(corners)

    def way(ball: jax.Array, target: jax.Array) -> jax.Array:
        ends = jnp.stack([ball[:2], target[:2]])  # the graph's two moving nodes
        to_corners = edges(ends[:, None], corners[None, :], blocking)  # [2, K]: from the ball, from the target
        corner_way = jax.lax.fori_loop(  # each corner's shortest way on to the target
            0, relaxations, lambda _, d: jnp.minimum(d, jnp.min(between_corners + d[None, :], -1)), to_corners[1])
        direct = edges(ends[0], ends[1], blocking)
        length = jnp.minimum(direct, jnp.min(to_corners[0] + corner_way))
        return jnp.where(jnp.isfinite(length), length, straight(ball, target))

    return way
