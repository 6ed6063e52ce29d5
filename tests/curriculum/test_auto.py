"""The automatic curriculum: levels made from the spec alone, the sampler's weights, and a run through them."""

from __future__ import annotations

import json
import time

import imageio.v3 as iio
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

from fieldgen.cli import app
from fieldgen.curriculum.auto import (HARDER, Auto, Sampler, counted_success, estimated_success, initial_buffer,
                                     kickoff_tables, learnability, level_weights, levels, next_levels, path)
from fieldgen.curriculum.contract import KICKOFF_BINS, start_sampling
from fieldgen.curriculum.levels import LevelError, LevelSpace
from fieldgen.env import FieldEnv
from fieldgen.curriculum.schedule import sampling_weights
from fieldgen.run import record
from fieldgen.schema import bundled_fields, load_spec

runner = CliRunner()
FIELDS = bundled_fields()
DEFAULT = Sampler()  # the sampler of a run that sets none
TARGET_SHARE, FRONTIER_SHARE, FLOOR = DEFAULT.target_share, DEFAULT.frontier_share, DEFAULT.floor
BUFFER, REPLACED, PRIOR, KEPT = DEFAULT.buffer, DEFAULT.replaced, DEFAULT.prior, DEFAULT.kept


@pytest.mark.parametrize("name", ["soccer_v1", "soccer_v2", "v2_wide_goalie"])
def test_levels_run_from_the_easy_end_to_the_spec_and_all_validate(name):
    spec = load_spec(FIELDS[name])
    made = levels(spec, 8)
    space = LevelSpace.of(spec)
    assert made[0].coordinates == tuple(space.easy) and made[-1].spec == spec
    assert all(space.playable(level.coordinates) for level in made)
    points = np.array([level.coordinates for level in made])
    assert np.all(np.diff(points, axis=0) >= 0)  # each level at least as hard as the one before, on every axis
    distances = [np.hypot(*np.subtract(level.spec.agent.start, spec.target_fixed())) for level in made]
    assert distances[0] < distances[-1]  # the easy end starts nearer the target


def test_the_path_moves_the_kickoff_first_then_the_geometry():
    p = path(3, 5)
    assert p[:, 0].tolist() == [0, 0.5, 1, 1, 1] and p[:, 1].tolist() == p[:, 2].tolist() == [0, 0, 0, 0.5, 1]
    assert path(1, 3)[:, 0].tolist() == [0, 0.5, 1]


def test_unplayable_levels_are_never_used(monkeypatch):
    """A level the schema refuses (its flood fill, a start inside an obstacle) is left out, the spec kept."""
    spec = load_spec(FIELDS["soccer_v2"])
    monkeypatch.setattr(LevelSpace, "playable", lambda self, level: float(level[0]) >= 0.5)
    made = levels(spec, 8)
    assert [level.coordinates[0] >= 0.5 for level in made] == [True] * len(made) and made[-1].spec == spec
    assert len(made) < 8


def test_a_spec_without_an_easy_end_is_one_sentence():
    with pytest.raises(LevelError, match="point_nav: the automatic curriculum moves a ball"):
        levels(load_spec(FIELDS["point_nav"]))
    with pytest.raises(LevelError, match="is a whole number from 2 to 64"):
        levels(load_spec(FIELDS["soccer_v1"]), 1)


def test_weights_keep_the_frontier_and_the_target_fed():
    """Hand-set histories: from nothing learnt the easiest level gets most episodes (the mixed weights give a
    level at success 0 as little as a solved one); the spec always keeps its share; the learnable and the
    frontier gain as levels are solved; the weights are a distribution."""
    start = level_weights(jnp.zeros(5))
    assert float(start[0]) > 0.7 and float(start[-1]) == pytest.approx(TARGET_SHARE)
    assert float(sampling_weights(jnp.zeros(5))[0]) == pytest.approx(0.2)  # the mixed curriculum's, for contrast
    middle = level_weights(jnp.array([0.95, 0.5, 0.1, 0.0, 0.0]))
    assert int(jnp.argmax(middle[:-1])) == 1 and float(middle[-1]) == pytest.approx(TARGET_SHARE)
    assert float(middle[1]) >= (1 - TARGET_SHARE) * FRONTIER_SHARE  # level 2 is the frontier (first below 0.8)
    assert float(middle[3]) < float(middle[2]) < float(middle[1])
    late = level_weights(jnp.array([1.0, 1.0, 0.9, 0.85, 0.4]))
    assert int(jnp.argmax(late[:-1])) == 3  # all solved: the hardest level before the spec is the frontier
    for w in (start, middle, late):
        assert float(jnp.sum(w)) == pytest.approx(1.0, abs=1e-6) and bool(jnp.all(w > 0))
    assert level_weights(jnp.array([0.3])).tolist() == [1.0]  # the spec alone


