"""The physics pipelines `sim.backend` names, and what brax's cannot represent of a field, found
before anything compiles.

BACKENDS is the one place a backend is named: the schema's choices and defaults, these checks,
fieldgen/env/brax_pipeline.py's pipelines (brax.<name>.pipeline) and MJX's implementation an MJX field
is stepped by (`mjx_impl`: fieldgen/env/mjx_physics.py) all read it.

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
    mjx_impl: str | None  # MJX's implementation that steps it (mujoco.mjx's impl: jax, warp); None: brax's pipeline
    joint_damping: bool  # it simulates joint damping, which is what slows a point agent on its slides
    # (section, key) -> value, where a spec leaves it out: the physics its reference was tuned with
    defaults: dict[tuple[str, str], float] = field(default_factory=dict)

    @property
    def brax(self) -> bool:
        """One of brax's pipelines, the module brax.<name>.pipeline."""
        return self.mjx_impl is None


BACKENDS: dict[str, Backend] = {
    "mjx": Backend("MuJoCo MJX", mjx_impl="jax", joint_damping=True),
    # the same scene and contacts as mjx, stepped by MuJoCo Warp's kernels through MJX
    "warp": Backend("MuJoCo Warp through MJX: NVIDIA GPUs; on a CPU Warp's CPU kernels, slow", mjx_impl="warp",
                    joint_damping=True),
    # brax's pipelines as its reference ant sets them: spring and positional step 0.005 s (10 steps per
    # 0.05 s control step), generalized 0.01 s with 4 solver iterations.
    "spring": Backend("brax's pipeline of the CRL reference's ant", mjx_impl=None, joint_damping=False,
                      defaults={("episode", "physics_dt"): 0.005}),
    "positional": Backend("brax's pipeline of the soccer study's CRL runs", mjx_impl=None, joint_damping=False,
                          defaults={("episode", "physics_dt"): 0.005}),
    "generalized": Backend("brax's pipeline", mjx_impl=None, joint_damping=True, defaults={("sim", "iterations"): 4}),
}
BRAX = tuple(name for name, backend in BACKENDS.items() if backend.brax)


def mjx_impl(spec: FieldSpec) -> str | None:
    """The MJX implementation that steps the spec's field, None where brax's pipeline does."""
    return BACKENDS[spec.sim.backend].mjx_impl


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
        *others, last = [name for name, b in BACKENDS.items() if b.joint_damping]
        damped = f"{', '.join(others)} or {last}" if others else last
        out.append((("sim", "backend"), f"brax's {backend} pipeline ignores joint damping, which is what slows the "
                    f"point agent (agent.kind: point) on its slides; use backend {damped}, or agent.kind: ant"))
    return out
