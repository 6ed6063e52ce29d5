"""`fieldgen train` and `fieldgen eval` on a team field: a self-play run end to end, its ratings, exact resume."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

import fieldgen
import fieldgen.policy_folder

from fieldgen.agents import loop
from fieldgen.agents.selfplay import SelfPlayConfig
from fieldgen.cli import app
from fieldgen.command import TIME_LIMIT_STATUS
from fieldgen.run import record, selfplay
from tiny_runs import TINY_SELFPLAY as TINY  # a few thousand env steps

runner = CliRunner()


def test_a_team_field_trains_by_self_play_with_ppo_alone(tmp_path):
    result = runner.invoke(app, ["train", "soccer_1v1", "--algo", "crl", "--out", str(tmp_path)])
    assert result.exit_code == 1 and "soccer_1v1 is a team field: it trains by self-play" in result.output
    result = runner.invoke(app, ["train", "soccer_1v1", "--set", "ppo.pool_sampling=oldest", "--out", str(tmp_path)])
    assert result.exit_code == 1 and "unknown ppo.pool_sampling 'oldest'" in result.output
    result = runner.invoke(app, ["train", "soccer_1v1", "--curriculum", "auto", "--out", str(tmp_path)])
    assert result.exit_code == 1 and "self-play, which takes no --curriculum" in result.output
    assert not list(tmp_path.iterdir())


def test_no_curriculum_is_made_of_team_fields_and_one_written_by_hand_is_refused_in_one_line(tmp_path):
    for args in (["soccer_1v1", "--to", "soccer_2v2"], ["soccer_v1", "--to", "soccer_2v2"],
                 ["soccer_1v1", "--vary", "goal.width=1,2"]):
        result = runner.invoke(app, ["curriculum", *args, "-o", str(tmp_path / "c")], env={"COLUMNS": "300"})
        assert result.exit_code == 1 and "Traceback" not in result.output, result.output
        team = args[2] if args[0] == "soccer_v1" else args[0]
        assert result.output.startswith(f"error: {team} is a team field: a match trains by self-play"), result.output
        assert not (tmp_path / "c").exists()
    made = runner.invoke(app, ["curriculum", "point_soccer", "--vary", "goal.width=1,2", "-o", str(tmp_path / "c")])
    assert made.exit_code == 0, made.output
    for stage in sorted((tmp_path / "c").glob("stage_*.yaml")):  # the same stages, by hand, on a team field
        stage.write_text(stage.read_text().replace("extends: point_soccer", "extends: soccer_1v1"))
    (tmp_path / "c" / "curriculum.yaml").write_text(
        (tmp_path / "c" / "curriculum.yaml").read_text().replace("base: point_soccer", "base: soccer_1v1"))
    result = runner.invoke(app, ["train", str(tmp_path / "c"), "--out", str(tmp_path / "runs")],
                           env={"COLUMNS": "300"})
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert "is a curriculum of team fields" in result.output and not (tmp_path / "runs").exists()


def test_a_team_runs_policy_exports_as_one_agents_and_acts_as_its_actor(tmp_path):
    """Before any training (the initial state, its normaliser moved off zero): the exported network, its
    normaliser and its loaded form act as the self-play actor on an agent's observation."""
    from fieldgen.agents.ppo.train import networks
    from fieldgen.policy_folder import save_policy
    from fieldgen.run import export

    result = runner.invoke(app, ["train", "soccer_1v1", "--seed", "4", "--prepare", "--out", str(tmp_path), *TINY])
    assert result.exit_code == 0, result.output
    run = selfplay.open_run(tmp_path / "soccer_1v1-ppo-4")
    untrained = runner.invoke(app, ["export", str(run.folder), "-o", str(tmp_path / "nothing")])
    assert untrained.exit_code == 1 and "has not trained yet, so it has no policy" in untrained.output
    sp, n = run.algorithm, run.env.observation_size
    template = jax.eval_shape(jax.vmap(sp.init), loop.seed_keys(run.seeds))  # traced, not run: MJX resets are slow
    state = jax.tree.map(lambda x: jnp.zeros(x.shape, x.dtype), template)
    policy_net = networks(run.config, run.env.action_size)[0]
    drawn = jax.vmap(lambda k: policy_net.init(k, jnp.zeros((1, n))))(jax.random.split(jax.random.PRNGKey(2), 1))
    state = state.replace(params={**state.params, "policy": drawn})
    moved = state.normalizer.replace(count=jnp.full((1,), 50.0), mean=jnp.linspace(-1, 1, n)[None],
                                     m2=jnp.linspace(10, 200, n)[None])
    run.state = state.replace(normalizer=moved)
    seed, policy, _ = export.team_policy(run)
    save_policy(policy, fieldgen.policy_folder.describe(policy, run.env.observation_names, run.env.action_names,
                                                          algorithm="ppo", field="soccer_1v1", seed=seed,
                                                          env_steps=0), tmp_path / "policy")
    obs = jax.random.normal(jax.random.PRNGKey(1), (7, n)) * 4
    acted = sp.act(sp.current(loop.seed_slice(run.state, 0)), obs)
    assert seed == 4 and acted.shape == (7, run.env.action_size)
    np.testing.assert_allclose(np.asarray(policy(obs)), np.asarray(acted), atol=1e-5)
    np.testing.assert_allclose(np.asarray(fieldgen.load_policy(tmp_path / "policy")(obs)), np.asarray(acted),
                               atol=1e-5)


