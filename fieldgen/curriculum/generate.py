"""Field variants generated from specs: interpolation between two specs (numbers linearly or
geometrically, booleans and choices switching at a stated stage), a grid over named keys,
explicit lists, and start states that move the kick-off from near the target back to the
base's own; any of them may go on by interpolation to further fields (`then`), so one staged
run can take an agent from a close start to the hardest field. Each variant is the keys that
differ from the base, with where it came from."""

from __future__ import annotations

import dataclasses
import itertools
import json
import re
from pathlib import Path
from typing import Callable

import yaml

from fieldgen.curriculum.folder import THEN, CurriculumError, layout_key
from fieldgen.schema import FieldSpec, SpecError, geometry, load_spec
from fieldgen.schema.errors import shown_text
from fieldgen.schema.loader import bundled_names_where, merge, validate
from fieldgen.schema.source import Source
from fieldgen.suggest import did_you_mean

IGNORED = ("name", "description", "extends")  # never interpolated


@dataclasses.dataclass(frozen=True)
class Asked:
    """What a curriculum was asked for (`fieldgen curriculum`'s options): one kind's options, then the fields
    to go on to (`then`, in `then_stages` stages each; default one fewer than `stages`)."""

    to: Path | None = None  # interpolation: the field of the last stage
    stages: int = 5
    geometric: tuple[str, ...] = ()  # dotted keys interpolated geometrically
    switch_at: int | None = None
    vary: tuple[str, ...] = ()  # grid axes, 'KEY=V1,V2'
    listed: tuple[str, ...] = ()  # listed variants, 'KEY=V KEY=V' each
    start_near: float | None = None  # start states: the first stage's ball this far from the target
    agent_near: float | None = None  # ... and its agent this far from the ball
    then: tuple[Path, ...] = ()
    then_stages: int | None = None


@dataclasses.dataclass(frozen=True)
class Kind:
    """One way of generating a curriculum's variants: its name (recorded in curriculum.yaml), how it is asked
    for, the options only it takes, and its generator."""

    name: str
    asked_by: str  # the option that asks for it, with what it takes
    noun: str  # "a NOUN curriculum"
    is_asked: Callable[[Asked], bool]
    generate: Callable[[Path, Asked], list[tuple[dict, str]]]
    own_options: dict[str, str] = dataclasses.field(default_factory=dict)  # Asked field -> its option


KINDS: dict[str, Kind] = {}


def kind(name: str, asked_by: str, noun: str, is_asked: Callable[[Asked], bool],
         own_options: dict[str, str] | None = None):
    """Register a generator of variants (base, asked) -> [(changes, origin)] as a curriculum kind."""

    def register(generate):
        KINDS[name] = Kind(name, asked_by, noun, is_asked, generate, own_options or {})
        return generate

    return register


def variants(base: Path, asked: Asked) -> tuple[str, list[tuple[dict, str]]]:
    """The kind and variants of the one curriculum asked for, then on to each field of `asked.then` in turn."""
    chosen = [k for k in KINDS.values() if k.is_asked(asked)]
    if len(chosen) != 1:
        choices = [f"{k.asked_by} ({k.name.replace('_', ' ')})" for k in KINDS.values()]
        raise CurriculumError(f"give exactly one of {', '.join(choices[:-1])} or {choices[-1]}")
    for other in KINDS.values():
        for field, option in other.own_options.items():
            if other is not chosen[0] and getattr(asked, field) is not None:
                article = "an" if other.noun[0] in "aeiou" else "a"
                raise CurriculumError(f"{option} belongs to {article} {other.noun} curriculum: "
                                      f"give {other.asked_by.split()[0]} too")
    if asked.then_stages is not None and not asked.then:
        raise CurriculumError("--then-stages belongs to --then: give the field to go on to")
    if asked.geometric and chosen[0].name != "interpolation" and not asked.then:
        raise CurriculumError(f"--geometric {asked.geometric[0]} belongs to an interpolation: give --to FIELD (or "
                              "--then FIELD), whose numbers it moves geometrically")
    for field in (base, asked.to, *asked.then):
        if field is not None and _is_team_field(field):
            raise CurriculumError(f"{field} is a team field: a match trains by self-play on one field from nothing "
                                  "(docs/teams.md), never through a curriculum's stages; make a curriculum between "
                                  "single-agent fields, or train the team field itself")
    out = chosen[0].generate(base, asked)
    for target in asked.then:
        out = out + go_on(base, out, target, asked.stages - 1 if asked.then_stages is None else asked.then_stages,
                          asked.geometric)
    return THEN.join([chosen[0].name] + ["interpolation"] * len(asked.then)), out


