"""Self-play on team fields: the Elo ratings, the opponent pool and one network playing both sides."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fieldgen.agents import elo
from fieldgen.agents.config import ConfigError
from fieldgen.agents.selfplay import (SelfPlayConfig, draw_opponents, fixed_opponents, make_selfplay, pool_actions,
                                      pool_probabilities)


def test_an_elo_update_matches_the_hand_computed_case_and_is_zero_sum():
    # 1000 against 1200: expected 1 / (1 + 10 ** (200 / 400)) = 0.240253; a win gains 32 * 0.759747 = 24.3119
    a, b = elo.update(1000.0, 1200.0, 1.0, k=32.0)
    assert a == pytest.approx(1024.3119, abs=1e-3) and b == pytest.approx(1175.6881, abs=1e-3)
    assert elo.expected(1000.0, 1200.0) == pytest.approx(0.240253, abs=1e-6)
    a, b = elo.update(1500.0, 1500.0, 0.5, k=16.0)  # a draw between equals changes nothing
    assert (a, b) == (1500.0, 1500.0)
    rng = np.random.default_rng(0)
    for ra, rb, s, k in zip(rng.uniform(500, 2000, 50), rng.uniform(500, 2000, 50), rng.uniform(0, 1, 50),
                            rng.uniform(1, 64, 50)):
        na, nb = elo.update(ra, rb, s, k)
        assert na + nb == pytest.approx(ra + rb, abs=1e-9)
        assert (na - ra) * (s - elo.expected(ra, rb)) >= 0  # scoring above expectation gains
    with pytest.raises(ValueError):
        elo.update(1000.0, 1000.0, 1.5)


def test_a_league_conserves_its_total_and_a_new_snapshot_starts_where_the_one_before_stands():
    games = [("0", "random", {"win": 3, "draw": 1, "loss": 0}),
             ("1", "random", {"win": 4, "draw": 0, "loss": 0}), ("1", "0", {"win": 2, "draw": 2, "loss": 0})]
    ratings = elo.league_ratings(games[:1], k=32.0)
    assert sum(ratings.values()) == pytest.approx(2 * elo.INITIAL)
    assert ratings["0"] > elo.INITIAL > ratings["random"]
    joined = ratings["0"]
    ratings = elo.league_ratings(games, k=32.0)
    assert sum(ratings.values()) == pytest.approx(2 * elo.INITIAL + joined)  # snapshot 1 joined at snapshot 0's
    assert ratings["1"] > ratings["0"] > ratings["random"]
    # a pairing's games enter as updates at their mean score: its order of wins and losses cannot matter
    one = {"a": 1000.0, "b": 1100.0}
    elo.rate_pairing(one, "a", "b", 2, 0, 2, k=32.0)
    expected_a = 1000.0
    expected_b = 1100.0
    for _ in range(4):
        expected_a, expected_b = elo.update(expected_a, expected_b, 0.5, 32.0)
    assert one == pytest.approx({"a": expected_a, "b": expected_b})


def test_the_fixed_earlier_opponents_run_evenly_from_the_first_snapshot_to_the_one_before():
    assert fixed_opponents(0, 4) == []
    assert fixed_opponents(1, 4) == [0]
    assert fixed_opponents(3, 4) == [0, 1, 2]
    assert fixed_opponents(10, 4) == [0, 3, 6, 9]
    assert fixed_opponents(10, 1) == [0]


def config(**kw) -> SelfPlayConfig:
    return SelfPlayConfig(**{"pool_size": 3, **kw})


def test_the_pool_draws_by_recency_newest_most():
    taken = jnp.ones(8, bool)
    ids, probs = pool_probabilities(config(pool_sampling="recency", recency_decay=0.5), 5, taken, jnp.zeros(8),
                                    jnp.zeros(8))
    assert list(np.asarray(ids)) == [5, 4, 3]
    np.testing.assert_allclose(probs, np.array([1, 0.5, 0.25]) / 1.75, rtol=1e-6)
    ids, probs = pool_probabilities(config(), 1, taken, jnp.zeros(8), jnp.zeros(8))  # snapshots 1 and 0 alone
    np.testing.assert_allclose(probs, np.array([1, 0.7, 0]) / 1.7, rtol=1e-6)


def test_the_pool_draws_by_win_rate_the_snapshots_the_policy_beats_least_most():
    taken = jnp.ones(8, bool)
    wins, games = jnp.zeros(8).at[5].set(98.0).at[4].set(50.0), jnp.zeros(8).at[5].set(98.0).at[4].set(98.0)
    c = config(pool_sampling="win_rate", win_rate_power=1.0)
    _, probs = pool_probabilities(c, 5, taken, wins, games)  # beats 5 always, 4 half the time, 3 never played
    rates = np.array([99 / 100, 51 / 100, 1 / 2])
    np.testing.assert_allclose(probs, (1 - rates + 1e-6) / (1 - rates + 1e-6).sum(), rtol=1e-5)
    assert probs[0] < probs[1] < probs[2] + 1e-6
    # drawn as the probabilities say, and only from the pool
    opponents, sides = draw_opponents(c.model_copy(update={"self_play_share": 0.0}), jax.random.PRNGKey(0), 20000,
                                      5, taken, wins, games)
    shares = np.bincount(np.asarray(opponents), minlength=8)[[5, 4, 3]] / 20000
    np.testing.assert_allclose(shares, probs, atol=0.015)
    assert set(np.asarray(sides).tolist()) == {0, 1}


def test_the_policy_plays_itself_as_configured_and_while_there_is_no_snapshot():
    taken = jnp.ones(8, bool)
    opponents, _ = draw_opponents(config(self_play_share=1.0), jax.random.PRNGKey(1), 100, 5, taken, jnp.zeros(8),
                                  jnp.zeros(8))
    assert (np.asarray(opponents) == -1).all()
    opponents, _ = draw_opponents(config(self_play_share=0.0), jax.random.PRNGKey(1), 100, 5, jnp.zeros(8, bool),
                                  jnp.zeros(8), jnp.zeros(8))
    assert (np.asarray(opponents) == -1).all()
    opponents, _ = draw_opponents(config(self_play_share=0.3), jax.random.PRNGKey(2), 4000, 5, taken, jnp.zeros(8),
                                  jnp.zeros(8))
    assert np.mean(np.asarray(opponents) == -1) == pytest.approx(0.3, abs=0.03)


def test_a_random_policy_is_drawn_as_often_as_configured_and_even_before_any_snapshot():
    from fieldgen.agents.config import ConfigError
    from fieldgen.agents.selfplay import ITSELF, RANDOM

    taken = jnp.ones(8, bool)
    opponents, _ = draw_opponents(config(self_play_share=0.2, random_share=0.3), jax.random.PRNGKey(3), 6000, 5,
                                  taken, jnp.zeros(8), jnp.zeros(8))
    drawn = np.asarray(opponents)
    assert np.mean(drawn == ITSELF) == pytest.approx(0.2, abs=0.02)
    assert np.mean(drawn == RANDOM) == pytest.approx(0.3, abs=0.02)
    assert set(drawn[drawn >= 0].tolist()) <= {5, 4, 3, 2, 1, 0}
    none_yet, _ = draw_opponents(config(self_play_share=0.2, random_share=0.3), jax.random.PRNGKey(3), 6000, 5,
                                 jnp.zeros(8, bool), jnp.zeros(8), jnp.zeros(8))
    none_yet = np.asarray(none_yet)  # no snapshot: the pool's share plays itself, the random share stays
    assert np.array_equal(none_yet == RANDOM, drawn == RANDOM) and set(none_yet.tolist()) == {ITSELF, RANDOM}
    before, _ = draw_opponents(config(self_play_share=0.3), jax.random.PRNGKey(2), 4000, 5, taken, jnp.zeros(8),
                               jnp.zeros(8))
    assert RANDOM not in np.asarray(before)  # left at 0, the draws are those of a run before the setting
    with pytest.raises(ConfigError, match="add up to more than every episode"):
        SelfPlayConfig.layered(sets=["ppo.self_play_share=0.8", "ppo.random_share=0.3"]).validate_env(
            match_env("soccer_1v1"))


def test_the_exploiter_is_drawn_as_often_as_configured_and_even_before_any_snapshot():
    from fieldgen.agents.selfplay import EXPLOITER, ITSELF, RANDOM

    taken = jnp.ones(8, bool)
    shares = config(self_play_share=0.2, random_share=0.1, exploiter_share=0.3)
    drawn = np.asarray(draw_opponents(shares, jax.random.PRNGKey(3), 6000, 5, taken, jnp.zeros(8), jnp.zeros(8))[0])
    assert np.mean(drawn == ITSELF) == pytest.approx(0.2, abs=0.02)
    assert np.mean(drawn == RANDOM) == pytest.approx(0.1, abs=0.02)
    assert np.mean(drawn == EXPLOITER) == pytest.approx(0.3, abs=0.02)
    none_yet = np.asarray(draw_opponents(shares, jax.random.PRNGKey(3), 6000, 5, jnp.zeros(8, bool), jnp.zeros(8),
                                         jnp.zeros(8))[0])
    assert np.array_equal(none_yet == EXPLOITER, drawn == EXPLOITER)  # no snapshot: the pool's share alone plays itself
    assert set(none_yet.tolist()) == {ITSELF, RANDOM, EXPLOITER}
    with pytest.raises(ConfigError, match="ppo.exploiter_share 0.3 add up to more than every episode"):
        SelfPlayConfig.layered(sets=["ppo.self_play_share=0.8", "ppo.exploiter_share=0.3"]).validate_env(
            match_env("soccer_1v1"))


@pytest.mark.slow
def test_the_exploiter_learns_from_its_own_matches_alone():
    """An exploiter that plays no match stays as it began, and the policy trains exactly as with none; one that
    plays every match learns, and the policy's games against it are scored."""
    from fieldgen.agents.selfplay import EXPLOITER

    env = match_env("soccer_1v1")
    settings = dict(total_steps=1600, num_envs=8, unroll_length=10, num_minibatches=4, num_evals=2, hidden=(8,),
                    eval_envs=8, update_epochs=2, stagger_starts=True)  # staggered: some matches end in a chunk

    def chunk(share):
        sp = make_selfplay(SelfPlayConfig(**settings, exploiter_share=share, self_play_share=min(0.5, 1 - share)),
                           env)
        state = jax.jit(sp.init)(jax.random.PRNGKey(3))
        if share == 1.0:  # as the first evaluation's redraw leaves them (until then every match plays itself)
            state = state.replace(opponent=jnp.full(8, EXPLOITER, jnp.int32))
        return state, *jax.jit(sp.chunk)(state)

    _, alone, _ = chunk(0.0)
    assert alone.exploiter is None
    before, idle, metrics = chunk(1e-9)
    assert float(metrics["exploiter_games"]) == 0
    jax.tree.map(np.testing.assert_array_equal, idle.exploiter, before.exploiter)
    jax.tree.map(np.testing.assert_array_equal, idle.params, alone.params)
    before, busy, metrics = chunk(1.0)
    assert (np.asarray(busy.opponent) == EXPLOITER).all() and float(metrics["exploiter_games"]) > 0
    assert 0.0 <= float(metrics["exploiter_score"]) <= 1.0
    moved = jax.tree.map(lambda a, b: float(np.abs(np.asarray(a) - np.asarray(b)).max()), busy.exploiter,
                         before.exploiter)
    assert min(jax.tree.leaves(moved)) > 0


