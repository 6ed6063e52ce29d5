"""A run's curriculum as one object: what `plan` makes of a source (a field, a build folder or a curriculum folder)
and the way a run goes through it (staged, mixed or auto), with the environments of its stages or levels. A run
holds its `Plan` and asks it everything curricular: its schedule, what its trainers train on, what run.json keeps
of it (`Plan.record`) and the plan back from run.json (`Plan.recorded`, older records included)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from fieldgen.curriculum.promotion import Promotion


class PlanError(Exception):
    """A source, kind or setting a run cannot train through, in one sentence."""


@dataclasses.dataclass(frozen=True)
class Plan:
    """How a run goes through its stages (a plain run has one): `kind` (one of SCHEDULES), the curriculum's
    `name` ("" for a field), its `promotion` rule; for an automatic curriculum each level's coordinates by axis
    name (`levels`), its kick-off points (`kickoffs`, curriculum.auto.kickoff_tables) and its `sampler`
    (curriculum.auto.Sampler; None: its defaults)."""

    kind: str = "staged"
    name: str = ""
    promotion: Promotion = Promotion()
    levels: list = dataclasses.field(default_factory=list)
    kickoffs: list = dataclasses.field(default_factory=list)
    sampler: object = None

    @property
    def schedule(self):
        """How the run moves through its stages (curriculum.contract.Schedule)."""
        from fieldgen.curriculum.kinds import schedule

        return schedule(self.kind, self.promotion, self.sampler)

    @property
    def mixed(self) -> bool:
        """Whether every environment carries its own stage, all trained at once (a mixed or automatic curriculum)."""
        return self.kind != "staged"

    @property
    def variant_name(self) -> str:
        """What the run's figures call a variant: an automatic curriculum's are levels, others' stages."""
        return "level" if self.kind == "auto" else "stage"

    def environments(self, envs: list) -> list:
        """What the trainers train on, from the environments of the stages: one per stage, or one batching them
        all (with an automatic curriculum's kick-off points)."""
        if self.kind == "auto" and self.kickoffs:
            return self.schedule.environments(envs, self.kickoffs)
        return self.schedule.environments(envs)

    def on_one_field(self) -> "Plan":
        """The plan of the run's policy put on one other field: that field alone, its label kept."""
        return dataclasses.replace(self, kind="staged", kickoffs=[], sampler=None)

    def record(self) -> dict:
        """What run.json keeps of the plan (beside the run's fields): read back by `recorded`."""
        return {"promotion": dataclasses.asdict(self.promotion), "mixed": self.mixed, "schedule": self.kind,
                **({"curriculum": self.name} if self.name else {}),
                **({"levels": self.levels, "kickoffs": self.kickoffs} if self.levels else {}),
                **({"sampler": (self.sampler or _sampler_type()()).model_dump()} if self.kind == "auto" else {})}

    @classmethod
    def recorded(cls, saved, stages: int, where: Path) -> "Plan":
        """The plan run.json at `where` records (`saved`, its fields read by fieldgen.run.record) for a run of
        `stages` stages or levels: a record without `schedule` (an older run) is staged or, with `mixed`, mixed;
        one without `sampler` samples with the defaults. PlanError where its kick-off points or sampler were
        edited or damaged."""
        kind = saved.schedule or ("mixed" if saved.mixed else "staged")
        points = {len(level) for level in saved.kickoffs}
        if saved.kickoffs and (len(saved.kickoffs) != stages or len(points) > 1 or min(points) < 2
                               or any(level[-1] is None for level in saved.kickoffs)):
            raise PlanError(f"{where} holds kick-off points that do not fit its {stages} levels (as many points for "
                            "each, at least 2, the last its own); it was edited or damaged: start the run again in a "
                            "new folder")
        if saved.levels and len(saved.levels) != stages:
            raise PlanError(f"{where} holds the coordinates of {len(saved.levels)} levels, and the run has {stages}; "
                            "it was edited or damaged: restore it, or start the run again in a new folder")
        sampler = None
        if saved.sampler:
            from fieldgen.curriculum.levels import LevelError

            try:
                sampler = _sampler_type().checked(saved.sampler, f"{where}: sampler")
            except LevelError as exc:
                raise PlanError(f"{exc}; it was edited or damaged: restore it, or start the run again in a new "
                                "folder") from None
        return cls(kind, saved.curriculum, saved.promotion, saved.levels, saved.kickoffs, sampler)


def _sampler_type():
    from fieldgen.curriculum.auto import Sampler

    return Sampler


