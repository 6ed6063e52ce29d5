"""Every algorithm acts two ways: its mean action, the one every evaluation during training judges, and with a
key the actions its policy draws in training (`fieldgen eval --actions sampled`)."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from fieldgen.agents import registry

SMALL = {"total_steps": 1900, "num_envs": 4, "unroll_length": 10, "num_evals": 1, "eval_envs": 4}
OFF_POLICY = {"batch_size": 32, "min_replay_rows": 100, "max_replay_rows": 400, "hidden": (16, 16)}
SETTINGS = {"crl": {**OFF_POLICY, "repr_dim": 8}, "icrl": {**OFF_POLICY, "repr_dim": 8}, "sac": OFF_POLICY,
            "td3": OFF_POLICY, "ppo": {"num_minibatches": 2, "update_epochs": 1}}


@pytest.mark.parametrize("algo", registry.ALGORITHMS)
def test_with_a_key_an_algorithm_acts_as_in_training_and_without_one_on_its_mean(algo, env_cache):
    env = env_cache("ant_nav" if algo == "icrl" else "point_nav")  # icrl splits an ant's joints among agents
    entry = registry.trainer(algo)
    trainer = entry.make_train(entry.config(**SMALL, **SETTINGS[algo]), env)
    state = trainer.init(jax.random.PRNGKey(0))
    obs = state.env_state.obs
    mean = np.asarray(trainer.act(state, obs))
    np.testing.assert_array_equal(mean, np.asarray(trainer.act(state, obs)))  # no key: the same every call
    drawn = [np.asarray(trainer.act(state, obs, jax.random.PRNGKey(k))) for k in (1, 2)]
    assert all(d.shape == mean.shape and np.all(np.abs(d) <= 1.0) for d in drawn)
    assert not np.allclose(drawn[0], mean) and not np.allclose(drawn[0], drawn[1])
    np.testing.assert_array_equal(drawn[0], np.asarray(trainer.act(state, obs, jax.random.PRNGKey(1))))


@pytest.mark.slow
def test_an_evaluation_acts_as_the_config_says_unless_told(env_cache):
    """loop.evaluate judges the mean action under eval_actions "mean" and the drawn ones under "sampled", as
    it does when told outright; an unknown value is refused naming the choices."""
    from fieldgen.agents import loop
    from fieldgen.agents.config import ConfigError

    env = env_cache("point_nav")
    entry = registry.trainer("crl")
    config = entry.config(**SMALL, **SETTINGS["crl"])
    state = entry.make_train(config, env).init(jax.random.PRNGKey(0))
    key = jax.random.PRNGKey(5)

    def judged(actions, told=None):
        trainer = entry.make_train(config.model_copy(update={"eval_actions": actions}), env)
        metrics, _ = loop.evaluate(trainer, state, key, sampled=told)
        return float(metrics["closest_distance"])

    assert judged("mean") == judged("sampled", told=False)
    assert judged("sampled") == judged("mean", told=True)
    assert judged("sampled") != judged("mean")
    assert registry.judged_on("mean") == "" and registry.judged_on("sampled") == ", actions sampled from the policy"
    with pytest.raises(ConfigError, match="unknown eval_actions 'drawn'; choose one of mean, sampled"):
        entry.config.layered(sets=["crl.eval_actions=drawn"])