def _is_team_field(path: Path) -> bool:
    """Whether the spec at `path` names two sides; a spec that does not load is left to the generator's own
    messages."""
    try:
        return load_spec(path).teams is not None
    except SpecError:
        return False


@kind("interpolation", "--to FIELD", "interpolation", lambda a: a.to is not None, {"switch_at": "--switch-at"})
def _interpolation(base: Path, asked: Asked) -> list[tuple[dict, str]]:
    return interpolate(base, asked.to, asked.stages, asked.geometric, asked.switch_at)


@kind("grid", "--vary KEY=V1,V2", "grid", lambda a: bool(a.vary))
def _grid(base: Path, asked: Asked) -> list[tuple[dict, str]]:
    return grid(base, dict(parse_axis(v) for v in asked.vary))


@kind("list", "--stage 'KEY=V'", "listed", lambda a: bool(a.listed))
def _list(base: Path, asked: Asked) -> list[tuple[dict, str]]:
    empty = [i + 1 for i, s in enumerate(asked.listed) if not s.strip()]
    if empty:
        raise CurriculumError(f"--stage number {empty[0]} is empty: each --stage changes the base, as in --stage "
                              "'goal.distance=12' (a stage that changes nothing is the base field itself)")
    return explicit(base, [parse_assignments(split_assignments(s), "--stage") for s in asked.listed])


@kind("start_states", "--start-near DISTANCE", "start-state", lambda a: a.start_near is not None, {"agent_near": "--agent-near"})
def _start_states(base: Path, asked: Asked) -> list[tuple[dict, str]]:
    return start_states(base, asked.start_near, asked.stages, asked.agent_near)


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
    if not _diff(a, b):
        raise CurriculumError(f"--to {target}: it is the same field as {base} (nothing but its name differs), so "
                              f"every stage would be that field; name a field that differs from it")
    switch = switch_at if switch_at is not None else stages // 2 + 1
    if not 1 <= switch <= stages:
        raise CurriculumError(f"--switch-at {switch_at}: choose a stage from 1 to {stages}")
    _check_geometric(geometric, a, b)
    return [(_diff(a, variant), f"stage {k + 1} of {stages}, t = {t:.3f}, from {base} to {target} "
                                f"(switches at stage {switch})")
            for k, (t, variant) in enumerate(_blends(a, b, stages, switch, geometric))]


def go_on(base: Path, before: list[tuple[dict, str]], target: Path, stages: int,
          geometric: tuple[str, ...] = ()) -> list[tuple[dict, str]]:
    """`stages` more variants of base, from the field of the last variant `before` on to target (the last):
    the stages after the first of an interpolation of stages + 1 (numbers move linearly or geometrically,
    booleans and choices switch halfway), each still written as its changes from base. The last variant's
    field is base merged with its changes, as its stage file will be loaded."""
    if stages < 1:
        raise CurriculumError(f"--then-stages {stages}: going on to another field takes at least 1 stage")
    spec_a, spec_b = _spec(base), _spec(target)
    _check_compatible(base, spec_a, target, spec_b)
    a = spec_a.model_dump(mode="json")
    try:
        last = validate(merge(Source(a), Source(before[-1][0]))).model_dump(mode="json")
    except SpecError as exc:
        problems = "; ".join(f"{p.path}: {p.message}" for p in exc.problems)
        raise CurriculumError(f"stage {len(before)}, which --then goes on from, is not a valid field ({problems}); "
                              "nothing was written") from None
    b = spec_b.model_dump(mode="json")
    if not _diff(last, b):
        raise CurriculumError(f"--then {target}: stage {len(before)} is that field already; there is nothing to go on to")
    _check_geometric(geometric, last, b)
    switch = (stages + 1) // 2 + 1  # the interpolation's default: halfway
    return [(_diff(a, variant), f"stage {len(before) + k}: {k} of {stages} from stage {len(before)} on to {target}, "
                                f"t = {t:.3f} (switches at {switch - 1} of {stages})")
            for k, (t, variant) in enumerate(_blends(last, b, stages + 1, switch, geometric)) if k > 0]