def plan(source, kind: str = "staged", levels: int | None = None, sampler=None) -> tuple[Plan, list]:
    """The plan of a run on `source` (a field's YAML file, build folder or FieldSpec, or a curriculum folder) as
    `kind` (one of SCHEDULES) says, and the environments of its stages: a field alone, a curriculum's stages one at a
    time (staged) or all at once (mixed, built to one structure), or with auto `levels` levels (curriculum.auto.LEVELS
    by default) between the field's easy end and itself, drawn as `sampler` (curriculum.auto.Sampler, its
    defaults where None) says. PlanError in one sentence where the source, kind and settings do not go together."""
    from fieldgen import curriculum
    from fieldgen.curriculum.kinds import SCHEDULES, schedule

    if kind not in SCHEDULES:
        raise PlanError(f"{kind}: a run goes through its stages as one of {', '.join(SCHEDULES)}")
    mixed, auto = kind == "mixed", kind == "auto"
    folder = isinstance(source, Path) and curriculum.is_curriculum(source)
    if sampler is not None and not auto:
        raise PlanError("--sampler sets how --curriculum auto draws its levels; add --curriculum auto")
    if auto:
        if folder:
            raise PlanError(f"--curriculum auto makes its own levels from one field and trains them all at once; "
                            f"give it a field (YAML or build folder), without --mixed, not the curriculum folder "
                            f"{source}")
        envs, coordinates, kickoffs = auto_environments(source, levels)
        _refuse_warp_batch(envs)
        from fieldgen.curriculum.auto import Sampler, run_label

        return Plan("auto", run_label(envs[-1].spec.name), levels=coordinates, kickoffs=kickoffs,
                    sampler=sampler or Sampler()), envs
    if folder:
        from fieldgen.compile.variants import VariantError

        try:
            c = curriculum.load(source)
            envs = schedule(kind, c.promotion).stage_environments(c.specs())
        except (curriculum.CurriculumError, VariantError, ValueError) as exc:
            raise PlanError(str(exc)) from None
        layouts = {json.dumps(e.layout.to_json()) for e in envs}
        if len(layouts) > 1:
            raise PlanError(f"{source}: the stages' observation layouts differ; a policy cannot move between them")
        if mixed:
            _refuse_warp_batch(envs)
        return Plan(kind, source.name + ("-mixed" if mixed else ""), c.promotion), envs
    if mixed:
        named = source if isinstance(source, Path) else source.name
        raise PlanError(f"{named} is a single field; --mixed trains the stages of a curriculum folder (or let "
                        "fieldgen make the stages: --curriculum auto)")
    import fieldgen

    return Plan(), [fieldgen.make(source)]


def _refuse_warp_batch(envs: list) -> None:
    """PlanError before anything is written where the environments would batch Warp's physics in one model."""
    from fieldgen.env.batch import refuse_warp_batch
    from fieldgen.schema.backends import mjx_impl

    try:
        for impl in {mjx_impl(env.spec) for env in envs}:
            refuse_warp_batch([env.spec.name for env in envs], impl)
    except ValueError as exc:
        raise PlanError(str(exc)) from None


def auto_environments(source, count: int | None) -> tuple[list, list[dict], list]:
    """The environments of `count` levels from `source`'s easy end to the field itself (curriculum.auto),
    built to one structure, each level's coordinates by axis name and its kick-off points, for run.json."""
    from fieldgen.compile.artifact import ArtifactError, load_artifact
    from fieldgen.compile.variants import VariantError
    from fieldgen.curriculum.auto import LEVELS, kickoff_tables, levels as auto_levels
    from fieldgen.curriculum.kinds import schedule
    from fieldgen.curriculum.levels import LevelError, LevelSpace
    from fieldgen.schema import load_spec

    try:
        spec = load_artifact(source).spec if isinstance(source, Path) and source.is_dir() else load_spec(source)
        wanted = LEVELS if count is None else count
        chosen = auto_levels(spec, wanted)
        if len(chosen) < 2:  # every level but the field refused: no curriculum is left to train through
            raise LevelError(f"--levels {wanted} on {spec.name}: the schema refuses the {wanted - 1} easier "
                             f"level{'s' * (wanted > 2)} of its path (a start the ball cannot leave, say), which "
                             "leaves the field alone; ask for more levels (--levels N) or train the field without "
                             "--curriculum auto")
        envs = schedule("auto").stage_environments([level.spec for level in chosen])
        kickoffs = kickoff_tables(spec, chosen)
    except (LevelError, VariantError, ArtifactError, ValueError) as exc:
        raise PlanError(str(exc)) from None
    names = [axis.name for axis in LevelSpace.of(spec).axes]
    return envs, [dict(zip(names, level.coordinates)) for level in chosen], kickoffs
