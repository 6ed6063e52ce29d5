"""`task: {reward: dense}`: the terms generated for a task's success kind, which the bundled _dense fields use and
build to the very field.json the same terms written out build to."""

from __future__ import annotations

import pytest

from fieldgen.schema import SpecError, bundled_fields, load_spec

# the terms the bundled dense fields stand for, written out
BALL_TERMS = """  reward:
    - {term: ball_progress, weight: 10}
    - {term: agent_behind_ball, weight: 1}
    - {term: success, weight: 10}
    - {term: upright, band: [0.2, 1.0]}
    - {term: control_cost, weight: 0.5}
"""
PATH_TERMS = BALL_TERMS.replace("term: ball_progress", "term: ball_path_progress")  # with a goalie in the way
AGENT_TERMS = """  reward:
    - {term: agent_progress}
    - {term: upright, band: [0.2, 1.0]}
    - {term: control_cost, weight: 0.5}
"""
WRITTEN_OUT = {"soccer_v1_dense": ("soccer_v1", BALL_TERMS), "soccer_v2_dense": ("soccer_v2", PATH_TERMS),
               "ant_nav_dense": ("ant_nav", AGENT_TERMS)}


def written_out(tmp_path, name: str):
    """The bundled dense field with its terms listed: its name, description and parent."""
    bundled = load_spec(bundled_fields()[name])
    parent, terms = WRITTEN_OUT[name]
    path = tmp_path / f"{name}.yaml"
    path.write_text(f"name: {name}\ndescription: {bundled.description}\nextends: {parent}\ntask:\n{terms}")
    return path


@pytest.mark.parametrize("name", WRITTEN_OUT)
def test_the_bundled_dense_fields_ask_for_the_generated_terms_and_get_the_ones_they_listed(tmp_path, name):
    assert "reward: dense" in bundled_fields()[name].read_text()
    generated = load_spec(bundled_fields()[name])
    assert generated.model_dump(mode="json") == load_spec(written_out(tmp_path, name)).model_dump(mode="json")


def test_a_dense_field_builds_to_the_same_field_json_byte_for_byte(tmp_path):
    from fieldgen.compile.build import build

    generated = build(bundled_fields()["soccer_v2_dense"], tmp_path / "generated", preview=False)
    listed = build(written_out(tmp_path, "soccer_v2_dense"), tmp_path / "listed", preview=False)
    assert (generated.out_dir / "field.json").read_bytes() == (listed.out_dir / "field.json").read_bytes()
    assert (generated.out_dir / "scene.xml").read_bytes() == (listed.out_dir / "scene.xml").read_bytes()


def test_fields_that_extend_a_dense_field_inherit_its_generated_terms():
    wide = load_spec(bundled_fields()["v2_wide_goalie_dense"]).task.reward
    assert wide == load_spec(bundled_fields()["soccer_v2_dense"]).task.reward
    assert [(t.term, t.weight) for t in wide] == [("ball_path_progress", 10.0), ("agent_behind_ball", 1.0),
                                                 ("success", 10.0), ("upright", 1.0), ("control_cost", 0.5)]


@pytest.mark.parametrize("name", ["v2_wide_goalie_dense", "soccer_v1_dense"])
def test_the_bench_fields_the_recipes_were_measured_on_carry_the_generated_terms(name):
    """The recipes' figures were measured on bench/fields/<name>_behind.yaml, written before `reward: dense` made
    the same terms: the two must stay one reward for the figure to be the bundled field's."""
    from pathlib import Path

    measured = load_spec(Path(__file__).parents[2] / "bench" / "fields" / f"{name}_behind.yaml")
    bundled = load_spec(bundled_fields()[name])
    assert measured.task.reward == bundled.task.reward
    assert measured.model_dump(exclude={"name", "description", "extends", "task"}) == bundled.model_dump(
        exclude={"name", "description", "extends", "task"})


def test_the_terms_follow_the_task_and_leave_out_what_the_agent_lacks(write_spec):
    ball = load_spec(write_spec("extends: ant_ball\nname: b\ntask: {reward: dense}\n")).task.reward
    assert [t.term for t in ball] == ["ball_progress", "agent_behind_ball", "success", "upright", "control_cost"]
    point = load_spec(write_spec("extends: point_nav\nname: p\ntask: {reward: dense}\n")).task.reward
    assert [(t.term, t.weight) for t in point] == [("agent_progress", 1.0), ("control_cost", 0.5)]  # no torso


def test_a_solid_obstacle_measures_the_balls_progress_along_its_way_round(write_spec):
    def terms(extra: str) -> list[str]:
        return [t.term for t in load_spec(write_spec(f"extends: ant_ball\nname: b\ntask: {{reward: dense}}\n{extra}")
                                          ).task.reward]

    assert terms("obstacles:\n  wall: {x: 1, y: 2}\n")[0] == "ball_path_progress"
    assert terms("obstacles:\n  shadow: {x: 1, y: 2, solid: false}\n")[0] == "ball_progress"  # decorative
    assert load_spec(bundled_fields()["soccer_v1_dense"]).task.reward[0].term == "ball_progress"  # no goalie


def only_problem(path) -> str:
    """The one problem loading the spec at `path` reports, as the user reads it."""
    with pytest.raises(SpecError) as caught:
        load_spec(path)
    (problem,) = caught.value.problems
    return str(problem)


def test_a_task_kind_without_generated_terms_is_one_line_naming_the_kinds_with_them(write_spec):
    path = write_spec("extends: point_soccer\nname: s\ntask:\n  reward: dense\n")
    assert only_problem(path) == (f"{path}:4:3: task.reward: dense names the terms generated for a task, and "
                                  "success kind 'ball_in_goal' has none; the kinds with them: ball_near_target, "
                                  "agent_near_target; list this task's terms instead (got 'dense')")


def test_a_field_that_leaves_its_success_to_the_default_gets_the_terms_of_that_kind(write_spec):
    spec = load_spec(write_spec("name: m\nagent: {kind: ant}\ntask:\n  reward: dense\n"))
    assert spec.task.success.kind == "ball_near_target"
    assert [t.term for t in spec.task.reward] == ["ball_progress", "agent_behind_ball", "success", "upright",
                                                  "control_cost"]


def test_a_field_with_teams_asking_for_dense_is_told_to_list_match_terms(write_spec):
    path = write_spec("extends: soccer_1v1\nname: t\ntask:\n  reward: dense\n")
    assert only_problem(path) == (f"{path}:4:3: task.reward: dense names the terms generated for one agent's task; "
                                  "a field with teams lists its match terms instead: goal, ball_progress, "
                                  "ball_goal_progress, agent_approaches_ball, agent_behind_ball, upright, "
                                  "control_cost (got 'dense')")


def test_a_word_other_than_dense_is_told_what_reward_takes(write_spec):
    path = write_spec("extends: soccer_v1\nname: h\ntask:\n  reward: Dense\n")
    assert only_problem(path) == (f"{path}:4:3: task.reward: expected a list of reward terms, or 'dense' for the "
                                  "terms generated for the task (got 'Dense'; did you mean 'dense'?)")


def test_a_wrong_success_is_the_one_problem_dense_reports(write_spec):
    path = write_spec("name: m\nagent: {kind: ant}\ntask:\n  success: 3\n  reward: dense\n")
    assert only_problem(path) == f"{path}:4:3: task.success: expected a mapping (got 3)"
