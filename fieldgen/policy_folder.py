"""An exported policy's folder: `policy.json` says what the network reads, how it is built and what its
outputs drive; `params.msgpack` holds its weights (flax's msgpack serialization).

`policy.json` also holds the SHA-256 of `params.msgpack`, so weights damaged or swapped are refused. Exported with
`--format onnx`, the folder also holds `policy.onnx`, the same policy as an ONNX graph (fieldgen.policy_onnx).

`load_policy(folder)` gives a jit-able `act(obs) -> action` from these two files alone: no trainer,
run folder, field or simulator is needed, so the policy can go wherever JAX and flax run.

The file's `agents` (and `network.per_agent`) are the actor's controllers (fieldgen.agents.team:
ICRL's one per leg or joint, one for every other algorithm), named as exported folders already say.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Annotated, Literal

import jax
import jax.numpy as jnp
import numpy as np
from flax import serialization
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from fieldgen.agents.actor import Policy
from fieldgen.agents.networks import residual_blocks
from fieldgen.files import Output, replace_folder, write_atomic
from fieldgen.suggest import shell

DESCRIPTION, PARAMS, ONNX = "policy.json", "params.msgpack", "policy.onnx"
MAX_DESCRIPTION_BYTES = 10_000_000  # a description names each observation and action: kilobytes
POLICY = Output("fieldgen export", (DESCRIPTION, PARAMS, ONNX), DESCRIPTION, "-o",
                record_keys=("observation_names",))
ACTION = "tanh of each agent's first network outputs, one per action it drives, in order"


class PolicyError(Exception):
    """An exported policy folder that cannot be loaded: missing, damaged, or inconsistent."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


Count = Annotated[int, Field(ge=1)]
Names = Annotated[list[str], Field(min_length=1)]


class Network(_Strict):
    """agents.networks.MLP: Dense -> (LayerNorm) -> swish per hidden layer, residual blocks of `skip_every`
    layers after the first, then a linear layer of `outputs`."""

    kind: Literal["mlp"] = "mlp"
    activation: Literal["swish"] = "swish"
    hidden: Annotated[list[Count], Field(min_length=1)]
    outputs: Count
    layer_norm: bool
    skip_every: Annotated[int, Field(ge=0)]
    matmul: Literal["float32", "bfloat16"] = "float32"  # the operands of each layer's product (agents.networks.MATMULS)
    per_agent: bool  # each controller has its own weights, stacked on a leading axis of params.msgpack


class Agent(_Strict):
    observes: Names  # the observation entries its network reads, in order
    drives: Names  # the action each of its first outputs drives


class Normalizer(_Strict):
    """Observations enter the network as clip((obs - mean) / std, -clip, clip)."""

    mean: list[Annotated[float, Field(allow_inf_nan=False)]]
    std: list[Annotated[float, Field(gt=0, allow_inf_nan=False)]]
    clip: Annotated[float, Field(gt=0, allow_inf_nan=False)]


