"""The automatic curriculum's levels: an easy end derived from the spec, the spec itself at the other end,
every level a validated spec of one structure, and a level the checks refuse never counted as playable."""

from __future__ import annotations

import numpy as np
import pytest

from fieldgen.compile.variants import compile_variants
from fieldgen.curriculum.levels import START_NEAR, LevelError, LevelSpace
from fieldgen.schema import SpecError, load_spec, resolve_spec_path


def space(name: str) -> LevelSpace:
    return LevelSpace.of(load_spec(resolve_spec_path(name)))


@pytest.mark.parametrize("name", ["soccer_v1", "soccer_v2", "v2_wide_goalie"])
def test_the_easy_end_validates_and_builds_to_the_specs_structure(name):
    levels = space(name)
    easy = levels.spec_at(levels.easy)
    target = np.asarray(levels.spec.target_fixed())
    centre = np.mean([easy.ball.spawn.x, easy.ball.spawn.y], axis=1)
    assert np.linalg.norm(centre - target) == pytest.approx(START_NEAR)
    assert np.linalg.norm(np.asarray(easy.agent.start) - centre) < np.linalg.norm(
        np.asarray(levels.spec.agent.start) - np.mean([levels.spec.ball.spawn.x, levels.spec.ball.spawn.y], axis=1))
    assert not easy.walls.enabled
    for obstacle_name, obstacle in easy.obstacles.items():
        assert obstacle.width < levels.spec.obstacles[obstacle_name].width
    artifacts = compile_variants([easy, levels.spec_at(np.full(len(levels.axes), 0.5)), levels.spec])
    assert len({a.model().ngeom for a in artifacts}) == 1


@pytest.mark.parametrize("name", ["soccer_v1", "soccer_v2", "point_soccer"])
def test_the_hard_end_is_the_spec_itself(name):
    levels = space(name)
    assert levels.changes(levels.hard) == {}
    assert levels.spec_at(levels.hard).model_dump() == levels.spec.model_dump()


def test_axes_follow_what_the_spec_has():
    assert [a.name for a in space("soccer_v1").axes] == ["kickoff"]
    assert [(a.name, a.switch) for a in space("soccer_v2").axes] == [
        ("kickoff", False), ("obstacles.goalie.width", False), ("walls", True)]


def test_levels_move_each_axis_between_its_ends():
    levels = space("soccer_v2")
    kickoff_y = [levels.spec_at([t, 1, 1]).ball.spawn.y[0] for t in (0.0, 0.25, 0.5, 1.0)]
    assert kickoff_y == sorted(kickoff_y, reverse=True) and kickoff_y[-1] == levels.spec.ball.spawn.y[0]
    widths = [levels.spec_at([1, t, 1]).obstacles["goalie"].width for t in (0.0, 0.5, 1.0)]
    assert widths == sorted(widths) and widths[-1] == levels.spec.obstacles["goalie"].width
    assert [levels.spec_at([1, 1, t]).walls.enabled for t in (0.0, 0.49, 0.5, 1.0)] == [False, False, True, True]
    assert levels.changes([-3, 7, 0.5]) == levels.changes([0, 1, 0.5])  # outside [0, 1]: the nearest end


def test_a_level_the_checks_refuse_is_not_playable():
    """A third of the way back, soccer_v2's kick-off puts the ball's spawn region on the goalie: refused, as a
    spec."""
    levels = space("soccer_v2")
    blocked = [0.3, 1.0, 1.0]
    with pytest.raises(SpecError, match="goalie"):
        levels.spec_at(blocked)
    assert not levels.playable(blocked) and levels.playable(levels.hard) and levels.playable(levels.easy)


def test_a_spec_without_a_ball_to_bring_to_a_fixed_target_is_refused_in_a_sentence():
    with pytest.raises(LevelError, match="ant_nav: the automatic curriculum moves a ball"):
        space("ant_nav")
    with pytest.raises(ValueError, match="has 3 numbers"):
        space("soccer_v2").changes([0.5])
