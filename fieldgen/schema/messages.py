"""pydantic's validation errors as spec problems, in the spec's words: one problem per value, at the key
that holds it, with no union tags or type names of pydantic's own."""

from __future__ import annotations

import re
import types
import typing

from pydantic import BaseModel

from fieldgen.schema.errors import Problem, shown_text
from fieldgen.schema.models import PATTERN_WORDS, FieldSpec, NotAsWritten
from fieldgen.schema.source import Source
from fieldgen.suggest import did_you_mean

# what a type error asked for, as a spec's author would say it
EXPECTED = {
    "int_type": "a whole number", "int_parsing": "a whole number", "int_from_float": "a whole number",
    "float_type": "a number", "float_parsing": "a number", "string_type": "text", "bool_type": "true or false",
    "bool_parsing": "true or false", "list_type": "a list", "tuple_type": "a pair [a, b]", "dict_type": "a mapping",
    "model_type": "a mapping", "model_attributes_type": "a mapping", "none_required": "null",
}


def problems(source: Source, errors: list[dict], model: type[BaseModel] = FieldSpec) -> list[Problem]:
    """One problem per value: a value that no choice of a union accepts draws one error per choice.
    `model` is what validated the document (a field spec, or another YAML file read the same way)."""
    by_value: dict[tuple, list[dict]] = {}
    for err in errors:
        by_value.setdefault(_data_path(source.data, err["loc"], err["type"] == "missing"), []).append(err)
    # a union's choice of another kind (a whole number, 'auto') refused a list or mapping that a choice of its kind
    # took and found wrong inside: what is wrong is inside ([-1] is a list, its -1 below 0), so only that is said
    inside = {parts for parts in by_value for other in by_value
              if len(other) > len(parts) and other[:len(parts)] == parts}
    by_value = {parts: errs for parts, errs in by_value.items() if not (
        parts in inside and all(_expected(e) is not None or e["type"] == "literal_error" for e in errs))}
    return [_problem(source, parts, errs, model) for parts, errs in by_value.items()]


def _problem(source: Source, parts: tuple, errs: list[dict], model: type[BaseModel]) -> Problem:
    err = errs[0]
    kind, value = err["type"], err.get("input")
    if isinstance(value, NotAsWritten):
        return source.problem(parts, value.reason)
    if len(errs) > 1:
        bounds = [e for e in errs if _expected(e) is None]  # the choice whose type it has, out of its range
        if bounds:
            return source.problem(parts, _plain(bounds[0]))
        wanted = dict.fromkeys(_expected(e) for e in errs)
        return source.problem(parts, f"expected {' or '.join(wanted)} (got {_shown(value)})")
    if kind == "extra_forbidden":
        allowed = _allowed_keys(model, err["loc"][:-1])
        msg = f"unknown key '{shown_text(str(parts[-1]))}'{did_you_mean(str(parts[-1]), allowed) or '.'}"
        return source.problem(parts, msg + (f" Allowed keys here: {', '.join(allowed)}." if allowed else ""))
    if kind == "missing" and isinstance(err["loc"][-1], int):
        return source.problem(parts, f"expected a pair [a, b] (got {len(value)} item{'s' * (len(value) != 1)})")
    if kind == "missing":
        return source.problem(parts, f"the key '{parts[-1]}' is required" if parts else err["msg"])
    if kind in ("too_long", "too_short"):
        bound = err["ctx"]["max_length" if kind == "too_long" else "min_length"]
        return source.problem(parts, f"{'at most' if kind == 'too_long' else 'at least'} {bound:,} "
                                     f"item{'s' * (bound != 1)} here (got {err['ctx']['actual_length']:,})")
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        return _tag_problem(source, parts, err, model)
    if kind == "literal_error" and err["loc"][-2:] == ("reward", "generated"):  # a word where terms are listed
        return source.problem(parts, f"expected a list of reward terms, or 'dense' for the terms generated for the "
                                     f"task (got {_shown(value)}{did_you_mean(str(value), ['dense'])})")
    if kind == "literal_error" and isinstance(value, str):
        expected = re.findall(r"'([^']*)'", err["ctx"]["expected"])
        return source.problem(parts, f"{err['msg']} (got {_shown(value)}{did_you_mean(value, expected)})")
    if kind == "string_pattern_mismatch" and err["ctx"]["pattern"] in PATTERN_WORDS:
        return source.problem(parts, f"a name is {PATTERN_WORDS[err['ctx']['pattern']]}, such as "
                                     f"'{_named(value, err['ctx']['pattern'])}' (got {_shown(value)})")
    if kind in EXPECTED:
        return source.problem(parts, f"expected {_expected(err)} (got {_shown(value)})")
    if kind == "finite_number":  # .inf, .nan: the words models.py gives nan and inf written plainly
        return source.problem(parts, f"expected a finite number (got {_shown(value)})")
    return source.problem(parts, _plain(err))


