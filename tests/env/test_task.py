"""Reward terms and success predicates against their formulas on hand-set states."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fieldgen.env.task import MIN_SCALE_DISTANCE, Transition, task_fns
from fieldgen.schema import bundled_fields, load_spec

DT = 0.05


def transition(ball_before=(0, 5, 0.5), ball=(0, 5.1, 0.5), agent_before=(0, 0, 0.55), agent=(0, 0, 0.55),
               target=(0, 10), action=(0.0,) * 8):
    arr = lambda v: jnp.asarray(v, jnp.float32)  # noqa: E731
    return Transition(arr(ball_before), arr(ball), arr(agent_before), arr(agent), arr(target), arr(action), DT)


def spec_with(write_spec, reward_yaml: str, extra: str = ""):
    return load_spec(write_spec(f"extends: soccer_v1\nname: t\n{extra}task:\n  reward:\n{reward_yaml}"))


def values(write_spec, reward_yaml, t, extra=""):
    fns = task_fns(spec_with(write_spec, reward_yaml, extra))
    return {name: float(fn(t)) for name, fn in fns.terms.items()}, fns


def test_ball_moved_0_1_towards_goal(write_spec):
    terms = ("    - {term: ball_progress, weight: 10}\n    - {term: scaled_ball_progress, weight: 5}\n")
    v, fns = values(write_spec, terms, transition())
    assert v["ball_progress"] == pytest.approx(0.1 / DT, rel=1e-4)
    assert v["scaled_ball_progress"] == pytest.approx(0.1 / DT / 4.9, rel=1e-4)
    assert float(fns.reward(v)) == pytest.approx(10 * 2.0 + 5 * 2.0 / 4.9, rel=1e-4)


def test_scaled_progress_is_bounded_at_the_target(write_spec):
    t = transition(ball_before=(0, 9.9, 0.5), ball=(0, 10, 0.5))
    v, _ = values(write_spec, "    - {term: scaled_ball_progress}\n", t)
    assert v["scaled_ball_progress"] == pytest.approx((0.1 / DT) / MIN_SCALE_DISTANCE, rel=1e-4)


def test_agent_terms(write_spec):
    t = transition(agent_before=(0, 0, 0.55), agent=(0.3, 0.4, 0.55), ball_before=(3, 4, 0.5), ball=(3, 4, 0.5),
                   target=(6, 8))
    terms = "    - {term: agent_approaches_ball}\n    - {term: agent_progress}\n"
    v, _ = values(write_spec, terms, t)
    assert v["agent_approaches_ball"] == pytest.approx((5.0 - 4.5) / DT, rel=1e-4)
    assert v["agent_progress"] == pytest.approx((10.0 - 9.5) / DT, rel=1e-4)


@pytest.mark.parametrize("z,expected", [(0.55, 1.0), (0.25, 0.0), (1.05, 0.0), (0.3, 1.0)])
def test_upright_band(write_spec, z, expected):
    v, _ = values(write_spec, "    - {term: upright, band: [0.3, 1.0]}\n", transition(agent=(0, 0, z)))
    assert v["upright"] == expected


def test_control_cost_is_negative_squared_action(write_spec):
    action = (0.5, -0.5, 1.0, 0, 0, 0, 0, 0)
    v, fns = values(write_spec, "    - {term: control_cost, weight: 0.5}\n", transition(action=action))
    assert v["control_cost"] == pytest.approx(-1.5)
    assert float(fns.reward(v)) == pytest.approx(-0.75)


@pytest.mark.parametrize("ball,inside", [((0, 10, 0.5), 1.0), ((1.9, 9.6, 0.5), 1.0), ((2.1, 10, 0.5), 0.0),
                                         ((0, 10.6, 0.5), 0.0), ((0, 9.4, 0.5), 0.0)])
def test_ball_in_goal_box(write_spec, ball, inside):
    extra = "task:\n  success: {kind: ball_in_goal}\n"
    spec = load_spec(write_spec(f"extends: soccer_v1\nname: t\n{extra}"))
    fns = task_fns(spec)
    assert float(fns.success(transition(ball=ball))) == inside  # goal box: 4 wide, 1 deep at y = 10


@pytest.mark.parametrize("ball,hit", [((0, 9.55, 0.5), 1.0), ((0.3, 10.3, 0.5), 1.0), ((0, 9.45, 0.5), 0.0),
                                      ((0.4, 10.4, 0.5), 0.0)])
def test_ball_near_target(ball, hit):
    fns = task_fns(load_spec("fields/soccer_v1.yaml"))
    assert float(fns.success(transition(ball=ball))) == hit


@pytest.mark.parametrize("agent,hit", [((6.2, 8.2, 0.5), 1.0), ((6.4, 8.4, 0.5), 0.0)])
def test_agent_near_target(agent, hit):
    fns = task_fns(load_spec("fields/ant_nav.yaml"))
    assert float(fns.success(transition(agent=agent, target=(6, 8)))) == hit


def test_repeated_terms_keep_separate_names(write_spec):
    terms = "    - {term: upright, band: [0.2, 1.0]}\n    - {term: upright, band: [0.5, 0.6], weight: 2}\n"
    v, fns = values(write_spec, terms, transition(agent=(0, 0, 0.8)))
    assert v == {"upright": 1.0, "upright_2": 0.0}
    assert fns.weights == {"upright": 1.0, "upright_2": 2.0}


def test_env_metrics_follow_the_formulas(env_cache):
    """In the environment: a hand-placed puck's progress term equals (d_before - d_after) / dt."""
    env = env_cache("point_soccer", auto_reset=False)
    state = env.reset(jax.random.PRNGKey(0))
    qpos = state.pipeline_state.qpos.at[env.layout.ball_qpos].set(jnp.array([0.3, 2.0]))
    qvel = state.pipeline_state.qvel.at[env.layout.ball_qpos].set(jnp.array([0.0, 2.0]))  # rolling to the goal
    state = state.replace(pipeline_state=state.pipeline_state.replace(qpos=qpos, qvel=qvel))
    after = jax.jit(env.step)(state, jnp.zeros(2))
    goal = np.asarray(state.info["goal"])
    ball_after = np.asarray(after.obs[4:6])
    expected = (np.linalg.norm(np.array([0.3, 2.0]) - goal) - np.linalg.norm(ball_after - goal)) / env.dt
    assert expected > 0.5
    assert float(after.metrics["ball_progress"]) == pytest.approx(expected, rel=1e-3)
    m = after.metrics
    total = 1.0 * m["success"] + 0.1 * m["agent_approaches_ball"] + 0.5 * m["ball_progress"]
    assert float(after.reward) == pytest.approx(float(total), rel=1e-5)


