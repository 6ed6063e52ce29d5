"""A run's curriculum as one object: what `curriculum.plan` makes of a source and a kind, and what run.json keeps
of it, read back as it was written and as older runs wrote it."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from fieldgen import curriculum
from fieldgen.curriculum.auto import Auto, Sampler
from fieldgen.curriculum.promotion import Promotion
from fieldgen.curriculum.schedule import Mixed, Staged
from fieldgen.run import record
from fieldgen.schema.loader import bundled_fields

ROOT = Path(__file__).resolve().parents[2]
WHERE = Path("runs/x/run.json")


def saved(plan_record: dict) -> record.RunRecord:
    """run.json's plan entries as fieldgen.run.record reads them back."""
    return record.RunRecord.model_validate({"algo": "crl", "config": {}, "observation": {}, **plan_record})


KICKOFFS = [[None, [0.0, 1, 1, 2, 2, 0, 0]], [[0.5, 1, 1, 2, 2, 0, 0], [1.0, 1, 1, 2, 2, 0, 0]]]
PLANS = [
    curriculum.Plan(),
    curriculum.Plan("staged", "near_to_far", Promotion(0.7, 3)),
    curriculum.Plan("mixed", "near_to_far-mixed"),
    curriculum.Plan("auto", "point_soccer-auto", levels=[{"kickoff": 0.0}, {"kickoff": 1.0}], kickoffs=KICKOFFS,
                    sampler=Sampler(replaced=8)),
]


@pytest.mark.parametrize("plan", PLANS, ids=[p.kind + "-" + (p.name or "field") for p in PLANS])
def test_a_plan_reads_back_from_run_json_as_it_was_written(plan):
    assert curriculum.Plan.recorded(saved(plan.record()), 2, WHERE) == plan
    assert plan.record()["schedule"] == plan.kind and plan.record()["mixed"] == plan.mixed


def test_what_run_json_keeps_of_a_plan_is_the_record_older_runs_wrote():
    """The keys and values run.json held before the plan was one object, so older run folders open as they did."""
    assert curriculum.Plan().record() == {"promotion": {"threshold": 0.5, "window": 2}, "mixed": False,
                                          "schedule": "staged"}
    auto = PLANS[-1].record()
    assert auto == {"promotion": {"threshold": 0.5, "window": 2}, "mixed": True, "schedule": "auto",
                    "curriculum": "point_soccer-auto", "levels": PLANS[-1].levels, "kickoffs": KICKOFFS,
                    "sampler": Sampler(replaced=8).model_dump()}
    assert curriculum.Plan("auto", "a-auto").record()["sampler"] == Sampler().model_dump()


def test_older_records_read_as_the_runs_that_wrote_them():
    """Without `schedule` a run is staged, or mixed where `mixed` says so; without `sampler` an automatic
    curriculum samples with the defaults; the schedule each makes is the one it trained with."""
    old_mixed = curriculum.Plan.recorded(saved({"mixed": True, "curriculum": "c-mixed"}), 3, WHERE)
    assert old_mixed.kind == "mixed" and old_mixed.mixed and isinstance(old_mixed.schedule, Mixed)
    old_staged = curriculum.Plan.recorded(saved({"promotion": {"threshold": 0.9, "window": 1}}), 3, WHERE)
    assert old_staged.kind == "staged" and old_staged.schedule == Staged(Promotion(0.9, 1))
    assert old_staged.variant_name == "stage" and not old_staged.mixed
    auto = curriculum.Plan.recorded(saved({"schedule": "auto", "mixed": True, "kickoffs": KICKOFFS}), 2, WHERE)
    assert auto.sampler is None and auto.schedule == Auto(Sampler()) and auto.variant_name == "level"


def test_a_damaged_plan_in_run_json_is_one_sentence():
    with pytest.raises(curriculum.PlanError, match=r"runs/x/run.json holds kick-off points that do not fit its 3 "
                                                   r"levels"):
        curriculum.Plan.recorded(saved({"schedule": "auto", "kickoffs": KICKOFFS}), 3, WHERE)
    with pytest.raises(curriculum.PlanError, match=r"runs/x/run.json: sampler kept=3: .* it was edited or damaged"):
        curriculum.Plan.recorded(saved({"schedule": "auto", "sampler": {"kept": 3}}), 2, WHERE)


def test_plan_refuses_what_does_not_go_together_in_one_sentence():
    field = bundled_fields()["point_nav"]
    with pytest.raises(curriculum.PlanError, match="--sampler sets how --curriculum auto draws its levels"):
        curriculum.plan(field, "staged", sampler=Sampler())
    with pytest.raises(curriculum.PlanError, match="is a single field; --mixed trains the stages of a curriculum"):
        curriculum.plan(field, "mixed")
    with pytest.raises(curriculum.PlanError, match="not the curriculum folder"):
        curriculum.plan(ROOT / "curricula" / "point_nav_to_far", "auto")
    with pytest.raises(curriculum.PlanError, match="a run goes through its stages as one of staged, mixed, auto"):
        curriculum.plan(field, "sideways")


def test_a_plan_of_a_field_or_a_curriculum_folder():
    plan, envs = curriculum.plan(bundled_fields()["point_nav"])
    assert plan == curriculum.Plan() and [e.spec.name for e in envs] == ["point_nav"]
    assert plan.environments(envs) == envs
    folder = ROOT / "curricula" / "point_nav_to_far"
    plan, envs = curriculum.plan(folder)
    assert plan.kind == "staged" and plan.name == "point_nav_to_far"
    assert plan.promotion == curriculum.load(folder).promotion
    assert len(envs) == len(curriculum.load(folder).stages) and plan.environments(envs) == envs
    assert plan.on_one_field() == dataclasses.replace(plan, kind="staged")
