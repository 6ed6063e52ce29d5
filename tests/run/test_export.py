"""fieldgen export: a run's policy out of its run folder, loaded by fieldgen.load_policy without the trainers."""

from __future__ import annotations

import json

import jax
import numpy as np
import pytest
from typer.testing import CliRunner

import fieldgen
from fieldgen.agents import loop
from fieldgen.cli import app
from fieldgen.policy_folder import DESCRIPTION, PARAMS, PolicyError
from fieldgen.run import session

runner = CliRunner()


pytestmark = pytest.mark.slow  # training the run they share takes minutes on two CPU cores


@pytest.fixture(scope="module")
def trained(train_point_nav):
    """A tiny CRL run of two seeds on point_nav."""
    return train_point_nav(2)


def test_exported_policy_acts_as_the_run(trained, tmp_path):
    folder = tmp_path / "policy"
    result = runner.invoke(app, ["export", str(trained), "-o", str(folder), "--seed", "1"])
    assert result.exit_code == 0, result.output
    assert "exported crl seed 1 at 1,760 env steps (point_nav: 6 observations -> 2 actions)" in result.output
    assert sorted(p.name for p in folder.iterdir()) == [".fieldgen", PARAMS, DESCRIPTION]
    run = session.open_run(trained)
    described = json.loads((folder / DESCRIPTION).read_text())
    assert described["algorithm"] == "crl" and described["seed"] == 1 and described["env_steps"] == 1760
    assert described["observation_names"] == list(run.env.observation_names)
    assert described["action_names"] == list(run.env.action_names) == described["agents"][0]["drives"]
    assert described["network"]["hidden"] == [32, 32] and described["normalizer"] is None

    act = fieldgen.load_policy(folder)
    obs = jax.vmap(run.env.reset)(jax.random.split(jax.random.PRNGKey(3), 32)).obs
    obs = obs.at[:, :2].add(jax.random.normal(jax.random.PRNGKey(4), (32, 2)))  # spread the agents over the field
    own = np.asarray(run.trainers[0].act(loop.seed_slice(run.state, 1), obs))
    other_seed = np.asarray(run.trainers[0].act(loop.seed_slice(run.state, 0), obs))
    assert not np.allclose(own, other_seed, atol=1e-3)  # the seeds' policies differ, so the export picked seed 1
    np.testing.assert_allclose(np.asarray(jax.jit(act)(obs)), own, rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.asarray(jax.jit(lambda a, o: a(o))(act, obs[0])), own[0], rtol=0, atol=1e-6)


def test_exported_onnx_policy_acts_as_the_run_in_onnxruntime(trained, tmp_path):
    import onnxruntime

    folder = tmp_path / "policy"
    result = runner.invoke(app, ["export", str(trained), "-o", str(folder), "--format", "onnx"])
    assert result.exit_code == 0, result.output
    said = "".join(result.output.split())  # the console breaks a long path anywhere, even inside a name
    assert f"orrun{folder}/policy.onnxinonnxruntime".replace(" ", "") in said
    run = session.open_run(trained)
    obs = jax.vmap(run.env.reset)(jax.random.split(jax.random.PRNGKey(3), 1000)).obs
    obs = obs.at[:, :2].add(jax.random.normal(jax.random.PRNGKey(4), (1000, 2)))  # spread the agents over the field
    own = np.asarray(run.trainers[0].act(loop.seed_slice(run.state, 0), obs))
    session_ = onnxruntime.InferenceSession(str(folder / "policy.onnx"))
    (by_onnx,) = session_.run(["action"], {"observation": np.asarray(obs, np.float32)})
    np.testing.assert_allclose(by_onnx, own, rtol=0, atol=1e-5)


def test_export_errors_are_one_sentence(trained, tmp_path, tiny_crl_args):
    unknown = runner.invoke(app, ["export", str(trained), "-o", str(tmp_path / "p"), "--seed", "7"])
    assert unknown.exit_code == 1 and "trained seeds 0, 1, not 7" in unknown.output
    assert not (tmp_path / "p").exists()
    prepared = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--prepare", *tiny_crl_args])
    assert prepared.exit_code == 0, prepared.output
    untrained = runner.invoke(app, ["export", str(tmp_path / "point_nav-crl-0"), "-o", str(tmp_path / "p")])
    assert untrained.exit_code == 1 and "has not trained yet" in untrained.output and "Traceback" not in untrained.output


def test_a_damaged_export_is_a_clear_error(trained, tmp_path):
    folder = tmp_path / "policy"
    assert runner.invoke(app, ["export", str(trained), "-o", str(folder)]).exit_code == 0
    with pytest.raises(PolicyError, match="is not a folder"):
        fieldgen.load_policy(tmp_path / "nowhere")
    described = json.loads((folder / DESCRIPTION).read_text())
    (folder / DESCRIPTION).write_text(json.dumps({**described, "network": {**described["network"], "hidden": [32]}}))
    with pytest.raises(PolicyError, match=r"\['params'\]\['Dense_1'\]\['bias'\] are \(32,\) where policy.json "
                                          r"describes a network whose .* is \(4,\)"):
        fieldgen.load_policy(folder)
    (folder / DESCRIPTION).write_text(json.dumps({**described, "agents": [{"observes": ["ball.x"],
                                                                             "drives": described["action_names"]}]}))
    with pytest.raises(PolicyError, match="'ball.x' is not in list"):
        fieldgen.load_policy(folder)
    (folder / DESCRIPTION).write_text(json.dumps({**described, "normalizer": {"mean": [0.0]}}))
    with pytest.raises(PolicyError, match="policy.json: normalizer.std: Field required"):
        fieldgen.load_policy(folder)
    (folder / DESCRIPTION).write_text(json.dumps(described))
    (folder / PARAMS).write_bytes((folder / PARAMS).read_bytes()[:100])
    with pytest.raises(PolicyError, match="params.msgpack is not the weights .*policy.json names"):
        fieldgen.load_policy(folder)
