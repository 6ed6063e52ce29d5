"""What fieldgen's messages suggest, worded once: the hint every "unknown name" message ends with, and what a
setting's value must be."""

from __future__ import annotations

import difflib
import shlex
import typing
from typing import Iterable, Mapping


def did_you_mean(word: str, choices: Iterable[str], shown: Mapping[str, object] | None = None,
                 cutoff: float = 0.6) -> str:
    """"; did you mean 'x'?" for the choice closest to `word`, or "" when none is as close as `cutoff` (difflib's
    ratio); `shown` gives what to write for a choice where it differs (a file's path, for its name matched without
    the folder)."""
    near = difflib.get_close_matches(word, list(choices), n=1, cutoff=cutoff)
    return f"; did you mean '{(shown or {}).get(near[0], near[0])}'?" if near else ""


def shell(word: object) -> str:
    """A path or word as a printed command must hold it to be pasted into a shell: quoted where it has spaces or
    characters the shell reads (a folder named 'my runs' or '-x')."""
    text = str(word)
    if text.startswith("-"):
        text = f"./{text}" if not text.startswith("./") else text
    return shlex.quote(text)


BOUNDS = {"greater_than": ("greater than", "gt"), "greater_than_equal": ("at least", "ge"),
          "less_than": ("less than", "lt"), "less_than_equal": ("at most", "le")}


# a whole number too large: past the setting's largest, past a machine integer (1e30), or infinite (1e400)
TOO_LARGE = ("less_than", "less_than_equal", "int_parsing_size", "finite_number")


def allowed(error: dict, field) -> str:
    """What a setting's value must be, in words, from pydantic's first complaint about it (`field`: the
    setting's pydantic FieldInfo): a trainer's config and a curriculum's sampler say it alike. A whole number
    too large is told the setting's whole range."""
    span = _whole_range(field)
    if span is not None and error["type"] in TOO_LARGE:
        return f"must be {span}"
    kind = typing.get_origin(field.annotation) or field.annotation
    if error["type"] in BOUNDS:
        phrase, key = BOUNDS[error["type"]]
        loc = error.get("loc") or ()
        if kind is tuple and loc and isinstance(loc[-1], int):  # an item's bound, not the list's
            return f"must be a list of layer widths, each {_bound(phrase, error['ctx'][key])}"
        return f"must be {_bound(phrase, error['ctx'][key])}"
    if error["type"] == "finite_number" and kind is not tuple:  # a list's item is told as the list is
        return f"must be {_passed_bound(field, error.get('input')) or 'a finite number'}"
    words = {int: "a whole number", float: "a number", bool: "true or false",
             tuple: "a list of layer widths, whole numbers above 0"}
    return f"must be {words.get(kind, kind.__name__)}"


def _passed_bound(field, value) -> str | None:
    """"at most 1,000" for an infinite `value` (1e999) of a setting bounded above, "greater than 0" for one
    infinite downwards of a setting bounded below: the bound it passed, not only that it is infinite. None for
    NaN, which lies on neither side, and for a setting unbounded on that side."""
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        return None
    sides = ("lt", "le") if number > 0 else ("gt", "ge") if number < 0 else ()  # NaN: neither
    for phrase, key in BOUNDS.values():
        bound = next((getattr(m, key) for m in field.metadata if getattr(m, key, None) is not None), None)
        if key in sides and bound is not None:
            return _bound(phrase, bound)
    return None


def _bound(phrase: str, bound) -> str:
    return f"{phrase} {bound:,}" if isinstance(bound, int) else f"{phrase} {bound}"


def _whole_range(field) -> str | None:
    """"a whole number from LOW to HIGH" for a whole-number setting bounded both ways; None for any other."""
    if field.annotation is not int:
        return None
    lows = [m.gt + 1 for m in field.metadata if getattr(m, "gt", None) is not None] + \
        [m.ge for m in field.metadata if getattr(m, "ge", None) is not None]
    highs = [m.lt - 1 for m in field.metadata if getattr(m, "lt", None) is not None] + \
        [m.le for m in field.metadata if getattr(m, "le", None) is not None]
    return f"a whole number from {max(lows):,} to {min(highs):,}" if lows and highs else None
