"""`fieldgen eval` over seeds: every seed of a run of several, or of several runs of one field and
algorithm, in a table and summary.json (the interquartile mean with its bootstrap interval); bad input
refused in one line before anything is written."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import jax
import pytest
from typer.testing import CliRunner

from fieldgen.agents import checkpoint
from fieldgen.cli import app
from fieldgen.run import record, session
from fieldgen.run.summary import SeedSummary, interval, iqm

runner = CliRunner()
WIDE = {"COLUMNS": "200"}  # a table's cells whole on their lines


def said(phrase: str, output: str) -> bool:
    """Whether the output says the phrase, wherever the console broke its lines (long paths, narrow cells)."""
    return "".join(phrase.split()) in "".join(output.split())


@pytest.fixture(scope="module")
def trained(train_point_nav):
    """A tiny CRL run of three seeds on point_nav, the one the file trains."""
    return train_point_nav(3)


def single_seed_run(run_dir: Path, i: int, out: Path) -> Path:
    """A run folder of seed i of `run_dir` alone, as `fieldgen train --seed S` would have written it: the
    same field, config and rows of that seed, and that seed's slice of the checkpoint."""
    saved = json.loads((run_dir / record.RUN).read_text())
    seed = saved["seeds"][i]
    folder = out / f"point_nav-crl-{seed}"
    shutil.copytree(run_dir / session.FIELD, folder / session.FIELD)
    record.write_run(folder, saved["field"], saved["algo"], session.open_run(run_dir, load_state=False).config,
                     saved["observation"], [seed], {"fields": saved["fields"]})
    record.write_metrics(folder, [r for r in record.read_metrics(run_dir) if r["seed"] == seed])
    state = session.open_run(run_dir).state
    (folder / record.CHECKPOINT).write_bytes(checkpoint.to_bytes(jax.tree.map(lambda x: x[i:i + 1], state)))
    return folder


EASY = "extends: point_nav\nname: point_nav_easy\ntask: {success: {kind: agent_near_target, radius: 2.6}}\n"


