"""Curriculum variants: interpolation ends, grids, lists, validation, and folders edited by hand."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fieldgen import curriculum
from fieldgen.cli import app
from fieldgen.compile.artifact import compile_spec
from fieldgen.schema import bundled_fields, load_spec

runner = CliRunner()
FIELDS = bundled_fields()


def resolved(path: Path) -> dict:
    data = load_spec(path).model_dump(mode="json")
    return {k: v for k, v in data.items() if k not in ("name", "description", "extends")}


def two_stages(out: Path) -> Path:
    """A list curriculum of point_nav at target radius 1 then 2, written by fieldgen curriculum into `out`."""
    result = runner.invoke(app, ["curriculum", "point_nav", "-o", str(out), "--stage", "task.target.radius=1",
                                 "--stage", "task.target.radius=2"])
    assert result.exit_code == 0, result.output
    return out


def test_interpolation_ends_are_the_two_specs_and_every_stage_builds(tmp_path):
    out = tmp_path / "v1_to_wide"
    variants = curriculum.interpolate(FIELDS["soccer_v1"], FIELDS["v2_wide_goalie"], 4)
    c = curriculum.write(out, "soccer_v1", FIELDS["soccer_v1"], "interpolation", variants, curriculum.Promotion())
    paths = c.spec_paths()
    assert len(paths) == 4
    assert resolved(paths[0]) == resolved(FIELDS["soccer_v1"])
    assert resolved(paths[-1]) == resolved(FIELDS["v2_wide_goalie"])
    middle = load_spec(paths[1])
    assert 10 < middle.goal.distance < 20 and middle.goal.distance == pytest.approx(10 + 10 / 3, rel=1e-5)
    assert not middle.walls.enabled and load_spec(paths[2]).walls.enabled  # switches at stage 3 of 4
    # every stage builds: the field's 15 geoms, the ant's 17, ball and target; the walls (4) and the goalie come
    # in with stage 3
    assert [compile_spec(spec).model().ngeom for spec in c.specs()] == [34, 34, 39, 39]
    text = paths[1].read_text()
    modeline, origin = text.splitlines()[:2]
    assert modeline.startswith("# yaml-language-server: $schema=") and origin.startswith("# stage 2 of 4")
    assert "extends: soccer_v1" in text and "agent:" not in text
    assert curriculum.load(out).stages == [s.__class__(s.name, s.file, {}, s.origin) for s in c.stages]


def test_geometric_interpolation(tmp_path):
    variants = curriculum.interpolate(FIELDS["soccer_v1"], FIELDS["soccer_v2"], 3, geometric=("goal.distance",))
    assert variants[1][0]["goal"]["distance"] == pytest.approx((10 * 20) ** 0.5, rel=1e-5)


def test_grid_has_the_product_size(tmp_path):
    axes = {"goal.distance": [8, 12, 16, 20], "obstacles.goalie.width": [0.5, 2, 4]}
    c = curriculum.write(tmp_path / "g", "soccer_v2", FIELDS["soccer_v2"], "grid",
                         curriculum.grid(FIELDS["soccer_v2"], axes), curriculum.Promotion())
    specs = c.specs()
    assert len(specs) == 12
    assert {(s.goal.distance, s.obstacles["goalie"].width) for s in specs} == {
        (d, w) for d in axes["goal.distance"] for w in axes["obstacles.goalie.width"]}


@pytest.mark.parametrize("args,phrase", [
    (["--vary", "goal.distance="], "the list of values is empty"),
    (["--vary", "goal.distance=8,9,8.0"], "--vary goal.distance: 8.0 is listed twice; list each value once"),
    (["--vary", "goal.distanse=8,12"], "unknown key 'goal.distanse'; did you mean 'goal.distance'?"),
    (["--stage", "goal.distance=9", "--stage", "goal.distance=12", "--stage", "goal.distance=9.0"],
     "--stage 3 (goal.distance=9.0) sets what --stage 1 sets: the same field twice; list each once"),
    (["--to", "point_nav"], "drives the ant agent and"),
    (["--stage", "goal.distance=200"], "stage 1 (listed: goal.distance=200) is not a valid field (goal.distance:"),
    (["--stage", "goal.distance=9 obstacles={rock:"], "--stage obstacles: the value '{rock:' is not valid YAML"),
    (["--vary", "goal.distance=[8"], "--vary goal.distance: the value '[8' is not valid YAML"),
    (["--to", "soccer_v2", "--stages", "1"], "--stages 1: a curriculum's stages, both ends included is a whole number from 2 to 1,000"),
    (["--start-near", "9"], "--start-near 9: choose a distance between 0 and 7.00"),
    (["--start-near", "3", "--then", "point_nav"], "drives the ant agent and"),
    (["--start-near", "3", "--then", "soccer_v2", "--then-stages", "0"], "--then-stages 0: the stages each --then adds is a whole number from 1 to 1,000"),
    (["--start-near", "3", "--then-stages", "2"], "--then-stages belongs to --then"),
    (["--vary", "goal.distance=8,12", "--geometric", "goal.distance"],  # before: both taken, neither used
     "--geometric goal.distance belongs to an interpolation: give --to FIELD (or --then FIELD)"),
    (["--stage", "goal.distance=9", "--switch-at", "2"], "--switch-at belongs to an interpolation curriculum: give --to too"),
    (["--to", "soccer_v2", "--stages", "2", "--then", "soccer_v2"], "stage 2 is that field already"),
    (["--start-near", "3", "--then", "soccer_v2", "--geometric", "goal.distanse"], "did you mean 'goal.distance'?"),
    # a key the interpolation does not move as a number: before, accepted and left as it was
    (["--to", "soccer_v2", "--geometric", "walls.enabled"], "--geometric walls.enabled: it goes from false to true, "
     "not a number that moves (booleans, choices and lists of other lengths switch at --switch-at); the numbers "
     "that move here: ball.spawn.y, field.length, field.width, goal.depth, goal.distance,"),
    (["--to", "soccer_v2", "--geometric", "episode.length"], "--geometric episode.length: both fields hold 1001, so "
                                                               "it does not move"),
    (["--to", "v2_wide_goalie", "--geometric", "obstacles.goalie.width"], "--geometric obstacles.goalie.width: only "
                                                                          "one of the two fields has it"),
    (["--stage", "goal.distance=abc", "--then", "soccer_v2"], "stage 1, which --then goes on from, is not a valid field (goal.distance: 'abc' is text"),
    ([], "give exactly one of"),
])
def test_bad_curriculum_input_writes_nothing(tmp_path, args, phrase):
    out = tmp_path / "c"
    result = runner.invoke(app, ["curriculum", "soccer_v1", "-o", str(out), *args])
    assert result.exit_code == 1, result.output
    assert phrase in " ".join(result.output.split()) and "Traceback" not in result.output
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_a_start_near_that_puts_the_ball_on_an_obstacle_names_the_distances_that_make_a_field(tmp_path):
    """point_soccer's goalie stands between the kick-off and the goal: the range 0 to 2.50 that --start-near states
    held distances refused after, with no word of which do make a field."""
    out = tmp_path / "c"
    result = runner.invoke(app, ["curriculum", "point_soccer", "-o", str(out), "--start-near", "1", "--stages", "3"])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and not out.exists(), result.output
    assert ("--start-near 1: the first stage, the ball's spawn centre 1 from the target, is not a valid field "
            "(obstacles.goalie: the ball can spawn touching obstacle 'goalie'); from point_soccer the distances that "
            "make a field, checked every 0.05, run 0.50 to 0.85 and 1.55 to 2.45") in message
    fits = runner.invoke(app, ["curriculum", "point_soccer", "-o", str(out), "--start-near", "2", "--stages", "2"])
    assert fits.exit_code == 0, fits.output


def test_a_variant_that_is_no_field_is_named_by_what_made_it_not_by_a_file_that_is_gone(tmp_path):
    """Before: "stage 2 (stage_02.yaml) is not a valid field: ... DIR/.c.XXXX.tmp/stage_02.yaml:7:3: ...", a line of
    the staging folder's file, which the refusal had removed."""
    out = tmp_path / "c"
    result = runner.invoke(app, ["curriculum", "point_nav", "-o", str(out), "--stage", "task.target.radius=1",
                                 "--stage", "task.target.radius=-2"])
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert " ".join(result.output.split()) == ("error: stage 2 (listed: task.target.radius=-2) is not a valid field "
                                               "(task.target: radius must be positive); nothing was written")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args,said", [
    (["--stage", "foo=1"], "error: --stage foo: unknown key 'foo'. A key is a dotted path into the base field, such as "
                           "goal.distance, starting with one of its sections: field, walls, goal, ball, agent, "
                           "obstacles, task, episode, sim, observation"),
    (["--stage", "name=x"], "error: --stage name: 'name' names the variant, it cannot be varied"),
], ids=["unknown", "name"])
def test_a_key_no_variant_can_set_names_its_option_and_the_keys_there_are(tmp_path, args, said):
    """Before: "unknown key 'foo'" alone, naming neither the option nor a key there is; and a stage's name, a key
    of every spec, was taken and refused later as a stage misnamed in curriculum.yaml."""
    out = tmp_path / "c"
    result = runner.invoke(app, ["curriculum", "point_nav", "-o", str(out), *args, "--stage", "task.target.radius=2"])
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert " ".join(result.output.split()) == said
    assert list(tmp_path.iterdir()) == []


