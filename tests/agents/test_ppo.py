"""PPO: advantages by hand, learning a point field on CPU, exact resume."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fieldgen.agents import loop, ppo
from fieldgen.agents.ppo.config import SPREADS
from fieldgen.agents.ppo.train import Normalizer


def tiny(**kw):
    base = dict(total_steps=2 * 8 * 20, num_envs=8, unroll_length=20, num_minibatches=4, update_epochs=2,
                hidden=(32, 32), num_evals=2, eval_envs=8)
    return ppo.PPOConfig(**{**base, **kw})


def test_normalizer_matches_numpy():
    rng = np.random.default_rng(0)
    a, b = rng.normal(3, 2, (50, 3)), rng.normal(-1, 0.5, (70, 3))
    n = Normalizer(jnp.zeros(()), jnp.zeros(3), jnp.zeros(3)).update(jnp.asarray(a)).update(jnp.asarray(b))
    both = np.concatenate([a, b])
    np.testing.assert_allclose(n.mean, both.mean(0), rtol=1e-5)
    np.testing.assert_allclose(n.m2 / n.count, both.var(0), rtol=1e-4)


def test_a_normalizer_that_has_counted_nothing_passes_observations_unscaled():
    obs = jnp.asarray([[0.5, -3.0, 40.0]])
    fresh = Normalizer(jnp.zeros(()), jnp.zeros(3), jnp.zeros(3))
    np.testing.assert_allclose(fresh(obs, True), [[0.5, -3.0, 10.0]])  # only the clip, no division by the floor
    counted = fresh.update(jnp.asarray([[1.0, 1.0, 1.0], [3.0, 1.0, 5.0]]))
    np.testing.assert_allclose(counted.std, [1.0, 1e-3, 2.0], rtol=1e-3)


@pytest.mark.parametrize("spread", SPREADS)
def test_a_small_policy_output_scale_starts_the_actions_near_the_middle_of_their_range(spread):
    """The policy's output layer alone is scaled: its first pre-tanh means shrink with policy_out_scale, the
    hidden layers and the value network are drawn as before, and its gradients still flow."""
    from fieldgen.agents.ppo.train import gaussian, networks

    obs = jax.random.normal(jax.random.PRNGKey(1), (512, 12)) * 3.0
    means, params = {}, {}
    for scale in (1.0, 1e-4):
        policy, value = networks(tiny(spread=spread, policy_out_scale=scale), 4)
        params[scale] = {"policy": policy.init(jax.random.PRNGKey(0), obs[:1])}
        if spread == "global":
            params[scale]["log_std"] = jnp.zeros(4)
        means[scale], _ = gaussian(policy, spread, params[scale], obs)
        value_params = value.init(jax.random.PRNGKey(0), obs[:1])
    assert float(jnp.abs(means[1.0]).mean()) > 0.3
    shrunk = float(jnp.abs(means[1e-4]).mean() / jnp.abs(means[1.0]).mean())
    assert 0.005 < shrunk < 0.02  # the output weights' spread: the square root of the variance's 1e-4
    hidden = [k for k in params[1.0]["policy"]["params"] if k != max(params[1.0]["policy"]["params"])]
    for k in hidden:  # the same draws for every layer below the output
        np.testing.assert_array_equal(params[1.0]["policy"]["params"][k]["kernel"],
                                      params[1e-4]["policy"]["params"][k]["kernel"])
    policy, _ = networks(tiny(spread=spread, policy_out_scale=1e-4), 4)
    grads = jax.grad(lambda p: jnp.sum(gaussian(policy, spread, p, obs)[0]))(params[1e-4])
    assert all(float(jnp.abs(g).max()) > 0 for g in jax.tree.leaves(grads["policy"]))
    assert value_params["params"]  # the value network is built beside it
    with pytest.raises(ValueError, match="policy_out_scale"):
        tiny(policy_out_scale=0)


def test_gradients_clipped_apart_move_the_policy_as_if_the_value_network_were_not_there():
    """Apart, the policy's steps are those of its gradients alone, whatever the value's gradients' size from
    step to step; together, a large value gradient shrinks the policy's share of the one norm."""
    import optax

    from fieldgen.agents.ppo.train import optimizer

    policy = {"w": jnp.asarray([0.3, -0.2])}
    params = {"policy": policy, "log_std": jnp.zeros(2), "value": {"w": jnp.zeros(3)}}
    policy_grads = [{"w": jnp.asarray([0.4, 0.1])}, {"w": jnp.asarray([-0.2, 0.3])}, {"w": jnp.asarray([0.1, 0.1])}]
    value_sizes = [100.0, 1.0, 30.0]

    def steps(c, with_value: bool):
        tx = optimizer(c)
        p = params if with_value else {"policy": policy, "log_std": params["log_std"]}
        state = tx.init(p)
        for g, size in zip(policy_grads, value_sizes):
            grads = {"policy": g, "log_std": jnp.full(2, 0.05)}
            if with_value:
                grads["value"] = {"w": jnp.full(3, size)}
            updates, state = tx.update(grads, state, p)
            p = optax.apply_updates(p, updates)
        return p["policy"]["w"]

    alone = steps(tiny(grad_clip="apart"), with_value=False)
    np.testing.assert_allclose(steps(tiny(grad_clip="apart"), with_value=True), alone, rtol=1e-6)
    assert not np.allclose(steps(tiny(grad_clip="together"), with_value=True), alone, rtol=1e-3)
    with pytest.raises(ValueError, match="grad_clip"):
        tiny(grad_clip="each")