@pytest.mark.slow
def test_eval_summarizes_every_seed_alike_from_one_run_or_one_run_per_seed(trained, tmp_path):
    """On a field where a barely trained policy succeeds now and then, so that the seeds differ."""
    easy = tmp_path / "easy.yaml"
    easy.write_text(EASY)
    judged = ["--episodes", "8", "--no-video", "--field", str(easy)]
    result = runner.invoke(app, ["eval", str(trained), *judged], env=WIDE)
    assert result.exit_code == 0, result.output
    assert said("IQM (3 seeds)", result.output) and said("interquartile mean of the 3 seeds", result.output)
    written = trained / "summary_point_nav_easy.json"
    assert said(f"summary: {written}", result.output)
    together = SeedSummary.model_validate_json(written.read_text())
    assert together.seeds == [0, 1, 2] and together.episodes == 8 and together.env_steps == dict.fromkeys(range(3), 1760)
    assert together.fields == ["point_nav_easy"] and together.algo == "crl" and together.runs == [str(trained)]
    assert together.command == f"fieldgen eval {trained} --episodes 8 --no-video --field {easy}"
    for metric in (together.success_any, together.time_at_goal):
        values = list(metric.per_seed.values())
        assert metric.iqm == pytest.approx(iqm(values)) and (metric.low, metric.high) == interval(values)
        assert min(values) <= metric.low <= metric.iqm <= metric.high <= max(values)
    assert len(set(together.time_at_goal.per_seed.values())) > 1, together  # the seeds' policies differ
    success = together.success_any
    assert said(f"{success.iqm:.3f} [{success.low:.3f}, {success.high:.3f}]", result.output), result.output
    assert together.actions == "mean"

    # the same episodes' starts with the actions the policies draw in training: recorded, said, and other values
    drawn = runner.invoke(app, ["eval", str(trained), *judged, "--actions", "sampled", "--summary",
                                str(tmp_path / "sampled.json")], env=WIDE)
    assert drawn.exit_code == 0, drawn.output
    assert said("8 episodes per seed, actions sampled from the policy", drawn.output), drawn.output
    sampled = SeedSummary.model_validate_json((tmp_path / "sampled.json").read_text())
    assert sampled.actions == "sampled" and "--actions sampled" in sampled.command
    assert sampled.time_at_goal.per_seed != together.time_at_goal.per_seed

    # each seed's checkpoint in a run of its own, the three evaluated together, one seed per run: the same
    # per-seed values, so the same summary
    singles = [single_seed_run(trained, i, tmp_path) for i in range(3)]
    apart = runner.invoke(app, ["eval", *map(str, singles), *judged], env=WIDE)
    assert apart.exit_code == 0, apart.output
    assert said("3 runs of crl at 1,760 env steps on point_nav_easy", apart.output), apart.output
    alone = SeedSummary.model_validate_json((tmp_path / "summary_point_nav_easy.json").read_text())  # beside them
    assert alone.runs == list(map(str, singles))
    assert alone.success_any == together.success_any and alone.time_at_goal == together.time_at_goal

    one = runner.invoke(app, ["eval", str(singles[1]), *judged, "--summary", str(tmp_path / "one.json")], env=WIDE)
    assert one.exit_code == 0, one.output
    assert said("IQM (one seed)", one.output) and said("one seed: its value", one.output)
    single = SeedSummary.model_validate_json((tmp_path / "one.json").read_text())
    value = together.time_at_goal.per_seed[1]
    assert single.time_at_goal.per_seed == {1: value} and single.time_at_goal.low == single.time_at_goal.high == value
    assert not list(singles[1].glob("summary*.json"))

    # an evaluation reads what the run learned alone (learner.msgpack), not the whole checkpoint: the same
    # summary with the checkpoint unreadable
    whole = (trained / record.CHECKPOINT).read_bytes()
    try:
        (trained / record.CHECKPOINT).write_bytes(b"not read")
        learned = runner.invoke(app, ["eval", str(trained), *judged, "--summary", str(tmp_path / "learned.json")],
                                env=WIDE)
    finally:
        (trained / record.CHECKPOINT).write_bytes(whole)
    assert learned.exit_code == 0, learned.output
    again = SeedSummary.model_validate_json((tmp_path / "learned.json").read_text())
    assert again.success_any == together.success_any and again.time_at_goal == together.time_at_goal


def prepared(out: Path, field: str, *args: str) -> Path:
    """A run folder set up without training (`fieldgen train --prepare`)."""
    result = runner.invoke(app, ["train", field, "--out", str(out), "--prepare", *args])
    assert result.exit_code == 0, result.output
    return next(p for p in out.iterdir() if p.is_dir())


def looks_trained(run: Path) -> Path:
    """The run with a file where its checkpoint goes: checks of what is given together come before any loads."""
    (run / record.CHECKPOINT).write_bytes(b"never read")
    return run


def test_eval_plays_as_many_episodes_as_the_runs_evaluations_did_unless_told(tmp_path, monkeypatch):
    """A run sized for a CPU (`--preset cpu`: 16 evaluation episodes) is judged as quickly by default, and
    on the actions its own evaluations took (its eval_actions) unless --actions says otherwise."""
    from fieldgen.run import evaluate as judging

    cpu = looks_trained(prepared(tmp_path / "a", "point_nav", "--preset", "cpu"))
    drawing = looks_trained(prepared(tmp_path / "b", "point_nav", "--set", "crl.eval_actions=sampled"))
    asked = []

    def evaluate(run, episodes, seed, film, actions):
        asked.append((episodes, actions))
        raise KeyboardInterrupt  # enough: the episodes were asked for

    monkeypatch.setattr(judging, "open_runs", lambda folders, field: [session.open_run(f, load_state=False)
                                                                     for f in folders])
    monkeypatch.setattr(judging, "evaluate", evaluate)
    for run, args, told in ((cpu, [], (16, "mean")), (cpu, ["--episodes", "64"], (64, "mean")),
                            (drawing, [], (128, "sampled")), (drawing, ["--actions", "mean"], (128, "mean"))):
        runner.invoke(app, ["eval", str(run), "--no-video", *args])
        assert asked.pop() == told