def test_folders_edited_into_an_inconsistent_state_are_refused(tmp_path):
    out = two_stages(tmp_path / "c")
    assert curriculum.load(out).stages[1].name == "c_s02"
    (out / "stage_03.yaml").write_text((out / "stage_02.yaml").read_text())
    with pytest.raises(curriculum.CurriculumError, match="does not list stage_03.yaml"):
        curriculum.load(out)
    (out / "stage_03.yaml").unlink()
    (out / "stage_02.yaml").write_text((out / "stage_02.yaml").read_text().replace("name: c_s02", "name: other"))
    with pytest.raises(curriculum.CurriculumError, match="named 'other' but curriculum.yaml lists 'c_s02'"):
        curriculum.load(out)
    (out / "stage_02.yaml").unlink()
    built = runner.invoke(app, ["build", str(out), "--no-preview"])
    assert built.exit_code == 1 and "lists stage_02.yaml, which is missing" in " ".join(built.output.split())


def test_promotion_averages_the_last_window_of_evaluations_on_the_current_stage():
    rule = curriculum.Promotion(threshold=0.5, window=2)
    history = [{"eval": 0, "stage": 0, "success_any": 1.0}, {"eval": 1, "stage": 0, "success_any": 0.6}]
    assert not rule.ready(history, 0)  # one evaluation after training; the untrained one does not count
    history += [{"eval": 2, "stage": 0, "success_any": s} for s in (0.5, 0.7)]  # two seeds
    assert rule.ready(history, 0) and not rule.ready(history, 1)  # (0.6 + 0.5 + 0.7) / 3 on stage 0
    history += [{"eval": 3, "stage": 0, "success_any": s} for s in (0.1, 0.2)]
    assert not rule.ready(history, 0)  # evaluations 2 and 3 only: 0.375