@pytest.mark.slow
def test_auto_run_records_its_levels_and_weights_and_resumes(tmp_path, monkeypatch):
    """A tiny point_soccer run: every level batched with its kick-off points (run.json), episodes drawn from
    the level buffer, which starts spread from the easy end to the spec and moves; each evaluation's weights
    by level and by kick-off recorded in the metrics; prepared and resumed as any run."""
    sets = ["crl.hidden=[32,32]", "crl.repr_dim=8", "crl.batch_size=64", "crl.unroll_length=25",
            "crl.min_replay_rows=100", "crl.max_replay_rows=400", "crl.num_evals=2", "crl.eval_envs=8"]
    args = ["train", "point_soccer", "--curriculum", "auto", "--levels", "4", "--steps", "4000", "--envs", "8",
            "--no-videos", "--out", str(tmp_path), *[x for s in sets for x in ("--set", s)]]
    prepared = runner.invoke(app, [*args, "--prepare"])
    assert prepared.exit_code == 0, prepared.output
    run = tmp_path / "point_soccer-auto-crl-0"
    early = runner.invoke(app, ["render", str(run), "--levels", "-o", str(tmp_path / "early.png")])
    assert early.exit_code != 0 and "has no evaluation yet" in " ".join(early.output.split())
    assert f"drawallofthemwithfieldgenrender{run}" in "".join(early.output.split())  # wrapped or not
    every = runner.invoke(app, ["render", str(run), "-o", str(tmp_path / "every.png")])
    assert every.exit_code == 0 and "4 built fields" in " ".join(every.output.split()), every.output
    from fieldgen.run.favoured import level_captions

    assert level_captions(run, 4)[1].startswith("kickoff 0.67, ")  # under each level, its place on the axes
    record = json.loads((run / "run.json").read_text())
    assert record["schedule"] == "auto" and record["mixed"] and len(record["levels"]) == 4
    assert record["levels"][0]["kickoff"] == 0.0 and all(v == 1.0 for v in record["levels"][-1].values())
    spec = load_spec(FIELDS["point_soccer"])
    assert record["kickoffs"] == kickoff_tables(spec, levels(spec, 4))
    result = runner.invoke(app, ["train", "--resume", str(run)])
    assert result.exit_code == 0, result.output
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert [r["eval"] for r in rows] == [0, 1, 2]
    coordinates = np.array([[row[0] if row else np.nan for row in level] for level in record["kickoffs"]])
    start = initial_buffer(np.isfinite(coordinates))  # no episode yet: every level but the spec alike
    first = np.where(start, (1 - TARGET_SHARE) / (start.sum() - 1), 0.0)
    first[-1, -1] = TARGET_SHARE
    np.testing.assert_allclose(rows[0]["variants"]["weight"], first.sum(axis=1), atol=1e-6)
    by_kickoff = np.bincount(np.minimum(coordinates[start] * KICKOFF_BINS, KICKOFF_BINS - 1).astype(int),
                             first[start], KICKOFF_BINS)
    np.testing.assert_allclose(rows[0]["variants"]["kickoff_share"], by_kickoff, atol=1e-6)
    for row in rows:
        v = row["variants"]
        assert sum(v["weight"]) == pytest.approx(1.0) and sum(v["kickoff_share"]) == pytest.approx(1.0)
        assert v["weight"][-1] >= TARGET_SHARE - 1e-6
        assert row["last_stage_success_any"] == v["success_any"][-1]
    assert rows[-1]["variants"]["kickoff_share"] != rows[0]["variants"]["kickoff_share"]  # the buffer moved
    assert iio.imread(run / "success.png").shape == (720, 1500, 4)  # six panels, three a row
    from fieldgen import render

    drawn = render.contact_sheet
    titles = []
    monkeypatch.setattr(render, "contact_sheet", lambda images, names: titles.extend(names) or drawn(images, names))
    sheet = runner.invoke(app, ["render", str(run), "--levels"])  # into the run's folder by default
    assert sheet.exit_code == 0, sheet.output
    assert "most played of 4 levels after evaluation 2" in " ".join(sheet.output.split())
    assert iio.imread(run / "levels.png").ndim == 3
    assert len(titles) == 4 and all(t.startswith(("level ", "the field itself")) for t in titles), titles
    from fieldgen.run import favoured, session

    buffer = favoured.level_buffer(session.open_run(run, load_state=False))  # learner.msgpack's sampling
    assert sum(b.share for b in buffer) == pytest.approx(1.0) and all(b.seed == 0 for b in buffer)
    assert buffer[-1].level == 3 and buffer[-1].kickoff[1] == 1.0 and buffer[-1].share >= TARGET_SHARE - 1e-6
    assert all(0 <= b.kickoff[0] <= b.kickoff[1] <= 1 and 0 < b.success[0] <= b.success[1] < 1 for b in buffer)
    lines = [line.strip() for line in sheet.output.splitlines() if line.startswith("  seed 0, ")]
    assert lines == [b.text(4) for b in buffer]  # one line a level of the buffer, unwrapped
    assert any("played at kick-off" in t for t in titles)


@pytest.mark.parametrize(("extra", "says"), [
    (["--mixed"], "--curriculum auto makes its own levels from one field"),
    (["--levels", "3"], "add --curriculum auto"),
    (["--sampler", "replaced=8"], "--sampler sets how --curriculum auto draws its levels; add --curriculum auto"),
    (["--curriculum", "manual"], "unknown curriculum 'manual'"),
])
def test_auto_bad_input_is_one_line(tmp_path, extra, says):
    base = ["train", "point_soccer", "--out", str(tmp_path)]
    result = runner.invoke(app, [*base, *(["--curriculum", "auto"] if extra == ["--mixed"] else []), *extra])
    assert result.exit_code != 0 and says in " ".join(result.output.split()), result.output
    assert "Traceback" not in result.output and not any(tmp_path.iterdir())


def test_auto_on_a_curriculum_folder_or_a_field_without_an_easy_end(tmp_path):
    made = runner.invoke(app, ["curriculum", "point_nav", "-o", str(tmp_path / "ring"),
                               "--stage", "task.target.radius=1", "--stage", "task.target.radius=3"])
    assert made.exit_code == 0, made.output
    folder = runner.invoke(app, ["train", str(tmp_path / "ring"), "--curriculum", "auto", "--out", str(tmp_path / "r")])
    assert folder.exit_code != 0 and "not the curriculum folder" in " ".join(folder.output.split())
    plain = runner.invoke(app, ["train", "point_nav", "--curriculum", "auto", "--out", str(tmp_path / "r")])
    assert plain.exit_code != 0 and "no such ball or target" in " ".join(plain.output.split()), plain.output


def test_levels_of_a_run_of_one_stage_is_one_sentence(tmp_path):
    prepared = runner.invoke(app, ["train", "point_nav", "--steps", "20000", "--envs", "8", "--prepare", "--out",
                                   str(tmp_path)])
    assert prepared.exit_code == 0, prepared.output
    result = runner.invoke(app, ["render", str(tmp_path / "point_nav-crl-0"), "--levels", "-o", str(tmp_path / "l.png")])
    assert result.exit_code != 0 and "trains one stage at a time" in " ".join(result.output.split()), result.output
    assert not (tmp_path / "l.png").exists()


def test_levels_are_drawn_only_over_shares_and_success_that_can_be_what_they_claim(tmp_path):
    """`render --levels` reads the last evaluation's weights and success: a success of 7.5 is a damaged file,
    refused at its line; a level no evaluation episode played (NaN) is said to be unmeasured, not drawn as nan."""
    prepared = runner.invoke(app, ["train", "point_soccer", "--curriculum", "auto", "--levels", "3", "--steps", "20000",
                                   "--envs", "8", "--prepare", "--out", str(tmp_path)])
    assert prepared.exit_code == 0, prepared.output
    run = next(p for p in tmp_path.iterdir() if p.is_dir())
    count = len(json.loads((run / record.RUN).read_text())["fields"])

    def last_row(success: list) -> None:
        row = {"eval": 1, "seed": 0, "env_steps": 800, "success_any": 0.5, "time_at_goal": 1.0,
               "variants": {"success_any": success, "weight": [1 / count] * count}}
        (run / record.METRICS).write_text(json.dumps(row) + "\n")

    last_row([7.5] + [0.5] * (count - 1))
    bad = runner.invoke(app, ["render", str(run), "--levels", "-o", str(tmp_path / "bad.png")])
    message = " ".join(bad.output.split())
    assert bad.exit_code == 1 and "metrics.jsonl:1 is not a metrics row (variants.success_any is 7.5, outside its " \
                                  "range (from 0 to 1))" in message and "Traceback" not in message, bad.output
    assert not (tmp_path / "bad.png").exists()
    last_row([float("nan")] + [0.5] * (count - 1))
    drawn = runner.invoke(app, ["render", str(run), "--levels", "-o", str(tmp_path / "ok.png")])
    assert drawn.exit_code == 0 and (tmp_path / "ok.png").is_file(), drawn.output


