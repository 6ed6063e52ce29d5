"""Stacked networks: the same outputs and gradients as the networks alone, padding that stays zero."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from agents.networks import MLP, PerAgent, Stacked

INPUTS, OUTPUTS = (5, 7, 2), (6, 4, 4)


@pytest.mark.parametrize("agents,shared", [(3, False), (3, True)])
def test_stacked_networks_equal_the_networks_alone(agents, shared):
    """Each member's output and its parameters' gradients equal those of its own MLP, initialised with
    the same key; the padded weights get zero gradients, so an optimizer leaves them at zero."""
    stack = Stacked((16, 16), INPUTS, OUTPUTS, layer_norm=True, agents=agents, shared=shared)
    keys = jax.random.split(jax.random.PRNGKey(0), 3)
    alone = [PerAgent(MLP((16, 16), out, layer_norm=True), agents, shared) for out in OUTPUTS]
    alone_params = [net.init(k, jnp.zeros((1, n))) for net, k, n in zip(alone, keys, INPUTS)]
    params = stack.init(keys)
    xs = [jax.random.normal(jax.random.PRNGKey(i + 1), (agents, 9, n)) for i, n in enumerate(INPUTS)]

    def loss(outs):  # a different weighting per member, so the gradients differ
        return sum((k + 1.0) * jnp.sum(jnp.sin(out)) for k, out in enumerate(outs))

    outs = jax.jit(stack.apply)(params, xs)
    grads = jax.jit(jax.grad(lambda p: loss(stack.apply(p, xs))))(params)
    for k, (net, own) in enumerate(zip(alone, alone_params)):
        np.testing.assert_allclose(outs[k], net.apply(own, xs[k]), rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(stack.apply_member(stack.member(params, k), k, xs[k]), outs[k], rtol=1e-5,
                                   atol=1e-6)
        own_grads = jax.grad(lambda p: (k + 1.0) * jnp.sum(jnp.sin(net.apply(p, xs[k]))))(own)
        for got, want in zip(jax.tree.leaves(grads), jax.tree.leaves(own_grads)):
            got = np.asarray(got[k])
            index = tuple(slice(0, d) for d in want.shape)
            np.testing.assert_allclose(got[index], want, rtol=1e-4, atol=1e-6)
            padding = np.ones(got.shape, bool)
            padding[index] = False
            assert not got[padding].any()  # padded weights: zero gradient
    stacked_on = (3,) if shared else (3, agents)  # the networks, then the agents unless they share one
    assert all(leaf.shape[:len(stacked_on)] == stacked_on for leaf in jax.tree.leaves(params))