def test_counts_in_a_config_file_and_set_read_as_the_command_line_writes_them(tmp_path):
    """50M, 1.5k and 2e6 mean in a config file (where YAML reads 2e6 as text) and in --set what --steps reads."""
    from fieldgen.agents.config import ConfigError

    written = tmp_path / "c.yaml"
    written.write_text("ppo:\n  total_steps: 2e6\n  num_envs: 1.5k\n  hidden: [64, 1k]\n")
    c = ppo.PPOConfig.layered(file=written)
    assert (c.total_steps, c.num_envs, c.hidden) == (2_000_000, 1500, (64, 1000))
    assert ppo.PPOConfig.layered(sets=["ppo.total_steps=50M"]).total_steps == 50_000_000
    for wrong in ("abc", "0", "1.5", "2e20", "1,000"):  # a comma in a config's count is a list gone wrong
        with pytest.raises(ConfigError, match="ppo.total_steps"):
            ppo.PPOConfig.layered(sets=[f"ppo.total_steps={wrong}"])
    written.write_text("ppo:\n  learning_rate: 3e-4\n  num_envs: 1.5\n")
    with pytest.raises(ConfigError, match=r"c.yaml:3: ppo.num_envs must be a whole number"):
        ppo.PPOConfig.layered(file=written)


def test_a_seed_written_in_a_config_file_or_by_set_is_refused_where_it_is_written(tmp_path):
    """The command line's --seed is always passed and would override it without a word: the run would train
    seed 0 where the user wrote 5."""
    from fieldgen.agents.config import ConfigError

    with pytest.raises(ConfigError, match=r"--set ppo.seed=5: ppo.seed is set on the command line, not here: --seed 5"):
        ppo.PPOConfig.layered(sets=["ppo.seed=5"])
    with pytest.raises(ConfigError, match=r"ppo.seed=-1: ppo.seed is set on the command line, not here: --seed N "):
        ppo.PPOConfig.layered(sets=["ppo.seed=-1"])  # not --seed -1, which the command line refuses too
    written = tmp_path / "c.yaml"
    written.write_text("ppo:\n  num_envs: 8\n  seed: 3\n")
    with pytest.raises(ConfigError, match=r"c.yaml:3: ppo.seed is set on the command line"):
        ppo.PPOConfig.layered(file=written)
    assert ppo.PPOConfig.layered(seed=5).seed == 5  # --seed itself


