"""The schedules a run records by name (run.json's `schedule`): staged and mixed (schedule.py) and the
automatic curriculum (auto.py), built from their names here, above the modules that define them."""

from __future__ import annotations

from fieldgen.curriculum.auto import Auto, Sampler
from fieldgen.curriculum.promotion import Promotion
from fieldgen.curriculum.schedule import Mixed, Staged

SCHEDULES = ("staged", "mixed", "auto")  # how a run moves through its stages, as run.json records it


def schedule(kind: str, promotion: Promotion = Promotion(), sampler: Sampler | None = None) -> Staged | Mixed:
    """The schedule of a run through a curriculum's stages (a plain run is a curriculum of one stage): one
    of SCHEDULES; an automatic curriculum's levels drawn as `sampler` says (its defaults where None)."""
    if kind == "auto":
        return Auto(sampler or Sampler())
    return Mixed() if kind == "mixed" else Staged(promotion)
