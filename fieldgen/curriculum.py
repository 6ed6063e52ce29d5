"""Curricula: field variants generated from specs, and the folder that lists them in order.

A variant is a full spec written as `extends: <base>` plus only the keys that differ
from the base, with a comment saying where it came from. Three ways to make them:
interpolation between two specs (numbers linearly or geometrically, booleans and
choices switching at a stated stage), a grid over named keys, and explicit lists.
`curriculum.yaml` lists the stages in order with the rule for moving on.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
import shutil
import tempfile
from pathlib import Path

import yaml

from fieldgen.promotion import Promotion
from fieldgen.schema import FieldSpec, SpecError, load_spec
from fieldgen.suggest import did_you_mean

INDEX = "curriculum.yaml"
IGNORED = ("name", "description", "extends")  # never interpolated


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
    kind: str  # interpolation | grid | list
    base: str  # as written in each stage's `extends:`
    stages: list[Stage]
    promotion: Promotion

    def spec_paths(self) -> list[Path]:
        return [self.folder / s.file for s in self.stages]

    def specs(self) -> list[FieldSpec]:
        return [load_spec(p) for p in self.spec_paths()]


# -- generation ----------------------------------------------------------------------------------

def interpolate(base: Path, target: Path, stages: int, geometric: tuple[str, ...] = (),
                switch_at: int | None = None) -> list[tuple[dict, str]]:
    """`stages` variants from base (first) to target (last): (changes, origin) each.

    Numbers (and equal-length lists of numbers) move linearly, or geometrically for the
    dotted keys in `geometric`; everything else (booleans, choices, keys only one spec
    has) switches to the target's value at stage `switch_at` (1-based; default: halfway).
    """
    if stages < 2:
        raise CurriculumError(f"--stages {stages}: an interpolation needs at least 2 stages (the two ends)")
    spec_a, spec_b = _spec(base), _spec(target)
    _check_compatible(base, spec_a, target, spec_b)
    a, b = spec_a.model_dump(mode="json"), spec_b.model_dump(mode="json")
    switch = switch_at if switch_at is not None else stages // 2 + 1
    if not 1 <= switch <= stages:
        raise CurriculumError(f"--switch-at {switch_at}: choose a stage from 1 to {stages}")
    known = set(_leaf_keys(a)) | set(_leaf_keys(b))
    for key in geometric:
        if key not in known:
            raise CurriculumError(f"--geometric {key}: no such key{did_you_mean(key, known)}")
    out = []
    for k in range(stages):
        t = k / (stages - 1)
        variant = _blend(a, b, t, k + 1 >= switch, geometric, ())
        out.append((_diff(a, variant), f"stage {k + 1} of {stages}, t = {t:.3f}, from {base} to {target} "
                                       f"(switches at stage {switch})"))
    return out


def grid(base: Path, axes: dict[str, list]) -> list[tuple[dict, str]]:
    """Every combination of the axes' values over the base spec, first axis slowest."""
    a = _resolved(base)
    for key, values in axes.items():
        _check_key(key, a)
        if not values:
            raise CurriculumError(f"--vary {key}: the list of values is empty")
    out = []
    for combo in itertools.product(*axes.values()):
        assignment = dict(zip(axes, combo))
        out.append((_nest(assignment), "grid point " + ", ".join(f"{k}={v}" for k, v in assignment.items())))
    return out


def explicit(base: Path, variants: list[dict[str, object]]) -> list[tuple[dict, str]]:
    """One variant per assignment dict, in the order given."""
    a = _resolved(base)
    for assignment in variants:
        for key in assignment:
            _check_key(key, a)
    return [(_nest(v), "listed: " + ", ".join(f"{k}={x}" for k, x in v.items())) for v in variants]


def write(folder: Path, base_ref: str, base: Path, kind: str, variants: list[tuple[dict, str]],
          promotion: Promotion, force: bool = False) -> Curriculum:
    """Validate every variant, then write the folder at once (nothing is written if one fails)."""
    if folder.exists() and not force:
        raise CurriculumError(f"{folder} exists; pass --force to replace it")
    if not 0.0 < promotion.threshold <= 1.0 or promotion.window < 1:
        raise CurriculumError(f"promotion threshold must be in (0, 1] and window >= 1, got {promotion}")
    prefix = _slug(folder.name)
    bundled = "/" not in base_ref and not base_ref.endswith((".yaml", ".yml"))
    # stage files sit in `folder`; the staging folder beside it has the same parent, so the path holds for both
    extends = base_ref if bundled else os.path.relpath(base.resolve(), folder.resolve())
    stages = [Stage(f"{prefix}_s{i + 1:02d}", f"stage_{i + 1:02d}.yaml", changes, origin)
              for i, (changes, origin) in enumerate(variants)]
    folder.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    try:
        for stage in stages:
            (staging / stage.file).write_text(_stage_text(stage, extends))
        curriculum = Curriculum(staging, kind, extends, stages, promotion)
        (staging / INDEX).write_text(_index_text(curriculum))
        _validate_all(curriculum)
        if folder.exists():
            shutil.rmtree(folder)
        os.replace(staging, folder)
    finally:
        if staging.exists():
            shutil.rmtree(staging)
    return dataclasses.replace(curriculum, folder=folder)