@pytest.mark.slow
def test_staged_training_reaches_the_last_stage_of_a_point_curriculum(tmp_path):
    """Targets 1, 2 then 3 away: promoted twice, and the last stage solved, within 48k env steps. The last
    stage also has a rock in a corner, out of the way: its scene has a body more, and its evaluation,
    compiled for that scene, judges the policy while the earlier stages train."""
    import json

    rock = "obstacles={rock: {x: 4.5, y: 4.5, width: 0.2, depth: 0.2, height: 0.2}}"
    made = runner.invoke(app, ["curriculum", "point_nav", "-o", str(tmp_path / "ring"), "--threshold", "0.6",
                               "--window", "1", "--stage", "task.target.radius=1", "--stage", "task.target.radius=2",
                               "--stage", f"task.target.radius=3 {rock}"])
    assert made.exit_code == 0, made.output
    ngeoms = [compile_spec(spec).model().ngeom for spec in curriculum.load(tmp_path / "ring").specs()]
    assert ngeoms[0] == ngeoms[1] < ngeoms[2]
    sets = ["crl.hidden=[64,64]", "crl.repr_dim=16", "crl.batch_size=64", "crl.windows=64", "crl.unroll_length=25",
            "crl.min_replay_rows=100", "crl.max_replay_rows=2000", "crl.num_evals=8", "crl.eval_envs=32"]
    args = ["train", str(tmp_path / "ring"), "--steps", "48000", "--envs", "16", "--out", str(tmp_path / "runs"),
            "--no-videos", *[x for s in sets for x in ("--set", s)]]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    run = tmp_path / "runs" / "ring-crl-0"
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    promotions = [r["promoted_to"] for r in rows if "promoted_to" in r]
    assert promotions == [1, 2]
    assert rows[0]["stage"] == 0 and rows[-1]["stage"] == 2
    assert rows[0]["last_stage_success_any"] <= 0.4 and rows[-1]["last_stage_success_any"] >= 0.8
    assert sorted(p.name for p in (run / "stages").iterdir()) == ["01", "02", "03"]
    assert "reached stage 3 of 3" in " ".join(result.output.split())
    done = runner.invoke(app, ["train", "--resume", str(run)])
    assert done.exit_code == 0 and "already complete" in done.output