def test_a_linear_learning_rate_falls_from_its_rate_to_zero_over_the_runs_updates():
    """Each of the run's `updates` gradient steps moves a parameter by the rate of its place in the run (Adam's
    step under a steady gradient is the rate itself): the first at learning_rate, half-way at half, the last
    near zero; constant keeps every step at learning_rate."""
    import optax

    from fieldgen.agents.ppo.train import optimizer

    def steps(schedule: str) -> np.ndarray:
        c = tiny(learning_rate_schedule=schedule, learning_rate=1e-2)
        tx, params = optimizer(c), {"policy": {"w": jnp.zeros(2)}, "value": {"w": jnp.zeros(1)}}
        state, moves = tx.init(params), []
        grads = {"policy": {"w": jnp.asarray([1e-3, -1e-3])}, "value": {"w": jnp.asarray([1e-3])}}
        for _ in range(c.updates):
            updates, state = tx.update(grads, state, params)
            moves.append(float(jnp.abs(updates["policy"]["w"][0])))
        return np.asarray(moves)

    n = tiny().updates
    assert n == 2 * 2 * 4  # two iterations, two epochs of four minibatches
    linear, constant = steps("linear"), steps("constant")
    np.testing.assert_allclose(constant, 1e-2, rtol=1e-3)
    np.testing.assert_allclose(linear, 1e-2 * (1 - np.arange(n) / n), rtol=1e-3)
    with pytest.raises(ValueError, match="learning_rate_schedule"):
        tiny(learning_rate_schedule="cosine")


@pytest.mark.slow
def test_the_schedules_length_is_the_number_of_updates_the_run_takes(env_cache):
    c = tiny(learning_rate_schedule="linear")
    algo = ppo.make_train(c, env_cache("point_nav"))
    state, chunk = algo.init(jax.random.PRNGKey(0)), jax.jit(algo.chunk)
    for _ in range(c.num_evals):  # the iterations between each pair of evaluations, as the loop runs them
        state, _ = chunk(state)
    counts = [np.asarray(leaf) for leaf in jax.tree.leaves(state.opt) if jnp.issubdtype(leaf.dtype, jnp.integer)]
    assert counts and all((count == c.updates).all() for count in counts)