def test_every_term_the_schema_accepts_has_a_function(write_spec):
    import typing

    from fieldgen.schema.models import RewardTerm

    from fieldgen.schema.terms import MATCH_TERMS, TERMS

    names = typing.get_args(RewardTerm.model_fields["term"].annotation)
    assert set(names) == set(TERMS) | set(MATCH_TERMS)  # a match's own terms: tests/env/test_team.py
    reward = "".join(f"    - {{term: {n}}}\n" for n in TERMS)
    v, _ = values(write_spec, reward, transition())
    assert set(v) == set(TERMS) and all(np.isfinite(x) for x in v.values())


def test_the_implementations_are_keyed_by_the_registry():
    from fieldgen.env import task
    from fieldgen.schema.terms import TERMS

    assert sorted(task.IMPLEMENTATIONS) == sorted(TERMS)


def test_a_registered_term_without_an_implementation_fails_the_import():
    import subprocess
    import sys

    code = ("from fieldgen.schema.terms import TERMS, Term\n"
            "TERMS['ball_spin'] = Term('the ball turning', ball=True)\n"
            "import fieldgen.env.task\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and proc.stderr.strip().splitlines()[-1] == (
        "ImportError: reward terms named in fieldgen/schema/terms.py without an implementation in "
        "fieldgen.env.task: ball_spin"), proc.stderr[-2000:]


def test_an_implementation_needs_a_registered_name_and_gets_one_only(monkeypatch):
    from fieldgen.env import task

    monkeypatch.setattr(task, "IMPLEMENTATIONS", dict(task.IMPLEMENTATIONS))
    with pytest.raises(ValueError, match="'ball_spin' is no reward term of fieldgen/schema/terms.py"):
        task.term("ball_spin")(lambda t, cfg: t.ball[2])
    with pytest.raises(ValueError, match="reward term 'upright' is implemented twice"):
        task.term("upright")(lambda t, cfg: t.agent[2])


@pytest.mark.parametrize("field,progress_weight", [("soccer_v1_shaped", 5.0), ("soccer_v2_shaped", 10.0)])
def test_the_study_shaped_soccer_rewards(field, progress_weight):
    """10 x ball-in-goal + upright(0.3..1) + 2 x approach + w / ||B-G|| x ball progress, term by term."""
    spec = load_spec(bundled_fields()[field])
    goal_y = spec.goal.distance
    fns = task_fns(spec)
    # The ball rolls 0.1 towards the goal, 3 from it; the standing ant closes 0.2 on the ball.
    t = transition(ball_before=(0, goal_y - 3.1, 0.5), ball=(0, goal_y - 3.0, 0.5), agent_before=(0, 0, 0.55),
                   agent=(0, 0.2, 0.55), target=(0, goal_y))
    v = {name: float(fn(t)) for name, fn in fns.terms.items()}
    assert v == pytest.approx({"ball_in_goal": 0.0, "upright": 1.0, "agent_approaches_ball": (0.2 - 0.1) / DT,
                               "scaled_ball_progress": 0.1 / DT / 3.0}, rel=1e-4)
    assert float(fns.reward(v)) == pytest.approx(1.0 + 2 * 0.1 / DT + progress_weight * 0.1 / DT / 3.0, rel=1e-4)
    inside = transition(ball_before=(0, goal_y, 0.5), ball=(0, goal_y, 0.5), agent=(0, 0, 0.1), target=(0, goal_y))
    v = {name: float(fn(inside)) for name, fn in fns.terms.items()}
    assert v["ball_in_goal"] == 1.0 and v["upright"] == 0.0  # in the goal, the ant lying down
    assert float(fns.reward(v)) == pytest.approx(10.0 + 2 * v["agent_approaches_ball"], rel=1e-4)