def test_a_team_field_takes_several_seeds_in_one_run(tmp_path):
    result = runner.invoke(app, ["train", "soccer_1v1", "--seed", "3", "--seeds", "2", "--prepare",
                                 "--out", str(tmp_path), *TINY])
    assert result.exit_code == 0, result.output
    folder = tmp_path / "soccer_1v1-ppo-3to4"
    saved = json.loads((folder / record.RUN).read_text())
    assert saved["seeds"] == [3, 4] and saved["selfplay"] and saved["config"]["seed"] == 3
    run = selfplay.open_run(folder)
    assert run.seeds == [3, 4] and run.state is None and run.rows == []


def test_a_match_batch_the_machine_cannot_hold_is_refused_before_any_folder_and_noted_when_prepared(tmp_path,
                                                                                                   monkeypatch):
    """Before: thousands of seeds or matches died in the allocator (std::bad_alloc, no Python at all), a run
    folder left behind."""
    from fieldgen.agents import memory

    monkeypatch.setattr(memory, "available", lambda: (16 * 10**9, "this machine"))
    big = ["--seeds", "50", "--envs", "100000", "--no-videos"]
    result = runner.invoke(app, ["train", "soccer_1v1", "--out", str(tmp_path / "runs"), *big])
    said = " ".join(result.output.split())
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert said.startswith("error: training 50 seeds of self-play ppo with 100,000 matches needs about") and \
        said.endswith("of memory, more than the 16 GB of this machine; lower --envs or --seeds")
    assert not (tmp_path / "runs").exists()
    prepared = runner.invoke(app, ["train", "soccer_1v1", "--out", str(tmp_path / "runs"), "--prepare", *big])
    assert prepared.exit_code == 0 and "resume it on a machine that holds it" in " ".join(prepared.output.split())
    folder = tmp_path / "runs" / "soccer_1v1-ppo-0to49"
    resumed = runner.invoke(app, ["train", "--resume", str(folder), "--no-videos"])
    assert resumed.exit_code == 1 and "lower --envs or --seeds" in " ".join(resumed.output.split())
    assert not (folder / record.CHECKPOINT).exists() and not (folder / record.METRICS).exists()