@pytest.mark.slow
def test_the_exploiter_becomes_a_copy_of_the_policy_at_every_nth_evaluation():
    """With exploiter_reset_every 2, the evaluation that takes snapshot 2 makes the exploiter the policy with a
    fresh optimiser; snapshot 1's leaves it as it was."""
    env = match_env("soccer_1v1")
    sp = make_selfplay(SelfPlayConfig(total_steps=1600, num_envs=8, unroll_length=10, num_minibatches=4, num_evals=2,
                                      hidden=(8,), eval_envs=2, league_opponents=1, exploiter_share=0.3,
                                      exploiter_reset_every=2), env)
    state = jax.jit(sp.init)(jax.random.PRNGKey(3))
    fresh = state.exploiter_opt  # an optimiser as it starts (the exploiter's shapes are the policy's)
    worn = jax.tree.map(lambda x: x + 1, fresh)  # one that has stepped
    state = state.replace(exploiter_opt=worn)
    judge = jax.jit(sp.judge)
    kept, _ = judge(state, 1, jnp.zeros(1, jnp.int32), jax.random.PRNGKey(0))
    jax.tree.map(np.testing.assert_array_equal, kept.exploiter, state.exploiter)
    jax.tree.map(np.testing.assert_array_equal, kept.exploiter_opt, worn)
    assert not all(np.array_equal(a, b) for a, b in zip(jax.tree.leaves(state.exploiter),
                                                         jax.tree.leaves(state.params)))  # two networks till then
    forked, _ = judge(state, 2, jnp.zeros(1, jnp.int32), jax.random.PRNGKey(0))
    jax.tree.map(np.testing.assert_array_equal, forked.exploiter, state.params)
    jax.tree.map(np.testing.assert_array_equal, forked.exploiter_opt, fresh)