def test_the_study_ball_dense_reward():
    """10 x ball progress + upright(0.2..1) - 0.5 |a|^2 on ant_ball_dense."""
    fns = task_fns(load_spec(bundled_fields()["ant_ball_dense"]))
    t = transition(ball_before=(0, 2.0, 0.5), ball=(0, 2.05, 0.5), agent=(0, 0, 0.25), target=(0, 5),
                   action=(0.5,) * 8)
    v = {name: float(fn(t)) for name, fn in fns.terms.items()}
    assert v == pytest.approx({"ball_progress": 0.05 / DT, "upright": 1.0, "control_cost": -8 * 0.25}, rel=1e-4)
    assert float(fns.reward(v)) == pytest.approx(10 * 0.05 / DT + 1.0 - 0.5 * 2.0, rel=1e-4)


def test_path_progress_is_ball_progress_where_no_obstacle_stands(write_spec):
    terms = "    - {term: ball_progress}\n    - {term: ball_path_progress}\n"
    t = transition(ball_before=(1, 3, 0.5), ball=(1.2, 3.4, 0.5), target=(0, 10))
    v, _ = values(write_spec, terms, t)
    assert v["ball_path_progress"] == pytest.approx(v["ball_progress"], rel=1e-5)


GOALIE = "obstacles:\n  goalie: {x: 0, y: 7, width: 3, depth: 0.6, height: 1}\n"  # x in [-1.5, 1.5], y in [6.7, 7.3]
# (soccer_v1's ball has a radius of 0.5: its centre stays 0.5 from the goalie's faces)


def test_path_goes_round_the_goalie_by_its_nearer_corners(write_spec):
    from fieldgen.env.paths import CORNER_RADII, way_to_target

    spec = spec_with(write_spec, "    - {term: ball_path_progress}\n", GOALIE)
    out = 1.5 + CORNER_RADII * spec.ball.radius
    below, above = 6.7 - CORNER_RADII * spec.ball.radius, 7.3 + CORNER_RADII * spec.ball.radius
    ball, target = np.asarray([0.3, 5.0]), np.asarray([0.0, 10.0])
    by_hand = (np.hypot(out - 0.3, below - 5.0) + (above - below) + np.hypot(out, 10.0 - above))
    way = way_to_target(spec)
    assert float(way(jnp.asarray(ball), jnp.asarray(target))) == pytest.approx(by_hand, rel=1e-5)
    clear = jnp.asarray([5.0, 9.0])  # beyond the goalie: the straight line
    assert float(way(clear, jnp.asarray(target))) == pytest.approx(np.hypot(5.0, 1.0), rel=1e-5)


def test_a_ball_pushed_round_the_goalie_progresses_where_straight_progress_says_it_loses(write_spec):
    terms = "    - {term: ball_progress}\n    - {term: ball_path_progress}\n"
    sideways = transition(ball_before=(0.2, 6.2, 0.5), ball=(0.6, 6.2, 0.5), target=(0, 10))  # against its face
    v, _ = values(write_spec, terms, sideways, GOALIE)
    assert v["ball_progress"] < 0 < v["ball_path_progress"]
    into = transition(ball_before=(0.2, 6.0, 0.5), ball=(0.2, 6.1, 0.5), target=(0, 10))  # straight at the goalie
    v, _ = values(write_spec, terms, into, GOALIE)
    assert v["ball_progress"] > 0 and v["ball_path_progress"] == pytest.approx(0.0, abs=0.5)


def test_a_ball_pressed_against_the_goalie_still_has_a_way(write_spec):
    from fieldgen.env.paths import way_to_target

    spec = spec_with(write_spec, "    - {term: ball_path_progress}\n", GOALIE)
    touching = jnp.asarray([0.0, 6.7 - 0.95 * spec.ball.radius])  # a little inside its radius, as in contact
    length = float(way_to_target(spec)(touching, jnp.asarray([0.0, 10.0])))
    assert np.isfinite(length) and length > 10.0 - float(touching[1]) + 2.0  # round an end, not through