def test_each_seed_is_rated_in_a_league_of_its_own(tmp_path):
    """Seed 0's snapshots beat everything, seed 1's lose to everything: each seed's ratings count its own games
    alone, as a run of that seed alone would rate them."""
    config = SelfPlayConfig(league_opponents=2, eval_envs=8)
    both = selfplay.TeamRun(tmp_path, config, None, [0, 1], [])
    alone = selfplay.TeamRun(tmp_path, config, None, [1], [])
    scores = {0: [6, 2, 0], 1: [0, 2, 6]}  # wins, draws, losses against every opponent
    for index in range(4):
        for run in (both, alone):
            rows = []
            for seed in run.seeds:
                results = {"random": np.asarray(scores[seed]),
                           "earlier": np.asarray([scores[seed]] * config.league_opponents)}
                rows.append(selfplay.seed_row(run, index, seed, {}, results, 100 * index))
            run.rows.extend(rows)
    last = {seed: selfplay.of_seed(both.rows, seed)[-1] for seed in (0, 1)}
    assert set(last[0]["ratings"]) == set(last[1]["ratings"]) == {"random", "0", "1", "2", "3"}
    assert last[0]["ratings"]["3"] > last[0]["ratings"]["random"] and last[0]["elo"] == last[0]["ratings"]["3"]
    assert last[1]["ratings"]["3"] < last[1]["ratings"]["random"]
    assert selfplay.of_seed(both.rows, 1) == alone.rows
    for seed in (0, 1):
        assert last[seed]["ratings"] == selfplay.ratings(selfplay.of_seed(both.rows, seed), config.elo_k)
    selfplay.plot_ratings(tmp_path, both.rows, "two seeds")
    assert (tmp_path / selfplay.RATINGS_PLOT).stat().st_size > 0


def test_a_league_or_rating_edited_in_a_self_play_row_is_refused_at_its_line(tmp_path):
    """compare reads each seed's Elo rating as a number, eval its ratings, a resumed run rates its new snapshots
    from the leagues before: a row whose league, elo or ratings were edited to another type, or left out, is
    refused in one line naming the file, not a traceback."""
    result = runner.invoke(app, ["train", "soccer_1v1", "--prepare", "--out", str(tmp_path), *TINY])
    assert result.exit_code == 0, result.output
    run = tmp_path / "soccer_1v1-ppo-0"
    played = selfplay.TeamRun(run, SelfPlayConfig(league_opponents=2, eval_envs=8), None, [0], [])
    for index in range(2):
        results = {"random": np.asarray([1, 6, 1]), "earlier": np.asarray([[2, 4, 2]] * 2)}
        played.rows.append(selfplay.seed_row(played, index, 0, {}, results, 800 * index))
    for key, value, said in (("elo", "high", "elo should be a valid number, not 'high'"),
                             ("ratings", [1], "ratings should be a valid dictionary, not [1]"),
                             ("league", {"random": {"win": 1}}, "it lacks league.random.draw, league.random.loss")):
        record.write_metrics(run, [*played.rows[:1], {**played.rows[1], key: value}])
        for command in (["compare", str(run), "-o", str(tmp_path / "c.png")], ["eval", str(run)]):
            result = runner.invoke(app, command)
            assert result.exit_code == 1 and "Traceback" not in result.output, result.output
            assert f"{run / record.METRICS}:2 is not a metrics row ({said})" in " ".join(result.output.split())
    record.write_metrics(run, [played.rows[0], {k: v for k, v in played.rows[1].items() if k != "ratings"}])
    with pytest.raises(record.RunError, match="evaluation 1 of seed 0 lacks ratings, which every row of a self-play"):
        selfplay.open_run(run, load_state=False)


def test_a_self_play_run_without_its_field_copy_is_refused_in_one_line(tmp_path):
    """The run's field/ removed (a copy of the run that left it out): eval, export and resume say so, where they
    read the missing folder as a spec file and ended in a traceback."""
    import shutil

    result = runner.invoke(app, ["train", "soccer_1v1", "--prepare", "--out", str(tmp_path), *TINY])
    assert result.exit_code == 0, result.output
    run = tmp_path / "soccer_1v1-ppo-0"
    shutil.rmtree(run / selfplay.FIELD)
    for command in (["eval", str(run), "--no-video"], ["export", str(run), "-o", str(tmp_path / "p")],
                    ["train", "--resume", str(run)]):
        result = runner.invoke(app, command)
        assert result.exit_code == 1 and "Traceback" not in result.output, result.output
        assert f"{run / selfplay.FIELD} is missing: the run's own copy of its field" in " ".join(result.output.split())