def test_a_config_is_ppos_keys_with_self_plays_own():
    from fieldgen.agents.config import ConfigError

    c = SelfPlayConfig.layered(sets=["ppo.pool_sampling=win_rate", "ppo.num_envs=64"])
    assert c.algo == "ppo" and c.pool_sampling == "win_rate" and c.num_envs == 64
    with pytest.raises(ConfigError, match="recency"):
        SelfPlayConfig.layered(sets=["ppo.pool_sampling=newest"])


def test_a_self_play_key_given_to_a_single_agent_ppo_run_is_refused_as_self_plays():
    from fieldgen.agents.ppo.config import PPOConfig

    for key in ("exploiter_share=0.3", "self_play_share=0.2", "pool_size=4"):
        with pytest.raises(ConfigError, match=rf"--set ppo.{key}: ppo.{key.split('=')[0]} is a setting of "
                                              r"self-play, which trains team fields \(soccer_1v1, soccer_2v2\)"):
            PPOConfig.layered(sets=[f"ppo.{key}"])
    with pytest.raises(ConfigError, match="unknown config key 'exploitr_share'"):
        PPOConfig.layered(sets=["ppo.exploitr_share=0.3"])
    assert PPOConfig.layered(sets=["ppo.hidden=[8]"]).hidden == (8,)  # PPO's own keys, self-play's too, still read
    assert SelfPlayConfig.layered(sets=["ppo.exploiter_share=0.3"]).exploiter_share == 0.3


