"""brax's own parameters of a scene that runs on one of its pipelines, written into scene.xml.

brax reads them from the MJCF's <custom> numerics (brax.io.mjcf): joint springs, their damping,
and how mass and inertia scale the spring pipeline's forces. The values are those of brax's
reference ant (brax/envs/assets/ant.xml), which the CRL reference and the soccer study copied
into their own scenes, ball and all. MJX reads none of them, so an MJX scene carries none.
"""

from __future__ import annotations

from fieldgen.schema.backends import mjx_impl
from fieldgen.schema.models import FieldSpec

REFERENCE_ANT = {
    "constraint_limit_stiffness": 1000.0,
    "constraint_stiffness": 4000.0,
    "constraint_ang_damping": 10.0,
    "constraint_vel_damping": 20.0,
    "joint_scale_pos": 0.5,
    "joint_scale_ang": 0.2,
    "ang_damping": 0.0,
    "spring_mass_scale": 1.0,
    "spring_inertia_scale": 1.0,
    "solver_maxls": 15.0,
}


def brax_parameters(spec: FieldSpec) -> dict[str, float]:
    """The <custom> numerics brax reads for this field: none under MJX."""
    return {} if mjx_impl(spec) else dict(REFERENCE_ANT)
