"""A curriculum at a glance: every stage drawn from one camera, side by side under its name, from above at
one scale with its field's size written under it."""

from __future__ import annotations

from pathlib import Path

from fieldgen.compile.artifact import META, compile_spec, load_artifact
from fieldgen.curriculum.folder import Curriculum
from fieldgen.render import contact_sheet, render_pose, same_scale


def stage_sheet(c: Curriculum, camera: str) -> bytes:
    """PNG bytes of a grid of the stages, numbered from 1, each compiled in memory (nothing is built)."""
    specs = c.specs()
    return _sheet([compile_spec(spec) for spec in specs], [stage.name for stage in c.stages], camera)


def built_fields(folder: Path) -> list[Path]:
    """The built fields in `folder`, or in its `stages/` (a curriculum run's variants), in name order; none
    where it holds none (or is a built field itself)."""
    for where in (folder, folder / "stages"):
        if where.is_dir() and not (where / META).exists():
            found = sorted(p for p in where.iterdir() if (p / META).is_file())
            if found:
                return found
    return []


def built_sheet(folders: list[Path], camera: str, captions: list[str] | None = None) -> bytes:
    """PNG bytes of a grid of built fields (`built_fields`), numbered from 1 under their folders' names, each
    with its caption (by default its field's size)."""
    artifacts = [load_artifact(f) for f in folders]
    return _sheet(artifacts, [f"{f.name}: {a.spec.name}" for f, a in zip(folders, artifacts)], camera, captions)


def field_caption(spec) -> str:
    """What tells a sheet's fields apart at a glance: the field's size, its goal, goalie and other obstacles, and
    where its target lies."""
    parts = [f"field {spec.field.width:g} wide, {spec.field.length:g} long"]
    if spec.goal.enabled:
        parts.append(f"goal {spec.goal.distance:g} ahead, {spec.goal.width:g} wide")
    obstacles = dict(spec.obstacles or {})
    if "goalie" in obstacles:
        parts.append(f"goalie {obstacles.pop('goalie').width:g} wide")
    if obstacles:
        parts.append(f"{len(obstacles)} obstacle{'s' if len(obstacles) > 1 else ''}")
    target = spec.task.target
    if target.kind == "ring":
        low, high = target.radius
        parts.append(f"target {low:g} away" if low == high else f"target {low:g}-{high:g} away")
    elif target.kind == "point":
        parts.append(f"target at ({target.x:g}, {target.y:g})")
    elif not spec.goal.enabled:
        parts.append("target at the goal point")
    return "; ".join(parts)


def _sheet(artifacts: list, names: list[str], camera: str, captions: list[str] | None = None) -> bytes:
    models = [a.model() for a in artifacts]
    if camera == "top":
        same_scale(models, camera)
    images = [render_pose(model, camera=camera, height=240) for model in models]
    captions = captions or [field_caption(a.spec) for a in artifacts]
    return contact_sheet(images, [f"{i}. {name}" for i, name in enumerate(names, 1)], captions=captions)
