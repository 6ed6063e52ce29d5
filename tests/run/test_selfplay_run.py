"""`fieldgen train` and `fieldgen eval` on a team field: a self-play run end to end, its ratings, exact resume."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from fieldgen.cli import app
from fieldgen.command import TIME_LIMIT_STATUS
from fieldgen.run import record, selfplay

runner = CliRunner()
# a few thousand env steps: 3 evaluations of 10 iterations of 8 envs x 10 steps
TINY = ["--steps", "2400", "--envs", "8", "--set", "ppo.unroll_length=10", "--set", "ppo.num_minibatches=4",
        "--set", "ppo.hidden=[32,32]", "--set", "ppo.num_evals=3", "--set", "ppo.eval_envs=8",
        "--set", "ppo.update_epochs=2", "--set", "ppo.pool_size=2"]


def test_a_team_field_trains_by_self_play_with_ppo_alone(tmp_path):
    result = runner.invoke(app, ["train", "soccer_1v1", "--algo", "crl", "--out", str(tmp_path)])
    assert result.exit_code == 1 and "soccer_1v1 is a team field: it trains by self-play" in result.output
    result = runner.invoke(app, ["train", "soccer_1v1", "--seeds", "2", "--out", str(tmp_path)])
    assert result.exit_code == 1 and "self-play trains one seed a run" in result.output
    result = runner.invoke(app, ["train", "soccer_1v1", "--set", "ppo.pool_sampling=oldest", "--out", str(tmp_path)])
    assert result.exit_code == 1 and "unknown ppo.pool_sampling 'oldest'" in result.output
    result = runner.invoke(app, ["train", "soccer_1v1", "--curriculum", "auto", "--out", str(tmp_path)])
    assert result.exit_code == 1 and "self-play, which takes no --curriculum" in result.output
    assert not list(tmp_path.iterdir())


def without_timings(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in row.items() if k not in record.TIMINGS} for row in rows]


@pytest.mark.slow
def test_self_play_writes_ratings_resumes_exactly_and_is_judged(tmp_path, interrupt_after_eval):
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    result = runner.invoke(app, ["train", "soccer_1v1", "--out", str(whole), *TINY])
    assert result.exit_code == 0, result.output
    run = whole / "soccer_1v1-ppo-0"
    assert "vs random" in result.output and "Elo" in result.output
    rows = record.read_metrics(run)
    assert [r["eval"] for r in rows] == [0, 1, 2, 3] and rows[-1]["env_steps"] == 2400
    last = rows[-1]
    assert set(last["league"]) == {"random", "0", "1", "2"}
    assert all(sum(games.values()) == 8 for games in last["league"].values())
    assert set(last["ratings"]) == {"random", "0", "1", "2", "3"} and last["elo"] == last["ratings"]["3"]
    assert last["win_vs_random"] + last["draw_vs_random"] + last["loss_vs_random"] == pytest.approx(1.0)
    assert (run / selfplay.RATINGS_PLOT).stat().st_size > 0
    assert json.loads((run / record.RUN).read_text())["config"]["pool_sampling"] == "recency"
    assert "league.random.win" in (run / record.CSV).read_text().splitlines()[0]
    # a match filmed at every evaluation, the new snapshot at home against the one before
    assert sorted(p.stem for p in (run / record.VIDEOS).iterdir()) == ["eval_000", "eval_001", "eval_002", "eval_003"]

    # stopped after evaluation 2's metrics, before its checkpoint: the resume trains evaluation 2 again
    interrupt_after_eval(2)
    result = runner.invoke(app, ["train", "soccer_1v1", "--out", str(cut), *TINY])
    assert result.exit_code == 130, result.output
    interrupt_after_eval(None)
    resumed = cut / "soccer_1v1-ppo-0"
    result = runner.invoke(app, ["train", "--resume", str(resumed)])
    assert result.exit_code == 0, result.output
    assert without_timings(record.read_metrics(resumed)) == without_timings(rows)
    assert (resumed / record.CHECKPOINT).read_bytes() == (run / record.CHECKPOINT).read_bytes()

    result = runner.invoke(app, ["eval", str(run)])
    assert result.exit_code == 0, result.output
    assert "random policy" in result.output and "snapshot 1 (800 env steps)" in result.output
    assert "Elo ratings" in result.output
    assert "snapshot 3 at home against snapshot 1" in " ".join(result.output.split())
    assert any(run.glob("eval.*"))  # the video of that match (or its kept episode where nothing renders)
    mine = tmp_path / "mine.json"
    mine.write_text("a user's notes\n")
    for target, said in ((run / record.RUN, "was written by fieldgen train, not fieldgen eval"),
                         (mine, "is not a file fieldgen wrote")):
        result = runner.invoke(app, ["eval", str(run), "--summary", str(target), "--no-video"])
        assert result.exit_code == 1 and said in " ".join(result.output.split()), result.output
    assert mine.read_text() == "a user's notes\n" and json.loads((run / record.RUN).read_text())["selfplay"]
    judged = json.loads((run / selfplay.EVALUATION).read_text())
    assert judged["vs_snapshot"]["snapshot"] == 1 and sum(judged["vs_random"].values()) == 8
    assert judged["ratings"] == last["ratings"]

    # a time limit shorter than the first chunk (which compiles) stops after it; the resume ends as the whole run
    limited = tmp_path / "limited"
    result = runner.invoke(app, ["train", "soccer_1v1", "--out", str(limited), "--time-limit", "1", *TINY])
    assert result.exit_code == TIME_LIMIT_STATUS, result.output
    assert "stopped at the time limit after evaluation 1 of 3 (800 of 2,400 env steps)" in result.output
    result = runner.invoke(app, ["train", "--resume", str(limited / "soccer_1v1-ppo-0")])
    assert result.exit_code == 0, result.output
    assert without_timings(record.read_metrics(limited / "soccer_1v1-ppo-0")) == without_timings(rows)
