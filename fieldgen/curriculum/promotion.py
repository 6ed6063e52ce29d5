"""When a staged run moves on: the rule a curriculum states, applied to the run's history.

The trainers only ask which stage comes next (fieldgen.curriculum.contract.Schedule, answered by
fieldgen.curriculum.schedule.Staged); the rule is the curriculum's, written in its curriculum.yaml
and kept in the run's run.json."""

from __future__ import annotations

import dataclasses
from typing import Annotated

from pydantic import ConfigDict, Field, StrictInt

from fieldgen.limits import MAX_STAGES

# what curriculum.yaml and a run's run.json may hold, each read against these
Threshold = Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)]
Window = Annotated[StrictInt, Field(ge=1, le=MAX_STAGES)]


@dataclasses.dataclass(frozen=True)
class Promotion:
    """Move to the next stage once success_any, averaged over seeds and the last `window`
    evaluations on the current stage, reaches `threshold`."""

    __pydantic_config__ = ConfigDict(extra="forbid")  # a run.json's promotion read with no key of its own

    threshold: Threshold = 0.5
    window: Window = 2

    def ready(self, history: list[dict], stage: int) -> bool:
        """Whether the last `window` evaluations on `stage` (mean over seeds) reach the threshold."""
        evals = sorted({r["eval"] for r in history if r.get("stage") == stage and r["eval"] > 0})[-self.window:]
        if len(evals) < self.window:
            return False
        scores = [r["success_any"] for r in history if r.get("stage") == stage and r["eval"] in evals]
        return sum(scores) / len(scores) >= self.threshold
