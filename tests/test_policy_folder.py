"""An exported policy's policy.json read as fieldgen's other records are: typed, range-checked, consistent with
itself and bounded in size, each problem one sentence naming the key."""

from __future__ import annotations

import json
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import serialization

import fieldgen
from fieldgen.agents.actor import Policy
from fieldgen.policy_folder import DESCRIPTION, PARAMS, PolicyError, describe, save_policy


@pytest.fixture
def exported(tmp_path):
    """A small policy of three observations and two actions, with a normalizer, exported to a folder."""
    policy = Policy(None, ((0, 1, 2),), ((0, 1),), (4,), 4, obs_mean=jnp.zeros(3), obs_std=jnp.ones(3))
    policy = policy.replace(params=policy.network.init(jax.random.PRNGKey(0), jnp.zeros((1, 3))))
    description = describe(policy, ["a", "b", "c"], ["x", "y"], algorithm="crl", field="f", seed=0, env_steps=0)
    folder = tmp_path / "policy"
    save_policy(policy, description, folder)
    return folder


def test_an_exported_policy_loads_and_acts(exported):
    actions = np.asarray(fieldgen.load_policy(exported)(jnp.ones((5, 3))))
    assert actions.shape == (5, 2) and np.all(np.abs(actions) <= 1)


@pytest.mark.parametrize("obs,phrase", [
    (jnp.ones(2), "observations of shape (2,): this policy reads 3 entries a step"),  # JAX would clamp the index
    (jnp.ones(4), "observations of shape (4,): this policy reads 3 entries a step"),  # and drop the 4th
    (jnp.ones((3, 5)), "observations of shape (3, 5)"),  # a batch the wrong way round
    (jnp.float32(1.0), "observations of shape ()"),
    (jnp.ones(3, jnp.complex64), "observations of dtype complex64: this policy reads real numbers"),
    (jnp.array([0.0, jnp.nan, 1.0]), "observations hold NaN or infinite values (row 0 of 1, entry 1): the actions "
     "of a network given them are NaN"),  # a sensor's NaN would drive the motors with NaN
    (jnp.ones((9, 3)).at[1:8, 0].set(jnp.inf).at[4, 2].set(jnp.nan), "(rows 1, 2, 3, 4, 5 and 2 more of 9, "
     "entries 0, 2)"),
])
def test_a_loaded_policy_refuses_observations_it_would_read_wrongly(exported, obs, phrase):
    act = fieldgen.load_policy(exported)
    with pytest.raises(ValueError, match=re.escape(phrase)):
        act(obs)
    assert act([0.1, 0.2, 0.3]).shape == (2,) and jax.jit(act)(jnp.ones((2, 4, 3))).shape == (2, 4, 2)
    assert act(jnp.zeros((0, 3))).shape == (0, 2)  # an empty batch: no actions, not JAX's ZeroDivisionError


def edited(**changes):
    def edit(d: dict) -> dict:
        return {**d, **{k: (v(d) if callable(v) else v) for k, v in changes.items()}}
    return edit


