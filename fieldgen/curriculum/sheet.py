"""A curriculum at a glance: every stage drawn from one camera, side by side under its name."""

from __future__ import annotations

from fieldgen.compile.artifact import compile_spec
from fieldgen.curriculum.folder import Curriculum
from fieldgen.render import contact_sheet, render_pose


def stage_sheet(c: Curriculum, camera: str) -> bytes:
    """PNG bytes of a grid of the stages, numbered from 1, each compiled in memory (nothing is built)."""
    images = [render_pose(compile_spec(spec).model(), camera=camera, height=240) for spec in c.specs()]
    return contact_sheet(images, [f"{i}. {stage.name}" for i, stage in enumerate(c.stages, 1)])