def test_film_seed_films_the_run_and_place_that_trained_it(tmp_path, monkeypatch):
    """--film-seed S films seed S's episode, whichever run of several trained it, as eval_seed<S>; a seed no
    run trained is one line naming the seeds there are."""
    from fieldgen.run import evaluate as judging

    first = looks_trained(prepared(tmp_path / "a", "point_nav", "--seed", "1", "--seeds", "2"))
    second = looks_trained(prepared(tmp_path / "b", "point_nav", "--seed", "5"))
    asked = []

    def evaluate(run, episodes, seed, film, actions):
        asked.append((run.seeds, film))
        if len(asked) == 2:
            raise KeyboardInterrupt  # both runs were asked
        return None

    monkeypatch.setattr(judging, "open_runs", lambda folders, field: [session.open_run(f, load_state=False)
                                                                     for f in folders])
    monkeypatch.setattr(judging, "evaluate", evaluate)
    for film_seed, told in (("2", [([1, 2], 1), ([5], None)]), ("5", [([1, 2], None), ([5], 0)])):
        runner.invoke(app, ["eval", str(first), str(second), "--film-seed", film_seed])
        assert [(list(seeds), film) for seeds, film in asked] == told
        asked.clear()
    assert judging.video_path(second, None, 5) == second / "eval_seed5"
    assert judging.video_path(second, "point_soccer", 5) == second / "eval_point_soccer_seed5"
    result = runner.invoke(app, ["eval", str(first), str(second), "--film-seed", "3"])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and message.startswith("error: --film-seed 3: no run evaluated here trained seed "
                                                        "3; its seeds are 1, 2, 5"), result.output
    assert not asked
    result = runner.invoke(app, ["eval", str(first), "--film-seed", "1", "--no-video"])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and "--no-video films none; drop one of them" in message and not asked


def test_bad_evaluations_are_one_line_and_write_nothing(tmp_path):
    untrained = prepared(tmp_path / "a", "point_nav")
    nav = looks_trained(prepared(tmp_path / "b", "point_nav", "--seed", "1"))
    soccer = looks_trained(prepared(tmp_path / "c", "point_soccer", "--seed", "2"))
    other_algo = looks_trained(prepared(tmp_path / "d", "point_nav", "--algo", "td3", "--seed", "3"))
    (tmp_path / "empty").mkdir()
    again = looks_trained(prepared(tmp_path / "e", "point_nav", "--seed", "1"))  # another run of nav's seed
    before = sorted(tmp_path.rglob("*"))
    cases = [
        ([str(tmp_path / "empty")], f"{tmp_path / 'empty'} is not a training run: run.json is missing"),
        ([str(tmp_path / "nowhere")], f"{tmp_path / 'nowhere'} is missing, not a run folder; name the folder "
                                      "fieldgen train wrote"),
        ([str(untrained)], f"{untrained} has no checkpoint: it has not trained yet"),
        ([str(nav), str(untrained)], f"{untrained} has no checkpoint"),
        ([str(nav), str(soccer)], f"{soccer} trained crl on point_soccer, {nav} crl on point_nav: runs evaluated "
                                  "together are seeds of one field and algorithm"),
        ([str(nav), str(other_algo)], f"{other_algo} trained td3 on point_nav, {nav} crl on point_nav"),
        ([str(nav), str(nav)], f"{nav} is named twice: each run's seeds count once in a summary; name it once"),
        ([str(nav), str(again)], f"seed 1 is in both {nav} and {again}: each seed counts once"),
        ([str(nav), "--summary", str(tmp_path / "no" / "s.json")], f"there is no folder {tmp_path / 'no'}"),
        ([str(nav), "--summary", str(tmp_path)], f"--summary {tmp_path} is a folder"),
        ([str(nav), "--summary", str(tmp_path / "s.png")], f"--summary {tmp_path / 's.png'}: fieldgen writes a "
                                                            "summary as JSON; give the file the .json ending"),
        ([str(nav), "--actions", "random"], "unknown actions 'random'. Choose one of: mean, sampled."),
    ]
    for args, phrase in cases:
        result = runner.invoke(app, ["eval", *args, "--no-video"])
        message = " ".join(result.output.split())
        assert result.exit_code == 1 and phrase in message and "Traceback" not in message, result.output
        assert message.startswith("error:") and message.count("error:") == 1
        assert "--resume takes" not in message  # eval's errors speak of what eval was given
    zero = runner.invoke(app, ["eval", str(nav), "--episodes", "0"])
    assert zero.exit_code == 2 and "'0' is not a positive whole count" in " ".join(zero.output.split())
    assert sorted(tmp_path.rglob("*")) == before


