"""`fieldgen train FIELD` with a field's recipe: which recipe and why in one line, flags and --set over it,
the PPO-on-sparse warning, `fieldgen list --recipes`, and run.json keeping the recipe a run was set up from."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fieldgen.cli import app
from fieldgen.run import recipe
from fieldgen.schema import bundled_fields, load_spec

runner = CliRunner()


FALL = ", on episodes ending once the ant has lain turned over for 50 control steps in a row"
FALL_KEYS = ("episode.fall.kind", "episode.fall.grace_steps", "episode.fall.tilt_deg")  # never -> flipped, 50 steps
BENCH_FIELDS = Path(__file__).resolve().parents[2] / "bench" / "fields"


def lines_with(output: str, phrase: str) -> list[str]:
    return [line for line in output.splitlines() if phrase in line]


def test_a_field_of_ones_own_takes_the_recipe_of_the_field_it_extends_and_says_so(tmp_path):
    spec = tmp_path / "my_wide.yaml"
    spec.write_text("extends: v2_wide_goalie_dense\nname: my_wide\nobstacles:\n  goalie: {width: 2.5}\n")
    chosen = recipe.choose(spec, None)
    assert chosen.algo == "ppo" and chosen.recipe.field == "v2_wide_goalie_dense"
    assert chosen.line([]) == (
        "recipe v2_wide_goalie_dense for my_wide, which extends v2_wide_goalie_dense: ppo, 300M env steps, 8,192 "
        "envs, --set ppo.num_evals=15 --set ppo.spread=global, on sim.backend warp, on episodes ending once the ant "
        "has lain turned over for 50 control steps in a row; not measured on my_wide yet "
        "(v2_wide_goalie_dense: "
        f"{chosen.recipe.measured.stated}, {chosen.recipe.measured.seeds})")
    own = recipe.choose(bundled_fields()["v2_wide_goalie_dense"], None)
    assert own.line(["--steps"]) == (  # its physics twin on Warp states the same runs: not again as another route
        "recipe v2_wide_goalie_dense: ppo, 300M env steps, 8,192 envs, --set ppo.num_evals=15 --set "
        "ppo.spread=global, on sim.backend warp, on episodes ending once the ant has lain turned over for 50 control "
        f"steps in a row; measured: {own.recipe.measured.stated}, three fresh seeds (1020-1022); --steps overrides it")
    assert recipe.choose(spec, None, use=False).recipe is None
    other = recipe.choose(spec, "crl")
    assert other.recipe is None and other.algo == "crl" and "not taken: --algo crl" in other.line([])


def test_a_sparse_field_without_a_recipe_of_its_own_points_to_its_dense_twin_as_the_measured_route():
    route = recipe.dense_route("soccer_v2")
    assert route.startswith("; the measured route is its dense twin soccer_v2_dense (ppo, 300M env steps, 8,192 "
                            "envs, --set ppo.num_evals=15 --set ppo.spread=global, on sim.backend warp, on episodes "
                            "ending once the ant has lain turned over for 50 control steps in a row): IQM 0.851")
    assert "also measured" not in route and route.endswith("three fresh seeds (1030-1032)")
    assert recipe.dense_route("point_nav") == ""  # no dense twin bundled


def test_a_field_on_other_physics_keeps_its_own_measured_recipe_over_the_one_it_extends():
    chosen = recipe.choose(bundled_fields()["v2_wide_goalie_dense_warp"], None)
    assert (chosen.algo, chosen.recipe.steps, chosen.recipe.envs) == ("ppo", 300_000_000, 8192)
    assert chosen.recipe.sets == ("ppo.num_evals=15", "ppo.spread=global")
    assert chosen.line([]).startswith("recipe v2_wide_goalie_dense_warp: ppo, 300M env steps, 8,192 envs")
    assert "three fresh seeds (1020-1022)" in chosen.line([]) and "also measured" not in chosen.line([])


def test_an_unmeasured_recipe_names_its_task_measured_on_other_physics_and_not_other_tasks_extending_it(
        tmp_path, monkeypatch):
    from fieldgen.agents import recipes

    table = tmp_path / "recipes.yaml"  # soccer_v2_dense's recipe before its own figure: its twins measured alone
    table.write_text("soccer_v2_dense:\n  algo: ppo\n  steps: 250000000\n"
                     "soccer_v2_dense_warp:\n  extends: soccer_v2_dense\n"
                     "  measured: {figure: IQM 0.668, seeds: three fresh seeds (1010-1012), data: here}\n"
                     "v2_wide_goalie_dense:\n  extends: soccer_v2_dense\n"
                     "  measured: {figure: IQM 0.675, seeds: three fresh seeds (990-992), data: there}\n")
    monkeypatch.setattr(recipes.read, "__defaults__", (table,))
    said = recipe.choose(bundled_fields()["soccer_v2_dense"], None).line([])
    assert said == ("recipe soccer_v2_dense: ppo, 250M env steps; not measured yet; also measured: "
                    "soccer_v2_dense_warp, IQM 0.668, three fresh seeds (1010-1012)")
    assert "v2_wide_goalie" not in said  # extends soccer_v2_dense with another goalie: another task
    sparse = dict((name, route) for name, _, route in recipe.listing())["soccer_v2"]
    assert sparse == "its dense twin soccer_v2_dense: measured on other physics"
    assert recipe.statement("soccer_v2") == (
        "soccer_v2: no recipe (its trainer's defaults); its dense twin soccer_v2_dense is not measured itself; "
        "also measured: soccer_v2_dense_warp, IQM 0.668, three fresh seeds (1010-1012)")


def test_fields_differing_in_physics_alone_set_the_same_task():
    fields = bundled_fields()
    assert recipe.same_task(fields["soccer_v2_dense"], fields["soccer_v2_dense_warp"])
    assert not recipe.same_task(fields["soccer_v2_dense"], fields["v2_wide_goalie_dense"])


def test_ppo_on_a_success_signal_alone_is_warned_of_naming_the_dense_twin():
    wide = load_spec(bundled_fields()["v2_wide_goalie"])
    assert recipe.sparse_warning(wide, "ppo") == (
        "warning: PPO learns nothing from a success signal alone, and v2_wide_goalie's reward is its success; "
        "train its dense twin instead: fieldgen train v2_wide_goalie_dense")
    assert recipe.sparse_warning(wide, "crl") is None
    assert recipe.sparse_warning(load_spec(bundled_fields()["v2_wide_goalie_dense"]), "ppo") is None
    soccer = load_spec(bundled_fields()["point_soccer"])  # reward terms, set aside by ppo.reward=sparse
    assert recipe.sparse_warning(soccer, "ppo") is None
    assert recipe.sparse_warning(soccer, "ppo", "sparse") == (
        "warning: PPO learns nothing from a success signal alone until its first success, and ppo.reward=sparse "
        "trains it on point_soccer's success; leave ppo.reward at dense to train on the field's reward terms")
    assert recipe.sparse_warning(soccer, "crl", "sparse") is None  # CRL learns from the success by hindsight
    match = load_spec(bundled_fields()["soccer_1v1"])  # a match's terms; its success is a goal
    assert recipe.sparse_warning(match, "ppo") is None
    assert "ppo.reward=sparse trains it on soccer_1v1's success" in recipe.sparse_warning(match, "ppo", "sparse")
    nav = load_spec(bundled_fields()["point_nav"])  # no twin: the dense reward its task has
    assert recipe.sparse_warning(nav, "ppo").endswith("give the field the dense reward of its task: task: "
                                                      "{reward: dense}")


def test_train_prints_the_recipe_its_overrides_and_the_warning_once_and_run_json_keeps_the_recipe(tmp_path):
    spec = tmp_path / "my_soccer.yaml"
    spec.write_text("extends: point_soccer\nname: my_soccer\ngoal: {distance: 3.5}\n")
    result = runner.invoke(app, ["train", str(spec), "--envs", "8", "--set", "crl.num_evals=2", "--prepare",
                                 "--out", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    said = lines_with(result.output, "recipe point_soccer")
    assert said == ["recipe point_soccer for my_soccer, which extends point_soccer: crl, --preset cpu; not measured "
                    "on my_soccer yet; --envs and --set override it"]
    saved = json.loads((tmp_path / "runs" / "my_soccer-crl-0" / "run.json").read_text())
    assert saved["recipe"] == {"field": "point_soccer", "algo": "crl", "preset": "cpu",
                               "overridden_by": ["--envs", "--set"]}
    assert (saved["config"]["num_envs"], saved["config"]["num_evals"], saved["config"]["hidden"]) == (8, 2, [64, 64])
    sparse = runner.invoke(app, ["train", "point_nav", "--algo", "ppo", "--seeds", "2", "--envs", "8", "--prepare",
                                 "--out", str(tmp_path / "ppo")])
    assert sparse.exit_code == 0, sparse.output
    assert len(lines_with(sparse.output, "PPO learns nothing from a success signal alone")) == 1
    plain = runner.invoke(app, ["train", "point_soccer", "--no-recipe", "--envs", "8", "--prepare",
                                "--out", str(tmp_path / "plain")])
    assert plain.exit_code == 0 and not lines_with(plain.output, "recipe point_soccer"), plain.output
    saved = json.loads((tmp_path / "plain" / "point_soccer-crl-0" / "run.json").read_text())
    assert "recipe" not in saved and saved["config"]["hidden"] == [256, 256]


def test_list_shows_each_bundled_fields_recipe_and_the_headline_of_its_figure_with_its_seeds():
    rows = {name: (recipe_text, measured) for name, recipe_text, measured in recipe.listing()}
    assert set(rows) == set(bundled_fields())
    assert rows["v2_wide_goalie_dense"] == ("ppo, 300M env steps, 8,192 envs, --set ppo.num_evals=15 --set "
                                            "ppo.spread=global, on sim.backend warp" + FALL, "IQM 0.885 "
                                            "[0.857, 0.913] success at 300M env steps; three fresh seeds (1020-1022)")
    assert rows["soccer_v2_dense"][1].startswith("IQM 0.851 [0.812, 0.897]")
    assert rows["ant_nav"][1] == "IQM 0.923 [0.899, 0.947] success at 14M env steps; five fresh seeds (600-604)"
    assert rows["v2_wide_goalie"][0].endswith("on its task's dense reward, on sim.backend warp" + FALL)
    assert rows["v2_wide_goalie"][1].startswith("IQM 0.866 [0.803, 0.906] success at 280M env steps")
    assert rows["soccer_v1_dense"][1].startswith("IQM 0.895 [0.887, 0.907]")
    assert rows["soccer_v2_dense_near"] == (rows["soccer_v2_dense"][0] + " (the recipe of soccer_v2_dense)",
                                            "not measured yet")
    assert rows["soccer_v2"][1] == "its dense twin soccer_v2_dense: IQM 0.851 [0.812, 0.897] success at 300M env steps"
    assert rows["point_soccer"] == ("crl, --preset cpu", "not measured yet")
    assert rows["point_nav"] == ("none: crl with its defaults", "-")
    assert rows["soccer_1v1"][0] == "none: ppo self-play with its defaults"  # a match trains by self-play
    shown = runner.invoke(app, ["list", "--recipes"])
    assert shown.exit_code == 0 and all(name in shown.output for name in rows), shown.output
    assert "0.885" in shown.output and "(1020-1022)" in shown.output
    assert "fieldgen list --recipes FIELD" in shown.output


def test_list_states_the_recipes_of_the_fields_named_in_full_with_the_page_of_their_runs():
    assert recipe.statement("ant_nav") == (
        "ant_nav: crl, 14M env steps, --set crl.num_evals=7; measured: IQM 0.923 [0.899, 0.947] success at 14M env "
        "steps, 1,024 episodes a seed; five seeds in one program in 414 s on one H200, five fresh seeds (600-604); "
        "data and commands: bench/results/crl_ant_residual_network/README.md")
    assert recipe.statement("soccer_v2_dense_near").startswith(
        "soccer_v2_dense_near: ppo, 300M env steps, 8,192 envs, --set ppo.num_evals=15 --set ppo.spread=global, on "
        "sim.backend warp" + FALL + " (the recipe of soccer_v2_dense); not measured on soccer_v2_dense_near yet "
        "(soccer_v2_dense: IQM 0.851 [0.812, 0.897] success at 300M env steps, 1,024 episodes a seed")
    assert recipe.statement("point_nav") == "point_nav: no recipe (its trainer's defaults); no measured route"
    shown = runner.invoke(app, ["list", "--recipes", "soccer_v1", "ant_nav"])
    said = [" ".join(line.split()) for line in shown.output.splitlines()]
    assert shown.exit_code == 0 and said == [recipe.statement("soccer_v1"), recipe.statement("ant_nav")]
    described = runner.invoke(app, ["list", "point_nav"])
    assert described.exit_code == 0 and "point_nav" in described.output and "ant_nav" not in described.output
    wrong = runner.invoke(app, ["list", "--recipes", "v2_wide_goali"])
    assert wrong.exit_code == 1 and "'v2_wide_goali' is not a bundled field; did you mean 'v2_wide_goalie'?" in \
        " ".join(wrong.output.split())


def test_a_broken_recipes_file_is_one_line_from_train_and_list(tmp_path, monkeypatch):
    from fieldgen.agents import recipes

    broken = tmp_path / "recipes.yaml"
    broken.write_text("point_soccer:\n  algo: crl\n  envz: 8\n")
    monkeypatch.setattr(recipes, "RECIPES", broken)
    monkeypatch.setattr(recipes.read, "__defaults__", (broken,))
    for args in (["train", "point_soccer", "--prepare", "--out", str(tmp_path)], ["list", "--recipes"]):
        result = runner.invoke(app, args)
        message = " ".join(result.output.split())
        assert result.exit_code == 1 and "Traceback" not in result.output, result.output
        assert f"{broken}:3: recipe 'point_soccer': unknown key 'envz'; did you mean 'envs'?" in message


@pytest.mark.slow
def test_train_point_soccer_end_to_end_with_its_cpu_recipe(tmp_path, tiny_crl_args):
    """point_soccer's recipe (CRL, the cpu preset) trained to its end with the tests' tiny settings over it."""
    result = runner.invoke(app, ["train", "point_soccer", "--no-videos", "--out", str(tmp_path), *tiny_crl_args])
    assert result.exit_code == 0, result.output
    run = tmp_path / "point_soccer-crl-0"
    saved = json.loads((run / "run.json").read_text())
    assert saved["recipe"]["field"] == "point_soccer" and saved["recipe"]["preset"] == "cpu"
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert [row["eval"] for row in rows] == list(range(saved["config"]["num_evals"] + 1))[-len(rows):]
    assert (run / "learner.msgpack").is_file() and rows[-1]["env_steps"] > rows[0]["env_steps"]


def test_a_team_field_takes_its_recipe_as_any_field_and_flags_override_it(tmp_path):
    result = runner.invoke(app, ["train", "soccer_2v2", "--prepare", "--out", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    assert len(lines_with(result.output, "recipe soccer_2v2: ppo, 1M env steps, 512 envs")) == 1
    saved = json.loads((tmp_path / "runs" / "soccer_2v2-ppo-0" / "run.json").read_text())
    assert saved["selfplay"] and saved["recipe"]["field"] == "soccer_2v2"
    config = saved["config"]
    assert (config["total_steps"], config["num_envs"], config["num_evals"], config["self_play_share"]) == (
        1_000_000, 512, 4, 0.2)
    over = runner.invoke(app, ["train", "soccer_2v2", "--set", "ppo.self_play_share=0.3", "--seed", "1",
                               "--prepare", "--out", str(tmp_path / "runs")])
    assert over.exit_code == 0 and lines_with(over.output, "--set overrides it"), over.output
    config = json.loads((tmp_path / "runs" / "soccer_2v2-ppo-1" / "run.json").read_text())["config"]
    assert (config["self_play_share"], config["num_envs"]) == (0.3, 512)
    plain = runner.invoke(app, ["train", "soccer_2v2", "--no-recipe", "--seed", "2", "--prepare",
                                "--out", str(tmp_path / "runs")])
    assert plain.exit_code == 0 and not lines_with(plain.output, "recipe soccer_2v2"), plain.output
    saved = json.loads((tmp_path / "runs" / "soccer_2v2-ppo-2" / "run.json").read_text())
    assert "recipe" not in saved and saved["config"]["self_play_share"] == 0.5


def test_a_match_paid_for_its_goals_alone_is_warned_of_naming_the_match_terms(tmp_path):
    spec = tmp_path / "goals_only.yaml"
    spec.write_text("extends: soccer_1v1\nname: goals_only\ntask: {reward: [{term: goal}]}\n")
    assert recipe.is_sparse(load_spec(spec)) and not recipe.is_sparse(load_spec(bundled_fields()["soccer_1v1"]))
    assert recipe.sparse_warning(load_spec(spec), "ppo") == (
        "warning: PPO learns nothing from a success signal alone, and goals_only's reward is its success; list match "
        "terms that pay the way to a goal under task.reward (docs/teams.md)")
    result = runner.invoke(app, ["train", str(spec), "--envs", "8", "--prepare", "--out", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    assert len(lines_with(result.output, "warning: PPO learns nothing")) == 1


def test_a_field_differing_in_physics_alone_names_the_field_it_is_judged_on(tmp_path):
    fields = bundled_fields()
    assert recipe.physics_twin(load_spec(fields["soccer_v2_dense_warp"])) == "soccer_v2_dense"
    assert recipe.physics_twin(load_spec(fields["soccer_v2_dense"])) is None  # extends soccer_v2: another task
    own = tmp_path / "point_soccer_warp.yaml"
    own.write_text("extends: point_soccer\nname: point_soccer_warp\nsim: {backend: warp}\n")
    assert recipe.physics_twin(load_spec(own)) == "point_soccer"
    own.write_text("extends: point_soccer\nname: point_soccer_warp\nsim: {backend: warp}\nepisode: {length: 100}\n")
    assert recipe.physics_twin(load_spec(own)) is None  # other physics and a shorter episode: not the same task


def changed_keys(trained, written, prefix: str = "") -> set[str]:
    """The dotted keys where two specs (or their dumps) differ, down to the first that is not a mapping."""
    a, b = (x.model_dump(mode="json") if hasattr(x, "model_dump") else x for x in (trained, written))
    if not (isinstance(a, dict) and isinstance(b, dict)):
        return {prefix.rstrip(".")} if a != b else set()
    return {k for key in a.keys() | b.keys() for k in changed_keys(a.get(key), b.get(key), f"{prefix}{key}.")}


def spec_keys(data: dict) -> dict:
    """A resolved spec without what names it: what a run trains on."""
    return {k: v for k, v in data.items() if k not in ("name", "description", "extends")}


def assert_builds_alike(trained, twin):
    """The field a recipe trains on builds to the same field.json and scene as `twin`, but for what names it."""
    from fieldgen.compile.artifact import compile_spec

    ours, theirs = compile_spec(trained), compile_spec(twin)
    named = (f'<mujoco model="{trained.name}">', f'<mujoco model="{twin.name}">')
    assert ours.xml.replace(*named) == theirs.xml  # the scene: the same but for the model's name
    digests = ("name", "hash", "scene_sha256", "record_sha256")  # each over the name too
    alike = [{**{k: v for k, v in meta.items() if k not in digests}, "spec": spec_keys(meta["spec"])}
             for meta in (ours.metadata(), theirs.metadata())]
    assert alike[0] == alike[1] and ours.metadata()["name"] == trained.name


def test_the_users_field_trains_on_the_field_its_recipes_figure_was_measured_on():
    """v2_wide_goalie's recipe trains it on its task's dense reward on Warp's physics, its episodes ending once
    the ant lies turned over: the very field bench/fields/v2_wide_goalie_dense_flip_warp.yaml builds to but for
    its name, which is why that field's figure is the recipe's."""
    fields = bundled_fields()
    chosen = recipe.choose(fields["v2_wide_goalie"], None)
    assert (chosen.algo, chosen.recipe.reward, chosen.recipe.backend) == ("ppo", "dense", "warp")
    assert (chosen.recipe.steps, chosen.recipe.envs) == (300_000_000, 8192)
    assert "1040-1042" in chosen.recipe.measured.seeds and chosen.line([]).startswith(
        "recipe v2_wide_goalie: ppo, 300M env steps, 8,192 envs, --set ppo.num_evals=15 --set ppo.spread=global, on "
        "its task's dense reward, on sim.backend warp" + FALL + "; measured: IQM 0.866 [0.803, 0.906]")
    written = load_spec(fields["v2_wide_goalie"])
    trained, note = recipe.training(written, chosen.recipe, trains_here=False)
    assert note is None and changed_keys(trained, written) == {"task.reward", "sim.backend", *FALL_KEYS}
    assert trained.sim.backend == "warp" and trained.name == "v2_wide_goalie"
    assert_builds_alike(trained, load_spec(BENCH_FIELDS / "v2_wide_goalie_dense_flip_warp.yaml"))
    assert recipe.trained_form(trained, written) == (
        "its task's dense reward, sim.backend warp and episodes ending once the ant has lain turned over for 50 "
        "control steps in a row (2.5 s)")
    assert recipe.training_line(trained, written) == (
        "trains v2_wide_goalie on its task's dense reward (task: {reward: dense}: ball_path_progress, "
        "agent_behind_ball, success, upright, control_cost), sim.backend warp (MuJoCo Warp through MJX: NVIDIA "
        "GPUs; on a CPU Warp's CPU kernels, slow) and episodes ending once the ant has lain turned over for 50 "
        "control steps in a row (2.5 s; episode: {fall: {kind: flipped, grace_steps: 50}}), as its recipe says; the "
        "run keeps the field as written, and fieldgen eval judges it there (the same success)")


def test_soccer_v1_dense_trains_on_the_field_its_recipes_figure_was_measured_on():
    """soccer_v1_dense's recipe is soccer_v2_dense's: Warp's physics and episodes ending once the ant lies turned
    over, the very field bench/fields/soccer_v1_dense_flip_warp.yaml builds to but for its name, whose tuning
    seeds gave the recipe's figure."""
    fields = bundled_fields()
    chosen = recipe.choose(fields["soccer_v1_dense"], None)
    assert (chosen.algo, chosen.recipe.steps, chosen.recipe.envs) == ("ppo", 300_000_000, 8192)
    written = load_spec(fields["soccer_v1_dense"])
    trained, note = recipe.training(written, chosen.recipe, trains_here=False)
    assert note is None and changed_keys(trained, written) == {"sim.backend", *FALL_KEYS}
    assert_builds_alike(trained, load_spec(BENCH_FIELDS / "soccer_v1_dense_flip_warp.yaml"))