def _tag_problem(source: Source, parts: tuple, err: dict, model: type[BaseModel]) -> Problem:
    """A choice (target, spawn, fall rule) named by its `kind` or `mode`: the key, and the names it takes."""
    value, ctx = err["input"], err.get("ctx", {})
    key = ctx.get("discriminator", "").strip("'")
    if key.endswith("()"):  # a function picks the choice; the key is the one holding the unknown name
        key = next((k for k, v in value.items() if v == ctx.get("tag")), key)
    names = _choices(model, err["loc"], key)
    listed = ", ".join(repr(n) for n in names)
    if err["type"] == "union_tag_not_found":
        return source.problem(parts, f"the key '{key}' is required here: one of {listed}")
    tag = str(ctx["tag"])
    return source.problem(parts + (key,), f"unknown {key} '{shown_text(tag)}': one of {listed}"
                                          f"{did_you_mean(tag, names)}")


def _expected(err: dict) -> str | None:
    if err["type"] == "literal_error":
        return err["ctx"]["expected"]
    return EXPECTED.get(err["type"])


def _plain(err: dict) -> str:
    """pydantic's own sentence, where it speaks of the value (a bound, a length), with what was written."""
    msg = err["msg"].removeprefix("Value error, ")
    if "input" in err and not isinstance(err["input"], (dict, list)):
        msg += f" (got {_shown(err['input'])})"
    return msg


def _named(text: str, pattern: str) -> str:
    """`text` made into a name `pattern` takes: lower case, each run of other characters one _."""
    name = re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_") or "field"
    return name if re.fullmatch(pattern, name) else f"x{name}"


def _shown(value) -> str:
    """A value as YAML writes it, a long text cut to its start (`shown_text`)."""
    if isinstance(value, bool) or value is None:
        return {True: "true", False: "false", None: "null"}[value]
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    return shown_text(value, quoted=True) if isinstance(value, str) else shown_text(repr(value))


def _data_path(data, loc: tuple, missing: bool = False) -> tuple:
    """Drop pydantic's union tags from an error location, keeping real keys (and, for a missing key,
    the key that belongs there)."""
    parts: list = []
    node = data
    for i, elem in enumerate(loc):
        if isinstance(node, dict) and elem in node:
            node = node[elem]
            parts.append(elem)
        elif isinstance(node, (list, tuple)) and isinstance(elem, int) and elem < len(node):
            node = node[elem]
            parts.append(elem)
        elif missing and i == len(loc) - 1 and not isinstance(elem, int):
            parts.append(elem)  # a missing key names where it belongs
        # anything else is a discriminator tag or a union member name
    return tuple(parts)


def _allowed_keys(root: type[BaseModel], loc: tuple) -> list[str]:
    """The keys the model at this location accepts, for did-you-mean hints."""
    model = _unwrap(_type_at(root, loc))
    if isinstance(model, type) and issubclass(model, BaseModel):
        return list(model.model_fields)
    return []


def _choices(root: type[BaseModel], loc: tuple, key: str) -> list[str]:
    """The names `key` takes in the choices of the union at this location."""
    names: list[str] = []
    for member in typing.get_args(_unwrap(_type_at(root, loc))):
        member = _unwrap(member)
        if isinstance(member, type) and issubclass(member, BaseModel) and key in member.model_fields:
            names += typing.get_args(member.model_fields[key].annotation)
    return names


def _type_at(root: type[BaseModel], loc: tuple):
    tp: object = root
    for elem in loc:
        tp = _step(tp, elem)
        if tp is None:
            return None
    return tp


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