def _blends(a: dict, b: dict, stages: int, switch: int, geometric: tuple[str, ...]) -> list[tuple[float, dict]]:
    """(t, the field at t) for `stages` evenly spaced steps from a (t = 0) to b (t = 1), booleans and choices
    switching to b's from stage `switch` (1-based) on."""
    return [(k / (stages - 1), _blend(a, b, k / (stages - 1), k + 1 >= switch, geometric, ())) for k in range(stages)]


def grid(base: Path, axes: dict[str, list]) -> list[tuple[dict, str]]:
    """Every combination of the axes' values over the base spec, first axis slowest."""
    a = _resolved(base)
    for key, values in axes.items():
        _check_key(key, a, "--vary")
        if not values:
            raise CurriculumError(f"--vary {key}: the list of values is empty")
        twice = next((v for i, v in enumerate(values) if v in values[:i]), None)
        if twice is not None:  # two stages of one field: a stage trained twice, weighed twice
            raise CurriculumError(f"--vary {key}: {shown_text(str(twice))} is listed twice; list each value once")
    out = []
    for combo in itertools.product(*axes.values()):
        assignment = dict(zip(axes, combo))
        out.append((_nest(assignment), "grid point " + ", ".join(f"{k}={v}" for k, v in assignment.items())))
    return out


def explicit(base: Path, variants: list[dict[str, object]]) -> list[tuple[dict, str]]:
    """One variant per assignment dict, in the order given."""
    a = _resolved(base)
    for i, assignment in enumerate(variants):
        for key in assignment:
            _check_key(key, a, "--stage")
        if assignment in variants[:i]:  # two stages of one field: a stage trained twice, weighed twice
            said = " ".join(f"{k}={v}" for k, v in assignment.items())
            raise CurriculumError(f"--stage {i + 1} ({shown_text(said)}) sets what --stage "
                                  f"{variants.index(assignment) + 1} sets: the same field twice; list each once")
    return [(_nest(v), "listed: " + ", ".join(f"{k}={x}" for k, x in v.items())) for v in variants]


def start_states(base: Path, near: float, stages: int, agent_near: float | None = None) -> list[tuple[dict, str]]:
    """`stages` variants of one field that differ only in where an episode starts: the first puts the
    ball's spawn centre `near` from the target, the agent's start moved by as much, and each later
    stage moves both back along the line to the target, the last being the base's own kick-off.

    With `agent_near` the first stage also starts the agent that far from the ball's spawn centre, on
    the side it starts in the base, and later stages widen the gap back to the base's: an agent that
    cannot yet walk touches a ball next to it, and hindsight then sees the ball move."""
    if stages < 2:
        raise CurriculumError(f"--stages {stages}: a start-state curriculum needs at least 2 stages")
    spec = _spec(base)
    target = spec.target_fixed()
    if not spec.ball.enabled or spec.ball.spawn.mode != "region" or target is None:
        raise CurriculumError(f"{base}: a start-state curriculum moves a ball spawned in a region towards a fixed "
                              "target (a goal or point target)")
    spawn = spec.ball.spawn
    centre = geometry.ball_spawn_centre(spec)
    to_target = (target[0] - centre[0], target[1] - centre[1])
    distance = (to_target[0] ** 2 + to_target[1] ** 2) ** 0.5
    if not 0 < near < distance:
        raise CurriculumError(f"--start-near {near:g}: choose a distance between 0 and {distance:.2f}, the distance "
                              f"from the ball's spawn centre to the target in {base}")
    behind = (spec.agent.start[0] - centre[0], spec.agent.start[1] - centre[1])  # the agent from the ball
    gap = (behind[0] ** 2 + behind[1] ** 2) ** 0.5
    if agent_near is not None and not 0 < agent_near < gap:
        raise CurriculumError(f"--agent-near {agent_near:g}: choose a distance between 0 and {gap:.2f}, the distance "
                              f"from the ball's spawn centre to the agent's start in {base}")

    def moved_by(moved: float, closer: float) -> dict:
        """The changes that move the kick-off `moved` of the way to the target and the agent `closer` of its gap."""
        dx, dy = (_rounded(moved * to_target[0]), _rounded(moved * to_target[1]))
        start = (spec.agent.start[0] + dx - closer * behind[0], spec.agent.start[1] + dy - closer * behind[1])
        return {} if moved == 0 and closer == 0 else {
            "ball": {"spawn": {"x": [_rounded(v + dx) for v in spawn.x], "y": [_rounded(v + dy) for v in spawn.y]}},
            "agent": {"start": [_rounded(start[0]), _rounded(start[1])]}}

    def problems_at(distance_left: float) -> str | None:
        """Why the field with the kick-off this far from the target is no field (None where it is one)."""
        closer = 0.0 if agent_near is None else 1 - agent_near / gap
        try:
            validate(merge(Source(spec.model_dump(mode="json")), Source(moved_by(1 - distance_left / distance, closer))))
        except SpecError as exc:
            return "; ".join(f"{p.path}: {p.message}" if p.path else p.message for p in exc.problems)
        return None

    if (problems := problems_at(near)) is not None:
        step = distance / 50
        fits = [round(k * step, 2) for k in range(1, 50) if problems_at(k * step) is None]
        where = (f"from {base} the distances that make a field, checked every {step:.2f}, run "
                 f"{_runs(fits, step)}" if fits else f"no distance from {base}'s kick-off makes a field")
        raise CurriculumError(f"--start-near {near:g}: the first stage, the ball's spawn centre {near:g} from the "
                              f"target, is not a valid field ({problems}); {where}")
    out = []
    for k in range(stages):
        t = k / (stages - 1)
        moved = (1 - near / distance) * (1 - t)
        closer = 0.0 if agent_near is None else (1 - agent_near / gap) * (1 - t)  # share of the gap taken away
        agent = "" if agent_near is None else f", the agent {gap - closer * gap:.2f} from it"
        out.append((moved_by(moved, closer), f"stage {k + 1} of {stages}: kick-off moved {moved * distance:.2f} "
                                             f"toward the target, the ball's spawn centre "
                                             f"{distance - moved * distance:.2f} from it{agent}"))
    return out