# -- reading -------------------------------------------------------------------------------------

def load(folder: Path) -> Curriculum:
    """A curriculum folder, checked: every listed stage exists, validates and has the base's layout."""
    index = folder / INDEX
    try:
        raw = yaml.safe_load(index.read_text())
    except FileNotFoundError:
        raise CurriculumError(f"{folder} is not a curriculum: {INDEX} is missing "
                              "(make one with `fieldgen curriculum`)") from None
    except yaml.YAMLError as exc:
        raise CurriculumError(f"{index} is not valid YAML: {exc}") from None
    if not isinstance(raw, dict) or not isinstance(raw.get("stages"), list) or not raw["stages"]:
        raise CurriculumError(f"{index}: expected a mapping with a non-empty 'stages:' list")
    try:
        promotion = Promotion(**(raw.get("promotion") or {}))
    except TypeError as exc:
        raise CurriculumError(f"{index}: promotion: {exc}; keys are threshold and window") from None
    stages = []
    for i, entry in enumerate(raw["stages"], 1):
        if not isinstance(entry, dict) or not {"name", "file"} <= set(entry):
            raise CurriculumError(f"{index}: stages[{i}] needs 'name' and 'file'")
        if not (folder / entry["file"]).exists():
            raise CurriculumError(f"{index}: stage {i} ('{entry['name']}') lists {entry['file']}, which is missing")
        stages.append(Stage(entry["name"], entry["file"], {}, entry.get("origin", "")))
    listed = {s.file for s in stages}
    stray = sorted(p.name for p in folder.glob("stage_*.yaml") if p.name not in listed)
    if stray:
        raise CurriculumError(f"{index} does not list {', '.join(stray)}; add them to 'stages:' or delete them")
    if len(listed) != len(stages) or len({s.name for s in stages}) != len(stages):
        raise CurriculumError(f"{index}: a stage file or name appears twice")
    curriculum = Curriculum(folder, raw.get("kind", "list"), raw.get("base", ""), stages, promotion)
    _validate_all(curriculum)
    return curriculum


def is_curriculum(path: Path) -> bool:
    return path.is_dir() and (path / INDEX).exists()


# -- helpers -------------------------------------------------------------------------------------

def _validate_all(curriculum: Curriculum) -> None:
    """Every stage loads, its name is the one listed, and every stage has the first one's observation layout."""
    layouts = {}
    for i, (stage, path) in enumerate(zip(curriculum.stages, curriculum.spec_paths()), 1):
        try:
            spec = load_spec(path)
        except SpecError as exc:
            raise CurriculumError(f"stage {i} ({stage.file}) is not a valid field: {exc}") from None
        if spec.name != stage.name:
            raise CurriculumError(f"stage {i} ({stage.file}) is named '{spec.name}' but {INDEX} lists "
                                  f"'{stage.name}'")
        layouts[i] = _layout_key(spec)
    first = layouts[1]
    for i, key in layouts.items():
        if key != first:
            raise CurriculumError(f"stage {i} ({curriculum.stages[i - 1].file}) observes {key}, stage 1 observes "
                                  f"{first}: every stage of a curriculum needs the same observation layout")


def _layout_key(spec: FieldSpec) -> str:
    """What fixes the observation layout: the agent, whether there is a ball and how it moves, the extras."""
    ball = f"{spec.ball.joint} ball" if spec.ball.enabled else "no ball"
    extra = ", ball velocity" if spec.observation.ball_velocity else ""
    return f"{spec.agent.kind} agent, {ball}{extra}"


def _check_compatible(a_path: Path, sa: FieldSpec, b_path: Path, sb: FieldSpec) -> None:
    if sa.agent.kind != sb.agent.kind:
        raise CurriculumError(f"{a_path} drives the {sa.agent.kind} agent and {b_path} the {sb.agent.kind}: "
                              "a curriculum keeps one agent (the policy's actions and observations depend on it)")
    if _layout_key(sa) != _layout_key(sb):
        raise CurriculumError(f"{a_path} observes {_layout_key(sa)} but {b_path} observes {_layout_key(sb)}: "
                              "a curriculum needs one observation layout")


def _resolved(path: Path) -> dict:
    return _spec(path).model_dump(mode="json")


def _spec(path: Path) -> FieldSpec:
    try:
        return load_spec(path)
    except SpecError as exc:
        raise CurriculumError(f"{path} is not a valid field: {exc}") from None


