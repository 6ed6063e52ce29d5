"""`extends:` merges maps by key, replaces lists whole, resolves names and paths, and detects cycles."""

from __future__ import annotations

import pytest

from fieldgen.schema import SpecError, load_spec


def test_bundled_name_maps_merge_by_key(write_spec):
    spec = load_spec(write_spec("extends: soccer_v2\nname: wide\nobstacles:\n  goalie: {width: 4.0}\n"))
    base = load_spec("fields/soccer_v2.yaml")
    goalie = spec.obstacles["goalie"]
    assert goalie.width == 4.0
    assert goalie.depth == base.obstacles["goalie"].depth == 0.6
    assert goalie.relative_to == "goal" and goalie.y == -6
    assert spec.goal == base.goal and spec.walls == base.walls
    assert spec.extends == "soccer_v2"


def test_lists_are_replaced_whole(write_spec):
    spec = load_spec(write_spec("extends: point_soccer\nname: p\ntask:\n  reward:\n    - {term: control_cost, weight: 0.5}\n"))
    assert [t.term for t in spec.task.reward] == ["control_cost"]
    assert spec.task.success.kind == "ball_in_goal"  # sibling keys of the list still merge


def test_relative_path_chain(write_spec):
    write_spec("extends: soccer_v1\nname: base\ngoal: {width: 5}\n", "base.yaml")
    child = write_spec("extends: ./base.yaml\nname: child\ngoal: {height: 3}\n", "child.yaml")
    spec = load_spec(child)
    assert (spec.goal.width, spec.goal.height, spec.goal.distance) == (5, 3, 10)


def test_error_in_inherited_value_points_at_the_base_file(write_spec):
    base = write_spec("extends: soccer_v1\nname: base\ngoal: {distance: 50}\n", "base.yaml")
    child = write_spec("extends: base.yaml\nname: child\n", "child.yaml")
    with pytest.raises(SpecError) as info:
        load_spec(child)
    (p,) = info.value.problems
    assert p.file == base and p.line == 3 and p.path == "goal.distance"


def test_cycle_is_detected(write_spec):
    write_spec("extends: b.yaml\nname: a\n", "a.yaml")
    b = write_spec("extends: a.yaml\nname: b\n", "b.yaml")
    with pytest.raises(SpecError) as info:
        load_spec(b)
    (p,) = info.value.problems
    assert "cycle" in p.message and p.path == "extends" and p.line == 1


def test_self_extension_is_a_cycle(write_spec):
    path = write_spec("extends: self.yaml\nname: s\n", "self.yaml")
    with pytest.raises(SpecError, match="cycle"):
        load_spec(path)


def test_null_removes_an_inherited_key(write_spec):
    spec = load_spec(write_spec("extends: soccer_v2\nname: open\nobstacles: {goalie: null}\ngoal: {post_setback: null}\n"))
    assert spec.obstacles == {}
    assert spec.goal.post_setback is None and spec.goal.posts_y == 20 - 0.8 + 0.25