@functools.cache
def match_env(name: str):
    import fieldgen

    return fieldgen.make(name)


def test_which_agents_the_learner_drives():
    sp = make_selfplay(SelfPlayConfig(total_steps=1600, num_envs=8, unroll_length=10, num_minibatches=4,
                                      num_evals=2, hidden=(8,), eval_envs=8), match_env("soccer_2v2"))
    learns = np.asarray(sp.controls(jnp.asarray([-1, 3, 3, -2]), jnp.asarray([1, 0, 1, 1])))
    # home0, home1, away0, away1: against itself all four; against a snapshot or a random policy the learner's
    # side alone
    assert learns.tolist() == [[True] * 4, [True, True, False, False], [False, False, True, True],
                               [False, False, True, True]]


def test_snapshots_act_in_training_as_configured_drawn_or_on_their_mean_as_evaluations_play_them():
    env = match_env("soccer_1v1")
    sp = make_selfplay(SelfPlayConfig(total_steps=1600, num_envs=8, unroll_length=10, num_minibatches=4,
                                      num_evals=2, hidden=(8,), eval_envs=8), env)
    me = sp.current(jax.jit(sp.init)(jax.random.PRNGKey(3)))
    pool = jax.tree.map(lambda x: jnp.stack([x, x * 0.5]), me)  # two snapshots
    obs = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 4)).obs  # [envs, agents, n]
    actions = jax.jit(functools.partial(pool_actions, sp.act), static_argnums=3)
    mean = [actions(pool, obs, jax.random.PRNGKey(k), "mean") for k in (1, 2)]
    drawn = [actions(pool, obs, jax.random.PRNGKey(k), "sampled") for k in (1, 2)]
    assert mean[0].shape == drawn[0].shape == (2, 4, 2, env.action_size)
    np.testing.assert_array_equal(mean[0], mean[1])  # the key plays no part
    np.testing.assert_allclose(mean[0][1], sp.act(jax.tree.map(lambda x: x[1], pool), obs), atol=1e-6)
    assert np.abs(np.asarray(drawn[0] - drawn[1])).max() > 1e-3  # drawn anew with each key
    with pytest.raises(ConfigError, match="opponent_actions 'greedy'; choose sampled"):
        SelfPlayConfig.layered(sets=["ppo.opponent_actions=greedy"])