def test_a_run_whose_schedule_or_levels_results_were_edited_is_refused_where_it_is_read(tmp_path):
    """Before: an automatic curriculum's rows without their levels' results, or its run.json edited to another
    schedule, were read on until a plot or table failed with a KeyError traceback."""
    prepared = runner.invoke(app, ["train", "point_soccer", "--curriculum", "auto", "--levels", "3", "--steps", "20000",
                                   "--envs", "8", "--prepare", "--out", str(tmp_path)])
    assert prepared.exit_code == 0, prepared.output
    run = next(p for p in tmp_path.iterdir() if p.is_dir())
    count = len(json.loads((run / record.RUN).read_text())["fields"])
    row = {"eval": 1, "seed": 0, "env_steps": 800, "success_any": 0.5, "time_at_goal": 1.0,
           "variants": {"success_any": [0.5] * count, "weight": [1 / count] * count}}
    cases = [({k: v for k, v in row.items() if k != "variants"}, {}, f"lack the {count} levels' weights and success"),
             ({**row, "variants": {"success_any": [0.5], "weight": [1.0]}}, {}, "lack the"),
             (row, {"schedule": "staged"}, "hold levels' results (variants), where")]
    for metrics, changes, phrase in cases:
        (run / record.METRICS).write_text(json.dumps(metrics) + "\n")
        saved = json.loads((run / record.RUN).read_text())
        (run / record.RUN).write_text(json.dumps({**saved, **changes}))
        for args in (["render", str(run), "--levels", "-o", str(tmp_path / "l.png")], ["train", "--resume", str(run)]):
            result = runner.invoke(app, args)
            message = " ".join(result.output.split())
            assert result.exit_code == 1 and "Traceback" not in message, result.output
            assert f"{run / record.METRICS}: the rows of evaluation 1 {phrase}" in message, message
        (run / record.RUN).write_text(json.dumps(saved))
    assert not (tmp_path / "l.png").exists()


def test_a_run_json_whose_level_coordinates_were_edited_is_refused_where_render_levels_reads_them(tmp_path):
    """render --levels titles each level with its coordinates from run.json: a level left out, or a coordinate
    edited to text, ended in an IndexError or a format traceback."""
    prepared = runner.invoke(app, ["train", "point_soccer", "--curriculum", "auto", "--levels", "3", "--steps", "20000",
                                   "--envs", "8", "--prepare", "--out", str(tmp_path)])
    assert prepared.exit_code == 0, prepared.output
    run = next(p for p in tmp_path.iterdir() if p.is_dir())
    saved = json.loads((run / record.RUN).read_text())
    count = len(saved["fields"])
    row = {"eval": 1, "seed": 0, "env_steps": 800, "success_any": 0.5, "time_at_goal": 1.0,
           "variants": {"success_any": [0.5] * count, "weight": [1 / count] * count}}
    (run / record.METRICS).write_text(json.dumps(row) + "\n")
    axis = next(iter(saved["levels"][0]))
    for levels, phrase in ((saved["levels"][1:], f"holds the coordinates of {count - 1} levels, and the run has "
                                                 f"{count}"),
                           ([{axis: "far"}, *saved["levels"][1:]], f"levels.0.{axis} should be a valid number")):
        (run / record.RUN).write_text(json.dumps({**saved, "levels": levels}))
        result = runner.invoke(app, ["render", str(run), "--levels", "-o", str(tmp_path / "l.png")])
        message = " ".join(result.output.split())
        assert result.exit_code == 1 and "Traceback" not in message and phrase in message, result.output
        assert message.startswith(f"error: {run / record.RUN}")
    assert not (tmp_path / "l.png").exists()


@pytest.mark.slow
def test_an_auto_run_killed_and_resumed_continues_its_levels_exactly(tmp_path, interrupt_after_eval, monkeypatch):
    """The level buffer's sampling (its weights and counts) is checkpointed beside the training state, so a run
    stopped after an evaluation and resumed weighs, counts and mutates its levels exactly as the run never
    stopped; so does one whose checkpoint was written before, when the counts lay in its environments' state."""
    import shutil

    from fieldgen.agents import checkpoint, programs
    from fieldgen.files import write_atomic
    from fieldgen.run import session

    running = programs.under_way

    def settled() -> bool:
        """The next chunk, dispatched before the evaluation's metrics were written, ends first: the stop then
        leaves `fieldgen train` as a wait would, rather than by os._exit, which would end the test's process."""
        while running():
            time.sleep(0.05)
        return False

    monkeypatch.setattr(programs, "under_way", settled)
    sets = ["crl.hidden=[32,32]", "crl.repr_dim=8", "crl.batch_size=64", "crl.unroll_length=25",
            "crl.min_replay_rows=100", "crl.max_replay_rows=400", "crl.num_evals=3", "crl.eval_envs=8"]
    args = ["train", "point_soccer", "--curriculum", "auto", "--levels", "3", "--steps", "5000", "--envs", "8",
            "--no-videos", *[x for s in sets for x in ("--set", s)]]
    whole = runner.invoke(app, [*args, "--out", str(tmp_path / "whole")])
    assert whole.exit_code == 0, whole.output
    interrupt_after_eval(1)
    assert runner.invoke(app, [*args, "--out", str(tmp_path / "cut")]).exit_code == 130
    interrupt_after_eval(None)
    cut = tmp_path / "cut" / "point_soccer-auto-crl-0"
    older = tmp_path / "older" / cut.name
    shutil.copytree(cut, older)
    opened = session.open_run(older)
    info = opened.state.env_state.info  # as checkpoints were: the counts in the first environment's state
    counts = np.array(info["level_counts"])
    assert not counts.any()  # each environment's tally starts again at every re-weighing
    counts[:, 0] = opened.sampling["level_counts"]
    state = opened.state.replace(env_state=opened.state.env_state.replace(info=dict(info, level_counts=counts)))
    write_atomic(older / record.CHECKPOINT, checkpoint.pieces(state))
    assert session.open_run(older).sampling is None
    for folder in (cut, older):
        resumed = runner.invoke(app, ["train", "--resume", str(folder)])
        assert resumed.exit_code == 0, resumed.output

    def rows(folder):
        return [{k: v for k, v in json.loads(line).items() if k not in record.TIMINGS}
                for line in (folder / "metrics.jsonl").read_text().splitlines()]

    assert rows(cut) == rows(tmp_path / "whole" / "point_soccer-auto-crl-0") == rows(older)
    shares = [row["variants"]["kickoff_share"] for row in rows(cut)]
    assert shares[-1] != shares[1]  # the buffer moved after the cut


