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