def _runs(values: list[float], step: float) -> str:
    """Sorted values checked `step` apart, as the runs they make: '0.50 to 1.00 and 2.00 to 2.40'."""
    spans, first = [], values[0]
    for before, value in zip(values, values[1:] + [None]):
        if value is None or value - before > step * 1.5:
            spans.append(f"{first:.2f}" if first == before else f"{first:.2f} to {before:.2f}")
            first = value
    return " and ".join(spans)


def _rounded(x: float) -> float:
    return float(f"{x:.6g}")


def _check_compatible(a_path: Path, sa: FieldSpec, b_path: Path, sb: FieldSpec) -> None:
    if sa.agent.kind != sb.agent.kind:
        same = bundled_names_where(lambda s: s.agent.kind == sb.agent.kind and s.name != sb.name
                                   and layout_key(s) == layout_key(sb))
        offer = f"; bundled fields that could start one to {b_path}: {', '.join(same)}" if same else ""
        raise CurriculumError(f"{a_path} drives the {sa.agent.kind} agent and {b_path} the {sb.agent.kind}: "
                              "a curriculum keeps one agent (the policy's actions and observations depend on it)"
                              + offer)
    if layout_key(sa) != layout_key(sb):
        raise CurriculumError(f"{a_path} observes {layout_key(sa)} but {b_path} observes {layout_key(sb)}: "
                              "a curriculum needs one observation layout")


def _check_geometric(keys: tuple[str, ...], a: dict, b: dict) -> None:
    """Each key names a number (or list of numbers) that the interpolation moves: a boolean, a choice, a key of one
    field alone or one both fields hold alike would have been accepted and left as it is."""
    known = set(_leaf_keys(a)) | set(_leaf_keys(b))
    moving = sorted(k for k in known if _at(a, k) != _at(b, k) and _moves(_at(a, k), _at(b, k)))
    for key in keys:
        if key not in known:
            raise CurriculumError(f"--geometric {key}: no such key{did_you_mean(key, sorted(known))}")
        if key not in moving:
            start, end = _at(a, key), _at(b, key)
            said = [shown_text(json.dumps(v)) for v in (start, end) if v is not _ABSENT]
            why = ("only one of the two fields has it, so it switches at --switch-at" if len(said) < 2 else
                   f"both fields hold {said[0]}, so it does not move" if start == end else
                   f"it goes from {said[0]} to {said[1]}, not a number that moves (booleans, choices and lists "
                   "of other lengths switch at --switch-at)")
            raise CurriculumError(f"--geometric {key}: {why}; the numbers that move here: "
                                  f"{', '.join(moving) or 'none'}")


_ABSENT = object()


