"""A curriculum at a glance: every stage drawn from one camera, side by side under its name, from above at
one scale with its field's size written under it."""

from __future__ import annotations

from fieldgen.compile.artifact import compile_spec
from fieldgen.curriculum.folder import Curriculum
from fieldgen.render import contact_sheet, render_pose, same_scale


def stage_sheet(c: Curriculum, camera: str) -> bytes:
    """PNG bytes of a grid of the stages, numbered from 1, each compiled in memory (nothing is built)."""
    specs = c.specs()
    models = [compile_spec(spec).model() for spec in specs]
    if camera == "top":
        same_scale(models, camera)
    images = [render_pose(model, camera=camera, height=240) for model in models]
    sizes = [f"field {spec.field.width:g} wide, {spec.field.length:g} long" for spec in specs]
    return contact_sheet(images, [f"{i}. {stage.name}" for i, stage in enumerate(c.stages, 1)], captions=sizes)