def test_a_folder_of_fields_given_as_field_says_which_field_to_name(tmp_path):
    """--field takes one field: a run folder is told apart and pointed at its own copy of its field, a curriculum
    folder at its stages, before any checkpoint loads; a folder that is neither is still told it is no built
    field."""
    root = Path(__file__).resolve().parents[2]
    run = looks_trained(prepared(tmp_path / "runs", "point_nav"))
    curriculum = root / "curricula" / "point_nav_to_far"
    for field, phrase in ((run, f"{run} is a run folder, not a field: --field takes one field (a YAML file, "
                                f"bundled name or build folder); the field that run trained on is its copy "
                                f"{run / session.FIELD}"),
                          (curriculum, f"{curriculum} is a curriculum folder: --field takes one field, such as one "
                                       f"of its stages (a stage's spec or its build folder), e.g. its last stage, "
                                       f"{curriculum / 'stage_04.yaml'}")):
        result = runner.invoke(app, ["eval", str(run), "--field", str(field), "--no-video"])
        message = " ".join(result.output.split())
        assert result.exit_code == 1 and message.startswith(f"error: {phrase}"), result.output
        assert message.count("error:") == 1 and "Traceback" not in message
    assert not list(run.glob("summary*"))
    (tmp_path / "empty").mkdir()
    with pytest.raises(record.RunError, match="empty is not a built field: field.json is missing"):
        session.on_field(session.open_run(run, load_state=False), tmp_path / "empty")


def test_runs_of_two_fields_that_share_a_name_are_not_judged_as_seeds_of_one(tmp_path):
    """A summary pools seeds by their field's digest: the bundled point_nav and a point_nav of your own are
    two fields, whatever their names say."""
    mine = tmp_path / "mine.yaml"
    mine.write_text("extends: point_nav\nname: point_nav\nfield: {length: 12, width: 12}\n")
    bundled = looks_trained(prepared(tmp_path / "a", "point_nav", "--seed", "1"))
    own = looks_trained(prepared(tmp_path / "b", str(mine), "--seed", "2"))
    result = runner.invoke(app, ["eval", str(bundled), str(own), "--no-video", "--summary", str(tmp_path / "s.json")])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and message.startswith(f"error: {own} trained crl on point_nav, {bundled} crl on "
                                                        "point_nav (fields of one name that differ)"), result.output
    assert "Traceback" not in message and not (tmp_path / "s.json").exists()


