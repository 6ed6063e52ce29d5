"""The automatic curriculum: levels made from the spec alone, the sampler's weights, and a run through them."""

from __future__ import annotations

import json

import imageio.v3 as iio
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

from fieldgen.cli import app
from fieldgen.curriculum.auto import FRONTIER_SHARE, TARGET_SHARE, level_weights, levels, path
from fieldgen.curriculum.levels import LevelError, LevelSpace
from fieldgen.curriculum.schedule import sampling_weights
from fieldgen.schema import bundled_fields, load_spec

runner = CliRunner()
FIELDS = bundled_fields()


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
    with pytest.raises(LevelError, match="at least 2 levels"):
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
    """A tiny point_soccer run: every level batched, each evaluation's weights by level_weights of its
    success, recorded in run.json and the metrics; prepared and resumed as any run."""
    sets = ["crl.hidden=[32,32]", "crl.repr_dim=8", "crl.batch_size=64", "crl.unroll_length=25",
            "crl.min_replay_rows=100", "crl.max_replay_rows=400", "crl.num_evals=2", "crl.eval_envs=8"]
    args = ["train", "point_soccer", "--curriculum", "auto", "--levels", "4", "--steps", "4000", "--envs", "8",
            "--no-videos", "--out", str(tmp_path), *[x for s in sets for x in ("--set", s)]]
    prepared = runner.invoke(app, [*args, "--prepare"])
    assert prepared.exit_code == 0, prepared.output
    run = tmp_path / "point_soccer-auto-crl-0"
    early = runner.invoke(app, ["render", str(run), "--levels", "-o", str(tmp_path / "early.png")])
    assert early.exit_code != 0 and "has no evaluation yet" in " ".join(early.output.split())
    record = json.loads((run / "run.json").read_text())
    assert record["schedule"] == "auto" and record["mixed"] and len(record["levels"]) == 4
    assert record["levels"][0]["kickoff"] == 0.0 and all(v == 1.0 for v in record["levels"][-1].values())
    result = runner.invoke(app, ["train", "--resume", str(run)])
    assert result.exit_code == 0, result.output
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert [r["eval"] for r in rows] == [0, 1, 2]
    for row in rows[1:]:
        v = row["variants"]
        expected = level_weights(jnp.asarray(v["success_any"]))
        np.testing.assert_allclose(v["weight"], expected, atol=1e-6)
        assert row["last_stage_success_any"] == v["success_any"][-1]
    assert iio.imread(run / "success.png").shape == (360, 2500, 4)  # with the panel of where episodes go
    from fieldgen import render

    drawn = render.contact_sheet
    titles = []
    monkeypatch.setattr(render, "contact_sheet", lambda images, names: titles.extend(names) or drawn(images, names))
    sheet = runner.invoke(app, ["render", str(run), "--levels"])  # into the run's folder by default
    assert sheet.exit_code == 0, sheet.output
    assert "most played of 4 levels after evaluation 2" in " ".join(sheet.output.split())
    assert iio.imread(run / "levels.png").ndim == 3
    assert len(titles) == 4 and all(t.startswith(("level ", "the field itself")) for t in titles), titles


@pytest.mark.parametrize(("extra", "says"), [
    (["--mixed"], "--curriculum auto makes its own levels from one field"),
    (["--levels", "3"], "add --curriculum auto"),
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


@pytest.mark.slow
def test_an_auto_run_killed_and_resumed_continues_its_levels_exactly(tmp_path, interrupt_after_eval):
    """The level weights live in the training state (each environment's next draw), so a run stopped after an
    evaluation and resumed weighs and plays its levels exactly as the run never stopped."""
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
    resumed = runner.invoke(app, ["train", "--resume", str(cut)])
    assert resumed.exit_code == 0, resumed.output

    def rows(folder):
        return [{k: v for k, v in json.loads(line).items() if k not in ("wall_seconds", "steps_per_second")}
                for line in (folder / "metrics.jsonl").read_text().splitlines()]

    assert rows(cut) == rows(tmp_path / "whole" / "point_soccer-auto-crl-0")
