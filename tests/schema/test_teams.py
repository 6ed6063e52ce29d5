"""Team fields: two sides, a goal at each end, kick-offs per side, and one-line problems for what a match
cannot be."""

from __future__ import annotations

import pytest

from fieldgen.schema import SpecError, bundled_fields, load_spec
from fieldgen.schema import geometry

BASE = "extends: soccer_1v1\nname: x\n"

# (yaml after BASE, line, key path, a phrase the message must contain)
BAD = [
    ("teams:\n  home: {start: [[0, -2.5]]}\n  away: {start: [[0, 2.5]]}\n", 5, "teams.away.start",
     "kick-offs of home0 at (0, -2.5) and away0 at (0, -2.5) overlap"),
    ("teams:\n  home: {agents: 2, start: [[0, -2], [0.3, -2]]}\n  away: {agents: 2}\n", 4, "teams.home.start",
     "overlap"),
    ("goal: {enabled: false}\n", 3, "goal.enabled", "a goal at each end"),
    ("teams:\n  home: {agents: 3}\n", 4, "teams.home.agents", "less than or equal to 2"),
    ("teams:\n  home: {agents: 2}\n", 4, "teams.home.agents", "home fields 2 agents and away 1"),
    ("teams:\n  home: {start: [[2.9, -2.5]]}\n", 4, "teams.home.start", "home0 at (2.9, -2.5) with reach 0.25 "
     "does not fit inside the field"),
    # two agents a side by default on a field too narrow for them
    ("field: {width: 1.2}\ngoal: {width: 1}\nteams:\n  home: {agents: 2}\n  away: {agents: 2}\n", 6,
     "teams.home.agents", "kick-offs of home0 at (-0.2, -2.5) and home1 at (0.2, -2.5) overlap"),
    ("teams:\n  away: {start: [[0, -2], [1, -2]]}\n", 4, "teams.away.start", "2 kick-offs for 1 agent"),
    ("task: {success: {kind: ball_near_target}}\n", 3, "task.success.kind", "a match is won by goals"),
    ("task: {target: {kind: ring, radius: 2}}\n", 3, "task.target.kind", "each side's target is the opponent's goal"),
    ("task:\n  reward:\n    - {term: success}\n", 5, "task.reward[0].term", "a match's terms: goal, ball_progress"),
    ("task:\n  reward:\n    - {term: upright}\n", 5, "task.reward[0].term", "needs agents with a torso"),
    ("task: {goal_positions: [ball]}\n", 3, "task.goal_positions", "names no goal"),
    ("episode: {fall: {kind: flipped}}\n", 3, "episode.fall.kind", "ends at a goal or on time"),
    ("sim: {backend: generalized}\n", 3, "sim.backend", "a team field runs on MJX"),
    ("sim: {contacts: study}\n", 3, "sim.contacts", "agents never touch each other"),
    ("agent: {start: [0, -2]}\n", 3, "agent.start", "teams.home.start and teams.away.start"),
    ("ball: {enabled: false}\n", 3, "ball.enabled", "a match needs a ball"),
    ("ball: {spawn: {x: 0, y: -2.2}}\n", 3, "ball.spawn", "from the home0's start"),
    # walls sealing the home side's goal alone: judged on the field turned half a turn
    ("obstacles:\n  wall: {x: 0, y: -4.3, width: 6, depth: 0.3}\n", 3, "obstacles", "cannot reach the goal"),
]


@pytest.mark.parametrize("text,line,path,phrase", BAD)
def test_a_bad_team_spec_names_line_key_and_reason(write_spec, text, line, path, phrase):
    spec_file = write_spec(BASE + text)
    with pytest.raises(SpecError) as info:
        load_spec(spec_file)
    matching = [p for p in info.value.problems if phrase in p.message]
    assert len(matching) == 1, f"not one problem mentions {phrase!r}: {[str(p) for p in info.value.problems]}"
    assert (matching[0].file, matching[0].line, matching[0].path) == (spec_file, line, path)
    assert "\n" not in matching[0].message


def test_a_match_term_on_a_single_agent_field_is_refused(write_spec):
    with pytest.raises(SpecError) as info:
        load_spec(write_spec("extends: point_soccer\nname: x\ntask:\n  reward:\n    - {term: goal}\n"))
    (problem,) = info.value.problems
    assert problem.path == "task.reward[0].term" and "a term of a match" in problem.message


def test_a_team_field_defaults_to_goals_and_mirrored_kickoffs():
    spec = load_spec(bundled_fields()["soccer_2v2"])
    assert spec.task.success.kind == "ball_in_goal" and spec.task.target.kind == "goal"
    assert dict(geometry.kickoffs(spec)) == {"home0": (-4 / 3, -3.0), "home1": (4 / 3, -3.0),
                                              "away0": (4 / 3, 3.0), "away1": (-4 / 3, 3.0)}
    bare = load_spec(spec.model_copy(update={"task": spec.task.model_validate({})}))
    assert [t.term for t in bare.task.reward] == ["goal"] and bare.task.success.kind == "ball_in_goal"


def test_a_team_field_has_a_goal_at_each_end_and_mouths_in_both_end_walls():
    spec = load_spec(bundled_fields()["soccer_1v1"])
    assert [(g.name, g.center[1]) for g in geometry.goal_regions(spec)] == [("away_goal_region", 5.0),
                                                                           ("home_goal_region", -5.0)]
    names = [w.name for w in geometry.walls(spec)]
    assert names == ["wall_left", "wall_right", "wall_back_left", "wall_back_right", "wall_front_left",
                     "wall_front_right"]


def test_single_agent_specs_dump_without_teams():
    """A field without teams resolves as it did before teams existed: its run records' digests stay the same."""
    for name, path in bundled_fields().items():
        spec = load_spec(path)
        assert ("teams" in spec.model_dump(mode="json")) == (spec.teams is not None), name
