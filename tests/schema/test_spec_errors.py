"""Bad specs give one clear problem per mistake, naming file, line, column and key path."""

from __future__ import annotations

import pytest

from fieldgen.schema import SpecError, load_spec


def problems_of(path):
    with pytest.raises(SpecError) as info:
        load_spec(path)
    return info.value.problems


# (yaml text, line, key path, a phrase the message must contain)
BAD = [
    ("name: x\ngoal:\n  widht: 3\n", 3, "goal.widht", "did you mean 'width'"),
    ("name: x\ngoal:\n  width: -2\n", 3, "goal.width", "greater than 0"),
    ("name: x\nball:\n  joint: rolling\n", 3, "ball.joint", "'planar' or 'free'"),
    ("name: x\nball:\n  spawn: {x: [1, -1], y: 3}\n", 3, "ball.spawn.x", "low end 1.0 is above the high end"),
    ("name: x\nball:\n  radius: .nan\n", 3, "ball.radius", "finite number"),
    ("name: x\nfield:\n  length: .inf\n", 3, "field.length", "expected a finite number (got inf)"),
    ("name: x\nfield:\n  length: nan\n", 3, "field.length", "expected a finite number (got nan)"),  # YAML's text
    ("name: x\nfield:\n  length: -inf\n", 3, "field.length", "expected a finite number (got -inf)"),
    ("name: x\nfield: {length: 1.0e+9}\n", 2, "field.length", "less than or equal to 500"),
    ("name: x\ntask:\n  reward:\n    - {term: success}\n    - {term: ball_progres}\n", 5,
     "task.reward[1].term", "did you mean 'ball_progress'"),
    ("name: x\ntask:\n  reward:\n    - {term: success, band: [0, 1]}\n", 4, "task.reward[0]", "upright term only"),
    ("name: x\nepisode: {length: 0}\n", 2, "episode.length", "greater than or equal to 1"),
    ("name: x\nobstacles:\n  goalie: {widht: 2}\n", 3, "obstacles.goalie.widht", "did you mean 'width'"),
    ("name: x\nballl: {}\n", 2, "balll", "did you mean 'ball'"),
    ("description: no name\n", 1, "name", "'name' is required"),
    ("name: Bad Name\n", 1, "name", "a name is lower-case letters, digits, _ and -, beginning with a letter or "
     "digit, such as 'bad_name' (got 'Bad Name')"),
    ("name: x\nobstacles:\n  Big-Rock: {x: 0, y: 3}\n", 3, "obstacles.Big-Rock", "a name is lower-case letters, "
     "digits and _, beginning with a letter or digit, such as 'big_rock' (got 'Big-Rock')"),
    ("name: x\nname: y\n", 2, "name", "duplicate key 'name' (first given on line 1)"),
    ("name: x\ngoal: {width: 3\n", 3, "", "YAML syntax error"),
    ("name: x\nfield:\n\tlength: 12\n", 3, "", "indented with a tab, and YAML indents with spaces alone"),
    ("name: x\nfield:\n  length: 12\n\t\n", 4, "", "indented with a tab"),
    ("- 1\n- 2\n", 1, "", "the document is a list"),
    ("just a string\n", 1, "", "a single value"),
    ("", 1, "", "the file is empty"),
    # physics sense
    ("name: x\ngoal: {distance: 30}\n", 2, "goal.distance", "beyond the field's end"),
    ("name: x\nepisode: {control_dt: 0.033, physics_dt: 0.01}\n", 2, "episode.control_dt", "whole multiple"),
    ("name: x\nball:\n  spawn: {x: 0, y: 0.5}\n", 3, "ball.spawn", "from the agent's start"),
    ("name: x\nball:\n  spawn: {x: 0, y: 30}\n", 3, "ball.spawn", "outside the field"),
    ("name: x\nball:\n  spawn: {x: 0, y: 9.8}\n", 3, "ball.spawn", "inside or touching the goal"),
    ("name: x\nobstacles:\n  rock: {x: 0, y: 3.2}\n", 3, "obstacles.rock", "touching obstacle 'rock'"),
    ("name: x\nobstacles:\n  rock: {x: 0, y: 0}\n", 3, "obstacles.rock", "overlaps the agent's start"),
    ("name: x\nball: {enabled: false}\n", 1, "task.success.kind", "'ball_near_target' needs a ball"),
    ("name: x\ntask:\n  goal_positions: [agent]\n", 3, "task.goal_positions", "judges the ball, so the goal must"),
    ("name: x\ntask:\n  goal_positions: [ball, ball]\n", 3, "task.goal_positions", "names 'ball' twice"),
    ("name: x\ntask:\n  goal_positions: [torso, ball]\n", 3, "task.goal_positions[0]", "'agent' or 'ball'"),
    ("name: x\nball: {enabled: false}\ntask:\n  success: {kind: agent_near_target}\n  goal_positions: [agent, ball]\n",
     5, "task.goal_positions", "'ball' needs a ball"),
    ("name: x\nagent: {kind: point}\ntask:\n  reward:\n    - {term: upright}\n", 5, "task.reward[0].term",
     "needs an agent with a torso"),
    ("name: x\nwalls: {enabled: true}\nfield: {length: 24, width: 8}\n"
     "obstacles:\n  wall: {relative_to: goal, y: -2, width: 8, depth: 0.5}\n", 4, "obstacles",
     "cannot reach the goal"),
    # a problem between two keys, one set in the spec and one in the bundled field it extends: shown where the
    # spec itself sets it, not at the bundled file's line of the other
    ("extends: soccer_v1\nname: x\nfield: {length: 8}\n", 3, "field.length", "make field.length at least 20"),
    ("extends: soccer_v1\nname: x\ngoal: {distance: 30}\n", 3, "goal.distance", "make field.length at least 60"),
    ("extends: soccer_v1\nname: x\ngoal: {distance: 30}\nfield: {length: 20}\n", 3, "goal.distance",
     "make field.length at least 60"),
    ("extends: soccer_v1\nname: x\nfield: {width: 3}\n", 3, "field.width",
     "the goal (4 wide) is wider than the field (3)"),
    ("extends: soccer_v1\nname: x\nagent: {start: [0, -11]}\n", 3, "agent.start", "does not fit inside the field"),
]


