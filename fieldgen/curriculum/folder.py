"""A curriculum on disk: stage files (each `extends: <base>` plus only the keys that differ from
it, with a comment saying where it came from) and `curriculum.yaml`, which lists the stages in
order with the rule for moving on; written whole or not at all, read back checked."""

from __future__ import annotations

import dataclasses
import os
import re
from pathlib import Path
from typing import Annotated

import yaml
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, StrictStr, ValidationError

from fieldgen.curriculum.promotion import Promotion, Threshold, Window
from fieldgen.files import Output, claim, replace_folder
from fieldgen.limits import MAX_STAGES
from fieldgen.schema import FieldSpec, SpecError, load_spec, messages
from fieldgen.schema.editor import SCHEMA_FILE
from fieldgen.schema.errors import shown_text
from fieldgen.schema.source import read_yaml

INDEX = "curriculum.yaml"
CURRICULUM = Output("fieldgen curriculum", (INDEX, "stage_*.yaml"), INDEX, "-o", record_keys=("stages",))


class CurriculumError(Exception):
    """A curriculum that cannot be generated or read; the message says which stage and why."""


@dataclasses.dataclass(frozen=True)
class Stage:
    name: str
    file: str  # relative to the curriculum folder
    changes: dict  # nested keys -> values, relative to the base spec
    origin: str  # one line: how this variant was made


@dataclasses.dataclass(frozen=True)
class Curriculum:
    folder: Path
    kind: str  # how fieldgen curriculum made the stages: a name of fieldgen.curriculum.generate.KINDS
    base: str  # as written in each stage's `extends:`
    stages: list[Stage]
    promotion: Promotion

    def spec_paths(self) -> list[Path]:
        return [self.folder / s.file for s in self.stages]

    def specs(self) -> list[FieldSpec]:
        return [load_spec(p) for p in self.spec_paths()]


def write(folder: Path, base_ref: str, base: Path, kind: str, variants: list[tuple[dict, str]],
          promotion: Promotion, force: bool = False) -> Curriculum:
    """Validate every variant, then write the folder at once (nothing is written if one fails)."""
    claim(folder, CURRICULUM)
    if folder.exists() and not force:
        raise CurriculumError(f"{folder} exists; pass --force to replace it")
    if not 0.0 < promotion.threshold <= 1.0:  # NaN included
        raise CurriculumError(f"promotion threshold (--threshold) {promotion.threshold:g}: the success_any that "
                              f"promotes a run is a share of episodes, above 0 and at most 1 (such as 0.5)")
    if not 1 <= promotion.window <= MAX_STAGES:
        raise CurriculumError(f"promotion window (--window) {promotion.window}: the evaluations averaged for "
                              f"promotion are a whole number from 1 to {MAX_STAGES}")
    if len(variants) > MAX_STAGES:
        raise CurriculumError(f"{len(variants):,} stages asked for; a curriculum has at most {MAX_STAGES:,}")
    prefix = _slug(folder.name)
    bundled = "/" not in base_ref and not base_ref.endswith((".yaml", ".yml"))
    # stage files sit in `folder`; the staging folder beside it has the same parent, so the path holds for both
    extends = base_ref if bundled else os.path.relpath(base.resolve(), folder.resolve())
    schema = os.path.relpath(SCHEMA_FILE, folder.resolve())
    stages = [Stage(f"{prefix}_s{i + 1:02d}", f"stage_{i + 1:02d}.yaml", changes, origin)
              for i, (changes, origin) in enumerate(variants)]
    curriculum = Curriculum(folder, kind, extends, stages, promotion)

    def fill(staging: Path) -> None:
        for stage in stages:
            (staging / stage.file).write_text(_stage_text(stage, extends, schema))
        (staging / INDEX).write_text(_index_text(curriculum))
        _validate_all(dataclasses.replace(curriculum, folder=staging), staged=True)

    replace_folder(folder, fill, CURRICULUM)
    return curriculum


# -- reading -------------------------------------------------------------------------------------

def _stage_file(name: str) -> str:
    """A stage's file: a .yaml file in the curriculum's own folder, so that a curriculum copied in from elsewhere
    never makes fieldgen read a file outside it."""
    if "/" in name or "\\" in name or name in ("", ".", "..") or not name.endswith((".yaml", ".yml")):
        raise ValueError("should name a .yaml file in the curriculum's folder, such as stage_01.yaml")
    return name


THEN = ", then "  # between the kinds of a curriculum that goes on to further fields: "start_states, then interpolation"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class _Promotion(_Strict):
    threshold: Threshold = 0.5
    window: Window = 2


class _Stage(_Strict):
    name: StrictStr
    file: Annotated[StrictStr, AfterValidator(_stage_file)]
    origin: StrictStr = ""


class _Index(_Strict):
    """What curriculum.yaml holds, each value of the type `write` gives it."""

    kind: StrictStr = "list"
    base: StrictStr = ""
    promotion: _Promotion = _Promotion()
    stages: Annotated[list[_Stage], Field(min_length=1, max_length=MAX_STAGES)]


