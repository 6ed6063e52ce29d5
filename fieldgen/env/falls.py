"""Fall rules, generated from the spec: when an ant has fallen, which ends its episode early.

`never` (the default, OGBench's ant soccer) leaves episodes to run out of time: the one
rule under which CRL has learnt the MJX ant. `flipped` ends it once the torso turns over
(for more than a grace of control steps), as MuJoCo Playground's quadrupeds do;
`height_band` is the soccer study's and the CRL reference's rule, a torso height band
tuned on brax's spring physics, where under MJX a hop that rises past it counts as a fall.
"""

from __future__ import annotations

import math
from typing import Callable

import jax

from fieldgen.env.contract import up_axis_z
from fieldgen.schema.models import FieldSpec


def fall_fn(spec: FieldSpec) -> tuple[Callable[[jax.Array, jax.Array], jax.Array], int] | None:
    """The spec's fall rule as (down(torso position (3,), torso quaternion (w, x, y, z)) -> bool, grace):
    the ant has fallen once it has been down for more than `grace` control steps in a row. None where
    nothing can fall (a point agent, or `never`)."""
    fall = spec.episode.fall
    if spec.agent.kind != "ant" or fall.kind == "never":
        return None
    if fall.kind == "height_band":
        lo, hi = fall.band
        return (lambda pos, quat: (pos[2] < lo) | (pos[2] > hi)), 0
    min_up = math.cos(math.radians(fall.tilt_deg))
    return (lambda pos, quat: up_axis_z(quat) < min_up), fall.grace_steps
