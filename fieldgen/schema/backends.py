"""The physics pipelines `sim.backend` names, and what brax's cannot represent of a field, found
before anything compiles.

BACKENDS is the one place a backend is named: the schema's choices and defaults, these checks and
fieldgen/env/brax_pipeline.py's pipelines (brax.<name>.pipeline) all read it.

brax 0.14.2 loads the same scene.xml as MJX and collides through MJX's own collision
functions, so every geom pair fieldgen builds (planes, spheres, capsules, boxes) collides on
every pipeline. What differs is the rest of the model: brax's loader refuses elliptic friction
cones, none of its pipelines has MJX's implicit joint damping, and spring and positional ignore
joint damping and armature altogether (the ant keeps them only as the reference's ant did, as
numbers brax never reads), which leaves a point agent, moved against the damping of its slides,
with nothing to slow it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # models reads BACKENDS, so this module cannot import it
    from fieldgen.schema.models import FieldSpec


@dataclass(frozen=True)
class Backend:
    description: str  # what sim.backend's description says of it
    brax: bool  # one of brax's pipelines, the module brax.<name>.pipeline
    joint_damping: bool  # it simulates joint damping, which is what slows a point agent on its slides
    # (section, key) -> value, where a spec leaves it out: the physics its reference was tuned with
    defaults: dict[tuple[str, str], float] = field(default_factory=dict)


BACKENDS: dict[str, Backend] = {
    "mjx": Backend("MuJoCo MJX", brax=False, joint_damping=True),
    # brax's pipelines as its reference ant sets them: spring and positional step 0.005 s (10 steps per
    # 0.05 s control step), generalized 0.01 s with 4 solver iterations.
    "spring": Backend("brax's pipeline of the CRL reference's ant", brax=True, joint_damping=False,
                      defaults={("episode", "physics_dt"): 0.005}),
    "positional": Backend("brax's pipeline of the soccer study's CRL runs", brax=True, joint_damping=False,
                          defaults={("episode", "physics_dt"): 0.005}),
    "generalized": Backend("brax's pipeline", brax=True, joint_damping=True, defaults={("sim", "iterations"): 4}),
}
BRAX = tuple(name for name, backend in BACKENDS.items() if backend.brax)


def backend_description() -> str:
    """sim.backend's description: each backend, and the defaults it brings."""
    def one(name: str, backend: Backend) -> str:
        defaults = ", ".join(f"{section}.{key} {value:g}" for (section, key), value in backend.defaults.items())
        return f"{name} ({backend.description}{'; default ' + defaults if defaults else ''})"

    return "physics pipeline: " + ", ".join(one(name, backend) for name, backend in BACKENDS.items())


def backend_problems(spec: FieldSpec) -> list[tuple[tuple, str]]:
    """(key path, message) for each thing of the spec that its sim.backend cannot simulate."""
    backend, sim = spec.sim.backend, spec.sim
    if not BACKENDS[backend].brax:
        return []
    out = []
    if sim.cone != "pyramidal":
        out.append((("sim", "cone"), f"brax's {backend} pipeline has only the pyramidal friction cone; "
                    "use cone: pyramidal, or backend: mjx for the elliptic cone"))
    if sim.euler_damping:
        out.append((("sim", "euler_damping"), f"implicit joint damping is MJX's; brax's {backend} pipeline has none: "
                    "use euler_damping: false, or backend: mjx"))
    if spec.agent.kind == "point" and not BACKENDS[backend].joint_damping:
        damped = " or ".join(name for name, b in BACKENDS.items() if b.joint_damping)
        out.append((("sim", "backend"), f"brax's {backend} pipeline ignores joint damping, which is what slows the "
                    f"point agent (agent.kind: point) on its slides; use backend {damped}, or agent.kind: ant"))
    return out
