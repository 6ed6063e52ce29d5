"""A trainer's exported actor (Trainer.export) acts as the trainer does, for every algorithm and network shape."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fieldgen.agents import registry

SMALL = {"total_steps": 10_000, "num_envs": 2, "num_evals": 1, "hidden": (8, 8)}
REPLAY = {"windows": 2, "min_replay_rows": 10}
CASES = {
    "crl": ("crl", REPLAY),
    "crl residual layer-norm": ("crl", {**REPLAY, "hidden": (8, 8, 8), "skip_every": 2, "layer_norm": True}),
    "crl bfloat16 matmuls": ("crl", {**REPLAY, "matmul": "bfloat16"}),
    "icrl an actor per controller": pytest.param("icrl", {**REPLAY, "agents": "joint"}, marks=pytest.mark.slow),
    "icrl one shared actor": ("icrl", {**REPLAY, "agents": "joint", "share_parameters": True}),
    "ppo normalised": ("ppo", {"num_minibatches": 2}),
    "ppo global spread": ("ppo", {"num_minibatches": 2, "spread": "global", "normalize_observations": False}),
    "sac layer-norm": ("sac", {**REPLAY, "layer_norm": True}),
    "td3": ("td3", REPLAY),
}


def random_state(trainer, key):
    """A training state of the trainer's shapes with random weights (a normaliser's statistics positive): what
    matters is that the exported actor computes what `act` does from any weights. The shapes are `init`'s, which
    `start` keeps, without tracing the environment steps of its prefill."""
    leaves, treedef = jax.tree_util.tree_flatten_with_path(jax.eval_shape(trainer.init, jax.random.PRNGKey(0)))
    keys = jax.random.split(key, len(leaves))

    def fill(path, x, k):
        if not jnp.issubdtype(x.dtype, jnp.floating):
            return jnp.zeros(x.shape, x.dtype)
        value = 0.5 * jax.random.normal(k, x.shape, x.dtype)
        return jnp.abs(value) + 0.1 if "normalizer" in jax.tree_util.keystr(path) else value

    return jax.tree.unflatten(treedef, [fill(path, x, k) for (path, x), k in zip(leaves, keys)])


@pytest.mark.parametrize(("algo", "options"), CASES.values(), ids=CASES)
def test_exported_actor_acts_as_the_trainer(algo, options, env_cache):
    env = env_cache("point_nav")
    entry = registry.trainer(algo)
    trainer = entry.make_train(entry.config(**{**SMALL, **options}), env)
    state = random_state(trainer, jax.random.PRNGKey(1))
    obs = 3 * jax.random.normal(jax.random.PRNGKey(2), (64, env.observation_size))
    own = np.asarray(jax.jit(trainer.act)(state, obs))
    policy = trainer.export(state)
    exported = np.asarray(jax.jit(lambda p, o: p(o))(policy, obs))
    assert np.abs(own).mean() < 0.9 and len(np.unique(own.round(3))) > 64  # unsaturated: actions tell policies apart
    np.testing.assert_allclose(exported, own, rtol=0, atol=1e-6)  # the same, up to a matmul's rounding
    np.testing.assert_allclose(policy(obs[0]), own[0], rtol=0, atol=1e-6)  # one observation as well as a batch
