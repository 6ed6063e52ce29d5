"""The automatic curriculum's levels: points between an easy end derived from a spec and the spec itself.

A level is one number in [0, 1] per axis, 0 the easy end and 1 the spec's own value: where the ball and
the agent start (the kick-off moved from next to the target back to the spec's), how wide each solid
obstacle is, and whether the walls stand. Every level is a full spec, validated as any spec is, so a
level whose walls and obstacles leave the ball no way into the goal (the schema's flood fill) is never
played. All levels of a space share the spec's bodies: an obstacle or wall a level lacks is narrowed or
switched off, never removed, so one batched simulation can step them all.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Sequence

import numpy as np

from fieldgen.schema import FieldSpec, SpecError
from fieldgen.schema.geometry import AGENT_REACH, ball_spawn_centre
from fieldgen.schema.loader import bundled_names_where, merge, validate
from fieldgen.schema.source import Source

START_NEAR = 1.5  # the easy end's ball spawn centre, this far from the target
NARROWEST = 0.1  # the easy end's obstacles: this share of their spec's width, moved aside of the ball's way
AGENT_GAP = 0.25  # the easy end's agent: its reach plus the ball's radius plus this from the ball's centre


class LevelError(Exception):
    """A spec whose easy end cannot be derived (what the automatic curriculum needs is missing)."""


@dataclasses.dataclass(frozen=True)
class Axis:
    """One way a level differs from the spec, named for what it moves; a switch is off below 0.5."""

    name: str
    switch: bool = False


@dataclasses.dataclass(frozen=True)
class LevelSpace:
    """The levels between `easy` (every axis at 0) and `spec` (every axis at 1)."""

    spec: FieldSpec
    axes: tuple[Axis, ...]

    @classmethod
    def of(cls, spec: FieldSpec) -> LevelSpace:
        """The space of a spec whose ball spawns in a region and is judged against a fixed target: the
        soccer fields. Refused, in a sentence, for a spec of another kind."""
        target = spec.target_fixed()
        if not spec.ball.enabled or spec.ball.spawn.mode != "region" or target is None:
            fit = bundled_names_where(lambda s: s.agent.kind == spec.agent.kind and s.ball.enabled
                                      and s.ball.spawn.mode == "region" and s.target_fixed() is not None)
            offer = f"; bundled fields for the {spec.agent.kind} agent that have both: {', '.join(fit)}" if fit else ""
            raise LevelError(f"{spec.name}: the automatic curriculum moves a ball spawned in a region towards a "
                             "fixed target (a goal or a point); this spec has no such ball or target" + offer)
        centre = ball_spawn_centre(spec)
        if math.dist(centre, target) <= START_NEAR:
            raise LevelError(f"{spec.name}: the ball already spawns within {START_NEAR:g} of the target; there is "
                             "no easier start to begin from")
        axes = [Axis("kickoff")]
        axes += [Axis(f"obstacles.{name}.width") for name, o in sorted(spec.obstacles.items()) if o.solid]
        if spec.walls.enabled and spec.walls.solid:
            axes.append(Axis("walls", switch=True))
        return cls(spec, tuple(axes))

    @property
    def easy(self) -> np.ndarray:
        return np.zeros(len(self.axes))

    @property
    def hard(self) -> np.ndarray:
        return np.ones(len(self.axes))

    def changes(self, level: Sequence[float]) -> dict:
        """The keys of the level's spec that differ from the spec's, as a stage file would write them."""
        level = np.clip(np.asarray(level, dtype=float), 0.0, 1.0)
        if level.shape != (len(self.axes),):
            raise ValueError(f"a level of {self.spec.name} has {len(self.axes)} numbers "
                             f"({', '.join(a.name for a in self.axes)}), not {level.shape}")
        out: dict = {}
        for axis, t in zip(self.axes, level):
            if axis.name == "kickoff":
                out.update(self._kickoff(t))
            elif axis.name == "walls":
                if t < 0.5:
                    out["walls"] = {"enabled": False}
            elif t < 1.0:
                _, name, _ = axis.name.split(".")
                out.setdefault("obstacles", {})[name] = self._obstacle(name, t)
        return out

    def spec_at(self, level: Sequence[float]) -> FieldSpec:
        """The level as a validated spec (SpecError where the schema's checks refuse it: a ball that cannot
        reach the goal, a start inside an obstacle...)."""
        base = self.spec.model_dump(mode="json")
        return validate(merge(Source(base), Source(self.changes(level))))

    def playable(self, level: Sequence[float]) -> bool:
        """Whether the level passes every check a spec passes, the flood fill of the goal's mouth included."""
        try:
            self.spec_at(level)
        except SpecError:
            return False
        return True

    def _obstacle(self, name: str, t: float) -> dict:
        """The obstacle narrowed to NARROWEST of its width at t = 0 and moved aside, clear of the ball's spawn
        region and of an agent beside the ball, growing and moving back to the spec's own at t = 1."""
        spec, obstacle = self.spec, self.spec.obstacles[name]
        narrow = obstacle.width * NARROWEST
        spawn = spec.ball.spawn
        clear = (spawn.x[1] - spawn.x[0]) / 2 + spec.ball.radius + AGENT_REACH[spec.agent.kind] + narrow / 2
        side = 1.0 if obstacle.x >= 0 else -1.0
        return {"width": _rounded(narrow + t * (obstacle.width - narrow)),
                "x": _rounded(obstacle.x + (1 - t) * side * clear)}

    def _kickoff(self, t: float) -> dict:
        """The ball's spawn region and the agent's start, moved from next to the target (t = 0) back along the
        line to the spec's own (t = 1); the agent's gap to the ball grows from the closest the spec allows."""
        spec = self.spec
        if t >= 1.0:
            return {}
        target, centre, start = spec.target_fixed(), ball_spawn_centre(spec), spec.agent.start
        distance = math.dist(centre, target)
        along = (1 - t) * (1 - START_NEAR / distance)  # share of the way from the spawn centre to the target
        shift = (along * (target[0] - centre[0]), along * (target[1] - centre[1]))
        behind = (start[0] - centre[0], start[1] - centre[1])
        gap = math.hypot(*behind)
        closest = AGENT_REACH[spec.agent.kind] + spec.ball.radius + AGENT_GAP
        scale = 1.0 if gap <= closest else (closest + t * (gap - closest)) / gap
        ball = (centre[0] + shift[0], centre[1] + shift[1])
        spawn = spec.ball.spawn
        return {"ball": {"spawn": {"x": [_rounded(v + shift[0]) for v in spawn.x],
                                   "y": [_rounded(v + shift[1]) for v in spawn.y]}},
                "agent": {"start": [_rounded(ball[0] + scale * behind[0]), _rounded(ball[1] + scale * behind[1])]}}


def _rounded(x: float) -> float:
    return float(f"{x:.6g}")