@pytest.mark.parametrize("spread", SPREADS)
@pytest.mark.slow
def test_resume_reproduces_the_uninterrupted_run(env_cache, spread):
    algo = ppo.make_train(tiny(spread=spread), env_cache("point_nav"))
    full, _ = loop.run(algo, [0], 2)
    saved = {}

    def keep(ts, index):
        saved[index] = ts

    loop.run(algo, [0], 2, on_eval=keep)
    resumed, history = loop.run(algo, [0], 2, resume=(saved[1], 1))
    assert [r["eval"] for r in history] == [2]
    for a, b in zip(jax.tree.leaves(full.params), jax.tree.leaves(resumed.params)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


@pytest.mark.slow
def test_ppo_learns_point_nav_with_a_dense_reward(write_spec):
    """agent_progress shaping: from ~0.1 to reaching the target in at least 80% of episodes in 200k steps."""
    import fieldgen

    spec = write_spec("extends: point_nav\nname: point_nav_dense\ntask:\n  reward:\n    - {term: success}\n"
                      "    - {term: agent_progress, weight: 0.1}\n")
    config = ppo.PPOConfig(total_steps=200_000, num_envs=64, unroll_length=20, num_minibatches=8,
                           hidden=(64, 64), num_evals=2, eval_envs=32)
    _, history = loop.run(ppo.make_train(config, fieldgen.make(spec)), [0], config.num_evals)
    assert history[0]["success_any"] <= 0.3
    assert history[-1]["success_any"] >= 0.8


def test_every_step_of_an_episode_that_blew_up_is_marked_and_no_other():
    from fieldgen.agents.ppo.train import blown_up

    done = jnp.asarray([[0, 0, 0], [1, 0, 0], [0, 0, 1], [0, 1, 0], [0, 0, 0], [1, 0, 0]], jnp.float32)
    broke = jnp.zeros_like(done).at[1, 0].set(1).at[3, 1].set(1)  # env 0's first episode, env 1's only one
    expected = [[1, 1, 0], [1, 1, 0], [0, 1, 0], [0, 1, 0], [0, 0, 0], [0, 0, 0]]
    np.testing.assert_array_equal(blown_up(done, broke), expected)


def test_a_normalizer_leaves_out_the_rows_that_weigh_nothing():
    rng = np.random.default_rng(1)
    kept = rng.normal(2, 3, (40, 3))
    rows = np.concatenate([kept, np.full((5, 3), 1e9)])
    weight = jnp.concatenate([jnp.ones(40), jnp.zeros(5)])
    fresh = Normalizer(jnp.zeros(()), jnp.zeros(3), jnp.zeros(3))
    n = fresh.update(jnp.asarray(kept)).update(jnp.asarray(rows), weight)
    both = np.concatenate([kept, kept])
    np.testing.assert_allclose(n.mean, both.mean(0), rtol=1e-5)
    np.testing.assert_allclose(n.m2 / n.count, both.var(0), rtol=1e-4)
    unchanged = n.update(jnp.asarray(rows[-5:]), jnp.zeros(5))
    np.testing.assert_allclose(unchanged.std, n.std)


class Blowing:
    """point_nav whose simulation 'blows up' every fifth step: the observation before it is 1e6, then the
    episode ends as a divergence where the state's `blow_flagged` says so or, for the control, merely looks
    that way to the normaliser. The flag is the state's, not the wrapper's, so that both cases run one program."""

    def __init__(self, env):
        self.env = env

    def __getattr__(self, name):
        return getattr(self.env, name)

    def step(self, state, action):
        from fieldgen.env.contract import DIVERGED

        nxt = self.env.step(state, action)
        count, flagged = state.info["blow_clock"] + 1, state.info["blow_flagged"]
        grow, blow = count % 5 == 4, count % 5 == 0
        info = dict(nxt.info, blow_clock=count, blow_flagged=flagged)
        info[DIVERGED] = nxt.info[DIVERGED] + (blow & flagged).astype(jnp.int32)
        return nxt.replace(obs=jnp.where(grow, 1e6, nxt.obs), done=jnp.where(blow, 1.0, nxt.done), info=info)

    def reset(self, key):
        state = self.env.reset(key)
        return state.replace(info=dict(state.info, blow_clock=jnp.zeros((), jnp.int32),
                                       blow_flagged=jnp.zeros((), bool)))


@pytest.fixture(scope="module")
def blowing(env_cache):
    """The start and the (single) chunk of a tiny PPO run on Blowing point_nav, each compiled once for both cases."""
    algo = ppo.make_train(tiny(num_evals=1), Blowing(env_cache("point_nav")))
    return jax.jit(algo.init), jax.jit(algo.chunk)


@pytest.mark.parametrize("flagged", [True, False])
def test_a_blown_up_episodes_observations_stay_out_of_the_normaliser(blowing, flagged):
    init, chunk = blowing
    state = init(jax.random.PRNGKey(0))
    env_state = state.env_state
    state = state.replace(env_state=env_state.replace(info=dict(
        env_state.info, blow_flagged=jnp.full_like(env_state.info["blow_flagged"], flagged))))
    state, _ = chunk(state)  # the run's two iterations, the normaliser updated after each rollout
    assert int(state.env_steps) == tiny().total_steps
    largest = float(jnp.max(state.normalizer.std))
    assert (largest < 100) if flagged else (largest > 1e5)
