"""Curricula, in one place: variants generated between easy and hard fields, the folder that lists
them, the rule that promotes a run from one stage to the next, and how a mixed run weights them."""

from fieldgen.curriculum.folder import INDEX, Curriculum, CurriculumError, Promotion, Stage, is_curriculum, load, write
from fieldgen.curriculum.generate import (explicit, grid, interpolate, parse_assignments, parse_axis, start_states,
                                          variants)

__all__ = ["INDEX", "Curriculum", "CurriculumError", "Promotion", "Stage", "explicit", "grid", "interpolate",
           "is_curriculum", "load", "parse_assignments", "parse_axis", "start_states", "variants", "write"]