def test_an_odd_number_of_evaluation_episodes_is_refused_as_the_option_given(tmp_path):
    """Before: `fieldgen eval RUN --episodes 3` was refused as "ppo.eval_envs 3 is odd", a key the user never set."""
    result = runner.invoke(app, ["train", "soccer_1v1", "--prepare", "--out", str(tmp_path), *TINY])
    assert result.exit_code == 0, result.output
    run = selfplay.open_run(tmp_path / "soccer_1v1-ppo-0")
    with pytest.raises(record.RunError, match=r"^--episodes 3 is odd: the last snapshot plays half its episodes on "
                                              r"each side; give an even number, such as 4$"):
        selfplay.evaluate(run, episodes=3)


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
    result = runner.invoke(app, ["eval", str(run), "--film-seed", "0", "--summary", str(tmp_path / "s0.json")])
    assert result.exit_code == 0 and any(run.glob("eval_seed0.*")), result.output
    result = runner.invoke(app, ["eval", str(run), "--film-seed", "7", "--summary", str(tmp_path / "s7.json")])
    assert result.exit_code == 1 and "its seeds are 0" in result.output, result.output
    mine = tmp_path / "mine.json"
    mine.write_text("a user's notes\n")
    for target, said in ((run / record.RUN, "was written by fieldgen train, not fieldgen eval"),
                         (mine, "is not a file fieldgen wrote")):
        result = runner.invoke(app, ["eval", str(run), "--summary", str(target), "--no-video"])
        assert result.exit_code == 1 and said in " ".join(result.output.split()), result.output
    assert mine.read_text() == "a user's notes\n" and json.loads((run / record.RUN).read_text())["selfplay"]
    judged = json.loads((run / selfplay.EVALUATION).read_text())
    assert judged["seeds"] == [0] and list(judged["per_seed"]) == ["0"] and "win_vs_random" not in judged
    mine = judged["per_seed"]["0"]
    assert mine["vs_snapshot"]["snapshot"] == 1 and sum(mine["vs_random"].values()) == 8
    assert mine["ratings"] == last["ratings"]
    before = (run / selfplay.EVALUATION).read_bytes()  # 8 matches a seed: a quick look of 2 goes beside it
    result = runner.invoke(app, ["eval", str(run), "--episodes", "2", "--no-video"])
    assert result.exit_code == 0 and json.loads((run / "selfplay_eval_2.json").read_text())["episodes"] == 2
    assert (run / selfplay.EVALUATION).read_bytes() == before, result.output

    # the learner exported as one agent's policy acts as the run's own actor does, on either side's observation
    policy_folder = tmp_path / "policy"
    result = runner.invoke(app, ["export", str(run), "-o", str(policy_folder)])
    assert result.exit_code == 0, result.output
    assert "exported ppo seed 0 at 2,400 env steps (soccer_1v1: 10 observations -> 2 actions, one agent's" in \
        " ".join(result.output.split())  # the console breaks lines where it likes
    opened = selfplay.open_run(run)
    sp, state = opened.algorithm, loop.seed_slice(opened.state, 0)
    obs = jax.random.normal(jax.random.PRNGKey(3), (5, opened.env.observation_size)) * 3
    np.testing.assert_allclose(np.asarray(fieldgen.load_policy(policy_folder)(obs)),
                               np.asarray(sp.act(sp.current(state), obs)), atol=1e-5)

    # a time limit shorter than the first chunk (which compiles) stops after it; the resume ends as the whole run
    limited = tmp_path / "limited"
    result = runner.invoke(app, ["train", "soccer_1v1", "--out", str(limited), "--time-limit", "1", *TINY])
    assert result.exit_code == TIME_LIMIT_STATUS, result.output
    assert "stopped at the time limit after evaluation 1 of 3 (800 of 2,400 env steps)" in result.output
    result = runner.invoke(app, ["train", "--resume", str(limited / "soccer_1v1-ppo-0")])
    assert result.exit_code == 0, result.output
    assert without_timings(record.read_metrics(limited / "soccer_1v1-ppo-0")) == without_timings(rows)