@pytest.mark.slow
def test_how_an_auto_run_is_evaluated_changes_nothing_it_trains_on(tmp_path):
    """The level buffer follows the training episodes and evaluations draw from their own random stream, so
    more evaluation episodes (firmer in-run figures) or the policy's drawn actions leave what is learnt, and
    the levels played, exactly as they were."""
    sets = ["crl.hidden=[32,32]", "crl.repr_dim=8", "crl.batch_size=64", "crl.unroll_length=25",
            "crl.min_replay_rows=100", "crl.max_replay_rows=400", "crl.num_evals=2"]
    args = ["train", "point_soccer", "--curriculum", "auto", "--levels", "3", "--steps", "4000", "--envs", "8",
            "--no-videos", *[x for s in sets for x in ("--set", s)]]
    for name, evaluated in (("few", ["crl.eval_envs=6"]), ("many", ["crl.eval_envs=24", "crl.eval_actions=sampled"])):
        done = runner.invoke(app, [*args, "--out", str(tmp_path / name), *[x for s in evaluated for x in ("--set", s)]])
        assert done.exit_code == 0, done.output
    few, many = (tmp_path / name / "point_soccer-auto-crl-0" for name in ("few", "many"))
    assert (few / "learner.msgpack").read_bytes() == (many / "learner.msgpack").read_bytes()

    def trained(folder):
        return [(row.get("actor_loss"), row.get("critic_loss"), row["variants"]["weight"])
                for row in map(json.loads, (folder / "metrics.jsonl").read_text().splitlines())]

    assert trained(few) == trained(many)


@pytest.mark.slow
def test_an_auto_run_copied_without_its_checkpoint_draws_its_levels_as_it_did(tmp_path, interrupt_after_eval,
                                                                             monkeypatch):
    """learner.msgpack keeps how the run drew its episodes (the level buffer's weights and counts) after what
    it learned, so a run moved without its gigabytes of checkpoint goes on with its curriculum where it was,
    its replay buffer alone filled anew, instead of spreading its episodes from the easy end again."""
    from fieldgen.agents import checkpoint, loop, programs
    from fieldgen.run import session, train

    running = programs.under_way

    def settled() -> bool:  # as above: the stop leaves `fieldgen train` as a wait would
        while running():
            time.sleep(0.05)
        return False

    monkeypatch.setattr(programs, "under_way", settled)
    monkeypatch.setattr(train, "skip_checkpoint", lambda *args: False)  # checkpoint and learner of one evaluation
    sets = ["crl.hidden=[32,32]", "crl.repr_dim=8", "crl.batch_size=64", "crl.unroll_length=25",
            "crl.min_replay_rows=100", "crl.max_replay_rows=400", "crl.num_evals=3", "crl.eval_envs=8"]
    args = ["train", "point_soccer", "--curriculum", "auto", "--levels", "3", "--steps", "5000", "--envs", "8",
            "--no-videos", "--seeds", "2", "--out", str(tmp_path), *[x for s in sets for x in ("--set", s)]]
    interrupt_after_eval(2)
    assert runner.invoke(app, args).exit_code == 130
    interrupt_after_eval(None)
    run = tmp_path / "point_soccer-auto-crl-0to1"
    whole = session.open_run(run)
    drawn = whole.sampling  # kept beside the whole state in its checkpoint
    assert set(drawn) == {"level_weights", "level_counts"} and float(np.sum(drawn["level_counts"])) > 0
    for name, kept in start_sampling(whole.state.env_state).items():  # its environments draw as it says
        np.testing.assert_array_equal(kept, drawn[name] if name == "level_weights" else 0 * drawn[name])
    (run / record.CHECKPOINT).unlink()
    moved = session.open_run(run)
    assert moved.refills and set(moved.sampling) == set(drawn)
    for name in drawn:
        np.testing.assert_array_equal(moved.sampling[name], drawn[name])
    for i, seed in enumerate(moved.seeds):  # the weights its last evaluation recorded
        row = [r for r in moved.rows if r["seed"] == seed][-1]
        np.testing.assert_allclose(drawn["level_weights"][i].sum(-1), row["variants"]["weight"], atol=1e-6)

    put = []
    drawing_as = loop.drawing_as
    monkeypatch.setattr(loop, "drawing_as", lambda *a: put.append(drawing_as(*a)) or put[-1])
    resumed = runner.invoke(app, ["train", "--resume", str(run)])
    assert resumed.exit_code == 0, resumed.output
    assert "its episodes drawn as they were" in " ".join(resumed.output.split())
    assert len(put) == 1
    np.testing.assert_allclose(start_sampling(put[0].env_state)["level_weights"], drawn["level_weights"], rtol=1e-6)
    assert json.loads((run / "metrics.jsonl").read_text().splitlines()[-1])["eval"] == 3
    _, sampling = checkpoint.load(run / record.LEARNER, *session.learner_template(moved))
    assert set(sampling) == set(drawn)  # the resumed run's learner keeps it too


# -- kick-off points and the level buffer ------------------------------------------------------------------

def test_kickoff_points_cover_the_kickoff_once_and_refused_ones_are_marked():
    """Each level's points move its kick-off alone, up to its own (the last point, the level itself): a level of
    the geometry before it over the stretch beyond that level's own, a level of new geometry from the easy end's
    kick-off; no start belongs to two levels; a point whose spec the schema refuses is None, every other one
    validates."""
    spec = load_spec(FIELDS["soccer_v2"])
    made = levels(spec, 6)
    space = LevelSpace.of(spec)
    tables = kickoff_tables(spec, made, 9)
    assert [len(t) for t in tables] == [9] * 6
    starts = set()
    for i, (level, table) in enumerate(zip(made, tables)):
        own = level.spec
        assert table[-1] == [level.coordinates[0], own.ball.spawn.x[0], own.ball.spawn.y[0], own.ball.spawn.x[1],
                             own.ball.spawn.y[1], *own.agent.start]
        before = made[i - 1].coordinates if i else None
        banded = before is not None and before[1:] == level.coordinates[1:]
        for j, row in enumerate(table):
            kickoff = before[0] + (level.coordinates[0] - before[0]) * (j + 1) / 9 if banded \
                else level.coordinates[0] * j / 8
            point = (kickoff, *level.coordinates[1:])
            if i == 0 and j < 8:
                assert row is None  # the easy end is its own point alone
                continue
            assert (row is not None) == space.playable(point)
            if row is not None:
                at = space.spec_at(point)
                assert row == pytest.approx([point[0], at.ball.spawn.x[0], at.ball.spawn.y[0], at.ball.spawn.x[1],
                                             at.ball.spawn.y[1], *at.agent.start])
                start = (*level.coordinates[1:], *row[1:])
                assert start not in starts  # no start counted as two levels
                starts.add(start)
        if banded:
            assert all(row is None or row[0] > before[0] for row in table)
    assert [row[0] for row in tables[-2] if row is not None][0] == 0.0  # new geometry: from the easy end's kick-off
    assert any(row is None for row in tables[-1])  # the full goalie leaves no room for some kick-offs
    with pytest.raises(LevelError, match="at least 2"):
        kickoff_tables(spec, made, 1)


