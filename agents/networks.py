"""MLPs, the tanh-Gaussian actor and its log-probabilities."""

from __future__ import annotations

from typing import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

LOG_STD_MIN, LOG_STD_MAX = -5.0, 2.0


class MLP(nn.Module):
    """Hidden layers of Dense -> (LayerNorm) -> swish, then a linear output.

    With `skip_every` k > 0 the hidden layers after the first form residual blocks of k
    layers, each adding its input to its output (x + block(x)): the networks that let
    contrastive RL use depth on long-horizon ant tasks (scaled CRL). Their widths must
    then all be the first layer's.

    Weights start uniform with variance init_scale / fan_in: 1/3 is the CRL reference's
    choice (PyTorch's default), 1 is LeCun's; the output layer's with out_scale / fan_in where
    given (a policy's small first outputs keep its squashed actions off their bounds at the
    start). With `matmul` "bfloat16" each layer's product reads its input and weights rounded
    to bfloat16 and sums in float32 (MATMULS): the weights, the layer norms and everything
    between layers stay float32."""

    hidden: Sequence[int]
    out: int
    layer_norm: bool = False
    init_scale: float = 1 / 3
    out_scale: float | None = None
    skip_every: int = 0
    matmul: str = "float32"

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        init = nn.initializers.variance_scaling(self.init_scale, "fan_in", "uniform")
        product = MATMULS[self.matmul]

        def dense(x, width, init=init):
            return nn.Dense(width, kernel_init=init, dot_general=product)(x)

        def layer(x, width):
            x = dense(x, width)
            return nn.swish(nn.LayerNorm()(x) if self.layer_norm else x)

        if not self.skip_every:
            for width in self.hidden:
                x = layer(x, width)
        else:
            x = layer(x, self.hidden[0])
            blocks = residual_blocks(self.hidden, self.skip_every)
            for block in blocks:
                y = x
                for width in block:
                    y = layer(y, width)
                x = x + y
        if self.out_scale is None:
            return dense(x, self.out)
        return dense(x, self.out, nn.initializers.variance_scaling(self.out_scale, "fan_in", "uniform"))


def _bfloat16_product(lhs, rhs, dimension_numbers, precision=None, preferred_element_type=None, **kw):
    """A Dense layer's product on bfloat16 operands, accumulated and returned in float32: on GPUs
    with bfloat16 tensor cores, the same product in fewer cycles and half the bytes read."""
    return jax.lax.dot_general(lhs.astype(jnp.bfloat16), rhs.astype(jnp.bfloat16), dimension_numbers,
                               preferred_element_type=jnp.float32, **kw)


# how a network's Dense layers multiply: the name a config gives (crl.matmul) -> the product
MATMULS = {"float32": jax.lax.dot_general, "bfloat16": _bfloat16_product}


def residual_blocks(hidden: Sequence[int], skip_every: int) -> list[Sequence[int]]:
    """The widths of each residual block: the hidden layers after the first, `skip_every` at a time."""
    rest = list(hidden[1:])
    if len(rest) % skip_every or any(w != hidden[0] for w in rest):
        raise ValueError(f"residual blocks of {skip_every} layers need 1 + a multiple of {skip_every} hidden layers "
                         f"of one width, not {list(hidden)}")
    return [rest[i:i + skip_every] for i in range(0, len(rest), skip_every)]


class Actor(nn.Module):
    """obs -> (mean, log_std) of a Gaussian squashed by tanh into [-1, 1]."""

    hidden: Sequence[int]
    action_size: int
    layer_norm: bool = False

    @nn.compact
    def __call__(self, obs: jax.Array) -> tuple[jax.Array, jax.Array]:
        return gaussian_head(MLP(self.hidden, 2 * self.action_size, self.layer_norm)(obs))


def gaussian_head(out: jax.Array) -> tuple[jax.Array, jax.Array]:
    """An actor network's 2A outputs -> (mean, log_std), the log-std squashed into
    [LOG_STD_MIN, LOG_STD_MAX] smoothly, so the bounds never stop the gradient."""
    mean, raw = jnp.split(out, 2, axis=-1)
    return mean, LOG_STD_MIN + 0.5 * (LOG_STD_MAX - LOG_STD_MIN) * (jnp.tanh(raw) + 1.0)


class PerAgent:
    """A network per agent, vmapped over a leading agent axis, or one shared by all agents."""

    def __init__(self, module: nn.Module, agents: int, shared: bool = False):
        self.module, self.agents, self.shared = module, agents, shared

    def init(self, key: jax.Array, example: jax.Array) -> dict:
        if self.shared:
            return self.module.init(key, example)
        return jax.vmap(self.module.init, in_axes=(0, None))(jax.random.split(key, self.agents), example)

    def apply(self, params: dict, x: jax.Array):
        """x: [agents, batch, features] -> the module's output per agent."""
        return jax.vmap(self.module.apply, in_axes=(None if self.shared else 0, 0))(params, x)