def test_where_warp_does_not_run_the_recipe_trains_on_the_fields_own_physics_and_says_why(monkeypatch):
    monkeypatch.setattr(recipe, "warp_runs_here", lambda: False)
    written = load_spec(bundled_fields()["v2_wide_goalie"])
    wide = recipe.choose(bundled_fields()["v2_wide_goalie"], None).recipe
    trained, note = recipe.training(written, wide)
    assert changed_keys(trained, written) == {"task.reward", *FALL_KEYS} and trained.sim.backend == "mjx"
    assert note.startswith("v2_wide_goalie trains on its own sim.backend mjx here: its recipe's backend warp")
    prepared, note = recipe.training(written, wide, trains_here=False)  # set up here, trained on a GPU elsewhere
    assert prepared.sim.backend == "warp" and note is None
    levels, note = recipe.training(written, wide, trains_here=False, batched=True)  # --curriculum auto's levels
    assert levels.sim.backend == "mjx" and "does not batch the levels of --curriculum auto" in note


def test_a_field_with_reward_terms_of_its_own_keeps_them_under_a_dense_recipe(tmp_path):
    own = tmp_path / "my_goalie.yaml"
    own.write_text("extends: v2_wide_goalie\nname: my_goalie\n"
                   "task: {reward: [{term: success, weight: 1.0}, {term: ball_progress, weight: 5.0}]}\n")
    written = load_spec(own)
    trained, _ = recipe.training(written, recipe.choose(own, None).recipe, trains_here=False)
    assert changed_keys(trained, written) == {"sim.backend", *FALL_KEYS} and trained.sim.backend == "warp"
    nowhere = tmp_path / "to_the_goal.yaml"  # the agent to a goal mouth: a task with no dense reward
    nowhere.write_text("extends: v2_wide_goalie\nname: to_the_goal\ntask: {success: {kind: ball_in_goal}}\n")
    with pytest.raises(recipe.RecipeError) as caught:
        recipe.training(load_spec(nowhere), recipe.choose(nowhere, None).recipe)
    assert "recipe 'v2_wide_goalie' trains to_the_goal on its task's dense reward, and its task " \
           "(task.success.kind: ball_in_goal) has none; the kinds with one are ball_near_target, " \
           "agent_near_target" in str(caught.value) and str(caught.value).endswith("--no-recipe")


