"""What brax's physics pipelines cannot represent of a field, found before anything compiles.

brax 0.14.2 loads the same scene.xml as MJX and collides through MJX's own collision
functions, so every geom pair fieldgen builds (planes, spheres, capsules, boxes) collides on
every pipeline. What differs is the rest of the model: brax's loader refuses elliptic friction
cones, none of its pipelines has MJX's implicit joint damping, and spring and positional ignore
joint damping and armature altogether (the ant keeps them only as the reference's ant did, as
numbers brax never reads), which leaves a point agent, moved against the damping of its slides,
with nothing to slow it.
"""

from __future__ import annotations

from fieldgen.schema.models import FieldSpec

BRAX = ("spring", "positional", "generalized")


def backend_problems(spec: FieldSpec) -> list[tuple[tuple, str]]:
    """(key path, message) for each thing of the spec that its sim.backend cannot simulate."""
    backend, sim = spec.sim.backend, spec.sim
    if backend not in BRAX:
        return []
    out = []
    if sim.cone != "pyramidal":
        out.append((("sim", "cone"), f"brax's {backend} pipeline has only the pyramidal friction cone; "
                    "use cone: pyramidal, or backend: mjx for the elliptic cone"))
    if sim.euler_damping:
        out.append((("sim", "euler_damping"), f"implicit joint damping is MJX's; brax's {backend} pipeline has none: "
                    "use euler_damping: false, or backend: mjx"))
    if spec.agent.kind == "point" and backend in ("spring", "positional"):
        out.append((("sim", "backend"), f"brax's {backend} pipeline ignores joint damping, which is what slows the "
                    "point agent (agent.kind: point) on its slides; use backend mjx or generalized, or agent.kind: ant"))
    return out
