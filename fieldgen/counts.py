"""Counts as people write them (50M, 1.5k, 2e6): the command line's options and a sweep file's keys read them
alike, so the reading lives below both."""

from __future__ import annotations

from decimal import Decimal, InvalidOperation

from fieldgen.limits import COUNT_MAX
from fieldgen.schema.errors import shown_text

SUFFIXES = {"k": 1_000, "m": 1_000_000, "g": 1_000_000_000}


def count(text: str | int) -> int:
    """A whole count as people write them: 50M, 1.5k, 2e6, 10_000_000 or 40000 (read as a Decimal, so
    that 1.1k is exactly 1100); an option's default comes as the number itself. ValueError, in one sentence
    saying how to write one, for anything else."""
    cleaned = str(text).strip().replace("_", "").replace(",", "")
    scale = SUFFIXES.get(cleaned[-1:].lower(), 1)
    try:
        value = Decimal(cleaned[:-1] if scale > 1 else cleaned) * scale
    except InvalidOperation:
        value = Decimal(0)
    if not (value.is_finite() and 1 <= value <= COUNT_MAX and value == value.to_integral_value()):
        raise ValueError(f"'{shown_text(str(text))}' is not a positive whole count (at most {COUNT_MAX:.0e}); write it "
                         "as 40000, 50M, 1.5k or 2e6 (k, M and G stand for thousand, million and billion)")
    return int(value)