@pytest.mark.parametrize("text,line,path,phrase", BAD)
def test_bad_spec_names_line_key_and_reason(write_spec, text, line, path, phrase):
    spec_file = write_spec(text)
    found = problems_of(spec_file)
    matching = [p for p in found if phrase in p.message]
    assert len(matching) == 1, f"not one problem mentions {phrase!r}: {[str(p) for p in found]}"
    p = matching[0]
    assert p.file == spec_file
    assert p.line == line
    assert p.path == path
    assert str(p).startswith(f"{spec_file}:{line}:")


def test_every_problem_is_reported_not_just_the_first(write_spec):
    found = problems_of(write_spec("name: x\ngoal: {widht: 1, height: -1}\nball: {joint: rolling}\n"))
    assert {p.path for p in found} == {"goal.widht", "goal.height", "ball.joint"}


def test_a_bad_or_missing_name_hides_none_of_the_specs_other_problems(write_spec):
    """The name is checked with the rest; the physics checks, which need a whole spec, still run beside it."""
    for name in ("name: My Field\n", ""):
        found = problems_of(write_spec(f"{name}goal: {{distance: 30}}\n"))
        assert [p.path for p in found] == ["name", "goal.distance"], found


def test_a_bad_obstacle_name_hides_none_of_the_specs_other_problems(write_spec):
    """An obstacle's name is checked with the rest too: the physics checks run with a valid name in its place, and
    what they find of that obstacle names it as written, at its line; `fieldgen validate` says it all at once."""
    from typer.testing import CliRunner

    from fieldgen.cli import app

    spec_file = write_spec("name: x\nobstacles:\n  unnamed_0: {x: 3, y: 3}\n  Big-Rock: {x: 0, y: 0}\n"
                           "goal: {distance: 30}\n")
    found = problems_of(spec_file)
    assert [(p.line, p.path) for p in found] == [(4, "obstacles.Big-Rock"), (4, "obstacles.Big-Rock"),
                                                 (5, "goal.distance")], found
    assert "such as 'big_rock' (got 'Big-Rock')" in found[0].message
    assert found[1].message == "obstacle 'Big-Rock' overlaps the agent's start at (0, 0)"
    assert "beyond the field's end" in found[2].message
    result = CliRunner().invoke(app, ["validate", str(spec_file)])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert result.output.splitlines() == ["3 problems in the field spec:", *(f"  {p}" for p in found)]


def test_unknown_key_lists_allowed_keys(write_spec):
    (p,) = problems_of(write_spec("name: x\nwalls: {hieght: 1}\n"))
    assert "did you mean 'height'" in p.message
    assert "Allowed keys here: enabled, height, thickness" in p.message


def test_missing_file_and_unknown_bundled_base(write_spec, tmp_path):
    (p,) = problems_of(tmp_path / "nope.yaml")
    assert "no such file" in p.message
    (p,) = problems_of(write_spec("extends: socer_v2\nname: x\n"))
    assert p.line == 1 and p.path == "extends"
    assert "did you mean 'soccer_v2'" in p.message


MERGED = """\
extends: soccer_v2
name: merged
obstacles:
  left: &block {x: -3, y: 6, width: 1.0, depth: 0.5, height: 0.5}
  middle: &tall
    <<: *block
    x: 0
    height: 1.5
  right: {<<: [*tall, *block], x: 3}
"""


def test_yaml_merge_keys_are_read_as_yaml_means_them(write_spec):
    """`<<: *anchor` and `<<: [*a, *b]` (the first named wins) under the mapping's own keys, which win over both.
    Before: refused as "keys must be plain names"."""
    spec = load_spec(write_spec(MERGED))
    left, middle, right = (spec.obstacles[k] for k in ("left", "middle", "right"))
    assert (middle.x, middle.y, middle.width, middle.height) == (0, 6, 1.0, 1.5)
    assert (right.x, right.y, right.height) == (3, 6, 1.5)  # middle's height, named first, over left's


def test_a_problem_in_a_merged_value_points_at_where_it_is_written(write_spec):
    with pytest.raises(SpecError) as caught:
        load_spec(write_spec(MERGED.replace("height: 0.5}", "height: -0.5}").replace("    height: 1.5\n", "")))
    problems = {p.path: (p.line, p.col) for p in caught.value.problems}
    assert set(problems) == {"obstacles.left.height", "obstacles.middle.height", "obstacles.right.height"}
    assert set(problems.values()) == {(4, 54)}  # all three at left's `height:`, where the value is written
    with pytest.raises(SpecError, match="bad.yaml:3:12: goal: a merge key '<<' takes a mapping or a list of mappings"):
        load_spec(write_spec("extends: soccer_v2\nname: a\ngoal: {<<: 5}\n", "bad.yaml"))