def _at(tree: dict, dotted: str):
    """The value at a dotted key of a resolved spec, or _ABSENT."""
    for part in dotted.split("."):
        if not isinstance(tree, dict) or part not in tree:
            return _ABSENT
        tree = tree[part]
    return tree


def _moves(a, b) -> bool:
    """Whether an interpolation moves a value from `a` to `b` as a number: two numbers, or two lists of numbers of
    one length; anything else switches at the switch stage."""
    if _is_number(a) and _is_number(b):
        return True
    return isinstance(a, list) and isinstance(b, list) and len(a) == len(b) and all(map(_is_number, a + b))


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


def _check_key(dotted: str, resolved: dict, option: str) -> None:
    """A key of the base field, or CurriculumError naming the option that gave it and the keys it may start with."""
    shown = shown_text(dotted)
    if dotted.split(".")[0] in IGNORED:  # a key of every spec, but each stage's is written for it
        raise CurriculumError(f"{option} {shown}: '{shown}' names the variant, it cannot be varied")
    known = _leaf_keys(resolved)
    if dotted in known:
        return
    sections = ", ".join(k for k in resolved if k not in IGNORED)
    raise CurriculumError(f"{option} {shown}: unknown key '{shown}'{did_you_mean(dotted, sorted(known)) or '.'} A key "
                          f"is a dotted path into the base field, such as goal.distance, starting with one of its "
                          f"sections: {sections}")


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
    if _moves(a, b):
        if _is_number(a):
            return _mix(a, b, t, key in geometric, key)
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


def split_assignments(text: str) -> list[str]:
    """'a=1 b={x: 1, y: 2}' -> ['a=1', 'b={x: 1, y: 2}']: a new assignment starts only where a word is
    followed by '=', so a value may hold spaces (a YAML mapping or list)."""
    return [item for item in re.split(r"\s+(?=[A-Za-z_][\w.]*=)", text.strip()) if item]


def parse_assignments(items: list[str], where: str) -> dict[str, object]:
    """'key=value' strings (values read as YAML) -> {key: value}; a key given twice is refused."""
    out = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise CurriculumError(f"{where} '{item}': write KEY=VALUE, e.g. goal.distance=12")
        if key.strip() in out:
            raise CurriculumError(f"{where} '{item}': {key.strip()} is given twice; give each key once")
        out[key.strip()] = _yaml_value(raw, f"{where} {key.strip()}")
    return out


def _yaml_value(raw: str, where: str):
    try:
        return yaml.safe_load(raw)
    except yaml.YAMLError as error:
        problem = getattr(error, "problem", None) or "not valid YAML"
        raise CurriculumError(f"{where}: the value '{raw}' is not valid YAML ({problem}); write a number, a word, "
                              "[a, list] or {a: mapping}") from None


def _top_level_values(raw: str) -> list[str]:
    """'8,[-1, 1],{a: 2}' -> ['8', '[-1, 1]', '{a: 2}']: a comma inside brackets, braces or quotes is part of
    its value, so an axis can vary a list or a mapping."""
    values, depth, quote, start = [], 0, "", 0
    for i, char in enumerate(raw):
        if quote:
            quote = "" if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char in "[{":
            depth += 1
        elif char in "]}":
            depth = max(depth - 1, 0)
        elif char == "," and depth == 0:
            values.append(raw[start:i])
            start = i + 1
    return values + [raw[start:]]


def parse_axis(item: str) -> tuple[str, list]:
    """'goal.distance=8,12,16' -> ('goal.distance', [8, 12, 16]); 'ball.spawn.x=[-1,1],[-2,2]' -> two lists."""
    key, sep, raw = item.partition("=")
    if not sep or not key:
        raise CurriculumError(f"--vary '{item}': write KEY=V1,V2,..., e.g. goal.distance=8,12,16")
    raws = _top_level_values(raw)
    if not raw.replace(",", "").strip():
        raise CurriculumError(f"--vary {key}: the list of values is empty")
    if any(not v.strip() for v in raws):
        empty = ", ".join(str(i + 1) for i, v in enumerate(raws) if not v.strip())
        raise CurriculumError(f"--vary '{item}': value {empty} of {len(raws)} is empty; write KEY=V1,V2,..., each "
                              f"value once, e.g. goal.distance=8,12,16")
    values = [_yaml_value(v, f"--vary {key.strip()}") for v in raws]
    return key.strip(), values