def test_train_the_users_field_keeps_it_as_written_beside_the_field_it_trains_on(tmp_path):
    result = runner.invoke(app, ["train", str(bundled_fields()["v2_wide_goalie"]), "--prepare",
                                 "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    said = lines_with(" ".join(result.output.split("\n")), "trains v2_wide_goalie on its task's dense reward")
    assert len(said) == 1 and "the run keeps the field as written, and fieldgen eval judges it there" in said[0]
    run = tmp_path / "v2_wide_goalie-ppo-0"
    saved = json.loads((run / "run.json").read_text())
    assert saved["judged"] == "judged" and (saved["recipe"]["reward"], saved["recipe"]["backend"]) == ("dense", "warp")
    trained, written = (json.loads((run / sub / "field.json").read_text())["spec"] for sub in ("field", "judged"))
    assert (trained["sim"]["backend"], written["sim"]["backend"]) == ("warp", "mjx")
    assert [t["term"] for t in written["task"]["reward"]] == ["success"]
    assert trained == saved["field"] and spec_keys(written) == spec_keys(
        load_spec(bundled_fields()["v2_wide_goalie"]).model_dump(mode="json"))


def test_a_run_judged_on_the_field_as_written_and_one_judged_where_it_trained_are_not_judged_together(tmp_path):
    from fieldgen.run import evaluate, record, session

    fields = bundled_fields()
    for args in ([str(fields["v2_wide_goalie"])], [str(fields["v2_wide_goalie"]), "--no-recipe", "--algo", "ppo"]):
        result = runner.invoke(app, ["train", *args, "--seed", str(len(list(tmp_path.iterdir()))), "--envs", "16",
                                     "--prepare", "--out", str(tmp_path)])
        assert result.exit_code == 0, result.output
    recipe_run, plain_run = tmp_path / "v2_wide_goalie-ppo-0", tmp_path / "v2_wide_goalie-ppo-1"
    def judged(*runs):
        return evaluate.judged_copy(list(runs), [session.open_run(run, load_state=False).judged for run in runs])

    assert judged(recipe_run) == recipe_run / "judged" and judged(plain_run) is None
    with pytest.raises(record.RunError, match="evaluate them separately, or name the field to judge both on"):
        judged(plain_run, recipe_run)


@pytest.mark.slow
def test_a_run_trained_on_its_recipes_dense_reward_is_judged_on_the_field_as_written(tmp_path, monkeypatch,
                                                                                     tiny_crl_args):
    """point_nav (paid for its success alone) under a recipe with `reward: dense`, trained to its end with the tests'
    tiny settings: `fieldgen eval RUN` judges it on point_nav as written, --field RUN/field where it trained."""
    from fieldgen.agents import recipes

    path = tmp_path / "recipes.yaml"
    path.write_text("point_nav:\n  algo: crl\n  reward: dense\n")
    monkeypatch.setattr(recipes.read, "__defaults__", (path,))
    result = runner.invoke(app, ["train", "point_nav", "--no-videos", "--out", str(tmp_path), *tiny_crl_args])
    assert result.exit_code == 0, result.output
    run = tmp_path / "point_nav-crl-0"
    assert lines_with(" ".join(result.output.split()), f"judged on the field as written ({run / 'judged'})")
    judged = runner.invoke(app, ["eval", str(run), "--episodes", "4", "--no-video"])
    assert judged.exit_code == 0, judged.output
    said = " ".join(judged.output.split())
    assert f"judged on point_nav as written ({run / 'judged'}), where its recipe trained it on its task's dense " \
           f"reward; --field {run / 'field'} judges it on the field it trained on" in said
    summary = json.loads((run / "summary.json").read_text())
    written = load_spec(bundled_fields()["point_nav"]).model_dump(mode="json")
    from fieldgen.compile.artifact import field_digest

    assert summary["fields"] == ["point_nav"] and summary["field_digests"] == [field_digest(written)]
    trained = runner.invoke(app, ["eval", str(run), "--episodes", "4", "--no-video", "--field", str(run / "field")])
    assert trained.exit_code == 0 and "judged on point_nav as written" not in trained.output, trained.output


def test_a_run_sized_for_a_gpu_about_to_train_on_a_cpu_is_noted_once(tmp_path, monkeypatch):
    """Its first progress line would come after a chunk of millions of env steps: hours away on a CPU."""
    import fieldgen.cli.training as training_command

    trained = []
    monkeypatch.setattr(training_command, "_train", lambda run, *args, **kwargs: trained.append(run.folder))
    note = "is a run sized for a GPU, and JAX finds none here"
    for seed, steps, prepare, said in ((0, "100M", [], 1), (1, "99M", [], 0), (2, "100M", ["--prepare"], 0)):
        result = runner.invoke(app, ["train", "point_nav", "--algo", "ppo", "--steps", steps, "--envs", "8",
                                     "--seed", str(seed), "--out", str(tmp_path), *prepare])
        assert result.exit_code == 0, result.output
        assert len(lines_with(" ".join(result.output.split()), note)) == said, result.output
    assert trained == [tmp_path / "point_nav-ppo-0", tmp_path / "point_nav-ppo-1"]


def test_ppo_on_the_users_field_without_its_recipe_is_warned_to_leave_out_no_recipe(tmp_path):
    result = runner.invoke(app, ["train", str(bundled_fields()["v2_wide_goalie"]), "--no-recipe", "--algo", "ppo",
                                 "--envs", "16", "--prepare", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert lines_with(result.output, "warning: PPO learns nothing")[0].endswith(
        "v2_wide_goalie's reward is its success; its recipe (v2_wide_goalie) trains it on its task's dense reward: "
        "leave out --no-recipe")


FLIP = {"kind": "flipped", "grace_steps": 50}
FLIP_WARP = Path(__file__).parents[2] / "bench" / "fields" / "v2_wide_goalie_dense_flip_warp.yaml"


def flip_recipes(tmp_path, monkeypatch) -> dict:
    """A recipes file, read as the bundled one is, whose v2_wide_goalie_dense trains with PPO on its task's dense
    reward on Warp's physics and on episodes that end once the ant has lain turned over 50 control steps in a row;
    v2_wide_goalie extends it."""
    from fieldgen.agents import recipes

    path = tmp_path / "recipes.yaml"
    path.write_text("v2_wide_goalie_dense:\n  algo: ppo\n  reward: dense\n  backend: warp\n"
                    "  fall: {kind: flipped, grace_steps: 50}\nv2_wide_goalie:\n  extends: v2_wide_goalie_dense\n")
    monkeypatch.setattr(recipes.read, "__defaults__", (path,))
    return recipes.read(path)


@pytest.mark.parametrize("name,form", [
    ("v2_wide_goalie_dense", "sim.backend warp and episodes ending once the ant has lain turned over for 50 control "
                             "steps in a row (2.5 s)"),
    ("v2_wide_goalie", "its task's dense reward, sim.backend warp and episodes ending once the ant has lain turned "
                       "over for 50 control steps in a row (2.5 s)"),
])
def test_a_fall_recipe_trains_the_field_on_the_twin_whose_episodes_end_once_the_ant_lies_turned_over(
        tmp_path, monkeypatch, name, form):
    """The recipe that bench/fields/v2_wide_goalie_dense_flip_warp.yaml's tuning runs say: the field it trains on
    builds to that field but for its name, from the dense field (whose reward terms are its own) and from the
    field paid for its success alone alike."""
    flip_recipes(tmp_path, monkeypatch)
    chosen = recipe.choose(bundled_fields()[name], None)
    assert chosen.recipe.fall == FLIP and chosen.line([]).startswith(
        f"recipe {name}: ppo, on its task's dense reward, on sim.backend warp, on episodes ending once the ant has "
        "lain turned over for 50 control steps in a row; not measured yet")
    written = load_spec(bundled_fields()[name])
    trained, note = recipe.training(written, chosen.recipe, trains_here=False)
    assert note is None and trained.name == name and trained.episode.fall.model_dump() == {**FLIP, "tilt_deg": 90.0}
    assert_builds_alike(trained, load_spec(FLIP_WARP))
    assert recipe.trained_form(trained, written) == form
    assert recipe.training_line(trained, written).startswith(f"trains {name} on ") and \
        " and episodes ending once the ant has lain turned over for 50 control steps in a row (2.5 s; episode: " \
        "{fall: {kind: flipped, grace_steps: 50}}), as its recipe says; the run keeps the field as written" in \
        recipe.training_line(trained, written)


def test_a_field_with_a_fall_rule_of_its_own_keeps_it_and_a_point_agent_is_left_as_written(tmp_path, monkeypatch):
    from fieldgen.agents.recipes import Recipe

    table = flip_recipes(tmp_path, monkeypatch)
    banded = tmp_path / "banded.yaml"
    banded.write_text("extends: v2_wide_goalie_dense\nname: banded\nepisode: {fall: {kind: height_band}}\n")
    trained, note = recipe.training(load_spec(banded), table["v2_wide_goalie_dense"], trains_here=False)
    assert changed_keys(trained, load_spec(banded)) == {"sim.backend"} and trained.episode.fall.kind == "height_band"
    assert recipe.training(load_spec(FLIP_WARP), table["v2_wide_goalie_dense"]) == (None, None)  # all its own already
    point = Recipe(field="point_nav", algo="crl", fall=FLIP, where="recipes.yaml:1")
    assert recipe.training(load_spec(bundled_fields()["point_nav"]), point) == (
        None, "point_nav trains with its own episode.fall never: its recipe's fall rule ends an ant's episodes, and "
              "its point agent never falls")


def test_a_fall_rule_the_field_refuses_is_one_line_at_the_recipe(tmp_path, monkeypatch):
    from fieldgen.schema import loader

    table = flip_recipes(tmp_path, monkeypatch)
    checked = loader.physics_problems
    monkeypatch.setattr(loader, "physics_problems", lambda spec: checked(spec) + [
        (("episode", "fall", "kind"), "not on this field")] * (spec.episode.fall.kind == "flipped"))
    with pytest.raises(recipe.RecipeError) as caught:
        recipe.training(load_spec(bundled_fields()["v2_wide_goalie_dense"]), table["v2_wide_goalie_dense"],
                        trains_here=False)
    assert str(caught.value) == (
        f"{tmp_path / 'recipes.yaml'}:1: recipe 'v2_wide_goalie_dense' trains v2_wide_goalie_dense with episode.fall "
        "{kind: flipped, grace_steps: 50}, which it refuses: episode.fall.kind: not on this field; write another fall "
        "rule in the recipe, or train with the defaults: --no-recipe")


def test_run_json_keeps_a_recipes_fall_rule_and_the_run_the_field_as_written(tmp_path, monkeypatch):
    flip_recipes(tmp_path, monkeypatch)
    result = runner.invoke(app, ["train", str(bundled_fields()["v2_wide_goalie"]), "--envs", "16", "--prepare",
                                 "--out", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())
    assert "sim.backend warp (MuJoCo Warp through MJX: NVIDIA GPUs; on a CPU Warp's CPU kernels, slow) and episodes " \
           "ending once the ant has lain turned over for 50 control steps in a row (2.5 s; episode: {fall: {kind: " \
           "flipped, grace_steps: 50}}), as its recipe says" in said
    run = tmp_path / "runs" / "v2_wide_goalie-ppo-0"
    saved = json.loads((run / "run.json").read_text())
    assert saved["recipe"] == {"field": "v2_wide_goalie", "algo": "ppo", "reward": "dense", "backend": "warp",
                               "fall": FLIP, "overridden_by": ["--envs"]}
    trained, written = (json.loads((run / sub / "field.json").read_text())["spec"] for sub in ("field", "judged"))
    assert trained["episode"]["fall"] == {**FLIP, "tilt_deg": 90.0} and written["episode"]["fall"] == {"kind": "never"}


@pytest.mark.parametrize("keys, named", [("  reward: dense\n", "names reward, which"),
                                         ("  fall: {kind: flipped, grace_steps: 50}\n", "names fall, which"),
                                         ("  backend: warp\n  fall: {kind: flipped}\n", "names backend and fall, which")])
def test_a_team_field_s_recipe_naming_what_a_match_keeps_its_own_is_refused_before_a_folder(tmp_path, monkeypatch,
                                                                                          keys, named):
    """A match trains on its own terms, physics and episode rules: a recipe's reward, backend or fall would be
    dropped without a word (a fall rule was, before), so each is refused, named, at the recipe's line."""
    from fieldgen.agents import recipes

    path = tmp_path / "recipes.yaml"
    path.write_text("soccer_1v1:\n  algo: ppo\n" + keys)
    monkeypatch.setattr(recipes.read, "__defaults__", (path,))
    result = runner.invoke(app, ["train", "soccer_1v1", "--prepare", "--out", str(tmp_path / "runs")])
    said = " ".join(result.output.split())
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert f"{path}:1: recipe 'soccer_1v1' {named} a team field's recipe cannot" in said
    assert "leave" in said and "--no-recipe" in said and not (tmp_path / "runs").exists()
