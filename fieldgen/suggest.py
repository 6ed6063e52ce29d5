"""The hint every "unknown name" message of fieldgen ends with, worded once."""

from __future__ import annotations

import difflib
from typing import Iterable, Mapping


def did_you_mean(word: str, choices: Iterable[str], shown: Mapping[str, object] | None = None) -> str:
    """"; did you mean 'x'?" for the choice closest to `word`, or "" when none is close; `shown` gives what to
    write for a choice where it differs (a file's path, for its name matched without the folder)."""
    near = difflib.get_close_matches(word, list(choices), n=1)
    return f"; did you mean '{(shown or {}).get(near[0], near[0])}'?" if near else ""