class Description(_Strict):
    format: Literal["fieldgen-policy"] = "fieldgen-policy"
    version: Literal[1] = 1
    algorithm: str
    field: str
    seed: Annotated[int, Field(ge=0)]
    env_steps: Annotated[int, Field(ge=0)]
    observation_names: Names
    action_names: Names
    network: Network
    agents: Annotated[list[Agent], Field(min_length=1)]
    normalizer: Normalizer | None
    action: Literal[ACTION] = ACTION
    params_sha256: str = ""  # the digest of params.msgpack, set as the folder is written (save_policy)

    @model_validator(mode="after")
    def _consistent(self):
        """What the network is built from agrees: its hidden layers form its residual blocks; every agent's network reads as many entries and drives as many
        actions as the others (one stacked network), and has an output for each; the normalizer has a mean and
        a spread for each observation."""
        if len({len(a.observes) for a in self.agents}) > 1 or len({len(a.drives) for a in self.agents}) > 1:
            raise ValueError("agents: every agent observes as many entries, and drives as many actions, as the others")
        driven = [name for a in self.agents for name in a.drives]
        if sorted(driven) != sorted(self.action_names):  # else an action held at 0, or two outputs fighting for one
            twice = sorted({n for n in driven if driven.count(n) > 1})
            left = [n for n in self.action_names if n not in driven]
            raise ValueError("agents: every action is driven once, by one agent"
                             + (f"; {', '.join(twice)} more than once" if twice else "")
                             + (f"; {', '.join(left)} by none" if left else ""))
        if len(self.agents[0].drives) > self.network.outputs:
            raise ValueError(f"agents drive {len(self.agents[0].drives)} actions each, but network.outputs is "
                             f"{self.network.outputs}")
        if self.network.skip_every:  # the blocks the network is built of can be formed
            try:
                residual_blocks(self.network.hidden, self.network.skip_every)
            except ValueError as exc:
                raise ValueError(f"network: {exc}") from None
        n = self.normalizer
        if n is not None and not len(n.mean) == len(n.std) == len(self.observation_names):
            raise ValueError(f"normalizer: mean and std need one value per observation "
                             f"({len(self.observation_names)}), not {len(n.mean)} and {len(n.std)}")
        return self


def describe(policy: Policy, observation_names, action_names, **about) -> Description:
    """The description of `policy` for an environment's names; `about`: algorithm, field, seed, env_steps."""
    network = Network(hidden=list(policy.hidden), outputs=policy.outputs, layer_norm=policy.layer_norm,
                      skip_every=policy.skip_every, matmul=policy.matmul, per_agent=policy.per_controller)
    agents = [Agent(observes=[observation_names[i] for i in seen], drives=[action_names[i] for i in driven])
              for seen, driven in zip(policy.observes, policy.drives)]
    normalizer = None
    if policy.obs_mean is not None:
        normalizer = Normalizer(mean=np.asarray(policy.obs_mean).tolist(), std=np.asarray(policy.obs_std).tolist(),
                                clip=policy.clip)
    return Description(observation_names=list(observation_names), action_names=list(action_names), network=network,
                       agents=agents, normalizer=normalizer, **about)


def save_policy(policy: Policy, description: Description, folder: Path, fmt: str = "flax") -> None:
    """Write (or replace whole) an exported policy's folder; with `fmt` "onnx" (fieldgen.policy_onnx.FORMATS)
    policy.onnx too, built before anything is written (OnnxMissing where onnx is not installed)."""
    params = serialization.msgpack_serialize(jax.device_get(policy.params))
    description = description.model_copy(update={"params_sha256": hashlib.sha256(params).hexdigest()})
    graph = None
    if fmt == "onnx":
        from fieldgen.policy_onnx import model_bytes

        graph = model_bytes(policy, description)

    def fill(staging: Path) -> None:
        write_atomic(staging / DESCRIPTION, (description.model_dump_json(indent=1) + "\n").encode())
        write_atomic(staging / PARAMS, params)
        if graph is not None:
            write_atomic(staging / ONNX, graph)

    replace_folder(folder, fill, POLICY)


def load_policy(folder: str | Path) -> jax.tree_util.Partial:
    """The policy exported to `folder` as `act(obs [..., observation_size]) -> actions [..., action_size]` in
    [-1, 1], deterministic: jit it, vmap it, call it as it is, or pass it into jitted code (it is a pytree of its
    weights, so a new policy of the same shape reuses the compiled program)."""
    folder = Path(folder)
    description = read_description(folder)
    path = folder / PARAMS
    try:
        blob = path.read_bytes()
        if not description.params_sha256:
            raise PolicyError(f"{folder / DESCRIPTION} names no params_sha256, so {path} cannot be told from damaged "
                              "weights (exported by an earlier fieldgen, or edited); export the policy again")
        if hashlib.sha256(blob).hexdigest() != description.params_sha256:
            raise PolicyError(f"{path} is not the weights {folder / DESCRIPTION} names (its digest differs: "
                              "damaged, or copied from another export); export the policy again")
        params = serialization.msgpack_restore(blob)
    except PolicyError:
        raise
    except OSError as exc:
        raise PolicyError(f"cannot read {folder / PARAMS}: {exc.strerror}") from None
    except Exception:  # msgpack raises many types on damaged input
        raise PolicyError(f"{folder / PARAMS} is damaged (not flax msgpack); export the policy again") from None
    policy = _policy(description, jax.tree.map(jnp.asarray, params))
    _check_shapes(policy, folder / PARAMS)
    return jax.tree_util.Partial(Policy.__call__, policy)