class Stacked:
    """MLPs of the same hidden widths (each per agent, as PerAgent) kept as one: their parameters
    stacked on a leading axis and zero-padded to the widest input and output.

    On the small batches of a gradient step a GPU's time goes to launching kernels, one per
    matmul and per fused elementwise op of each network; stacked, the networks share each
    layer's kernels. The padding is exact: padded weights meet zero inputs or feed outputs
    that are cut off, so their gradients are zero and they stay zero. Each network starts as
    it would alone (its own fan-in), so the stacking changes no result."""

    def __init__(self, hidden: Sequence[int], inputs: Sequence[int], outputs: Sequence[int],
                 layer_norm: bool, agents: int, shared: bool = False, skip_every: int = 0, matmul: str = "float32"):
        self.members = [PerAgent(MLP(hidden, out, layer_norm, skip_every=skip_every, matmul=matmul), agents, shared)
                        for out in outputs]
        self.joint = PerAgent(MLP(hidden, max(outputs), layer_norm, skip_every=skip_every, matmul=matmul),
                              agents, shared)
        self.inputs, self.outputs = tuple(inputs), tuple(outputs)

    def init(self, keys: Sequence[jax.Array]) -> dict:
        """One key per network."""
        alone = [m.init(k, jnp.zeros((1, n))) for m, k, n in zip(self.members, keys, self.inputs)]

        def stack(*leaves):
            shape = [max(sizes) for sizes in zip(*(x.shape for x in leaves))]
            return jnp.stack([jnp.pad(x, [(0, w - d) for w, d in zip(shape, x.shape)]) for x in leaves])

        return jax.tree.map(stack, *alone)

    def apply(self, params: dict, xs: Sequence[jax.Array]) -> list[jax.Array]:
        """xs: one input per network, [agents, batch, its inputs] -> one output per network."""
        out = jax.vmap(self.joint.apply)(params, jnp.stack([self._widen(x) for x in xs]))
        return [out[k, ..., :n] for k, n in enumerate(self.outputs)]

    def apply_some(self, params: dict, first: int, xs: Sequence[jax.Array]) -> list[jax.Array]:
        """Networks first, first + 1, ... (one per input in xs) of the stack, without the others: a pass
        that needs fewer networks than the stack holds multiplies only theirs. The slice is of a leading
        axis, so it takes no gather."""
        last = first + len(xs)
        chosen = jax.tree.map(lambda p: p[first:last], params)
        out = jax.vmap(self.joint.apply)(chosen, jnp.stack([self._widen(x) for x in xs]))
        return [out[k, ..., :n] for k, n in enumerate(self.outputs[first:last])]

    def member(self, params: dict, k: int) -> dict:
        """Network k's weights (still padded), to call it alone with `apply_member`: taken once
        outside a loop that only acts, rather than at every step."""
        return jax.tree.map(lambda p: p[k], params)

    def apply_member(self, member: dict, k: int, x: jax.Array) -> jax.Array:
        return self.joint.apply(member, self._widen(x))[..., :self.outputs[k]]

    def alone(self, params: dict, k: int) -> dict:
        """Network k's weights cut to its own inputs and outputs: what an MLP of its shape holds (per agent,
        as PerAgent), to be called without the stack."""
        layers = dict(self.member(params, k)["params"])
        dense = sorted((n for n in layers if n.startswith("Dense_")), key=lambda n: int(n.split("_")[1]))
        layers[dense[0]] = dict(layers[dense[0]], kernel=layers[dense[0]]["kernel"][..., :self.inputs[k], :])
        layers[dense[-1]] = {name: w[..., :self.outputs[k]] for name, w in layers[dense[-1]].items()}
        return {"params": layers}

    def _widen(self, x: jax.Array) -> jax.Array:
        return jnp.pad(x, [(0, 0)] * (x.ndim - 1) + [(0, max(self.inputs) - x.shape[-1])])


def sample_tanh_gaussian(key: jax.Array, mean: jax.Array, log_std: jax.Array) -> tuple[jax.Array, jax.Array]:
    """A squashed sample and its log-probability (with the tanh change of variables)."""
    std = jnp.exp(log_std)
    u = mean + std * jax.random.normal(key, mean.shape)
    gaussian = -0.5 * (((u - mean) / std) ** 2 + 2 * log_std + jnp.log(2 * jnp.pi))
    return jnp.tanh(u), jnp.sum(gaussian - tanh_log_slope(u), axis=-1)


def tanh_log_slope(u: jax.Array) -> jax.Array:
    """log(1 - tanh(u)^2), elementwise, written stably: the log-density change of squashing by tanh."""
    return 2 * (jnp.log(2.0) - u - jax.nn.softplus(-2 * u))