@pytest.mark.slow
def test_a_run_with_an_exploiter_scores_its_games_and_resumes_exactly(tmp_path):
    settings = [*TINY, "--set", "ppo.exploiter_share=0.5", "--set", "ppo.stagger_starts=true"]
    whole, limited = tmp_path / "whole", tmp_path / "limited"
    result = runner.invoke(app, ["train", "soccer_1v1", "--out", str(whole), *settings])
    assert result.exit_code == 0, result.output
    rows = record.read_metrics(whole / "soccer_1v1-ppo-0")
    assert sum(r["exploiter_games"] for r in rows[1:]) > 0 and all(0 <= r["exploiter_score"] <= 1 for r in rows[1:])
    # stopped after its first chunk, the exploiter's state in the checkpoint: the resume ends as the whole run
    result = runner.invoke(app, ["train", "soccer_1v1", "--out", str(limited), "--time-limit", "1", *settings])
    assert result.exit_code == TIME_LIMIT_STATUS, result.output
    result = runner.invoke(app, ["train", "--resume", str(limited / "soccer_1v1-ppo-0")])
    assert result.exit_code == 0, result.output
    assert without_timings(record.read_metrics(limited / "soccer_1v1-ppo-0")) == without_timings(rows)
    assert (limited / "soccer_1v1-ppo-0" / record.CHECKPOINT).read_bytes() == \
        (whole / "soccer_1v1-ppo-0" / record.CHECKPOINT).read_bytes()


@pytest.mark.slow
def test_several_seeds_train_in_one_program_as_each_would_alone(tmp_path, interrupt_after_eval):
    """Seeds 0 and 1 in one run: seed 1 starts exactly as a run of seed 1 alone; its rows match that run's
    (the untrained evaluation to the bit, the first chunk's to float rounding: vmapped matrix products may add
    in another order, which training later amplifies); each seed rated on its own; an exact resume; a time
    limit; and fieldgen eval judging each seed and the seeds together."""
    result = runner.invoke(app, ["train", "soccer_1v1", "--seed", "1", "--no-videos", "--out", str(tmp_path / "alone"),
                                 *TINY])
    assert result.exit_code == 0, result.output
    alone = record.read_metrics(tmp_path / "alone" / "soccer_1v1-ppo-1")
    result = runner.invoke(app, ["train", "soccer_1v1", "--seeds", "2", "--out", str(tmp_path / "both"), *TINY])
    assert result.exit_code == 0, result.output
    run = tmp_path / "both" / "soccer_1v1-ppo-0to1"
    assert json.loads((run / record.RUN).read_text())["seeds"] == [0, 1]
    assert "eval 3/3 at 2,400 env steps, seed 1: vs random" in result.output
    rows = record.read_metrics(run)
    assert [(r["eval"], r["seed"]) for r in rows] == [(i, s) for i in range(4) for s in (0, 1)]
    assert [r["diverged_episodes"] for r in rows if r["eval"]] == [0.0] * 6  # each seed's blown-up episodes
    # one video an evaluation, of the first seed
    assert sorted(p.stem for p in (run / record.VIDEOS).iterdir()) == ["eval_000", "eval_001", "eval_002", "eval_003"]

    opened = selfplay.open_run(run)
    init = selfplay.programs(opened.config, opened.env, len(opened.seeds))[1]
    together, single = init(loop.seed_keys([0, 1])), init(loop.seed_keys([1]))
    for a, b in zip(jax.tree.leaves(loop.seed_slice(together, 1)), jax.tree.leaves(loop.seed_slice(single, 0))):
        np.testing.assert_array_equal(a, b)
    mine = without_timings(selfplay.of_seed(rows, 1))
    alone = without_timings(alone)
    assert mine[0] == alone[0]
    assert mine[1]["league"] == alone[1]["league"] and mine[1].keys() == alone[1].keys()
    figures = [k for k, v in alone[1].items() if isinstance(v, float)]
    np.testing.assert_allclose([mine[1][k] for k in figures], [alone[1][k] for k in figures], rtol=1e-5, atol=1e-7)

    for seed in (0, 1):
        own = selfplay.of_seed(rows, seed)
        assert own[-1]["ratings"] == selfplay.ratings(own, opened.config.elo_k)
        assert set(own[-1]["ratings"]) == {"random", "0", "1", "2", "3"}

    interrupt_after_eval(2)
    result = runner.invoke(app, ["train", "soccer_1v1", "--seeds", "2", "--no-videos", "--out", str(tmp_path / "cut"),
                                 *TINY])
    assert result.exit_code == 130, result.output
    interrupt_after_eval(None)
    resumed = tmp_path / "cut" / "soccer_1v1-ppo-0to1"
    result = runner.invoke(app, ["train", "--resume", str(resumed), "--no-videos"])
    assert result.exit_code == 0, result.output
    assert without_timings(record.read_metrics(resumed)) == without_timings(rows)
    assert (resumed / record.CHECKPOINT).read_bytes() == (run / record.CHECKPOINT).read_bytes()

    limited = tmp_path / "limited"
    result = runner.invoke(app, ["train", "soccer_1v1", "--seeds", "2", "--no-videos", "--out", str(limited),
                                 "--time-limit", "1", *TINY])
    assert result.exit_code == TIME_LIMIT_STATUS, result.output
    assert "stopped at the time limit after evaluation 1 of 3" in result.output
    result = runner.invoke(app, ["train", "--resume", str(limited / "soccer_1v1-ppo-0to1"), "--no-videos"])
    assert result.exit_code == 0, result.output
    assert without_timings(record.read_metrics(limited / "soccer_1v1-ppo-0to1")) == without_timings(rows)

    result = runner.invoke(app, ["eval", str(run), "--no-video"])
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())
    assert "Elo ratings of seed 1" in said and "interquartile mean of the 2 seeds" in said
    judged = json.loads((run / selfplay.EVALUATION).read_text())
    assert judged["seeds"] == [0, 1] and sorted(judged["per_seed"]) == ["0", "1"]
    for seed, one in judged["per_seed"].items():
        assert sum(one["vs_random"].values()) == sum(one["vs_snapshot"][r] for r in selfplay.RESULTS) == 8
        assert one["vs_snapshot"]["snapshot"] == 1 and one["ratings"] == rows[-2 + int(seed)]["ratings"]
    for opponent in ("vs_random", "vs_snapshot"):
        won = judged[f"win_{opponent}"]
        assert won["per_seed"] == {s: one[opponent]["win"] / 8 for s, one in judged["per_seed"].items()}
        assert won["low"] <= won["iqm"] <= won["high"]