def test_start_states_move_the_kickoff_back_to_the_base_and_every_stage_builds(tmp_path):
    """Stage 1 spawns the ball `near` from the goal with the agent moved as far; the last stage is the base."""
    variants = curriculum.start_states(FIELDS["soccer_v1"], 3.0, 3)
    c = curriculum.write(tmp_path / "kickoff", "soccer_v1", FIELDS["soccer_v1"], "start_states", variants,
                         curriculum.Promotion())
    specs = c.specs()
    base = load_spec(FIELDS["soccer_v1"])
    first = specs[0]
    assert first.ball.spawn.y == (7.0, 7.0) and first.ball.spawn.x == base.ball.spawn.x  # 3 from the goal at y 10
    assert first.agent.start == (0.0, 4.0)  # moved by as much as the ball
    assert specs[1].ball.spawn.y == (5.0, 5.0) and specs[1].agent.start == (0.0, 2.0)
    assert resolved(c.spec_paths()[-1]) == resolved(FIELDS["soccer_v1"])
    for spec in specs:
        compile_spec(spec)


def test_the_cli_writes_a_start_state_curriculum(tmp_path):
    out = tmp_path / "v2_kickoff"
    result = CliRunner().invoke(app, ["curriculum", "soccer_v2", "--start-near", "3", "--stages", "4", "-o", str(out)])
    assert result.exit_code == 0, result.output
    specs = curriculum.load(out).specs()
    assert [s.ball.spawn.y for s in specs] == [(17.0, 17.0), (13.0, 13.0), (9.0, 9.0), (5.0, 5.0)]
    assert curriculum.load(out).kind == "start_states"
    # stage 1 starts the ant at y 12 behind the goalie (y 14) with the ball at 17; from stage 2 on the goalie
    # stands beyond the ball, as on soccer_v2 itself
    said = " ".join(result.output.split())
    assert "stage 1: obstacle 'goalie' stands between the agent's start (0, 12) and the ball" in said
    assert "stage 2:" not in said and "stage 4:" not in said


def test_a_curriculum_goes_on_to_further_fields(tmp_path):
    """--then appends the stages after the first of an interpolation from the last stage on to a field: after
    soccer_v1's start states, those of soccer_v1 -> soccer_v2; a second --then goes on from there."""
    out = tmp_path / "close_to_wide"
    result = runner.invoke(app, ["curriculum", "soccer_v1", "--start-near", "3", "--stages", "3", "--then", "soccer_v2",
                                 "--then-stages", "3", "--then", "v2_wide_goalie", "-o", str(out)])
    assert result.exit_code == 0, result.output
    c = curriculum.load(out)
    assert c.kind == "start_states, then interpolation, then interpolation" and len(c.stages) == 3 + 3 + 3
    to_v2 = curriculum.write(tmp_path / "v1_to_v2", "soccer_v1", FIELDS["soccer_v1"], "interpolation",
                             curriculum.interpolate(FIELDS["soccer_v1"], FIELDS["soccer_v2"], 4), curriculum.Promotion())
    paths = c.spec_paths()
    assert [resolved(p) for p in paths[2:6]] == [resolved(p) for p in to_v2.spec_paths()]
    assert resolved(paths[0]) != resolved(paths[2])  # the start states come first
    assert resolved(paths[-1]) == resolved(FIELDS["v2_wide_goalie"])
    assert [load_spec(p).obstacles["goalie"].width for p in paths[5:]] == pytest.approx([1.5, 2.0, 2.5, 3.0])
    assert "stage 7: 1 of 3 from stage 6 on to" in paths[6].read_text()
    compile_spec(load_spec(paths[-2]))