@pytest.mark.slow
def test_one_network_plays_both_sides_each_from_its_own_sides_view():
    """From the mirrored kick-off (home and away each half a turn from the other), the two agents see the same
    in their own frames, so the one network gives both the same action in their own frames; stepped together,
    the match stays mirrored: the network drives each side as that side's observations say."""
    env = match_env("soccer_1v1")
    sp = make_selfplay(SelfPlayConfig(total_steps=1600, num_envs=8, unroll_length=10, num_minibatches=4,
                                      num_evals=2, hidden=(32, 32), eval_envs=8, normalize_observations=False),
                       env)
    state = sp.init(jax.random.PRNGKey(3))
    me = sp.current(state)
    me = me | {"policy": {"policy": jax.tree.map(lambda x: x * 3.0, me["policy"]["policy"])}}  # decisive actions
    match = env.reset(jax.random.PRNGKey(0))
    kickoff = match.pipeline_state.replace(qpos=env.home_qpos, qvel=jnp.zeros_like(match.pipeline_state.qvel))
    match = match.replace(pipeline_state=kickoff, obs=env.observe(kickoff))
    step = jax.jit(env.step)
    for _ in range(5):
        obs = match.obs  # [agents, n]
        np.testing.assert_allclose(obs[0], obs[1], atol=1e-4)
        actions = sp.act(me, obs)
        for a in range(2):  # per agent: its own row of observations alone gives its own action
            np.testing.assert_allclose(actions[a], sp.act(me, obs[a][None])[0], atol=1e-6)
        assert np.abs(np.asarray(actions)).max() > 0.05  # it acts, so that the check sees something move
        match = step(match, actions)
    np.testing.assert_allclose(match.obs[0], match.obs[1], atol=1e-3)
    qpos = np.asarray(match.pipeline_state.qpos)
    home, away = env.layout.agent_qpos
    np.testing.assert_allclose(qpos[home[:2]], -qpos[away[:2]], atol=1e-3)  # each where the other is, turned


def test_matches_start_staggered_when_told():
    env = match_env("soccer_1v1")
    for stagger in (False, True):
        sp = make_selfplay(SelfPlayConfig(total_steps=1600, num_envs=16, unroll_length=10, num_minibatches=4,
                                          num_evals=2, hidden=(8,), eval_envs=8, stagger_starts=stagger), env)
        begun = np.asarray(jax.jit(sp.init)(jax.random.PRNGKey(3)).env_state.info["episode_step"])
        assert (len(set(begun.tolist())) > 1) == stagger and begun.max() < env.episode_length
