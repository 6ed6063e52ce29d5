"""Too few --steps for the envs asked for: the refusal offers the envs or evaluations that keep the steps."""

from __future__ import annotations

from typer.testing import CliRunner

from fieldgen.cli import app

runner = CliRunner()


def refusal(tmp_path, *args: str) -> str:
    result = runner.invoke(app, ["train", "point_nav", "--prepare", "--out", str(tmp_path), *args])
    assert result.exit_code == 1, result.output
    return " ".join(result.output.split())


def test_a_replay_trainer_offers_fewer_envs(tmp_path):
    said = refusal(tmp_path, "--steps", "300000", "--envs", "1024")
    assert "use at least 1,714,176; or keep the steps with --envs 179" in said, said


def test_ppo_offers_fewer_envs_that_split_into_its_minibatches_or_fewer_evaluations(tmp_path):
    said = refusal(tmp_path, "--algo", "ppo", "--steps", "100000", "--envs", "2048")
    assert "or keep the steps with --envs 480 or --set ppo.num_evals=2" in said, said


def test_steps_too_few_for_any_envs_offer_nothing_else(tmp_path):
    said = refusal(tmp_path, "--steps", "1000")
    assert "use at least" in said and "keep the steps" not in said
