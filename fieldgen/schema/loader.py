"""YAML file -> validated FieldSpec: `extends:` merging, then every problem at once.

Maps merge by key, lists are replaced whole, and a key set to null is removed
(back to its default; an inherited obstacle deleted). Each merged key remembers the
file and line it came from, so an error in an inherited value points at the
base file that set it.
"""

from __future__ import annotations

from importlib import resources
import re
import types
import typing
from pathlib import Path

from pydantic import BaseModel, ValidationError

from fieldgen.schema.checks import physics_problems
from fieldgen.schema.errors import Problem, SpecError
from fieldgen.schema.models import FieldSpec
from fieldgen.schema.source import Source, read_yaml
from fieldgen.suggest import did_you_mean



def bundled_fields() -> dict[str, Path]:
    """Bundled field names -> their YAML files: the package data `fieldgen.fields`, which is the
    repository's fields/ folder in a checkout and a folder of the installed package otherwise."""
    folder = Path(str(resources.files("fieldgen.fields")))
    return {p.stem: p for p in sorted(folder.glob("*.yaml"))}


def resolve_spec_path(ref: str, relative_to: Path | None = None) -> Path:
    """A bundled name, or a path (relative to `relative_to`'s folder if given)."""
    looks_like_path = "/" in ref or ref.endswith((".yaml", ".yml"))
    if not looks_like_path:
        bundled = bundled_fields()
        if ref in bundled:
            return bundled[ref]
    path = Path(ref)
    if relative_to is not None and not path.is_absolute():
        path = relative_to.parent / path
    return path


def load_spec(path: str | Path | FieldSpec, backend: str | None = None) -> FieldSpec:
    """Load, merge and validate a field spec; raises SpecError listing every problem. `backend`
    replaces its sim.backend, with that pipeline's defaults for whatever the spec leaves out."""
    if isinstance(path, FieldSpec):
        source = Source(path.model_dump(mode="json", exclude_unset=True))
    else:
        source = _load_merged(Path(path), ())
    if backend is not None:
        source = _merge(source, Source({"sim": {"backend": backend}}))
    return validate(source)


def validate(source: Source) -> FieldSpec:
    try:
        spec = FieldSpec.model_validate(source.data)
    except ValidationError as exc:
        problems = [_problem_from(source, err) for err in exc.errors()]
        raise SpecError(list(dict.fromkeys(problems))) from None
    problems = [source.problem(parts, message) for parts, message in physics_problems(spec)]
    if problems:
        raise SpecError(problems)
    return spec


def _load_merged(path: Path, chain: tuple[Path, ...]) -> Source:
    chain = chain + (path.resolve(),)
    source = read_yaml(path)
    parent_ref = source.data.get("extends")
    if parent_ref is None:
        return source
    if not isinstance(parent_ref, str):
        raise SpecError([source.problem(("extends",), "'extends' takes a bundled field name or a relative path")])
    parent_path = resolve_spec_path(parent_ref, relative_to=path)
    if not parent_path.exists():
        names = ", ".join(bundled_fields())
        hint = did_you_mean(parent_ref, bundled_fields())
        raise SpecError(
            [source.problem(("extends",), f"'{parent_ref}' is neither a bundled field ({names}) nor a file{hint}")]
        )
    if parent_path.resolve() in chain:
        cycle = " -> ".join(str(p) for p in chain + (parent_path.resolve(),))
        raise SpecError([source.problem(("extends",), f"'extends' forms a cycle: {cycle}")])
    parent = _load_merged(parent_path, chain)
    return _merge(parent, source)


def _merge(base: Source, child: Source) -> Source:
    data = _deep_merge(base.data, child.data)
    positions = dict(base.positions)
    for parts in list(positions):
        if parts and _replaced(child.data, parts):
            del positions[parts]
    positions.update(child.positions)
    return Source(data, positions)


def _deep_merge(base, child):
    if isinstance(base, dict) and isinstance(child, dict):
        out = dict(base)
        for key, value in child.items():
            if value is None:
                out.pop(key, None)  # null deletes: back to the default, or an inherited obstacle removed
            else:
                out[key] = _deep_merge(base[key], value) if key in base else value
        return out
    return child


def _replaced(child: dict, parts: tuple) -> bool:
    """Whether the child overrides this base key path with a non-mapping value."""
    node = child
    for part in parts:
        if not isinstance(node, dict) or part not in node:
            return False
        node = node[part]
        if not isinstance(node, dict):
            return True
    return False


def _problem_from(source: Source, err: dict) -> Problem:
    parts = _data_path(source.data, err["loc"])
    kind, msg = err["type"], err["msg"]
    if kind == "extra_forbidden":
        key = parts[-1]
        allowed = _allowed_keys(err["loc"][:-1])
        msg = f"unknown key '{key}'{did_you_mean(str(key), allowed)}"
        if allowed:
            msg += f" Allowed keys here: {', '.join(allowed)}."
    elif kind == "missing":
        msg = f"the key '{parts[-1]}' is required" if parts else msg
    elif kind == "literal_error" and isinstance(err.get("input"), str):
        expected = re.findall(r"'([^']*)'", err.get("ctx", {}).get("expected", ""))
        msg = f"{msg} (got {err['input']!r}{did_you_mean(err['input'], expected)})"
    else:
        if msg.startswith("Value error, "):
            msg = msg[len("Value error, ") :]
        if "input" in err and not isinstance(err["input"], (dict, list)):
            msg += f" (got {err['input']!r})"
    return source.problem(parts, msg)


def _data_path(data, loc: tuple) -> tuple:
    """Drop pydantic's union tags from an error location, keeping real keys."""
    parts: list = []
    node = data
    for i, elem in enumerate(loc):
        if isinstance(node, dict) and elem in node:
            node = node[elem]
            parts.append(elem)
        elif isinstance(node, (list, tuple)) and isinstance(elem, int) and elem < len(node):
            node = node[elem]
            parts.append(elem)
        elif i == len(loc) - 1 and not isinstance(elem, int):
            parts.append(elem)  # a missing key names where it belongs
        # anything else is a discriminator tag or a union member name
    return tuple(parts)


def _allowed_keys(loc: tuple) -> list[str]:
    """The keys the model at this location accepts, for did-you-mean hints."""
    model: object = FieldSpec
    for elem in loc:
        model = _step(model, elem)
        if model is None:
            return []
    model = _unwrap(model)
    if isinstance(model, type) and issubclass(model, BaseModel):
        return list(model.model_fields)
    return []


def _unwrap(tp):
    while typing.get_origin(tp) is typing.Annotated:
        tp = typing.get_args(tp)[0]
    return tp


def _step(tp, elem):
    tp = _unwrap(tp)
    origin = typing.get_origin(tp)
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        field = tp.model_fields.get(elem)
        return field.annotation if field else None
    if origin in (typing.Union, types.UnionType):
        for member in typing.get_args(tp):
            member = _unwrap(member)
            if isinstance(member, type) and issubclass(member, BaseModel):
                for f in member.model_fields.values():
                    if typing.get_origin(f.annotation) is typing.Literal and elem in typing.get_args(f.annotation):
                        return member
        return None
    if origin is dict:
        return typing.get_args(tp)[1]
    if origin is list:
        return typing.get_args(tp)[0]
    return None