def test_commands_of_single_agent_runs_and_an_edited_record_refuse_a_self_play_run_in_one_line(tmp_path):
    """`render --levels` and `videos` read runs of one agent: on a self-play run they name the commands that read
    it; a record whose `selfplay` key was removed, or metrics missing an evaluation between others, are said to be
    edited (each ended in a KeyError or a StopIteration before)."""
    result = runner.invoke(app, ["train", "soccer_1v1", "--prepare", "--out", str(tmp_path), *TINY])
    assert result.exit_code == 0, result.output
    run = tmp_path / "soccer_1v1-ppo-0"
    for command in (["render", str(run), "--levels"], ["videos", str(run)]):
        result = runner.invoke(app, command)
        assert result.exit_code == 1 and "Traceback" not in result.output, result.output
        assert f"{run} is a self-play run on a team field: fieldgen eval, export and view read it" in \
            " ".join(result.output.split())
    result = runner.invoke(app, ["train", "point_soccer", "--out", str(tmp_path / "new"), "--init-from", str(run)])
    assert "it is a self-play run on a team field; start from a run of one agent" in " ".join(result.output.split())
    played = selfplay.TeamRun(run, SelfPlayConfig(league_opponents=2, eval_envs=8), None, [0], [])
    for index in range(3):
        results = {"random": np.asarray([1, 6, 1]), "earlier": np.asarray([[2, 4, 2]] * 2)}
        played.rows.append(selfplay.seed_row(played, index, 0, {}, results, 800 * index))
    record.write_metrics(run, [played.rows[0], played.rows[2]])
    with pytest.raises(record.RunError, match="metrics.jsonl lacks evaluation 1 of seed 0, which a self-play run's"):
        selfplay.open_run(run, load_state=False)
    saved = json.loads((run / record.RUN).read_text())
    (run / record.RUN).write_text(json.dumps({k: v for k, v in saved.items() if k != "selfplay"}))
    for command in (["eval", str(run), "--no-video"], ["export", str(run), "-o", str(tmp_path / "p")]):
        result = runner.invoke(app, command)
        assert result.exit_code == 1 and "Traceback" not in result.output, result.output
        assert "run.json does not say selfplay: true, yet the run's field" in " ".join(result.output.split())