def read_description(folder: Path) -> Description:
    path = folder / DESCRIPTION
    if not folder.is_dir():
        raise PolicyError(f"{folder} is not a folder; export a run's policy there with: fieldgen export RUN -o {shell(folder)}")
    try:
        if path.stat().st_size > MAX_DESCRIPTION_BYTES:
            raise PolicyError(f"{path} has {path.stat().st_size:,} bytes, more than a policy's description ever "
                              f"needs ({MAX_DESCRIPTION_BYTES:,}); export the policy again")
        return Description.model_validate_json(path.read_bytes())
    except OSError as exc:
        raise PolicyError(f"cannot read {path}: {exc.strerror}; is {folder} a folder written by fieldgen export?") \
            from None
    except ValidationError as exc:  # each told the way on: the folder is remade whole from its run
        problem = exc.errors()[0]
        again = f"it was edited or damaged: export the policy again (fieldgen export RUN -o {shell(folder)})"
        if problem["type"] == "json_invalid":  # cut short in a copy, or not JSON: pydantic names the line
            raise PolicyError(f"{path} is not JSON ({problem['msg'].removeprefix('Invalid JSON: ')}); {again}") \
                from None
        where = ".".join(str(p) for p in problem["loc"]) or "(the file)"
        if problem["type"] == "value_error" and not problem["loc"]:  # the file's parts disagree: it says which
            raise PolicyError(f"{path}: {problem['msg'].removeprefix('Value error, ')}; {again}") from None
        raise PolicyError(f"{path}: {where}: {problem['msg']}; {again}") from None


def _policy(d: Description, params: dict) -> Policy:
    try:
        observes = tuple(tuple(d.observation_names.index(n) for n in a.observes) for a in d.agents)
        drives = tuple(tuple(d.action_names.index(n) for n in a.drives) for a in d.agents)
    except ValueError as exc:  # "'x' is not in list"
        raise PolicyError(f"{DESCRIPTION}: agents: {exc}: each agent observes observation_names and drives "
                          "action_names") from None
    stats = {}
    if d.normalizer is not None:
        stats = dict(obs_mean=jnp.asarray(d.normalizer.mean, jnp.float32),
                     obs_std=jnp.asarray(d.normalizer.std, jnp.float32), clip=d.normalizer.clip)
    n = d.network
    return Policy(params, observes, drives, tuple(n.hidden), n.outputs, layer_norm=n.layer_norm,
                  skip_every=n.skip_every, per_controller=n.per_agent, matmul=n.matmul,
                  observation_size=len(d.observation_names), **stats)


def _check_shapes(policy: Policy, path: Path) -> None:
    """The weights are those of the network the description builds, layer by layer."""
    inputs = jnp.zeros((1, len(policy.observes[0])))
    init, key = policy.network.init, jax.random.PRNGKey(0)
    if policy.per_controller:
        init, key = jax.vmap(init, in_axes=(0, None)), jax.random.split(key, len(policy.observes))
    want, got = _shapes(jax.eval_shape(init, key, inputs)), _shapes(policy.params)
    for name in sorted(want.keys() | got.keys()):
        if want.get(name) != got.get(name):
            raise PolicyError(f"{path}: the weights {name} are {got.get(name, 'missing')} where {DESCRIPTION} "
                              f"describes a network whose {name} is {want.get(name, 'absent')}; export the policy again")


def _shapes(tree) -> dict[str, tuple[int, ...]]:
    return {jax.tree_util.keystr(path): tuple(x.shape) for path, x in jax.tree_util.tree_flatten_with_path(tree)[0]}