def load(folder: Path) -> Curriculum:
    """A curriculum folder, checked: curriculum.yaml read as specs are (bounded, every problem at its line),
    every listed stage a file of the folder that exists, validates and has the base's layout."""
    index = folder / INDEX
    if not index.exists():
        raise CurriculumError(f"{folder} is not a curriculum: {INDEX} is missing "
                              "(make one with `fieldgen curriculum`)")
    try:
        source = read_yaml(index, INDEX, "it lists the stages under 'stages:'")
        raw = _Index.model_validate(source.data)
    except SpecError as exc:
        raise CurriculumError(_problems(index, exc.problems)) from None
    except ValidationError as exc:
        raise CurriculumError(_problems(index, messages.problems(source, exc.errors(), _Index))) from None
    from fieldgen.curriculum.generate import KINDS  # generate writes folders through this module

    if any(part not in KINDS for part in raw.kind.split(THEN)):  # --then goes on to further fields
        raise CurriculumError(f"{index}: kind {shown_text(raw.kind, quoted=True)} is not how fieldgen curriculum "
                              f"makes stages; one of: {', '.join(KINDS)}, or several joined by '{THEN}'")
    stages, seen = [], {}
    for i, entry in enumerate(raw.stages, 1):
        path, said = folder / entry.file, f"{index}: stage {i} ({shown_text(entry.name, quoted=True)})"
        for what, value in (("file", entry.file), ("name", entry.name)):
            if (what, value) in seen:
                raise CurriculumError(f"{said} has the {what} {shown_text(value, quoted=True)} of stage "
                                      f"{seen[what, value]}; each stage has a {what} of its own")
            seen[what, value] = i
        if path.is_symlink() and not path.exists():
            raise CurriculumError(f"{said} lists {shown_text(entry.file)}, a link that leads to no file (its target "
                                  "is gone, or the link leads back to itself); copy the stage's file in instead")
        if not path.exists():
            raise CurriculumError(f"{said} lists {shown_text(entry.file)}, which is missing")
        if path.is_symlink() and not path.resolve().is_relative_to(folder.resolve()):
            raise CurriculumError(f"{said} lists {shown_text(entry.file)}, a link to {path.resolve()} outside the "
                                  "curriculum's folder; copy the file in instead")
        stages.append(Stage(entry.name, entry.file, {}, entry.origin))
    listed = {s.file for s in stages}
    stray = sorted(p.name for p in folder.glob("stage_*.yaml") if p.name not in listed)
    if stray:
        raise CurriculumError(f"{index} does not list {', '.join(stray)}; add them to 'stages:' or delete them")
    curriculum = Curriculum(folder, raw.kind, raw.base, stages, Promotion(**raw.promotion.model_dump()))
    _validate_all(curriculum)
    return curriculum


def _problems(index: Path, problems: list) -> str:
    """A file's problems in one paragraph, each at its line."""
    return f"{index} is not a curriculum index: " + "; ".join(str(p) for p in problems)


def is_curriculum(path: Path) -> bool:
    try:
        return path.is_dir() and (path / INDEX).exists()
    except OSError:  # a name too long for the system is no curriculum; reading it as a field says why
        return False


# -- helpers -------------------------------------------------------------------------------------

def _validate_all(curriculum: Curriculum, staged: bool = False) -> None:
    """Every stage loads, its name is the one listed, and every stage has the first one's observation layout.
    `staged`: the stages are being written and the folder is a staging one that goes away on a refusal, so a
    problem names the stage by what made it (its --stage, --vary or interpolation), not by a file to open."""
    layouts = {}
    for i, (stage, path) in enumerate(zip(curriculum.stages, curriculum.spec_paths()), 1):
        try:
            spec = load_spec(path)
        except SpecError as exc:
            if staged:
                problems = "; ".join(f"{p.path}: {p.message}" if p.path else p.message for p in exc.problems)
                raise CurriculumError(f"stage {i} ({stage.origin}) is not a valid field ({problems}); nothing was "
                                      "written") from None
            raise CurriculumError(f"stage {i} ({stage.file}) is not a valid field: {exc}") from None
        if spec.name != stage.name:
            raise CurriculumError(f"stage {i} ({stage.file}) is named '{spec.name}' but {INDEX} lists "
                                  f"'{stage.name}'")
        layouts[i] = layout_key(spec)
    first = layouts[1]
    for i, key in layouts.items():
        if key != first:
            raise CurriculumError(f"stage {i} ({curriculum.stages[i - 1].file}) observes {key}, stage 1 observes "
                                  f"{first}: every stage of a curriculum needs the same observation layout")


def layout_key(spec: FieldSpec) -> str:
    """What fixes the observation layout: the agent, whether there is a ball and how it moves, the extras."""
    ball = f"{spec.ball.joint} ball" if spec.ball.enabled else "no ball"
    extra = ", ball velocity" if spec.observation.ball_velocity else ""
    return f"{spec.agent.kind} agent, {ball}{extra}"


def _slug(name: str) -> str:
    """A stage name's stem from its folder's name: field names are ASCII (a folder may be named in any script)."""
    slug = re.sub("_+", "_", "".join(c if c.isascii() and c.isalnum() else "_" for c in name.lower())).strip("_")
    slug = slug or "curriculum"
    return slug[:56]


def _stage_text(stage: Stage, extends: str, schema: str) -> str:
    """A stage's spec, its first line pointing editors at the JSON Schema (fieldgen.schema.editor)."""
    body = {"extends": extends, "name": stage.name, **stage.changes}
    head = (f"# yaml-language-server: $schema={schema}\n# {stage.origin}\n"
            "# Written by `fieldgen curriculum`; only the keys that differ from the base.\n")
    return head + yaml.safe_dump(body, sort_keys=False, default_flow_style=None)


def _index_text(c: Curriculum) -> str:
    body = {"kind": c.kind, "base": c.base,
            "promotion": dataclasses.asdict(c.promotion),
            "stages": [{"name": s.name, "file": s.file, "origin": s.origin} for s in c.stages]}
    head = ("# Stages in training order. A run moves from one stage to the next once success_any, averaged over\n"
            "# the last `window` evaluations, reaches `threshold`. Written by `fieldgen curriculum`.\n")
    return head + yaml.safe_dump(body, sort_keys=False)