def _leaf_keys(tree: dict, prefix: str = "") -> list[str]:
    keys = []
    for k, v in tree.items():
        dotted = f"{prefix}.{k}" if prefix else k
        keys.append(dotted)
        if isinstance(v, dict):
            keys.extend(_leaf_keys(v, dotted))
    return keys


def _check_key(dotted: str, resolved: dict) -> None:
    known = _leaf_keys(resolved)
    if dotted in known:
        return
    if dotted.split(".")[0] in IGNORED:
        raise CurriculumError(f"'{dotted}' names the variant, it cannot be varied")
    raise CurriculumError(f"unknown key '{dotted}'{did_you_mean(dotted, known)}")


def _nest(assignment: dict[str, object]) -> dict:
    out: dict = {}
    for dotted, value in assignment.items():
        node = out
        *parents, last = dotted.split(".")
        for p in parents:
            node = node.setdefault(p, {})
        node[last] = value
    return out


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _blend(a, b, t: float, switched: bool, geometric: tuple[str, ...], path: tuple):
    key = ".".join(path)
    if a == b or key in IGNORED:
        return a
    if isinstance(a, dict) and isinstance(b, dict):
        out = {}
        for k in list(a) + [k for k in b if k not in a]:
            if k in a and k in b:
                out[k] = _blend(a[k], b[k], t, switched, geometric, path + (k,))
            elif (k in b) == switched:  # only in b and switched in, or only in a and not yet switched out
                out[k] = b[k] if k in b else a[k]
        return out
    if _is_number(a) and _is_number(b):
        return _mix(a, b, t, key in geometric, key)
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b) and all(map(_is_number, a + b)):
        return [_mix(x, y, t, key in geometric, key) for x, y in zip(a, b)]
    return b if switched else a


def _mix(a, b, t: float, geometric: bool, key: str):
    if geometric:
        if a <= 0 or b <= 0:
            raise CurriculumError(f"--geometric {key}: both ends must be positive, got {a} and {b}")
        value = a * (b / a) ** t
    else:
        value = a + (b - a) * t
    if isinstance(a, int) and isinstance(b, int):
        return int(round(value))
    return float(f"{value:.6g}") if t not in (0.0, 1.0) else (a if t == 0.0 else b)


def _diff(base: dict, variant: dict) -> dict:
    """The keys of variant that differ from base; a key the variant lacks becomes null (deleted)."""
    out = {}
    for k in list(variant) + [k for k in base if k not in variant]:
        if k in IGNORED:
            continue
        if k not in variant:
            out[k] = None
        elif k not in base:
            out[k] = variant[k]
        elif isinstance(variant[k], dict) and isinstance(base[k], dict):
            sub = _diff(base[k], variant[k])
            if sub:
                out[k] = sub
        elif variant[k] != base[k]:
            out[k] = variant[k]
    return out


def _slug(name: str) -> str:
    slug = "".join(c if c.isalnum() else "_" for c in name.lower()).strip("_") or "curriculum"
    return slug[:56]


def _stage_text(stage: Stage, extends: str) -> str:
    body = {"extends": extends, "name": stage.name, **stage.changes}
    head = f"# {stage.origin}\n# Written by `fieldgen curriculum`; only the keys that differ from the base.\n"
    return head + yaml.safe_dump(body, sort_keys=False, default_flow_style=None)


def _index_text(c: Curriculum) -> str:
    body = {"kind": c.kind, "base": c.base,
            "promotion": dataclasses.asdict(c.promotion),
            "stages": [{"name": s.name, "file": s.file, "origin": s.origin} for s in c.stages]}
    head = ("# Stages in training order. A run moves from one stage to the next once success_any, averaged over\n"
            "# the last `window` evaluations, reaches `threshold`. Written by `fieldgen curriculum`.\n")
    return head + yaml.safe_dump(body, sort_keys=False)


def parse_assignments(items: list[str], where: str) -> dict[str, object]:
    """'key=value' strings (values read as YAML) -> {key: value}."""
    out = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise CurriculumError(f"{where} '{item}': write KEY=VALUE, e.g. goal.distance=12")
        out[key.strip()] = yaml.safe_load(raw)
    return out


def parse_axis(item: str) -> tuple[str, list]:
    """'goal.distance=8,12,16' -> ('goal.distance', [8, 12, 16])."""
    key, sep, raw = item.partition("=")
    if not sep or not key:
        raise CurriculumError(f"--vary '{item}': write KEY=V1,V2,..., e.g. goal.distance=8,12,16")
    values = [yaml.safe_load(v) for v in raw.split(",") if v.strip()]
    if not values:
        raise CurriculumError(f"--vary {key}: the list of values is empty")
    return key.strip(), values
