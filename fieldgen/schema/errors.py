"""Spec problems that point at the file, line, column and key path."""

from __future__ import annotations

import reprlib
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Problem:
    file: Path | None
    line: int | None  # 1-based
    col: int | None  # 1-based
    path: str  # dotted key path, e.g. "goal.width" or "task.reward[1].weight"
    message: str

    def __str__(self) -> str:
        where = str(self.file) if self.file else "<spec>"
        if self.line is not None:
            where += f":{self.line}:{self.col or 1}"
        key = f" {self.path}:" if self.path else ""
        return f"{where}:{key} {self.message}"


class SpecError(Exception):
    """A spec that cannot become a field; carries every problem found, not just the first."""

    document = "the field spec"  # what the problems are in, as the first line names it

    def __init__(self, problems: list[Problem]):
        self.problems = sorted(problems, key=lambda p: (str(p.file), p.line or 0, p.col or 0))
        super().__init__(str(self))

    def __str__(self) -> str:
        n = len(self.problems)
        head = f"{n} problem{'s' if n != 1 else ''} in {self.document}:"
        return "\n".join([head] + [f"  {p}" for p in self.problems])


SHOWN_CHARACTERS = 60  # of a key or value echoed in a problem: enough to recognise it, a line at most


def shown_text(text: str, most: int = SHOWN_CHARACTERS, quoted: bool = False) -> str:
    """Text from a spec as a problem echoes it: characters that print as nothing or reorder a terminal's line
    (U+202E...) escaped, and a text longer than `most` cut to its start with its length, so that one problem
    stays a line. `quoted`: the text (or its start) as Python's repr writes it, which escapes them itself."""
    if not quoted:
        text = "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text)
    cut = len(text) > most
    kept = text[:most - 20] if cut else text
    kept = repr(kept) if quoted else kept
    return f"{kept}... ({len(text):,} characters)" if cut else kept


def shown_value(value) -> str:
    """Any value a record holds as a problem echoes it: Python's repr (true, false and null as written), cut as
    `shown_text` cuts text, and never written out whole first (a list of millions of items, a number of a million
    digits, is cut at its start)."""
    if isinstance(value, str):
        return shown_text(value, quoted=True)
    if isinstance(value, bool) or value is None:  # as YAML and JSON write them, where the value came from
        return {True: "true", False: "false", None: "null"}[value]
    brief = reprlib.Repr()
    brief.maxstring = brief.maxother = brief.maxlong = SHOWN_CHARACTERS
    try:
        return shown_text(brief.repr(value))
    except ValueError:  # an integer past Python's digits for a string
        return f"a {type(value).__name__} too long to show"


def format_path(parts: tuple) -> str:
    out = ""
    for part in parts:
        out += f"[{part}]" if isinstance(part, int) else (f".{shown_text(part)}" if out else shown_text(str(part)))
    return out
