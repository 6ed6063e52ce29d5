"""policy.onnx acts as the exported policy does: onnxruntime's actions on random observations against
load_policy's, for a plain MLP, a residual one with layer norm, PPO with its observation normaliser, controllers
of their own (ICRL's) and bfloat16 products."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import onnxruntime
import pytest
from typer.testing import CliRunner

import fieldgen
from fieldgen.agents.actor import Policy
from fieldgen.cli import app
from fieldgen.policy_folder import ONNX, describe, save_policy
from fieldgen.policy_onnx import INPUT, OUTPUT

OBSERVATIONS = 1000
TOLERANCE = 1e-5  # float32 throughout: the two differ only in the order each sums a product's terms


def random_params(shapes, seed: int):
    """Weights of these shapes drawn at random as a trained network's might be (kernels of variance 1 / fan-in),
    biases and layer norms included, so that none is left at its initial zero or one and each is seen to reach
    the graph."""
    rng = np.random.default_rng(seed)

    def draw(path, s):
        name = path[-1].key
        if name == "kernel":
            return jnp.asarray(rng.normal(0, s.shape[-2] ** -0.5, s.shape), jnp.float32)
        return jnp.asarray((name == "scale") + rng.normal(0, 0.1, s.shape), jnp.float32)

    return jax.tree_util.tree_map_with_path(draw, shapes)


def mlp_policy(hidden, outputs: int, observes, drives, seed: int = 0, **options) -> Policy:
    """A Policy as a trainer's `export` gives it, its network's weights drawn at random."""
    policy = Policy(None, observes, drives, tuple(hidden), outputs, **options)
    init = policy.network.init
    if policy.per_controller:
        init = jax.vmap(init, in_axes=(0, None))
        keys = jax.random.split(jax.random.PRNGKey(seed), len(observes))
    else:
        keys = jax.random.PRNGKey(seed)
    shapes = jax.eval_shape(init, keys, jnp.zeros((1, len(observes[0]))))
    return policy.replace(params=random_params(shapes, seed))


def exported_actions(policy: Policy, folder, observation_size: int, action_size: int, algorithm: str = "crl"):
    """(load_policy's actions, onnxruntime's actions of policy.onnx) on the same random observations."""
    description = describe(policy, [f"obs_{i}" for i in range(observation_size)],
                           [f"act_{i}" for i in range(action_size)], algorithm=algorithm, field="f", seed=0,
                           env_steps=0)
    save_policy(policy, description, folder, "onnx")
    observations = np.random.default_rng(1).normal(0, 3, (OBSERVATIONS, observation_size)).astype(np.float32)
    by_jax = np.asarray(jax.jit(fieldgen.load_policy(folder))(observations))
    session = onnxruntime.InferenceSession(str(folder / ONNX), providers=["CPUExecutionProvider"])
    by_onnx = session.run([OUTPUT], {INPUT: observations})[0]
    assert by_onnx.shape == by_jax.shape == (OBSERVATIONS, action_size) and by_onnx.dtype == np.float32
    return by_jax, by_onnx


def test_a_plain_mlp_acts_alike_in_onnxruntime(tmp_path):
    policy = mlp_policy((64, 64), 2 * 3, (tuple(range(11)),), ((0, 1, 2),))
    by_jax, by_onnx = exported_actions(policy, tmp_path / "p", 11, 3)
    np.testing.assert_allclose(by_onnx, by_jax, atol=TOLERANCE, rtol=0)
    assert np.abs(by_jax).max() > 0.5  # the actions vary: the weights reached the graph


def test_a_residual_mlp_with_layer_norm_acts_alike_in_onnxruntime(tmp_path):
    policy = mlp_policy((64,) * 5, 2 * 4, (tuple(range(12)),), ((0, 1, 2, 3),), layer_norm=True, skip_every=2)
    by_jax, by_onnx = exported_actions(policy, tmp_path / "p", 12, 4)
    np.testing.assert_allclose(by_onnx, by_jax, atol=TOLERANCE, rtol=0)


def test_ppo_with_its_observation_normaliser_acts_alike_in_onnxruntime(tmp_path, env_cache):
    """PPO's own export (its policy network and running statistics) of a state whose normaliser has seen
    observations far from zero mean and unit spread, some beyond its clip."""
    from fieldgen.agents import ppo
    from fieldgen.agents.ppo.train import Normalizer

    env = env_cache("point_nav")
    config = ppo.PPOConfig(num_envs=4, unroll_length=5, num_minibatches=4, hidden=(32, 32), total_steps=10_000)
    trainer = ppo.make_train(config, env)
    shapes = jax.eval_shape(trainer.init, jax.random.PRNGKey(0))
    seen = np.random.default_rng(2).normal(1.0, 0.2, (256, env.observation_size))
    normalizer = Normalizer(jnp.float32(len(seen)), jnp.asarray(seen.mean(0), jnp.float32),
                                jnp.asarray(seen.var(0) * len(seen), jnp.float32))
    policy = trainer.export(shapes.replace(params=random_params(shapes.params, 3), normalizer=normalizer))
    assert policy.obs_mean is not None and policy.clip == Normalizer.CLIP
    by_jax, by_onnx = exported_actions(policy, tmp_path / "p", env.observation_size, env.action_size, "ppo")
    np.testing.assert_allclose(by_onnx, by_jax, atol=TOLERANCE, rtol=0)
    assert json.loads((tmp_path / "p" / "policy.json").read_text())["normalizer"]["clip"] == 10.0


def test_controllers_of_their_own_act_alike_in_onnxruntime(tmp_path):
    """ICRL's shape: each controller its own weights, some of the observation entries, and its own actions,
    out of order, put in their places as agents.team.Team.joint_action puts them."""
    observes = ((0, 1, 2, 5), (0, 1, 3, 4))
    drives = ((3, 0), (1, 2))
    policy = mlp_policy((32, 32), 2 * 2, observes, drives, per_controller=True, layer_norm=True)
    by_jax, by_onnx = exported_actions(policy, tmp_path / "p", 6, 4, "icrl")
    np.testing.assert_allclose(by_onnx, by_jax, atol=TOLERANCE, rtol=0)


def test_bfloat16_products_act_alike_in_onnxruntime_within_a_bfloat16_step(tmp_path):
    """The graph rounds each product's operands to bfloat16 as JAX does (the same round-to-nearest-even) and sums
    in float32. Where an activation lies within float32 summation error of a rounding boundary, the two may round
    it to neighbouring bfloat16 values, a step of 2**-8 of its size, which moves the actions after it by about
    that much: so the actions agree to float32 error nearly everywhere, and within 1e-2 everywhere."""
    options = dict(layer_norm=True, skip_every=2)
    policy = mlp_policy((64,) * 5, 2 * 3, (tuple(range(10)),), ((0, 1, 2),), matmul="bfloat16", **options)
    by_jax, by_onnx = exported_actions(policy, tmp_path / "p", 10, 3)
    error = np.abs(by_onnx - by_jax)
    assert error.max() < 1e-2 and np.median(error) < 1e-6 and np.mean(error > TOLERANCE) < 0.05
    as_float32, _ = exported_actions(policy.replace(matmul="float32"), tmp_path / "f32", 10, 3)
    assert np.median(np.abs(as_float32 - by_jax)) > 100 * np.median(error)  # the rounding is in the graph


def test_the_onnx_model_is_made_from_what_load_policy_returns(tmp_path):
    from fieldgen.policy_folder import read_description
    from fieldgen.policy_onnx import model_bytes

    folder = tmp_path / "policy"
    policy = Policy(None, ((0, 1, 2),), ((0, 1),), (4,), 4)
    policy = policy.replace(params=policy.network.init(jax.random.PRNGKey(0), jnp.zeros((1, 3))))
    description = describe(policy, ["a", "b", "c"], ["x", "y"], algorithm="crl", field="f", seed=0, env_steps=0)
    save_policy(policy, description, folder)
    act = fieldgen.load_policy(folder)
    assert model_bytes(act, read_description(folder)) == model_bytes(policy, description)
    with pytest.raises(TypeError, match="takes the policy's description"):
        model_bytes(act, None)
    with pytest.raises(TypeError, match="takes a policy"):
        model_bytes("policy", description)


def test_an_export_replaces_policy_onnx_with_the_folder(tmp_path):
    policy = mlp_policy((8,), 2, (tuple(range(3)),), ((0,),))
    description = describe(policy, ["a", "b", "c"], ["x"], algorithm="crl", field="f", seed=0, env_steps=0)
    folder = tmp_path / "p"
    save_policy(policy, description, folder)
    save_policy(policy, description, folder, "onnx")
    assert sorted(p.name for p in folder.iterdir() if not p.name.startswith(".")) == \
        ["params.msgpack", "policy.json", "policy.onnx"]
    import onnx

    model = onnx.load(folder / ONNX)
    about = {p.key: p.value for p in model.metadata_props}
    assert json.loads(about["observation_names"]) == ["a", "b", "c"] and about["field"] == "f"
    save_policy(policy, description, folder)
    assert not (folder / ONNX).exists()


def test_export_as_onnx_without_onnx_installed_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "onnx", None)  # `import onnx` raises ImportError
    result = CliRunner().invoke(app, ["export", str(tmp_path / "no_run"), "-o", str(tmp_path / "p"),
                                      "--format", "onnx"])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert " ".join(result.output.split()) == ("error: writing policy.onnx needs the onnx package, which is not "
                                               "installed here: pip install 'fieldgen[onnx]'")
    assert not (tmp_path / "p").exists()


@pytest.mark.parametrize("fmt", ["tflite", "ONNX"])
def test_an_unknown_export_format_is_refused(tmp_path, fmt):
    result = CliRunner().invoke(app, ["export", str(tmp_path), "-o", str(tmp_path / "p"), "--format", fmt])
    assert result.exit_code == 1 and f"unknown format '{fmt}'" in result.output and "flax, onnx" in result.output