def own_kickoffs(playable: np.ndarray) -> jnp.ndarray:
    """The weights an environment starts with: each level from its own kick-off, evenly."""
    return jnp.zeros(playable.shape).at[:, -1].set(1.0 / playable.shape[0])


def test_buffer_levels_stay_inside_the_grid_on_playable_points_and_mutate_harder():
    """Over many evaluations with random outcomes: no weight ever on a refused point, the spec always at its
    share; the buffer starts spread over each level's playable points, then each evaluation swaps at most
    REPLACED levels, each new one a harder neighbour (HARDER) of a level it held."""
    rng = np.random.default_rng(0)
    playable = rng.random((6, 12)) > 0.3
    playable[:, -1] = True
    weights = own_kickoffs(playable)
    start = initial_buffer(playable)
    assert start.sum() <= BUFFER and np.all(start[:, -1]) and not np.any(start & ~playable)
    assert all(row.sum() == min(BUFFER // 6, ok.sum()) for row, ok in zip(start, playable))
    swapped = 0
    for i in range(10):
        before = np.asarray(weights) > 0
        counts = jnp.asarray(rng.integers(0, 20, (2, 6, 12)), jnp.float32)
        counts = counts.at[1].set(jnp.minimum(counts[0], counts[1]))
        weights, keep = next_levels(counts, weights, playable, jax.random.PRNGKey(i))
        member = np.asarray(weights) > 0
        assert not np.any(member & ~playable) and member[-1, -1]
        assert float(weights[-1, -1]) == pytest.approx(TARGET_SHARE) and float(jnp.sum(weights)) == pytest.approx(1.0)
        assert np.all(np.asarray(keep) == np.where(member, KEPT, 0.0))
        if i == 0:
            assert np.array_equal(member, start)
            continue
        added, removed = np.argwhere(member & ~before), np.argwhere(before & ~member)
        assert len(added) == len(removed) <= REPLACED
        for level, point in added:  # moves in reading order: past a level's last point, the next level's first
            parents = [level * 12 + point - dl * 12 - dp for dl, dp in HARDER]
            assert any(before.ravel()[f] for f in parents if 0 <= f < 6 * 12)
        swapped += len(added)
    assert swapped > 9


def test_buffer_weights_on_hand_set_counts():
    """Success estimated from PRIOR and the counts; the spec keeps TARGET_SHARE, every other level FLOOR
    evenly and the rest by p(1 - p): most to the level at one success in two and to levels not yet played."""
    playable = np.ones((2, 4), bool)
    weights = jnp.full((2, 4), 1 / 8)  # a full buffer: every level of the grid
    episodes = jnp.array([[10.0, 10, 10, 0], [0, 0, 0, 30]])
    successes = jnp.array([[10.0, 5, 0, 0], [0, 0, 0, 3]])
    new, keep = next_levels(jnp.stack([episodes, successes]), weights, playable, jax.random.PRNGKey(0))
    p = (np.asarray(successes) + PRIOR / 2) / (np.asarray(episodes) + PRIOR)
    score = (p * (1 - p)).ravel()[:-1]
    expected = (1 - TARGET_SHARE) * (FLOOR / 7 + (1 - FLOOR) * score / score.sum())
    np.testing.assert_allclose(np.asarray(new).ravel(), [*expected, TARGET_SHARE], rtol=1e-5)
    assert float(new[0, 1]) > float(new[0, 0]) and float(new[0, 1]) > float(new[0, 2])
    assert float(new[1, 0]) == pytest.approx(float(new[0, 1]))  # unplayed: the prior's p = 0.5
    assert np.all(np.asarray(keep) == KEPT)


def test_a_sampler_of_its_own_shares_and_replaces_as_it_says():
    """The same counts as above under other settings: the spec's share, the floor, the prior and the share
    kept are the sampler's; a buffer of 16 starts with 16 // levels points a level and swaps up to `replaced`."""
    mine = Sampler(target_share=0.4, floor=0.1, prior=4.0, kept=0.25, buffer=16, replaced=8, sharpness=2.0)
    playable = np.ones((2, 4), bool)
    episodes = jnp.array([[10.0, 10, 10, 0], [0, 0, 0, 30]])
    successes = jnp.array([[10.0, 5, 0, 0], [0, 0, 0, 3]])
    new, keep = next_levels(jnp.stack([episodes, successes]), jnp.full((2, 4), 1 / 8), playable,
                            jax.random.PRNGKey(0), mine)
    p = (np.asarray(successes) + 2.0) / (np.asarray(episodes) + 4.0)
    score = (p * (1 - p)).ravel()[:-1]
    expected = 0.6 * (0.1 / 7 + 0.9 * score ** 2 / (score ** 2).sum())
    np.testing.assert_allclose(np.asarray(new).ravel(), [*expected, 0.4], rtol=1e-5)
    assert np.all(np.asarray(keep) == 0.25)
    grid = np.ones((4, 32), bool)
    start = initial_buffer(grid, mine.buffer)
    assert start.sum() == 16 and all(row.sum() == 4 for row in start)
    weights, _ = next_levels(jnp.zeros((2, 4, 32)), jnp.zeros((4, 32)).at[:, -1].set(0.25), grid,
                             jax.random.PRNGKey(1), mine)
    before = np.asarray(weights) > 0
    counts = jnp.zeros((2, 4, 32)).at[:, :, :].set(jnp.where(jnp.asarray(before), 10.0, 0.0))  # all solved
    weights, _ = next_levels(counts, weights, grid, jax.random.PRNGKey(2), mine)
    after = np.asarray(weights) > 0
    assert after.sum() == before.sum() and 4 < np.sum(after & ~before) <= 8  # more than the default's 4 swapped
    assert level_weights(jnp.zeros(3), mine)[-1] == pytest.approx(0.4)
    even = next_levels(jnp.stack([episodes, successes]), jnp.full((2, 4), 1 / 8), playable, jax.random.PRNGKey(0),
                       Sampler(sharpness=0.0))[0]
    np.testing.assert_allclose(np.asarray(even).ravel()[:-1], 0.8 / 7, rtol=1e-5)  # every level alike


def test_ahead_grows_a_levels_learnability_with_its_place_along_the_path():
    """`ahead` multiplies p (1 - p) by 1 + ahead x place (0 the easy end, 1 the spec): the episodes follow it, and
    of two levels one replacement apart, the easier at success 0.5 gives way before the harder at 0.2; at 0 the
    shares are p (1 - p)'s as before."""
    playable = np.ones((2, 4), bool)
    episodes = jnp.array([[10.0, 10, 10, 0], [0, 0, 0, 30]])
    successes = jnp.array([[10.0, 5, 0, 0], [0, 0, 0, 3]])
    p = (np.asarray(successes) + PRIOR / 2) / (np.asarray(episodes) + PRIOR)
    place = np.arange(8) / 7
    for ahead in (0.0, 2.0):
        new, _ = next_levels(jnp.stack([episodes, successes]), jnp.full((2, 4), 1 / 8), playable,
                             jax.random.PRNGKey(0), Sampler(ahead=ahead))
        score = (p.ravel() * (1 - p.ravel()) * (1 + ahead * place))[:-1]
        expected = (1 - TARGET_SHARE) * (FLOOR / 7 + (1 - FLOOR) * score / score.sum())
        np.testing.assert_allclose(np.asarray(new).ravel(), [*expected, TARGET_SHARE], rtol=1e-5)
    # a buffer of an easy level at success 0.5 and a hard one at 0.2 (each with its neighbour to mutate into):
    # the replacement takes the easy one out by p (1 - p), the hard one with ahead 2
    grid = np.ones((4, 8), bool)
    held = jnp.zeros((4, 8)).at[0, 2].set(0.1).at[2, 5].set(0.1).at[3, 7].set(0.2).at[1, 0].set(0.1)
    counts = jnp.zeros((2, 4, 8)).at[0, 0, 2].set(100).at[1, 0, 2].set(50).at[0, 2, 5].set(100).at[1, 2, 5].set(20)
    counts = counts.at[0, 1, 0].set(100).at[1, 1, 0].set(40)  # a third level, the most learnable: the parent
    kept = {}
    for ahead in (0.0, 2.0):
        weights, _ = next_levels(counts, held, grid, jax.random.PRNGKey(3), Sampler(replaced=1, buffer=4, ahead=ahead))
        member = np.asarray(weights) > 0
        kept[ahead] = (bool(member[0, 2]), bool(member[2, 5]))
    assert kept == {0.0: (True, False), 2.0: (False, True)}
    ahead_, plain = (level_weights(jnp.array([0.5, 0.2, 0.0]), s) for s in (Sampler(ahead=2.0), DEFAULT))
    assert ahead_[1] / ahead_[0] > plain[1] / plain[0]  # levels without kick-off points alike: the harder gains


def test_ahead_from_grows_only_the_levels_that_already_succeed():
    """With `ahead_from`, a level the sampler estimates below it scores p (1 - p) alone: of levels all near 0 the
    harder are not rated up by place (what `ahead` alone does before anything is learned); a level at or above
    it is grown as with `ahead`."""
    p = jnp.array([0.02, 0.02, 0.3, 0.3])
    place = jnp.array([0.0, 1.0, 0.0, 1.0])
    grown = learnability(p, place, Sampler(ahead=2.0))
    gated = learnability(p, place, Sampler(ahead=2.0, ahead_from=0.1))
    plain = np.asarray(p * (1 - p))
    np.testing.assert_allclose(np.asarray(gated), [plain[0], plain[1], plain[2], plain[3] * 3], rtol=1e-6)
    assert grown[1] > grown[0] and gated[1] == gated[0]  # near 0: ranked by place only without the gate
    np.testing.assert_allclose(np.asarray(gated)[2:], np.asarray(grown)[2:], rtol=1e-6)


def test_ahead_from_grows_no_level_on_the_prior_alone():
    """Before: a level with no episode counted sat at the prior's 0.5, above any `ahead_from`, so the first
    evaluations (whose episodes, drawn before the buffer, had not ended on most of its kick-offs) grew every
    level as `ahead` alone does. A level is now grown only by what its counted episodes show; without
    `ahead_from` nothing changes."""
    playable = np.ones((2, 4), bool)
    unplayed = jnp.zeros((2, 2, 4))
    # two episodes lost on each of the easier level's kick-offs (estimated with the prior at 0.25, above the gate:
    # grown before), ten on each of the harder's with three won
    played = unplayed.at[0, 0].set(2.0).at[0, 1].set(10.0).at[1, 1].set(3.0)

    def weights(counts, **setting):
        return np.asarray(next_levels(counts, jnp.full((2, 4), 1 / 8), playable, jax.random.PRNGKey(0),
                                      Sampler(**setting))[0])

    np.testing.assert_allclose(weights(unplayed, ahead=2.0, ahead_from=0.1), weights(unplayed), rtol=1e-6)
    assert weights(unplayed, ahead=2.0, ahead_from=0.0)[1, 2] > weights(unplayed)[1, 2]  # no gate: the harder grown
    p, place = estimated_success(played, PRIOR).ravel(), jnp.arange(8) / 7
    gated = learnability(p, place, Sampler(ahead=2.0, ahead_from=0.1), counted_success(played).ravel())
    np.testing.assert_allclose(np.asarray(gated), p * (1 - p) * (1 + 2.0 * place * (np.arange(8) >= 4)), rtol=1e-6)


@pytest.mark.parametrize(("setting", "says"), [
    ("replaced=-1", "--sampler replaced=-1: replaced must be at least 0 (of the buffer's levels, replaced after"),
    ("repalced=8", "unknown key 'repalced'; did you mean 'replaced'?"),
    ("nope=1", "--sampler nope=1: unknown key 'nope'. Keys: target_share, "),  # with no near key, a sentence ends
    ("floor=0.8", "floor 0.8 and frontier_share 0.3 together pass 1"),
    ("hardest_share=0.99", "floor 0.05 and hardest_share 0.99 together pass 1"),
    ("target_share", "write KEY=VALUE, e.g. --sampler replaced=8"),
    ("target_share=half", "--sampler target_share='half': target_share must be a number (of new episodes, on the "
                          "spec itself)"),
    ("target_share=1", "--sampler target_share=1: target_share must be less than 1.0 (of new episodes"),
    # before: NaN said "must be at most 1000.0", and true was taken as 1 (a prior) or said to be below 2 (a buffer)
    ("prior=nan", "--sampler prior='nan': prior must be a finite number (episodes at success 0.5"),
    ("prior=-1e999", "--sampler prior='-1e999': prior must be greater than 0 (episodes at success 0.5"),
    ("prior=true", "--sampler prior=true: prior must be a number (episodes at success 0.5"),
    ("buffer=true", "--sampler buffer=true: buffer must be a whole number (entries episodes are drawn from"),
    ("ahead=-1", "--sampler ahead=-1: ahead must be at least 0.0 (a level's learnability grows by this much"),
    ("ahead_from=1", "--sampler ahead_from=1: ahead_from must be less than 1.0 (`ahead` grows only the levels"),
])
def test_a_bad_sampler_setting_is_one_line(tmp_path, setting, says):
    result = runner.invoke(app, ["train", "point_soccer", "--curriculum", "auto", "--sampler", setting,
                                 "--out", str(tmp_path), "--prepare"])  # a setting taken trains nothing
    assert result.exit_code != 0 and says in " ".join(result.output.split()), result.output
    assert "Traceback" not in result.output and not any(tmp_path.iterdir())


def test_a_runs_sampler_is_kept_in_run_json_and_resumed_with(tmp_path):
    """--sampler's settings go into run.json with the defaults of the rest; the run opens with them; a run
    that records none (set up before they were kept) opens with the defaults; a damaged one is one line;
    --resume cannot change them."""
    from fieldgen.run import session

    made = runner.invoke(app, ["train", "point_soccer", "--curriculum", "auto", "--levels", "3", "--steps", "20k",
                               "--envs", "8", "--sampler", "replaced=8", "--sampler", "prior=4", "--prepare",
                               "--out", str(tmp_path)])
    assert made.exit_code == 0, made.output
    run = tmp_path / "point_soccer-auto-crl-0"
    saved = json.loads((run / "run.json").read_text())
    assert saved["sampler"] == {**DEFAULT.model_dump(), "replaced": 8, "prior": 4.0}
    opened = session.open_run(run, load_state=False)
    assert opened.plan.sampler == Sampler(replaced=8, prior=4.0) and opened.plan.schedule.sampler == opened.plan.sampler
    again = runner.invoke(app, ["train", "--resume", str(run), "--sampler", "replaced=2"])
    assert again.exit_code != 0 and "--sampler cannot change" in " ".join(again.output.split())
    (run / "run.json").write_text(json.dumps({**saved, "sampler": {**saved["sampler"], "kept": 3}}))
    with pytest.raises(record.RunError, match="run.json: sampler kept=3: .* it was edited or damaged"):
        session.open_run(run, load_state=False)
    (run / "run.json").write_text(json.dumps({k: v for k, v in saved.items() if k != "sampler"}))
    assert session.open_run(run, load_state=False).plan.schedule.sampler == DEFAULT


def test_the_sampler_options_help_names_every_key_the_sampler_takes():
    """The help is written before JAX loads, so it cannot read Sampler's keys: it must list them as they are."""
    helped = " ".join(runner.invoke(app, ["train", "--help"], terminal_width=200).output.split())
    listed = helped.split("kept in run.json: ", 1)[1].split(" (docs", 1)[0].split(", ")
    assert listed == list(Sampler.model_fields)


def test_a_config_files_sampler_section_sets_the_runs_sampler_under_the_command_lines(tmp_path):
    """A --config file's `sampler:` holds a recipe's sampler as its `crl:` holds the trainer's: run.json keeps it,
    --sampler given beside it wins key by key."""
    config = tmp_path / "recipe.yaml"
    config.write_text("crl:\n  num_evals: 2\nsampler:\n  replaced: 8\n  buffer: 16\n")
    args = ["train", "point_soccer", "--curriculum", "auto", "--levels", "3", "--steps", "20k", "--envs", "8",
            "--config", str(config), "--prepare"]
    made = runner.invoke(app, [*args, "--out", str(tmp_path / "a")])
    assert made.exit_code == 0, made.output
    assert "the level sampler: buffer=16, replaced=8; the rest at their defaults" in made.output
    saved = json.loads((tmp_path / "a" / "point_soccer-auto-crl-0" / "run.json").read_text())
    assert saved["sampler"] == {**DEFAULT.model_dump(), "replaced": 8, "buffer": 16}
    over = runner.invoke(app, [*args, "--sampler", "replaced=2", "--out", str(tmp_path / "b")])
    assert over.exit_code == 0, over.output
    saved = json.loads((tmp_path / "b" / "point_soccer-auto-crl-0" / "run.json").read_text())
    assert (saved["sampler"]["replaced"], saved["sampler"]["buffer"]) == (2, 16)


@pytest.mark.parametrize(("section", "says"), [
    ("sampler:\n  replaced: -1\n", "recipe.yaml:3: sampler: replaced=-1: replaced must be at least 0"),
    ("sampler:\n  bufer: 64\n", "recipe.yaml:3: sampler: bufer: unknown key 'bufer'; did you mean 'buffer'?"),
    ("sampler: 8\n", "recipe.yaml:2: sampler holds 8 where the sampler's keys go"),
    ("sampler:\n  buffer: 16\n  replaced: 20\n", "recipe.yaml:2: sampler: replaced 20 is more than the buffer's "
                                                   "16 levels"),
])
def test_a_bad_sampler_section_of_a_config_file_is_one_line_at_its_line(tmp_path, section, says):
    config = tmp_path / "recipe.yaml"
    config.write_text("crl: {num_evals: 2}\n" + section)
    result = runner.invoke(app, ["train", "point_soccer", "--curriculum", "auto", "--config", str(config),
                                 "--out", str(tmp_path / "runs"), "--prepare"])
    assert result.exit_code != 0 and says in " ".join(result.output.split()), result.output
    assert "Traceback" not in result.output and not (tmp_path / "runs").exists()


@pytest.mark.parametrize("command", [["train", "point_soccer"], ["compare", "point_soccer"]])
def test_a_sampler_section_where_no_automatic_curriculum_reads_it_is_refused_at_its_line(tmp_path, command):
    """Nothing but --curriculum auto draws levels: a recipe's sampler given to another run would be dropped
    without a word, so it is refused where it is written."""
    config = tmp_path / "recipe.yaml"
    config.write_text("crl: {num_evals: 2}\nsampler:\n  replaced: 8\n")
    result = runner.invoke(app, [*command, "--config", str(config), "--out", str(tmp_path / "runs"), "--prepare"])
    said = " ".join(result.output.split())
    assert result.exit_code != 0 and "recipe.yaml:2: sampler: sets how the automatic curriculum draws its levels" in said
    assert "Traceback" not in result.output and not (tmp_path / "runs").exists()


def test_a_buffer_whose_levels_are_solved_moves_towards_the_spec():
    """A policy whose frontier (success 0.5) moves out along the kick-off: the buffer gives up levels solved or
    out of reach for harder neighbours of the learnable ones, so its levels move towards the spec's kick-off."""
    playable = np.ones((4, 32), bool)
    weights = own_kickoffs(playable)
    coordinate = np.tile(np.arange(32) / 31, (4, 1))
    means = []
    for i in range(16):
        member = np.asarray(weights) > 0
        success = np.clip((0.2 + 0.04 * i - coordinate) / 0.2 + 0.5, 0.0, 1.0)
        episodes = np.where(member, 20.0, 0.0)
        weights, _ = next_levels(jnp.asarray(np.stack([episodes, episodes * success])), weights, playable,
                                 jax.random.PRNGKey(i))
        means.append(float(coordinate[np.asarray(weights) > 0].mean()))
    assert means[-1] > min(means) + 0.2 and means[-1] > means[-4], means


def furthest_along(weights) -> int:
    """The buffer's level furthest along the path but the spec, as a cell in reading order."""
    member = np.asarray(weights).ravel() > 0
    member[-1] = False
    return int(np.flatnonzero(member).max())


def test_a_buffer_with_a_hardest_share_never_retreats_from_its_furthest_level():
    """A policy that succeeds in one episode of two up to 30% of the path and never beyond: the default buffer
    gives up the levels it cannot solve (their p(1 - p) is as low as a solved level's) and retreats; with
    `hardest_share` the level furthest along the path keeps that share and moves only forward."""
    playable = np.ones((4, 32), bool)
    along = np.arange(4 * 32).reshape(4, 32) / (4 * 32 - 1)
    success = np.where(along < 0.3, 0.5, 0.0)
    furthest = {}
    for name, sampler in [("default", DEFAULT), ("hardest", Sampler(hardest_share=0.25))]:
        weights, seen = own_kickoffs(playable), []
        for i in range(12):
            member = np.asarray(weights) > 0
            episodes = np.where(member, 20.0, 0.0)
            weights, _ = next_levels(jnp.asarray(np.stack([episodes, episodes * success])), weights, playable,
                                     jax.random.PRNGKey(i), sampler)
            seen.append(furthest_along(weights))
            assert float(jnp.sum(weights)) == pytest.approx(1.0)
        furthest[name] = seen
        if name == "hardest":
            cell = np.unravel_index(seen[-1], playable.shape)
            learnable = np.asarray(weights)[along < 0.3].max()
            assert float(weights[cell]) >= (1 - TARGET_SHARE) * 0.25 > learnable
    assert furthest["default"][-1] < furthest["default"][0], furthest  # retreats
    assert furthest["hardest"] == sorted(furthest["hardest"]), furthest  # only forward
    assert furthest["hardest"][-1] >= furthest["hardest"][0]


def test_a_hardest_share_adds_its_share_to_the_same_weights():
    """The hand-set counts of test_buffer_weights_on_hand_set_counts with hardest_share: the level furthest
    along but the spec gets that share on top of its floor and learnability, the others' learnable part shrinks."""
    playable = np.ones((2, 4), bool)
    episodes = jnp.array([[10.0, 10, 10, 0], [0, 0, 0, 30]])
    successes = jnp.array([[10.0, 5, 0, 0], [0, 0, 0, 3]])
    new, _ = next_levels(jnp.stack([episodes, successes]), jnp.full((2, 4), 1 / 8), playable,
                         jax.random.PRNGKey(0), Sampler(hardest_share=0.3))
    p = (np.asarray(successes) + PRIOR / 2) / (np.asarray(episodes) + PRIOR)
    score = (p * (1 - p)).ravel()[:-1]
    furthest = np.arange(7) == 6  # the last level's third point: the spec is its fourth
    expected = (1 - TARGET_SHARE) * (FLOOR / 7 + 0.3 * furthest + (1 - FLOOR - 0.3) * score / score.sum())
    np.testing.assert_allclose(np.asarray(new).ravel(), [*expected, TARGET_SHARE], rtol=1e-5)


@pytest.mark.slow
def test_a_field_starts_from_a_kickoff_point_and_counts_its_levels(env_cache):
    """An environment of two levels of point_soccer with 3 kick-off points each: an episode starts where its
    point puts the ball and the agent, new episodes draw only weighted levels, and every episode that ends
    is counted on its level; a plain field keeps the state it always had."""
    spec = load_spec(FIELDS["point_soccer"])
    made = levels(spec, 2)
    tables = kickoff_tables(spec, made, 3)
    tables[1][0] = None  # a point the schema refused
    starts = np.array([[row[1:] if row else [np.nan] * 6 for row in level] for level in tables])
    artifacts = [e.artifact for e in Auto().stage_environments([level.spec for level in made])]
    env = FieldEnv(artifacts, episode_length=2, kickoffs=starts, kickoff_coordinates=starts[..., 0] * 0 + 0.5)
    assert env.kickoff_coordinates.shape == (2, 3) and np.isnan(env.kickoff_coordinates[1, 0])
    n = 16
    state = jax.vmap(env.reset_variant, in_axes=(0, None, None))(jax.random.split(jax.random.PRNGKey(0), n), 1, 1)
    layout = env.layout
    np.testing.assert_allclose(state.pipeline_state.qpos[:, np.asarray(layout.agent_qpos[:2])],
                               np.tile(tables[1][1][5:], (n, 1)), atol=0.15)  # the start, and its noise
    ball_y = state.pipeline_state.qpos[:, np.asarray(layout.ball_qpos[1])]
    np.testing.assert_allclose(ball_y, tables[1][1][2], atol=1e-5)
    assert np.all(np.asarray(state.info["kickoff"]) == 1)
    weights = jnp.zeros((2, 3)).at[0, 0].set(0.5).at[1, 2].set(0.5)
    state = env.with_level_weights(state, weights, jnp.ones((2, 3)))
    step = jax.jit(jax.vmap(env.step))
    drawn = set()
    for _ in range(2 * env.episode_length):  # two episodes each
        state = step(state, jnp.zeros((n, env.action_size)))
        drawn |= {(int(v), int(k)) for v, k, d in zip(state.info["variant"], state.info["kickoff"], state.done) if d}
    assert drawn == {(0, 0), (1, 2)}
    counts = np.asarray(state.info["level_counts"]).sum(0)
    assert counts[0, 1, 1] == n and counts[0].sum() == float(np.sum(state.info["episode"]))
    assert np.all(counts[1] <= counts[0])
    plain = env_cache("point_soccer")
    assert plain.kickoff_coordinates.shape == (1, 0) and "kickoff" not in plain.reset(jax.random.PRNGKey(0)).info


def test_levels_the_schema_refuses_down_to_the_field_alone_are_refused_not_a_run_of_one_level(monkeypatch):
    """Before: `--levels 2` on a field whose easy end the schema refuses set up a run of the field alone."""
    from fieldgen import curriculum
    from fieldgen.curriculum import auto

    every = auto.levels
    monkeypatch.setattr(auto, "levels", lambda spec, count: every(spec, count)[-1:])  # only the field is playable
    with pytest.raises(curriculum.PlanError, match=r"--levels 2 on point_soccer: the schema refuses the 1 easier "
                                                   r"level of its path .* leaves the field alone; ask for more levels"):
        curriculum.plan(bundled_fields()["point_soccer"], "auto", 2)
