"""Curricula, in one place: everything that chooses what an environment plays. Variants generated
between easy and hard fields, one generator per kind (generate.py), the folder that lists them
(folder.py), the rule that promotes a staged run (promotion.py), how a run moves through the
stages, staged or mixed, and how a mixed run weights them (schedule.py), a sheet of the stages
(sheet.py); the automatic curriculum's levels between a spec's easy end and the spec (levels.py) and
its sampler (auto.py); each schedule built from the name a run records (kinds.py); a run's curriculum as one
object, what `plan` makes of a source and a kind (plans.py)."""

from fieldgen.curriculum.folder import INDEX, Curriculum, CurriculumError, Promotion, Stage, is_curriculum, load, write
from fieldgen.curriculum.generate import (KINDS, Asked, explicit, grid, interpolate, parse_assignments, parse_axis,
                                          start_states, variants)
from fieldgen.curriculum.plans import Plan, PlanError, plan

__all__ = ["INDEX", "KINDS", "Asked", "Curriculum", "CurriculumError", "Plan", "PlanError", "Promotion", "Stage",
           "explicit", "grid", "interpolate", "is_curriculum", "load", "parse_assignments", "parse_axis", "plan",
           "start_states", "variants", "write"]