def test_runs_of_two_algorithms_on_one_field_are_told_the_algorithms_differ_and_a_team_run_goes_alone(tmp_path):
    """Two algorithms on the bundled point_nav differ in their algorithm alone (said, before, to be "fields of one
    name that differ"); a self-play run named beside another, or with --field, is told to be evaluated alone
    (before: "without --field" where none was given)."""
    crl = looks_trained(prepared(tmp_path / "a", "point_nav"))
    ppo = looks_trained(prepared(tmp_path / "b", "point_nav", "--algo", "ppo"))
    message = " ".join(runner.invoke(app, ["eval", str(crl), str(ppo), "--no-video"]).output.split())
    assert message.startswith(f"error: {ppo} trained ppo on point_nav, {crl} crl on point_nav: runs evaluated "
                              "together are seeds of one field and algorithm"), message
    team = prepared(tmp_path / "c", "soccer_1v1")
    message = " ".join(runner.invoke(app, ["eval", str(crl), str(team), "--no-video"]).output.split())
    assert message == (f"error: {team} is a self-play run: it is evaluated alone, in matches on its own field; "
                       f"name it alone (fieldgen eval {team}) and evaluate the other runs without it"), message
    message = " ".join(runner.invoke(app, ["eval", str(team), "--field", "point_nav"]).output.split())
    assert message == f"error: {team} is a self-play run: it is evaluated on its own team field alone; leave out --field"


def test_ctrl_c_says_what_an_evaluation_wrote_and_exits_as_train_does(tmp_path, monkeypatch):
    """Stopped while it evaluates, an evaluation has written nothing; stopped while it draws its video, the
    summary written whole before it is all there is. Either way one line says so, and the status is Ctrl-C's."""
    import numpy as np

    from fieldgen.run import evaluate as judging
    from fieldgen.run.videos import EpisodeRecorder

    run = looks_trained(prepared(tmp_path, "point_nav"))
    before = sorted(tmp_path.rglob("*"))

    def stop(*args):
        raise KeyboardInterrupt

    def evaluated(run, episodes, seed, film, actions):
        metrics = ("success_any", "time_at_goal", "closest_distance", "episode_length", "episode_return")
        return judging.Evaluation({m: np.ones(len(run.seeds)) for m in metrics}, 0, {})

    monkeypatch.setattr(judging, "open_runs", lambda folders, field: [session.open_run(f, load_state=False)
                                                                     for f in folders])
    monkeypatch.setattr(judging, "evaluate", stop)
    result = runner.invoke(app, ["eval", str(run)])
    assert result.exit_code == 130 and said(f"interrupted evaluating {run}; nothing was written", result.output)
    assert "Traceback" not in result.output and "Aborted" not in result.output, result.output
    assert sorted(tmp_path.rglob("*")) == before

    monkeypatch.setattr(judging, "evaluate", evaluated)
    monkeypatch.setattr(EpisodeRecorder, "save", stop)
    result = runner.invoke(app, ["eval", str(run), "--field", "point_nav"])
    written = run / "summary_point_nav.json"
    assert result.exit_code == 130, result.output
    assert said(f"interrupted evaluating {run} on point_nav; {written} was written, the video was not", result.output)
    assert sorted(tmp_path.rglob("*")) == sorted([*before, written])


@pytest.mark.slow
def test_a_run_on_other_physics_alone_is_told_which_field_its_recipe_is_judged_on(train_point_nav, monkeypatch,
                                                                                  tmp_path):
    """As a run of soccer_v2_dense_warp is, whose recipe's figure is judged on soccer_v2_dense (here the run's
    field is taken for such a twin); naming --field says nothing more."""
    from fieldgen.run import recipe

    monkeypatch.setattr(recipe, "physics_twin", lambda spec: "point_nav_mjx" if spec.name == "point_nav" else None)
    run = train_point_nav(2)
    plain = runner.invoke(app, ["eval", str(run), "--episodes", "2", "--no-video", "--summary",
                                str(tmp_path / "plain.json")], env=WIDE)
    assert plain.exit_code == 0, plain.output
    assert said(f"note: point_nav is point_nav_mjx with sim.backend mjx: its evaluations play that physics, and its "
                f"recipe's figure is judged on point_nav_mjx itself: fieldgen eval {run} --episodes 1024 --field "
                "point_nav_mjx", plain.output)
    judged = runner.invoke(app, ["eval", str(run), "--episodes", "2", "--no-video", "--field", "point_nav",
                                 "--summary", str(tmp_path / "judged.json")], env=WIDE)
    assert judged.exit_code == 0, judged.output
    assert "note:" not in judged.output