def test_start_states_can_begin_with_the_agent_next_to_the_ball(tmp_path):
    """--agent-near starts the first stage's agent that far behind the ball, on its base side, and widens
    the gap back to the base's by the last stage, the ball moving back as with --start-near alone."""
    out = tmp_path / "v1_close"
    result = CliRunner().invoke(app, ["curriculum", "soccer_v1", "--start-near", "1.5", "--agent-near", "1.75",
                                      "--stages", "3", "-o", str(out)])
    assert result.exit_code == 0, result.output
    specs = curriculum.load(out).specs()
    assert [s.ball.spawn.y for s in specs] == [(8.5, 8.5), (5.75, 5.75), (3.0, 3.0)]
    assert [s.agent.start for s in specs] == [(0.0, 6.75), (0.0, 3.375), (0.0, 0.0)]
    with pytest.raises(curriculum.CurriculumError, match="between 0 and 3.00"):
        curriculum.start_states(FIELDS["soccer_v1"], 1.5, 3, agent_near=3.5)
    with pytest.raises(curriculum.CurriculumError, match="give --start-near too"):
        curriculum.variants(FIELDS["soccer_v1"], curriculum.Asked(listed=("ball.radius=0.4",), agent_near=1.75))


def test_start_states_need_a_fixed_target_and_a_reachable_distance():
    with pytest.raises(curriculum.CurriculumError, match="fixed target"):
        curriculum.start_states(FIELDS["ant_nav"], 3.0, 3)
    with pytest.raises(curriculum.CurriculumError, match="between 0 and 7.00"):
        curriculum.start_states(FIELDS["soccer_v1"], 8.0, 3)


def test_a_curriculum_renders_as_a_sheet_of_its_stages(tmp_path):
    import imageio.v3 as iio

    folder = tmp_path / "near"
    made = runner.invoke(app, ["curriculum", "point_nav", "-o", str(folder), "--vary", "task.target.radius=1,2,3"])
    assert made.exit_code == 0, made.output
    sheet = tmp_path / "sheet.png"
    result = runner.invoke(app, ["render", str(folder), "-o", str(sheet), "--camera", "both"])
    assert result.exit_code == 0 and f"3 stages of {folder}, camera top" in " ".join(result.output.split())
    image = iio.imread(sheet)
    assert image.ndim == 3 and image.std() > 10


def test_a_folder_of_built_fields_renders_as_a_sheet_of_them(tmp_path):
    """A build folder of several fields, or a curriculum run whose `stages/` holds its built levels, draws as a
    sheet of every field in it, in name order."""
    import imageio.v3 as iio

    for where in ("build", "run/stages"):
        built = runner.invoke(app, ["build", "point_nav", "point_soccer", "--out", str(tmp_path / where),
                                    "--no-preview"])
        assert built.exit_code == 0, built.output
    for folder in ("build", "run"):
        sheet = tmp_path / f"{folder}.png"
        result = runner.invoke(app, ["render", str(tmp_path / folder), "-o", str(sheet)])
        assert result.exit_code == 0 and "2 built fields of" in " ".join(result.output.split()), result.output
        assert iio.imread(sheet).std() > 10
    from fieldgen.run.favoured import level_captions

    assert level_captions(tmp_path / "build", 2) is None  # no run: each field's size under it
    one = runner.invoke(app, ["render", str(tmp_path / "build" / "point_nav"), "-o", str(tmp_path / "one.png")])
    assert one.exit_code == 0 and "camera top" in one.output and "built fields" not in one.output
    record = {"field": {}, "algo": "crl", "observation": {}, "seeds": [0], "config": {"seed": 0},
              "fields": ["stages/point_nav", "stages/point_soccer", "stages/gone"]}  # a run copied in part
    (tmp_path / "run" / "run.json").write_text(json.dumps(record))
    part = runner.invoke(app, ["render", str(tmp_path / "run"), "-o", str(tmp_path / "part.png")])
    assert part.exit_code == 0 and "note: the run's stages/gone is missing" in " ".join(part.output.split())
    assert runner.invoke(app, ["build", "point_nav", "--out", str(tmp_path / "single"), "--no-preview"]).exit_code == 0
    alone = runner.invoke(app, ["render", str(tmp_path / "single"), "-o", str(tmp_path / "single.png")])
    assert alone.exit_code == 0 and "1 built field of" in " ".join(alone.output.split()), alone.output