@pytest.mark.parametrize("edit,phrase", [
    (edited(agents=[]), "agents: List should have at least 1 item after validation, not 0"),
    (edited(agents=lambda d: [d["agents"][0], {"observes": ["a"], "drives": ["x", "y"]}]),
     "agents: every agent observes as many entries, and drives as many actions, as the others"),
    (edited(agents=[{"observes": [], "drives": ["x"]}]), "agents.0.observes: List should have at least 1 item"),
    (edited(agents=lambda d: [{**d["agents"][0], "drives": ["x", "x"]}]),
     "agents: every action is driven once, by one agent; x more than once; y by none"),  # y would be held at 0
    (edited(agents=lambda d: [{**d["agents"][0], "drives": ["x"]}]), "agents: every action is driven once, by one "
     "agent; y by none"),
    (edited(network=lambda d: {**d["network"], "outputs": 1}), "agents drive 2 actions each, but network.outputs is 1"),
    (edited(network=lambda d: {**d["network"], "hidden": []}), "network.hidden: List should have at least 1 item"),
    (edited(network=lambda d: {**d["network"], "hidden": [0]}), "network.hidden.0: Input should be greater than or "
     "equal to 1"),
    (edited(network=lambda d: {**d["network"], "skip_every": -1}), "network.skip_every: Input should be greater than "
     "or equal to 0"),
    (edited(normalizer=lambda d: {**d["normalizer"], "mean": [0.0]}), "normalizer: mean and std need one value per "
     "observation (3), not 1 and 3"),
    (edited(normalizer=lambda d: {**d["normalizer"], "std": [1.0, 0.0, 1.0]}), "normalizer.std.1: Input should be "
     "greater than 0"),
    (edited(normalizer=lambda d: {**d["normalizer"], "clip": -1}), "normalizer.clip: Input should be greater than 0"),
    (edited(observation_names=[]), "observation_names: List should have at least 1 item"),
    (edited(seed=-4), "seed: Input should be greater than or equal to 0"),
    (lambda d: [d], "(the file): Input should be an object"),
    (edited(network=lambda d: {**d["network"], "hidden": [4, 4], "skip_every": 2}), "network: residual blocks of 2 "
     "layers need 1 + a multiple of 2 hidden layers of one width, not [4, 4]"),
], ids=["no_agents", "uneven_agents", "observes_nothing", "drives_twice", "drives_short", "outputs", "no_layers",
        "empty_layer", "skip", "mean", "std", "clip", "no_observations", "seed", "list", "residual_layout"])
def test_a_damaged_or_edited_policy_json_is_one_sentence(exported, edit, phrase):
    """Before: an empty agent list was an IndexError traceback, a zero std gave infinite actions, a short mean a
    broadcasting error at the first call, residual blocks the hidden layers cannot form a ValueError traceback."""
    path = exported / DESCRIPTION
    path.write_text(json.dumps(edit(json.loads(path.read_text()))))
    with pytest.raises(PolicyError) as caught:
        fieldgen.load_policy(exported)
    assert str(caught.value).startswith(f"{path}: {phrase}")
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize("cut", [0, 100], ids=["empty", "cut_short"])
def test_a_policy_json_cut_short_says_it_is_not_json_and_to_export_again(exported, cut):
    """Before: "policy.json: (the file): Invalid JSON: EOF while parsing ...", with no way on; every refusal of the
    description now ends with one."""
    path = exported / DESCRIPTION
    path.write_bytes(path.read_bytes()[:cut])
    with pytest.raises(PolicyError) as caught:
        fieldgen.load_policy(exported)
    said = str(caught.value)
    assert said.startswith(f"{path} is not JSON (EOF while parsing") and " at line " in said
    assert said.endswith(f"; it was edited or damaged: export the policy again (fieldgen export RUN -o {exported})")


def test_a_policy_json_too_large_to_be_one_is_refused_unread(exported):
    path = exported / DESCRIPTION
    with path.open("ab") as f:
        f.truncate(20_000_000)
    with pytest.raises(PolicyError, match="policy.json has 20,000,000 bytes, more than a policy's description ever "
                                          "needs"):
        fieldgen.load_policy(exported)


@pytest.mark.parametrize("damage,phrase", [
    (lambda folder: (folder / PARAMS).write_bytes(bytes([(folder / PARAMS).read_bytes()[0] ^ 1]) +
                                                  (folder / PARAMS).read_bytes()[1:]),
     "params.msgpack is not the weights {folder}/policy.json names (its digest differs"),
    (lambda folder: (folder / PARAMS).write_bytes(serialization.msgpack_serialize(
        jax.tree.map(lambda x: x + 1, serialization.msgpack_restore((folder / PARAMS).read_bytes())))),
     "params.msgpack is not the weights"),
    (lambda folder: (folder / DESCRIPTION).write_text(json.dumps(
        {k: v for k, v in json.loads((folder / DESCRIPTION).read_text()).items() if k != "params_sha256"})),
     "policy.json names no params_sha256, so {folder}/params.msgpack cannot be told from damaged weights"),
], ids=["flipped", "other_weights", "no_digest"])
def test_weights_that_are_not_those_described_are_refused(exported, damage, phrase):
    """Weights of the right shapes but other values (a flipped bit, another export's) acted without a word."""
    damage(exported)
    with pytest.raises(PolicyError) as caught:
        fieldgen.load_policy(exported)
    assert phrase.format(folder=exported) in str(caught.value)
