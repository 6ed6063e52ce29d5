"""bench/env_throughput.py on team fields and dm_control's soccer: a row counts agent steps as match steps times
the agents of a match, a match acts with [agents, action_size], dm_control's soccer gives a row of its team
size, and a row measured without brax's ant prints no ratio and writes it as null. Nothing here is timed against
a bound."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
import env_throughput  # noqa: E402

sys.path.remove(str(ROOT / "bench"))

import fieldgen  # noqa: E402
from fieldgen.env.contract import agents_per_env  # noqa: E402
from fieldgen.env.throughput import Throughput, action_shape  # noqa: E402


def test_a_team_row_counts_agent_steps_as_match_steps_times_agents():
    row = env_throughput.throughput_row("soccer_2v2", Throughput(n_envs=16, steps=50, seconds=2.0, agents=4), 0.05,
                                        backend="mjx")
    assert row["steps_per_second"] == 16 * 50 / 2.0
    assert row["agents"] == 4
    assert row["agent_steps_per_second"] == row["steps_per_second"] * 4
    assert row["simulated_seconds_per_second"] == pytest.approx(row["steps_per_second"] * 0.05)
    assert row["backend"] == "mjx"


def test_a_row_without_the_reference_prints_no_ratio_and_writes_null(capsys, tmp_path):
    result = Throughput(n_envs=8192, steps=200, seconds=1.0, agents=2)
    ratio = env_throughput.ratio_to_reference(result.steps_per_second, None)
    row = env_throughput.throughput_row("soccer_1v1", result, 0.05, backend="mjx", ratio_to_brax_ant=ratio)
    env_throughput.report("soccer_1v1 (mjx)", row)
    printed = capsys.readouterr().out
    assert "brax ant" not in printed and "nan" not in printed.lower()
    assert "1,638,400 steps/s   -" in printed
    env_throughput.append_jsonl(tmp_path / "rows.jsonl", row)
    line = (tmp_path / "rows.jsonl").read_text()
    assert '"ratio_to_brax_ant": null' in line
    assert json.loads(line)["ratio_to_brax_ant"] is None


def test_a_row_with_the_reference_prints_its_ratio(capsys):
    row = env_throughput.throughput_row("soccer_1v1", Throughput(n_envs=16, steps=100, seconds=1.0, agents=2), 0.05,
                                        ratio_to_brax_ant=env_throughput.ratio_to_reference(1600.0, 800.0))
    env_throughput.report("soccer_1v1 (mjx)", row)
    assert row["ratio_to_brax_ant"] == 2.0
    assert "2.00x brax ant" in capsys.readouterr().out


def test_a_single_agent_row_has_one_agent():
    row = env_throughput.throughput_row("soccer_v2", Throughput(n_envs=8, steps=10, seconds=1.0), 0.05)
    assert row["agents"] == 1
    assert row["agent_steps_per_second"] == row["steps_per_second"]


@pytest.mark.parametrize("field, agents", [("soccer_1v1", 2), ("soccer_2v2", 4)])
def test_a_match_acts_with_every_agents_action(field, agents):
    env = fieldgen.make(field)
    assert agents_per_env(env) == agents
    assert action_shape(env) == (agents, env.action_size)


def test_a_single_agent_field_acts_with_one_action():
    env = fieldgen.make("point_nav")
    assert agents_per_env(env) == 1
    assert action_shape(env) == (env.action_size,)


@pytest.mark.parametrize("team_size", [1, 2])
def test_dm_control_soccer_gives_a_row_of_its_team_size(team_size):
    env = env_throughput.dm_control_soccer(team_size)
    result = env_throughput.measure_dm_control(env, steps=2, repeats=1)
    row = env_throughput.throughput_row(f"dm_control_soccer_{team_size}v{team_size}", result, env.control_timestep())
    assert row["envs"] == 1
    assert row["agents"] == 2 * team_size
    assert row["agent_steps_per_second"] == row["steps_per_second"] * 2 * team_size
    assert row["control_dt"] == pytest.approx(0.025)
