"""The reward-term registry is what the schema offers, and what the checks ask of a field (tests/test_docs.py:
the DSL reference's table lists it)."""

from __future__ import annotations

import typing
from dataclasses import replace

import pytest

from fieldgen.schema import SpecError, load_spec
from fieldgen.schema.editor import json_schema
from fieldgen.schema.models import RewardTerm
from fieldgen.schema.terms import TERMS

def test_the_schema_offers_exactly_the_registered_terms():
    """A single agent's terms, then the terms only a match has (fieldgen.schema.terms.MATCH_TERMS)."""
    from fieldgen.schema.terms import MATCH_TERMS

    names = tuple(dict.fromkeys([*TERMS, *MATCH_TERMS]))
    assert typing.get_args(RewardTerm.model_fields["term"].annotation) == names
    assert json_schema()["$defs"]["RewardTerm"]["properties"]["term"]["enum"] == list(names)


# a field that lacks each thing a term may need, and what the check then says
LACKING = {
    "ball": ("ball: {enabled: false}\n", "needs a ball, but ball.enabled is false"),
    "goal": ("goal: {enabled: false}\n", "needs a goal, but goal.enabled is false"),
    "torso": ("agent: {kind: point}\n", "needs an agent with a torso (kind: ant)"),
}


@pytest.mark.parametrize("need", LACKING)
def test_the_checks_read_what_a_term_needs_from_the_registry(write_spec, monkeypatch, need):
    """agent_progress needs nothing; registered as needing a ball (a goal, a torso), a field without one is refused."""
    lacking, message = LACKING[need]
    text = ("name: x\n" + lacking + "task:\n  target: {kind: point, x: 0, y: 5}\n"
            "  success: {kind: agent_near_target}\n  reward:\n    - {term: agent_progress}\n")
    load_spec(write_spec(text))
    monkeypatch.setitem(TERMS, "agent_progress", replace(TERMS["agent_progress"], **{need: True}))
    with pytest.raises(SpecError) as info:
        load_spec(write_spec(text))
    assert [(p.path, p.message) for p in info.value.problems] == [
        ("task.reward[0].term", f"the 'agent_progress' term {message}")]
