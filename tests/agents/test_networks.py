"""Stacked networks: the same outputs and gradients as the networks alone, padding that stays zero."""

from __future__ import annotations

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fieldgen.agents.networks import MLP, PerAgent, Stacked, residual_blocks

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


@pytest.mark.parametrize("first,count", [(1, 1), (1, 2), (0, 1)])
def test_some_networks_of_the_stack_equal_the_whole_stacks_members(first, count):
    """A pass over some members gives the whole stack's outputs for them and the same gradients for
    their weights, and none for the members it leaves out."""
    stack = Stacked((16,) * 5, INPUTS, OUTPUTS, layer_norm=True, agents=2, skip_every=2)
    params = stack.init(jax.random.split(jax.random.PRNGKey(0), 3))
    xs = [jax.random.normal(jax.random.PRNGKey(i + 1), (2, 9, n)) for i, n in enumerate(INPUTS)]
    chosen = range(first, first + count)

    def loss(outs):
        return sum((k + 1.0) * jnp.sum(jnp.sin(out)) for k, out in enumerate(outs))

    some = stack.apply_some(params, first, [xs[k] for k in chosen])
    whole = stack.apply(params, xs)
    for out, k in zip(some, chosen):
        assert out.shape == (2, 9, OUTPUTS[k])
        np.testing.assert_allclose(out, whole[k], rtol=1e-5, atol=1e-6)
    grads = jax.grad(lambda p: loss(stack.apply_some(p, first, [xs[k] for k in chosen])))(params)
    whole_grads = jax.grad(lambda p: loss([stack.apply(p, xs)[k] for k in chosen]))(params)
    for got, want in zip(jax.tree.leaves(grads), jax.tree.leaves(whole_grads)):
        np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-6)
        left_out = [k for k in range(3) if k not in chosen]
        assert not np.asarray(got)[left_out].any()


def test_residual_network_shapes_skips_and_layer_norms():
    """Hidden layers after the first form blocks of `skip_every`, each with a layer norm per layer;
    a block whose weights are all zero passes its input through unchanged."""
    net = MLP((8, 8, 8, 8, 8), 3, layer_norm=True, skip_every=2)
    params = net.init(jax.random.PRNGKey(0), jnp.zeros((1, 5)))["params"]
    dense = sorted(k for k in params if k.startswith("Dense"))
    norms = sorted(k for k in params if k.startswith("LayerNorm"))
    assert len(dense) == 6 and len(norms) == 5  # 5 hidden layers and the output; a norm per hidden layer
    assert params["Dense_0"]["kernel"].shape == (5, 8) and params["Dense_5"]["kernel"].shape == (8, 3)
    x = jax.random.normal(jax.random.PRNGKey(1), (4, 5))
    # zero both blocks: the output layer then sees the first hidden layer's output itself
    zeroed = {k: (jax.tree.map(jnp.zeros_like, v) if k not in ("Dense_0", "LayerNorm_0", "Dense_5") else v)
              for k, v in params.items()}
    first = jax.nn.swish(nn.LayerNorm().apply({"params": params["LayerNorm_0"]},
                                              x @ params["Dense_0"]["kernel"] + params["Dense_0"]["bias"]))
    want = first @ params["Dense_5"]["kernel"] + params["Dense_5"]["bias"]
    np.testing.assert_allclose(net.apply({"params": zeroed}, x), want, rtol=1e-5, atol=1e-6)
    # with its weights, a block changes what passes through
    assert not np.allclose(net.apply({"params": params}, x), want, atol=1e-3)


def test_residual_blocks_need_one_width_and_whole_blocks():
    assert [list(b) for b in residual_blocks((4, 4, 4, 4, 4), 2)] == [[4, 4], [4, 4]]
    for hidden in ((4, 4, 4, 4), (4, 8, 8)):
        with pytest.raises(ValueError, match="residual blocks of 2 layers"):
            residual_blocks(hidden, 2)


def test_stacked_residual_networks_equal_the_networks_alone():
    stack = Stacked((16,) * 5, INPUTS, OUTPUTS, layer_norm=True, agents=1, shared=True, skip_every=4)
    keys = jax.random.split(jax.random.PRNGKey(0), 3)
    params = stack.init(keys)
    xs = [jax.random.normal(jax.random.PRNGKey(i + 1), (1, 9, n)) for i, n in enumerate(INPUTS)]
    for k, (out, key, n) in enumerate(zip(stack.apply(params, xs), keys, INPUTS)):
        alone = MLP((16,) * 5, OUTPUTS[k], layer_norm=True, skip_every=4)
        np.testing.assert_allclose(out[0], alone.apply(alone.init(key, jnp.zeros((1, n))), xs[k][0]),
                                   rtol=1e-5, atol=1e-6)


def test_bfloat16_products_keep_float32_weights_and_outputs_near_float32():
    """bfloat16 changes only the operands of each product: the same weights, float32 out and float32 gradients,
    within bfloat16's rounding of the float32 network (and not equal to it: the option does something)."""
    x = jax.random.normal(jax.random.PRNGKey(1), (16, 12))
    exact, rounded = MLP((64, 64), 5, layer_norm=True), MLP((64, 64), 5, layer_norm=True, matmul="bfloat16")
    params = exact.init(jax.random.PRNGKey(0), x)
    assert jax.tree.structure(params) == jax.tree.structure(rounded.init(jax.random.PRNGKey(0), x))
    y, y16 = exact.apply(params, x), rounded.apply(params, x)
    assert y16.dtype == jnp.float32
    gap = float(jnp.abs(y16 - y).max())
    assert 0 < gap < 0.05 * float(jnp.abs(y).max())
    grads = jax.grad(lambda p: jnp.sum(rounded.apply(p, x) ** 2))(params)
    assert all(g.dtype == jnp.float32 and bool(jnp.all(jnp.isfinite(g))) for g in jax.tree.leaves(grads))
