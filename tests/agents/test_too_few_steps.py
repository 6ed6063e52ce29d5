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


def test_a_run_ends_at_the_whole_iterations_its_steps_hold():
    """trained_steps, which the progress bar counts to, is where a run's last row ends: the tiny CRL run's
    1,900 steps end at 1,760 (tests/run/test_export.py trains it), 800 of prefill and 2 x 6 iterations of 80."""
    from tiny_runs import TINY_CRL

    from fieldgen.agents import crl, ppo

    config = crl.CRLConfig(**TINY_CRL)
    assert config.trained_steps == 1760 and "trains 1,760 of the 1,900 env steps asked" in config.short_of_asked()
    exact = ppo.PPOConfig(total_steps=2 * 3 * 8 * 20, num_envs=8, unroll_length=20, num_minibatches=4, num_evals=2)
    assert exact.trained_steps == exact.total_steps and exact.short_of_asked() is None
    assert ppo.PPOConfig(**{**exact.model_dump(), "total_steps": exact.total_steps + 159}).trained_steps == 960


def test_a_run_that_filled_its_buffer_anew_ends_past_trained_steps_by_the_refill():
    """A resume from what a run learned alone fills its buffer anew, and those env steps count: a run at
    evaluation 1 with 1,280 + 800 steps ends 800 past trained_steps; PPO, which keeps no buffer, where it would."""
    from tiny_runs import TINY_CRL

    from fieldgen.agents import crl, ppo

    config = crl.CRLConfig(**TINY_CRL)
    assert (config.steps_at(0), config.steps_at(1)) == (800, 1280)
    assert config.ends_at(1, 1280) == config.trained_steps == 1760
    assert config.ends_at(2, 1760 + 800) == 1760 + 800
    run = ppo.PPOConfig(total_steps=960, num_envs=8, unroll_length=20, num_minibatches=4, num_evals=2)
    assert run.steps_at(0) == 0 and run.ends_at(1, 480) == run.trained_steps == 960