@pytest.mark.parametrize("edit,phrase", [
    (lambda t: t.replace("file: stage_01.yaml", "file: ../../outside.yaml"), "curriculum.yaml:10:3: stages[0].file: "
     "should name a .yaml file in the curriculum's folder, such as stage_01.yaml (got '../../outside.yaml')"),
    (lambda t: t.replace("file: stage_01.yaml", "file: /etc/hosts"), "stages[0].file: should name a .yaml file in "
     "the curriculum's folder, such as stage_01.yaml (got '/etc/hosts')"),
    (lambda t: t.replace("file: stage_01.yaml", "file: sub/stage_01.yaml"), "(got 'sub/stage_01.yaml')"),
    (lambda t: t.replace("file: stage_01.yaml", "file: 7"), "stages[0].file: expected text (got 7)"),
    (lambda t: t.replace("threshold: 0.5", "threshold: 7"), "curriculum.yaml:6:3: promotion.threshold: Input should "
     "be less than or equal to 1 (got 7)"),
    (lambda t: t.replace("threshold: 0.5", "threshold: .nan"), "promotion.threshold: expected a finite number (got nan)"),
    (lambda t: t.replace("window: 2", "window: two"), "promotion.window: expected a whole number (got 'two')"),
    (lambda t: t.replace("window: 2", "window: 0"), "promotion.window: Input should be greater than or equal to 1"),
    (lambda t: t.replace("window: 2", "windw: 2"), "promotion.windw: unknown key 'windw'; did you mean 'window'?"),
    (lambda t: t.replace("- name: c_s01\n  file", "- file"), "stages[0].name: the key 'name' is required"),
    (lambda t: t.split("stages:")[0] + "stages: []\n", "stages: at least 1 item here (got 0)"),
    (lambda t: "", "curriculum.yaml:1:1: the file is empty; it lists the stages under 'stages:'"),
    (lambda t: "- a\n- b\n", "the document is a list; curriculum.yaml is a mapping of sections"),
    (lambda t: "a: &a [*a]\n", "an alias refers to the collection it stands in, so curriculum.yaml would nest "
     "without end"),
    (lambda t: t + "stages: []\n", "duplicate key 'stages' (first given on line 8)"),
    (lambda t: t + "#" * 1_000_001, "the file has 1,00"),
], ids=["outside", "absolute", "subfolder", "number", "threshold", "nan", "window_text", "window_zero", "unknown_key",
        "no_name", "no_stages", "empty", "list", "alias_loop", "duplicate", "huge"])
def test_a_damaged_or_hostile_curriculum_index_is_one_paragraph_at_its_line(tmp_path, edit, phrase):
    """curriculum.yaml is read as specs are: bounded, typed, each problem at its file, line and key; a stage's file
    stays in the curriculum's folder. Before: '../' paths were read, 7 and NaN thresholds taken, and an
    alias loop or a wrong type a traceback."""
    out = two_stages(tmp_path / "c")
    (tmp_path / "outside.yaml").write_text((out / "stage_01.yaml").read_text())
    index = out / "curriculum.yaml"
    index.write_text(edit(index.read_text()))
    with pytest.raises(curriculum.CurriculumError) as caught:
        curriculum.load(out)
    assert str(caught.value).startswith(f"{index} is not a curriculum index: {index}:")
    assert phrase in str(caught.value) and "\n" not in str(caught.value)
    built = runner.invoke(app, ["build", str(out), "--no-preview"])
    assert built.exit_code == 1 and "Traceback" not in built.output and phrase[:40] in " ".join(built.output.split())


def test_a_stage_linked_from_outside_its_folder_is_refused(tmp_path):
    out = two_stages(tmp_path / "c")
    (tmp_path / "elsewhere.yaml").write_text((out / "stage_01.yaml").read_text())
    (out / "stage_01.yaml").unlink()
    (out / "stage_01.yaml").symlink_to(tmp_path / "elsewhere.yaml")
    with pytest.raises(curriculum.CurriculumError, match="lists stage_01.yaml, a link to .*elsewhere.yaml outside the "
                                                         "curriculum's folder; copy the file in instead"):
        curriculum.load(out)