def test_scaled_path_progress_is_scaled_progress_where_no_obstacle_stands(write_spec):
    terms = "    - {term: scaled_ball_progress}\n    - {term: scaled_ball_path_progress}\n"
    onto = transition(ball_before=(0, 9.9, 0.5), ball=(0, 10, 0.5))  # onto the target: the bound
    short = transition(ball_before=(0.3, 9.0, 0.5), ball=(0.2, 9.3, 0.5))  # under a metre short of it
    for t in (onto, short):
        v, _ = values(write_spec, terms, t)
        assert v["scaled_ball_path_progress"] == pytest.approx(v["scaled_ball_progress"], rel=1e-4)


def test_scaled_path_progress_divides_path_progress_by_the_way_left(write_spec):
    from fieldgen.env.paths import way_to_target

    terms = "    - {term: ball_path_progress}\n    - {term: scaled_ball_path_progress}\n"
    t = transition(ball_before=(0.2, 6.2, 0.5), ball=(0.6, 6.2, 0.5), target=(0, 10))  # round the goalie's end
    v, _ = values(write_spec, terms, t, GOALIE)
    way = way_to_target(spec_with(write_spec, terms, GOALIE))
    left = float(way(jnp.asarray([0.6, 6.2]), jnp.asarray([0.0, 10.0])))
    assert left > 3.8 and v["ball_path_progress"] > 0
    assert v["scaled_ball_path_progress"] == pytest.approx(v["ball_path_progress"] / left, rel=1e-4)
    past = transition(ball_before=(0, 10.2, 0.5), ball=(0, 10.4, 0.5), target=(0, 10))  # pushed on past the target
    v, _ = values(write_spec, terms, past, GOALIE)
    assert v["scaled_ball_path_progress"] == pytest.approx(-0.2 / DT / 0.4, rel=1e-4)


BEHIND = 0.5 + 0.25  # soccer_v1's ball radius plus the ant's torso radius


def test_behind_ball_pays_the_approach_to_the_point_behind_the_ball_from_the_target(write_spec):
    terms = "    - {term: agent_behind_ball}\n"
    ball = (0.0, 5.0, 0.5)  # the target straight ahead at (0, 10): the point behind the ball is (0, 5 - BEHIND)
    to_it = transition(ball_before=ball, ball=ball, agent_before=(1.0, 3.0, 0.55), agent=(0.0, 3.0, 0.55))
    v, _ = values(write_spec, terms, to_it)
    by_hand = (np.hypot(1.0, 5.0 - BEHIND - 3.0) - (5.0 - BEHIND - 3.0)) / DT
    assert v["agent_behind_ball"] == pytest.approx(by_hand, rel=1e-4)
    in_front = transition(ball_before=ball, ball=ball, agent_before=(0.0, 6.0, 0.55), agent=(0.0, 6.1, 0.55))
    v, _ = values(write_spec, terms, in_front)
    assert v["agent_behind_ball"] < 0  # walking away on the far side of the ball


def test_an_agent_following_the_ball_it_pushes_keeps_its_distance_to_the_point(write_spec):
    terms = "    - {term: agent_behind_ball}\n"
    pushed = transition(ball_before=(0, 5, 0.5), ball=(0, 5.1, 0.5), agent_before=(0, 5 - BEHIND, 0.55),
                        agent=(0, 5.1 - BEHIND, 0.55))
    v, _ = values(write_spec, terms, pushed)
    assert v["agent_behind_ball"] == pytest.approx(0.0, abs=1e-3)


def test_behind_ball_points_the_push_round_the_goalie(write_spec):
    # the ball against the goalie's face, right of its centre: its way runs round the right end, so the point
    # behind it lies to its left, and an agent stepping left (not straight up behind it) approaches it
    terms = "    - {term: agent_behind_ball}\n"
    ball = (0.6, 6.2, 0.5)
    left = transition(ball_before=ball, ball=ball, agent_before=(0.6, 5.0, 0.55), agent=(0.4, 5.0, 0.55))
    right = transition(ball_before=ball, ball=ball, agent_before=(0.6, 5.0, 0.55), agent=(0.8, 5.0, 0.55))
    v_left, _ = values(write_spec, terms, left, GOALIE)
    v_right, _ = values(write_spec, terms, right, GOALIE)
    assert v_left["agent_behind_ball"] > 0 > v_right["agent_behind_ball"]


def test_behind_ball_is_finite_with_the_ball_on_the_target(write_spec):
    terms = "    - {term: agent_behind_ball}\n"
    on = transition(ball_before=(0, 10, 0.5), ball=(0, 10, 0.5), agent_before=(1, 8, 0.55), agent=(0.9, 8, 0.55))
    v, _ = values(write_spec, terms, on)
    assert np.isfinite(v["agent_behind_ball"])