def test_the_table_says_how_long_an_agent_with_a_torso_lay_turned_over_and_nothing_of_it_for_one_without(
        tmp_path, monkeypatch):
    """`turned_over` comes with the evaluation of an ant (agents.loop.evaluate_policy); the table shows it as a
    column where every run measured it, and leaves the column out where none could."""
    import numpy as np

    from fieldgen.run import evaluate as judging

    run = looks_trained(prepared(tmp_path, "point_nav"))
    shown = {}

    def evaluated(run, episodes, seed, film, actions):
        metrics = ("success_any", "time_at_goal", "closest_distance", "episode_length", "episode_return",
                   *shown["extra"])
        return judging.Evaluation({m: np.full(len(run.seeds), 0.25) for m in metrics}, 0, {})

    monkeypatch.setattr(judging, "open_runs", lambda folders, field: [session.open_run(f, load_state=False)
                                                                     for f in folders])
    monkeypatch.setattr(judging, "evaluate", evaluated)
    for extra, column in (((), False), (("turned_over",), True)):
        shown["extra"] = extra
        result = runner.invoke(app, ["eval", str(run), "--no-video", "--summary", str(tmp_path / f"s{column}.json")])
        assert result.exit_code == 0, result.output
        assert ("turned" in result.output) == column and "0.25" in result.output  # a narrow cell splits its title


def test_a_quick_evaluation_keeps_the_summary_of_more_episodes_and_writes_its_own_beside_it(tmp_path):
    """Filming four episodes after the 1,024-episode figure leaves that figure where it was."""
    from types import SimpleNamespace

    from fieldgen.run import evaluate as judging
    from fieldgen.run import summary

    run = SimpleNamespace(env=SimpleNamespace(spec=SimpleNamespace(name="soccer_v2_dense")))
    folder = tmp_path / "run"
    folder.mkdir()
    assert judging.summary_path([folder], run, False, 4) == (folder / "summary.json", None)  # none there yet
    values = {metric: {0: 0.5, 1: 0.75} for metric in summary.METRICS}
    for name in ("summary.json", "summary_soccer_v2_dense.json"):
        summary.write(summary.summarize(["point_nav"], "ppo", [folder], 1024, {0: 10, 1: 10}, values, "eval"),
                      folder / name)
    assert judging.summary_path([folder], run, False, 4) == (folder / "summary_4.json", folder / "summary.json")
    assert judging.summary_path([folder], run, True, 16) == (folder / "summary_soccer_v2_dense_16.json",
                                                              folder / "summary_soccer_v2_dense.json")
    for as_many_or_more in (1024, 2048):  # a re-evaluation as large replaces it, as before
        assert judging.summary_path([folder], run, False, as_many_or_more) == (folder / "summary.json", None)
    (folder / "summary.json").write_text("{}")  # not a summary of eval's: the writer refuses or replaces it
    assert judging.summary_path([folder], run, False, 4) == (folder / "summary.json", None)
    team = folder / "selfplay_eval.json"  # a self-play run's evaluation records its episodes the same way
    team.write_text(json.dumps({"episodes": 1024, "per_seed": {}}))
    assert judging.kept_beside(team, 8) == (folder / "selfplay_eval_8.json", team)
    assert judging.kept_beside(team, 1024) == (team, None)


def test_a_video_of_the_users_where_eval_films_says_how_to_go_on_without_it(tmp_path):
    """Before: "move it aside or choose another --no-video", as if --no-video named a path."""
    from tiny_runs import as_if_learned

    run = as_if_learned(prepared(tmp_path, "point_nav"))
    (run / "eval.gif").write_bytes(b"a video of mine")
    result = runner.invoke(app, ["eval", str(run), "--episodes", "2", "--video-format", "gif"])
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert said(f"{run / 'eval.gif'} is not a file fieldgen wrote; fieldgen replaces only what it "
                "wrote itself: move it aside or pass --no-video", result.output)
    assert (run / "eval.gif").read_bytes() == b"a video of mine"