@pytest.mark.parametrize("edit,phrase", [
    (lambda t: t.replace("kind: list", "kind: bogus"), "kind 'bogus' is not how fieldgen curriculum makes stages; one "
     "of: interpolation, grid, list, start_states, or several joined by ', then '"),
    (lambda t: t.replace("file: stage_02.yaml", "file: stage_01.yaml"), "stage 2 ('c_s02') has the file "
     "'stage_01.yaml' of stage 1; each stage has a file of its own"),
    (lambda t: t.replace("name: c_s02", "name: c_s01"), "stage 2 ('c_s01') has the name 'c_s01' of stage 1"),
    (lambda t: t.replace("name: c_s02", "name: \"c\\u202e\\0\""), "stage 2 ('c\\u202e\\x00') lists stage_02.yaml"),
], ids=["kind", "file_twice", "name_twice", "name_unprintable"])
def test_an_index_edited_past_what_fieldgen_writes_names_the_stage_and_what_is_allowed(tmp_path, edit, phrase):
    """Before: an unknown kind was read, a stage listed twice was "a stage file or name appears twice" (or a stray
    file), and a name's NUL or right-to-left mark was printed raw."""
    out = two_stages(tmp_path / "c")
    index = out / "curriculum.yaml"
    index.write_text(edit(index.read_text()))
    if "unprintable" in phrase or "\\x00" in phrase:
        (out / "stage_02.yaml").unlink()
    with pytest.raises(curriculum.CurriculumError) as caught:
        curriculum.load(out)
    assert phrase in str(caught.value) and "\0" not in str(caught.value) and "\u202e" not in str(caught.value)


def test_a_stage_that_is_a_link_to_itself_is_said_to_lead_nowhere(tmp_path):
    """Before: a link loop was reported as a file that is missing."""
    out = two_stages(tmp_path / "c")
    (out / "stage_02.yaml").unlink()
    (out / "stage_02.yaml").symlink_to(out / "stage_02.yaml")
    with pytest.raises(curriculum.CurriculumError, match="lists stage_02.yaml, a link that leads to no file"):
        curriculum.load(out)


def test_a_curriculum_of_more_stages_than_fieldgen_reads_is_refused_before_it_is_written(tmp_path):
    """Before: --stages 100000 ran for minutes writing a folder no run could use."""
    result = runner.invoke(app, ["curriculum", "point_nav", "--to", "point_nav", "--stages", "100000", "-o",
                                 str(tmp_path / "c")])
    assert result.exit_code == 1 and "is a whole number from 2 to 1,000" in result.output
    assert list(tmp_path.iterdir()) == []


def test_refusals_name_the_bundled_fields_that_would_serve(tmp_path):
    """A curriculum across agents offers fields of the target's agent; the automatic curriculum on a field
    without a ball and a fixed target offers fields of its agent that have both."""
    from fieldgen.curriculum.levels import LevelError, LevelSpace

    refused = runner.invoke(app, ["curriculum", "point_soccer", "--to", "soccer_v1", "--stages", "3",
                                  "-o", str(tmp_path / "c")])
    said = " ".join(refused.output.split())
    assert refused.exit_code == 1 and "bundled fields that could start one to soccer_v1:" in said, said
    offered = said.split("could start one to soccer_v1:")[1].replace(",", " ").split()
    assert "soccer_v2" in offered and "point_nav" not in offered and "soccer_v1" not in offered
    with pytest.raises(LevelError, match="bundled fields for the point agent that have both: point_soccer"):
        LevelSpace.of(load_spec(bundled_fields()["point_nav"]))


@pytest.mark.parametrize("args,phrase", [
    (["--threshold", "2"], "promotion threshold (--threshold) 2: the success_any that promotes a run is a share of "
                           "episodes, above 0 and at most 1"),
    (["--threshold", "nan"], "--threshold nan: the success_any that promotes a run to the next stage is a number"),
    (["--threshold", "abc"], "--threshold abc: the success_any that promotes a run to the next stage is a number, "
                             "such as 0.5"),
    (["--window", "0"], "promotion window (--window) 0: the evaluations averaged for promotion are a whole number "
                        "from 1 to"),
    (["--window", "2.5"], "--window 2.5: the number of evaluations averaged for promotion is a whole number"),
    (["--window", "two"], "--window two: the number of evaluations averaged for promotion is a whole number"),
])
def test_a_promotion_out_of_range_names_its_option_and_writes_nothing(tmp_path, args, phrase):
    out = tmp_path / "c"
    result = runner.invoke(app, ["curriculum", "point_nav", "--vary", "task.target.radius=1,2", "-o", str(out), *args])
    said = " ".join(result.output.split())
    assert result.exit_code == 1 and phrase in said and "Promotion(" not in said and not out.exists(), said


