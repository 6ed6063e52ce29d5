"""A team field as a match on MJX: observations in each side's own frame, zero-sum terms, and an episode that a
goal ends for both sides, counted once."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import fieldgen
from fieldgen.env.contract import Environment
from fieldgen.env.team_contract import TeamEnvironment, refuse_team
from fieldgen.schema import load_spec


@functools.cache
def match(name: str):
    return fieldgen.make(name)


@functools.cache
def jitted_step(name: str):
    return jax.jit(match(name).step)


def turned_world(env, data, rng):
    """The state `data` turned half a turn about the centre spot with the sides swapped (home i where away i
    stood, and the other way round), built from mujoco's own quaternion product rather than the environment's
    maps; velocities random, to check them too."""
    layout, n = env.layout, len(env.agent_names) // 2
    qvel = jnp.asarray(rng.normal(size=data.qvel.shape), jnp.float32)
    qpos, new_qpos, new_qvel = np.asarray(data.qpos), np.asarray(data.qpos).copy(), np.asarray(qvel).copy()

    def turn_q(q):
        q = q.copy()
        q[:2] *= -1
        if env.spec.agent.kind == "ant":
            out = np.zeros(4)
            mujoco.mju_mulQuat(out, np.array([0.0, 0.0, 0.0, 1.0]), q[3:7])
            q[3:7] = out
        return q

    def turn_v(v):
        v = v.copy()
        v[:2] *= -1  # world velocity; an ant's angular velocity is in its own frame, which turns with it
        return v

    for i in range(n):
        for a, b in ((i, n + i), (n + i, i)):
            new_qpos[layout.agent_qpos[b]] = turn_q(qpos[layout.agent_qpos[a]])
            new_qvel[layout.agent_qvel[b]] = turn_v(np.asarray(qvel)[layout.agent_qvel[a]])
    new_qpos[layout.ball_qpos[:2]] *= -1
    return data.replace(qvel=qvel), data.replace(qpos=jnp.asarray(new_qpos), qvel=jnp.asarray(new_qvel))


def test_a_team_field_makes_a_match_that_single_agent_trainers_refuse():
    env = match("soccer_1v1")
    assert isinstance(env, TeamEnvironment) and not isinstance(env, Environment)
    assert env.agent_names == ("home0", "away0") and list(env.agent_sides) == [0, 1]
    assert env.observation_size == 10 and env.action_size == 2 and env.zero_sum_terms == ("goal", "ball_progress")
    with pytest.raises(ValueError) as info:
        refuse_team(env, "crl")
    assert "\n" not in str(info.value) and "soccer_1v1 is a team field (home0, away0)" in str(info.value)
    refuse_team(fieldgen.make("point_nav"), "crl")  # a single-agent field passes


@pytest.mark.parametrize("name", ["soccer_1v1", "soccer_2v2"])
def test_the_away_side_sees_a_turned_state_as_the_home_side_sees_the_state(name):
    env = match(name)
    state = env.reset(jax.random.PRNGKey(3))
    original, turned = turned_world(env, state.pipeline_state, np.random.default_rng(0))
    seen, seen_turned = np.asarray(env.observe(original)), np.asarray(env.observe(turned))
    n = len(env.agent_names) // 2
    np.testing.assert_allclose(seen_turned[n:], seen[:n], atol=1e-6)  # away i of the turned = home i of the original
    np.testing.assert_allclose(seen_turned[:n], seen[n:], atol=1e-6)  # and the other way round
    opponent = env.observation_names.index("opponent0.y")
    assert seen[0, opponent] > 0 and seen[n, opponent] > 0  # each sees its opponents ahead, towards their goal


def test_an_away_ant_sees_itself_as_a_home_ant_does(write_spec):
    spec = load_spec(write_spec("extends: soccer_1v1\nname: ants\nagent: {kind: ant}\nfield: {length: 16, width: 10}\n"
                                "goal: {distance: 8}\n"))
    env = fieldgen.make(spec)
    state = env.reset(jax.random.PRNGKey(1))
    original, turned = turned_world(env, state.pipeline_state, np.random.default_rng(1))
    seen, seen_turned = np.asarray(env.observe(original)), np.asarray(env.observe(turned))
    np.testing.assert_allclose(seen_turned[1], seen[0], atol=1e-5)
    assert env.observation_names[3:7] == ("root.qw", "root.qx", "root.qy", "root.qz")
    np.testing.assert_allclose(seen[:, 3:7], [[1, 0, 0, 0], [1, 0, 0, 0]], atol=1e-6)  # both face their attack


def with_ball(env, data, x: float, y: float):
    return data.replace(qpos=data.qpos.at[env.layout.ball_qpos[:2]].set(jnp.asarray([x, y])))


def test_zero_sum_terms_sum_to_zero_over_the_sides():
    """Scored on pairs of states the physics could step between: random moves of the agents and the ball,
    into either goal or neither."""
    env = match("soccer_2v2")
    before = env.reset(jax.random.PRNGKey(0)).pipeline_state
    rng = np.random.default_rng(0)
    assert env.zero_sum_terms == ("goal", "ball_progress")
    for ball_y in (0.5, 6.2, -6.2, -1.0):
        moved = before.qpos.at[env.layout.agent_qpos.ravel()].add(rng.uniform(-0.2, 0.2, env.layout.agent_qpos.size))
        after = with_ball(env, before.replace(qpos=moved), float(rng.uniform(-0.5, 0.5)), ball_y)
        actions = jnp.asarray(rng.uniform(-1, 1, (4, 2)), jnp.float32)
        metrics, reward, _ = env.score(before, after, actions)
        for term in env.zero_sum_terms:
            assert float(metrics[term].sum()) == pytest.approx(0.0, abs=1e-5), term
        assert reward.shape == (2,)
    assert float(metrics["ball_progress"][0]) < 0  # the ball went towards the home goal: the away side's progress


@pytest.mark.parametrize("side", [0, 1])
def test_a_goal_counts_for_the_side_that_scores_and_against_the_other(side):
    env = match("soccer_1v1")
    before = env.reset(jax.random.PRNGKey(0)).pipeline_state
    after = with_ball(env, before, 0.0, 4.9 if side == 0 else -4.9)  # inside the goal `side` attacks
    metrics, reward, scored = env.score(before, after, jnp.zeros((2, 2)))
    assert bool(scored)
    assert list(np.asarray(metrics["success"])) == [1.0 - side, float(side)]
    assert list(np.asarray(metrics["goal"])) == ([1.0, -1.0] if side == 0 else [-1.0, 1.0])
    assert float(reward[side]) > 9 > -9 > float(reward[1 - side])  # 10 x goal dominates


@pytest.fixture
def no_physics(monkeypatch):
    """The match's episode rules alone: `advance` leaves the physics where it was (MJX's step takes a minute to
    compile on two CPU cores; the slow tests below step it)."""
    from fieldgen.env import team

    monkeypatch.setattr(team, "advance",
                        lambda sys, data, ctrl, substeps, impl, guard=None: (data.replace(ctrl=ctrl), None))


@pytest.mark.parametrize("side", [0, 1])
def test_a_goal_ends_the_episode_for_both_sides_and_counts_once(no_physics, side):
    env = match("soccer_1v1")
    check_goal_ends_the_episode_once(env, env.step, side)


def check_goal_ends_the_episode_once(env, step, side: int):
    state = env.reset(jax.random.PRNGKey(0))
    state = state.replace(pipeline_state=with_ball(env, state.pipeline_state, 0.0, 4.9 if side == 0 else -4.9))
    scored = step(state, jnp.zeros((2, 2)))
    assert float(scored.done) == 1.0 and float(scored.info["truncation"]) == 0.0
    assert list(np.asarray(scored.metrics["success"])) == [1.0 - side, float(side)]
    assert list(np.asarray(scored.metrics["goal"])) == ([1.0, -1.0] if side == 0 else [-1.0, 1.0])
    assert int(scored.info["episode"]) == 1 and int(scored.info["episode_step"]) == 0
    fresh_ball = np.asarray(scored.pipeline_state.qpos[env.layout.ball_qpos[:2]])
    np.testing.assert_allclose(fresh_ball, [0.0, 0.0], atol=1e-6)  # the next episode is already under way
    after = step(scored, jnp.zeros((2, 2)))
    assert float(after.done) == 0.0 and not np.asarray(after.metrics["success"]).any()
    assert not np.asarray(after.metrics["goal"]).any()


def test_time_runs_out_for_both_sides(no_physics):
    env = match("soccer_1v1")
    state = env.reset(jax.random.PRNGKey(0))
    last = dict(state.info, episode_step=jnp.asarray(env.episode_length - 1, jnp.int32))
    state = env.step(state.replace(info=last), jnp.zeros((2, 2)))
    assert float(state.done) == 1.0 and float(state.info["truncation"]) == 1.0
    assert not np.asarray(state.metrics["success"]).any() and int(state.info["episode_step"]) == 0


@pytest.mark.parametrize("pushed", [False, True])
def test_a_ball_left_near_one_spot_is_moved_to_the_neutral_spot_farthest_from_the_agents(no_physics, write_spec,
                                                                                         pushed):
    """teams.lack_of_progress: after its time (three steps here) of a ball within its distance of one spot, the
    ball is moved, at rest, to the centre spot, the spot farthest from agents at their kick-offs; a ball pushed
    farther than that each step is left alone, and a field without the rule leaves a still one alone."""
    spec = load_spec(write_spec("extends: soccer_1v1\nname: stalls\nball: {spawn: {x: 2, y: 1}}\n"
                                "teams: {lack_of_progress: {seconds: 0.15, distance: 0.5}}\n"))
    for env, moved in ((fieldgen.make(spec), not pushed), (match("soccer_1v1"), False)):
        state = env.reset(jax.random.PRNGKey(0))
        ball = np.array([2.0, 1.0])
        state = state.replace(pipeline_state=with_ball(env, state.pipeline_state, *ball))
        for step in range(3):
            if pushed and step:
                ball += [0.0, 0.6]
                state = state.replace(pipeline_state=with_ball(env, state.pipeline_state, *ball))
            state = env.step(state, jnp.zeros((2, 2)))
        np.testing.assert_allclose(state.pipeline_state.qpos[env.layout.ball_qpos[:2]],
                                   [0.0, 0.0] if moved else ball, atol=1e-6)
        assert float(state.done) == 0.0 and int(state.info["episode_step"]) == 3  # the match goes on
        if moved:
            assert not np.asarray(state.pipeline_state.qvel[env._ball_dofs]).any()  # at rest
            assert int(state.info["ball_still_steps"]) == 0


@pytest.mark.slow
@pytest.mark.parametrize("side", [0, 1])
def test_on_mjx_a_goal_ends_the_episode_once_and_the_zero_sum_terms_cancel(side):
    env, step = match("soccer_1v1"), jitted_step("soccer_1v1")
    check_goal_ends_the_episode_once(env, step, side)
    state = env.reset(jax.random.PRNGKey(0))
    rolling = state.pipeline_state.qvel.at[env.mj_model.joint("ball_y").dofadr[0]].set(1.0)  # the ball rolls to +y
    state = step(state.replace(pipeline_state=state.pipeline_state.replace(qvel=rolling)), jnp.ones((2, 2)))
    assert float(state.metrics["ball_progress"][0]) > 0
    for term in env.zero_sum_terms:
        assert float(state.metrics[term].sum()) == pytest.approx(0.0, abs=1e-6), term


@pytest.mark.slow
def test_a_2v2_match_steps_batched_with_vmap():
    env = match("soccer_2v2")
    states = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 3))
    states = jax.jit(jax.vmap(env.step))(states, jnp.ones((3, 4, 2)))
    assert states.obs.shape == (3, 4, env.observation_size) and states.reward.shape == (3, 2)
    np.testing.assert_allclose(np.asarray(states.metrics["goal"]).sum(-1), 0.0)


def test_every_match_term_has_a_value_per_side(write_spec):
    from fieldgen.schema.terms import MATCH_TERMS

    names = [n for n, t in MATCH_TERMS.items() if not t.torso]
    reward = "".join(f"    - {{term: {n}}}\n" for n in names)
    env = fieldgen.make(load_spec(write_spec(f"extends: soccer_1v1\nname: every\ntask:\n  reward:\n{reward}")))
    before = env.reset(jax.random.PRNGKey(0)).pipeline_state
    metrics, reward, _ = env.score(before, with_ball(env, before, 0.3, 1.0), jnp.ones((2, 2)))
    assert set(metrics) == {"success", *names} and all(m.shape == (2,) for m in metrics.values())
    assert np.isfinite(np.asarray(reward)).all()


def test_each_sides_own_terms_read_a_turned_match_as_the_other_side_reads_the_match(write_spec):
    """agent_behind_ball draws each agent behind the ball on the ball's way to the goal it attacks: in the match
    turned half a turn with the sides swapped, the away side's value is the home side's of the match."""
    reward = "    - {term: agent_approaches_ball}\n    - {term: agent_behind_ball}\n"
    env = fieldgen.make(load_spec(write_spec(f"extends: soccer_1v1\nname: own\ntask:\n  reward:\n{reward}")))
    start = env.reset(jax.random.PRNGKey(0)).pipeline_state
    rng = np.random.default_rng(2)
    at = env.layout.agent_qpos.ravel()
    before = with_ball(env, start.replace(qpos=start.qpos.at[at].add(rng.uniform(-1, 1, at.size))), 0.4, -0.7)
    after = with_ball(env, before.replace(qpos=before.qpos.at[at].add(rng.uniform(-0.1, 0.1, at.size))), 0.5, -0.6)
    (before, turned_before), (after, turned_after) = (turned_world(env, d, rng) for d in (before, after))
    seen = env.score(before, after, jnp.zeros((2, 2)))[0]
    seen_turned = env.score(turned_before, turned_after, jnp.zeros((2, 2)))[0]
    for term in ("agent_approaches_ball", "agent_behind_ball"):
        np.testing.assert_allclose(np.asarray(seen_turned[term]), np.asarray(seen[term])[::-1], atol=1e-5)
        assert abs(float(seen[term][0] - seen[term][1])) > 1e-3, term  # the sides' values differ here


def test_ball_goal_progress_is_zero_sum_is_ball_progress_on_the_centre_line_and_pays_the_way_to_the_mouth(write_spec):
    reward = "    - {term: ball_progress}\n    - {term: ball_goal_progress}\n"
    env = fieldgen.make(load_spec(write_spec(f"extends: soccer_1v1\nname: mouth\ntask:\n  reward:\n{reward}")))
    assert env.zero_sum_terms == ("ball_progress", "ball_goal_progress")
    start = env.reset(jax.random.PRNGKey(0)).pipeline_state

    def seen(a, b):
        return env.score(with_ball(env, start, *a), with_ball(env, start, *b), jnp.zeros((2, 2)))[0]

    along = seen((0.0, 1.0), (0.0, 1.5))  # on the centre line, towards the away goal (+y)
    np.testing.assert_allclose(np.asarray(along["ball_goal_progress"]), np.asarray(along["ball_progress"]), atol=1e-4)
    beside = seen((2.5, 4.6), (2.0, 4.6))  # along the end wall from the corner towards the goal home attacks
    assert float(beside["ball_progress"][0]) == pytest.approx(0.0, abs=1e-6)
    assert float(beside["ball_goal_progress"][0]) > 0.5
    for m in (along, beside, seen((-1.0, -3.0), (-0.4, -4.2))):
        assert float(m["ball_goal_progress"].sum()) == pytest.approx(0.0, abs=1e-5)
