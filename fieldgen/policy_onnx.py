"""policy.onnx: an exported policy as an ONNX graph, so that onnxruntime (or any other ONNX runtime) acts with it
where JAX is not installed: a robot's computer, a C++ or C# controller, a browser.

The graph is built from the policy's weights with onnx's helper API rather than traced from JAX: the policy is a
small MLP (agents.actor.Policy), and a graph written op by op says exactly what it computes. It takes
`observation` [batch, observation_size] (float32) and returns `action` [batch, action_size] in [-1, 1], the
deterministic action `load_policy` computes: the observation normaliser (PPO's) as Sub, Div and Clip, each
controller's observation entries gathered, then per hidden layer MatMul and Add, LayerNormalization where the
network has it and swish as x * Sigmoid(x), residual blocks added, the output layer, Tanh of the first outputs,
and each controller's actions put in their places. A network whose products read bfloat16 operands (`matmul:
bfloat16`) has its weights rounded to bfloat16 here and its activations rounded by a Cast to bfloat16 and back
before each MatMul, which then sums in float32 as JAX's product does.

onnx is an optional extra (`pip install 'fieldgen[onnx]'`), imported only when a graph is built.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import numpy as np

from fieldgen.version import VERSION

if TYPE_CHECKING:  # the command line reads FORMATS and `require` without loading JAX
    from fieldgen.agents.actor import Policy

INPUT, OUTPUT = "observation", "action"
OPSET = 17  # the first with LayerNormalization; onnxruntime has run it since 1.14
IR_VERSION = 8  # the IR of opset 17, which runtimes of that age read
LAYER_NORM_EPSILON = 1e-6  # flax.linen.LayerNorm's default, as agents.networks.MLP builds it
MISSING = "writing policy.onnx needs the onnx package, which is not installed here: pip install 'fieldgen[onnx]'"
# what `fieldgen export --format` writes: flax's msgpack for load_policy alone, or policy.onnx beside it too
FORMATS = ("flax", "onnx")


class OnnxMissing(ImportError):
    """onnx is not installed; `str()` says which extra brings it."""


def require() -> None:
    """Refuse (OnnxMissing) before anything is read or written where onnx is not installed."""
    try:
        import onnx  # noqa: F401
    except ImportError:
        raise OnnxMissing(MISSING) from None


def model_bytes(policy: Policy, description) -> bytes:
    """The serialized ONNX model of `policy` (a Policy, or what fieldgen.load_policy returns), described by
    `description` (policy_folder.Description: its sizes, and the metadata the model carries)."""
    import jax

    from fieldgen.agents.actor import Policy

    if isinstance(policy, jax.tree_util.Partial) and policy.args and isinstance(policy.args[0], Policy):
        policy = policy.args[0]  # load_policy's act: the Policy it calls
    if not isinstance(policy, Policy):
        raise TypeError(f"model_bytes takes a policy (fieldgen.load_policy's, or agents.actor.Policy), not "
                        f"{type(policy).__name__}")
    if not hasattr(description, "observation_names"):
        raise TypeError("model_bytes takes the policy's description (fieldgen.policy_folder.read_description("
                        f"FOLDER)), not {type(description).__name__}")
    graph = _Graph(policy, len(description.observation_names), len(description.action_names))
    return graph.model(metadata(description)).SerializeToString()


class _Graph:
    """The nodes and weights of one policy's graph, added in order."""

    def __init__(self, policy: Policy, observation_size: int, action_size: int):
        require()
        self.policy, self.observation_size, self.action_size = policy, observation_size, action_size
        self.nodes, self.weights, self.count = [], [], 0

    def name(self, what: str) -> str:
        self.count += 1
        return f"{what}_{self.count}"

    def constant(self, what: str, value) -> str:
        from onnx import numpy_helper

        name = self.name(what)
        self.weights.append(numpy_helper.from_array(np.asarray(value), name))
        return name

    def op(self, kind: str, *inputs: str, **attributes) -> str:
        from onnx import helper

        out = self.name(kind.lower())
        self.nodes.append(helper.make_node(kind, list(inputs), [out], name=out, **attributes))
        return out

    def model(self, about: dict[str, str]):
        import onnx
        from onnx import TensorProto, helper

        policy = self.policy
        x = INPUT
        if policy.obs_mean is not None:  # PPO's normaliser, as agents.actor.Policy applies it
            x = self.op("Sub", x, self.constant("obs_mean", np.asarray(policy.obs_mean, np.float32)))
            x = self.op("Div", x, self.constant("obs_std", np.asarray(policy.obs_std, np.float32)))
            x = self.op("Clip", x, self.constant("low", np.float32(-policy.clip)),
                        self.constant("high", np.float32(policy.clip)))
        actions, slots = [], []
        observation_size, action_size = self.observation_size, self.action_size
        every = _numpy(policy.params)["params"]
        for k, (seen, driven) in enumerate(zip(policy.observes, policy.drives)):
            inputs = x if seen == tuple(range(observation_size)) else \
                self.op("Gather", x, self.constant("observes", np.asarray(seen, np.int64)), axis=1)
            weights = every if not policy.per_controller else \
                {layer: {name: w[k] for name, w in values.items()} for layer, values in every.items()}
            out = self.network(inputs, weights)
            first = self.op("Slice", out, self.constant("start", np.asarray([0], np.int64)),
                            self.constant("end", np.asarray([len(driven)], np.int64)),
                            self.constant("axis", np.asarray([1], np.int64)))
            actions.append(self.op("Tanh", first))
            slots.extend(driven)
        action = self.placed(actions, slots)
        self.nodes.append(helper.make_node("Identity", [action], [OUTPUT], name=OUTPUT))
        graph = helper.make_graph(
            self.nodes, "fieldgen_policy",
            [helper.make_tensor_value_info(INPUT, TensorProto.FLOAT, ["batch", observation_size])],
            [helper.make_tensor_value_info(OUTPUT, TensorProto.FLOAT, ["batch", action_size])], self.weights)
        model = helper.make_model(graph, producer_name="fieldgen", producer_version=VERSION,
                                  opset_imports=[helper.make_opsetid("", OPSET)], ir_version=IR_VERSION,
                                  doc_string=f"{INPUT} [batch, {observation_size}] -> {OUTPUT} [batch, {action_size}] "
                                             "in [-1, 1]: the policy's deterministic action (tanh of its mean)")
        helper.set_model_props(model, about)
        onnx.checker.check_model(model, full_check=True)
        return model

    def network(self, x: str, weights: dict) -> str:
        """agents.networks.MLP on `x`: hidden layers Dense -> (LayerNorm) -> swish, residual blocks of
        `skip_every` layers after the first, then the output layer."""
        from fieldgen.agents.networks import residual_blocks

        policy, layers = self.policy, iter(range(len(self.policy.hidden)))

        def layer(x: str) -> str:
            k = next(layers)
            x = self.dense(x, weights[f"Dense_{k}"])
            if policy.layer_norm:
                norm = weights[f"LayerNorm_{k}"]
                x = self.op("LayerNormalization", x, self.constant("scale", norm["scale"]),
                            self.constant("bias", norm["bias"]), axis=-1, epsilon=LAYER_NORM_EPSILON)
            return self.op("Mul", x, self.op("Sigmoid", x))

        x = layer(x)
        rest = residual_blocks(policy.hidden, policy.skip_every) if policy.skip_every else \
            [[width] for width in policy.hidden[1:]]
        for block in rest:
            y = x
            for _ in block:
                y = layer(y)
            x = self.op("Add", x, y) if policy.skip_every else y
        return self.dense(x, weights[f"Dense_{len(policy.hidden)}"])

    def dense(self, x: str, weights: dict) -> str:
        kernel = weights["kernel"]
        if self.policy.matmul == "bfloat16":  # the operands rounded to bfloat16, their products summed in float32
            import ml_dtypes
            from onnx import TensorProto

            kernel = kernel.astype(ml_dtypes.bfloat16).astype(np.float32)
            x = self.op("Cast", self.op("Cast", x, to=TensorProto.BFLOAT16), to=TensorProto.FLOAT)
        return self.op("Add", self.op("MatMul", x, self.constant("kernel", kernel)),
                       self.constant("bias", weights["bias"]))

    def placed(self, actions: list[str], slots: list[int]) -> str:
        """Each controller's actions in the slots it drives (agents.team.Team.joint_action: every action driven by
        one controller); one controller driving every action in order is its output as it is."""
        if sorted(slots) != list(range(self.action_size)):
            raise ValueError(f"the controllers drive actions {slots}, not each of {self.action_size} once")
        joined = actions[0] if len(actions) == 1 else self.op("Concat", *actions, axis=1)
        if slots == list(range(self.action_size)):
            return joined
        return self.op("Gather", joined, self.constant("slots", np.argsort(slots).astype(np.int64)), axis=1)


def _numpy(tree: dict) -> dict:
    """The weights as float32 numpy arrays, nested as flax keeps them."""
    return {k: _numpy(v) if isinstance(v, dict) else np.asarray(v, np.float32) for k, v in tree.items()}


def metadata(description) -> dict[str, str]:
    """What policy.json says of the policy, as the ONNX model's metadata (strings): the field, algorithm, seed and
    env steps, and the observation and action names in order, so that the graph alone says what it reads."""
    about = description.model_dump(mode="json", include={"algorithm", "field", "seed", "env_steps",
                                                          "observation_names", "action_names"})
    return {key: value if isinstance(value, str) else json.dumps(value) for key, value in about.items()}