@pytest.mark.parametrize("args,phrase", [
    (["--start-near", "far"], "--start-near far: the first stage's distance from the ball to the target is a number"),
    (["--start-near", "2", "--agent-near", "x"], "--agent-near x: the first stage's distance from the agent to the "
                                                 "ball is a number"),
    (["--to", "point_nav", "--switch-at", "half"], "--switch-at half: the stage where booleans and choices switch is "
                                                   "a whole number"),
])
def test_a_curriculum_option_given_no_number_says_what_it_takes(tmp_path, args, phrase):
    out = tmp_path / "c"
    result = runner.invoke(app, ["curriculum", "point_nav", "-o", str(out), *args])
    said = " ".join(result.output.split())
    assert result.exit_code == 1 and phrase in said and "Invalid value" not in said and not out.exists(), said


@pytest.mark.parametrize("args,phrase", [
    (["--vary", "task.target.radius=1,,2"], "--vary 'task.target.radius=1,,2': value 2 of 3 is empty"),
    (["--stage", ""], "--stage number 1 is empty: each --stage changes the base"),
    (["--to", "point_nav"], "--to point_nav: it is the same field as point_nav (nothing but its name differs)"),
])
def test_a_curriculum_asked_for_nothing_is_refused_rather_than_written(tmp_path, args, phrase):
    """An empty value, an empty stage or a target that is the base would write stages that quietly drop what was
    asked or repeat the base field."""
    out = tmp_path / "c"
    result = runner.invoke(app, ["curriculum", "point_nav", "-o", str(out), *args])
    said = " ".join(result.output.split())
    assert result.exit_code == 1 and phrase in said and not out.exists(), said


def test_a_grid_axis_varies_a_list_written_in_brackets(tmp_path):
    """A comma inside brackets belongs to its value: ball.spawn.x=[-0.5,0.5],[-1,1] is two spawn ranges (before,
    the commas split it into four values that were no YAML)."""
    out = tmp_path / "spread"
    result = runner.invoke(app, ["curriculum", "soccer_v1", "--vary", "ball.spawn.x=[-0.5,0.5],[-1, 1]", "-o", str(out)])
    assert result.exit_code == 0, result.output
    stages = sorted(out.glob("stage_*.yaml"))
    assert [load_spec(path).ball.spawn.x for path in stages] == [(-0.5, 0.5), (-1.0, 1.0)]


def test_a_curriculum_folder_under_a_file_names_the_file_in_the_way(tmp_path):
    """Before: "fix the folder's permissions", which no permission mends."""
    (tmp_path / "notes.json").write_text("mine")
    out = tmp_path / "notes.json" / "cur"
    result = runner.invoke(app, ["curriculum", "point_nav", "--vary", "task.target.radius=1,2", "-o", str(out)])
    said = " ".join(result.output.split())
    assert result.exit_code == 1 and f"{tmp_path / 'notes.json'} is a file, not a folder; move it aside or choose " \
        "another -o" in said, said
    assert (tmp_path / "notes.json").read_text() == "mine"


@pytest.mark.parametrize("folder, first", [("日本", "curriculum_s01"), ("Wide Goalie (v2)", "wide_goalie_v2_s01"),
                                           ("é2", "2_s01")])
def test_stage_names_come_from_any_folder_name_as_field_names(tmp_path, folder, first):
    """A stage's name is a field name (ASCII letters, digits, _ and -), whatever letters its folder's name uses."""
    variants = curriculum.interpolate(FIELDS["soccer_v1"], FIELDS["soccer_v2"], 2)
    c = curriculum.write(tmp_path / folder, "soccer_v1", FIELDS["soccer_v1"], "interpolation", variants,
                         curriculum.Promotion())
    assert [s.name for s in c.stages] == [first, first.replace("s01", "s02")]
