"""Recipes: read from presets/recipes.yaml with `extends`, found through a field's own `extends`, layered between
the agent's preset and everything the command line says, and refused in one sentence where a key is wrong."""

from __future__ import annotations

import pytest

from fieldgen.agents import recipes
from fieldgen.agents.config import ConfigError
from fieldgen.agents.crl import CRLConfig
from fieldgen.agents.ppo import PPOConfig
from fieldgen.agents.recipes import RecipeError
from fieldgen.agents.registry import trainer
from fieldgen.agents.selfplay import SelfPlayConfig
from fieldgen.schema import bundled_fields, load_spec


def test_every_bundled_recipe_names_settings_its_trainer_takes():
    table = recipes.read()
    assert {"soccer_v2_dense", "v2_wide_goalie_dense", "v2_wide_goalie", "ant_nav", "point_soccer"} <= set(table)
    fields = bundled_fields()
    for recipe in table.values():
        team = load_spec(fields[recipe.field]).teams is not None  # a match trains by self-play
        trains = SelfPlayConfig if team else trainer(recipe.algo).config
        config = trains.layered(recipe=recipe, agent="ant")
        assert config.total_steps == (recipe.steps or trains().total_steps)


def test_the_measured_recipes_are_the_commands_their_figures_came_from():
    table = recipes.read()
    dense = table["soccer_v2_dense"]  # as its twin on Warp's physics, soccer_v2_dense_warp, was measured
    assert (dense.algo, dense.steps, dense.envs, dense.backend, dense.sets) == (
        "ppo", 300_000_000, 8192, "warp", ("ppo.num_evals=15", "ppo.spread=global"))
    assert dense.fall == {"kind": "flipped", "grace_steps": 50}  # as bench/fields/soccer_v2_dense_flip_warp.yaml
    assert dense.measured.figure.startswith("IQM 0.851 [0.812, 0.897]") and "1030-1032" in dense.measured.seeds
    near = table["soccer_v1_dense"]  # soccer_v2_dense's recipe, as bench/fields/soccer_v1_dense_flip_warp.yaml
    assert (near.algo, near.steps, near.envs, near.backend, near.fall, near.sets) == (
        dense.algo, dense.steps, dense.envs, dense.backend, dense.fall, dense.sets)
    assert near.measured.figure.startswith("IQM 0.895 [0.887, 0.907]") and "1050-1052" in near.measured.seeds
    ant = table["ant_nav"]
    assert (ant.algo, ant.steps, ant.sets) == ("crl", 14_000_000, ("crl.num_evals=7",))
    assert ant.measured.figure.startswith("IQM 0.923 [0.899, 0.947]") and "600-604" in ant.measured.seeds
    wide_goalie = table["v2_wide_goalie"]  # the field as written trains as its dense twin on Warp did
    assert (wide_goalie.algo, wide_goalie.steps, wide_goalie.envs, wide_goalie.reward, wide_goalie.backend) == (
        "ppo", 300_000_000, 8192, "dense", "warp")
    for name in ("v2_wide_goalie", "v2_wide_goalie_dense", "v2_wide_goalie_dense_warp"):
        assert table[name].sets == dense.sets and table[name].backend == "warp" and table[name].fall == dense.fall
    for name in ("v2_wide_goalie_dense", "v2_wide_goalie_dense_warp"):
        assert table[name].measured.figure.startswith("IQM 0.885 [0.857, 0.913]")
        assert "1020-1022" in table[name].measured.seeds
    # the user's field measured by its own command, `fieldgen train fields/v2_wide_goalie.yaml`
    assert wide_goalie.measured.figure.startswith("IQM 0.866 [0.803, 0.906]")
    assert "1040-1042" in wide_goalie.measured.seeds and "fields/v2_wide_goalie.yaml" in wide_goalie.measured.detail


def test_a_recipe_extends_another_keeping_its_own_set_items_and_never_its_figure(tmp_path):
    table = recipes.read()
    wide, dense = table["v2_wide_goalie_dense"], table["soccer_v2_dense"]
    assert (wide.algo, wide.steps, wide.envs, wide.sets) == (dense.algo, dense.steps, dense.envs, dense.sets)
    assert "1030-1032" in dense.measured.seeds and "1020-1022" in wide.measured.seeds  # each its own runs
    path = tmp_path / "recipes.yaml"
    path.write_text("base:\n  algo: ppo\n  steps: 1000\n  set: [ppo.num_evals=2, ppo.spread=global]\n"
                    "  measured: {figure: '0.5', seeds: one seed (0), data: here}\n  reward: dense\n  backend: warp\n"
                    "child:\n  extends: base\n  envs: 8\n  set: [ppo.num_evals=3]\n  backend: mjx\n")
    child = recipes.read(path)["child"]
    assert (child.algo, child.steps, child.envs, child.reward, child.backend) == ("ppo", 1000, 8, "dense", "mjx")
    assert child.sets == ("ppo.spread=global", "ppo.num_evals=3") and child.measured is None
    assert child.where == f"{path}:8"
    base = recipes.read(path)["base"].measured
    assert (base.stated, base.text()) == ("0.5", "0.5, one seed (0) (here)")
    path.write_text("f:\n  algo: ppo\n  measured: {figure: '0.5', detail: '128 episodes', seeds: one seed (0), "
                    "data: here}\n")
    assert recipes.read(path)["f"].measured.stated == "0.5, 128 episodes"  # the headline, then its detail


def test_a_recipe_names_a_fall_rule_as_a_spec_writes_it_and_passes_it_on_through_extends(tmp_path):
    path = tmp_path / "recipes.yaml"
    path.write_text("base:\n  algo: ppo\n  backend: warp\n  fall: {kind: flipped, grace_steps: 50}\n"
                    "child:\n  extends: base\n  envs: 8\n"
                    "own:\n  extends: base\n  fall: {kind: height_band, band: [0.3, 1.2]}\n"
                    "rule_off:\n  extends: base\n  fall: {kind: never}\n")
    table = recipes.read(path)
    assert table["base"].fall == table["child"].fall == {"kind": "flipped", "grace_steps": 50}
    assert table["own"].fall == {"kind": "height_band", "band": [0.3, 1.2]}
    assert table["child"].record() == {"field": "child", "algo": "ppo", "envs": 8, "backend": "warp",
                                       "fall": {"kind": "flipped", "grace_steps": 50}}
    assert table["child"].summary() == ("ppo, 8 envs, on sim.backend warp, on episodes ending once the ant has lain "
                                        "turned over for 50 control steps in a row")
    assert table["own"].summary().endswith("on episodes ending once the ant's torso leaves heights 0.3 to 1.2 m")
    assert table["child"] != table["own"] and len({table["base"], table["child"]}) == 2  # compared, and hashable
    assert table["rule_off"].fall == {"kind": "never"}  # a child may keep the rule off


def test_a_field_takes_the_recipe_of_the_nearest_field_it_extends():
    table = recipes.read()
    found = recipes.find(["my_wide", "v2_wide_goalie_dense", "soccer_v2_dense", "soccer_v2"], table)
    assert found.recipe.field == "v2_wide_goalie_dense" and found.lineage == ("my_wide", "v2_wide_goalie_dense")
    assert found.inherited
    own = recipes.find(["soccer_v2_dense", "soccer_v2"], table)
    assert own.recipe.field == "soccer_v2_dense" and not own.inherited
    assert recipes.find(["mine", "soccer_v2", "soccer_v1"], table) is None


def test_a_recipe_sits_over_the_agents_preset_and_under_every_setting_the_command_line_gives():
    recipe = recipes.read()["soccer_v2_dense"]
    config = PPOConfig.layered(recipe=recipe)
    assert (config.total_steps, config.num_envs, config.num_evals, config.spread) == (300_000_000, 8192, 15, "global")
    mine = PPOConfig.layered(sets=["ppo.num_evals=3"], recipe=recipe, total_steps=40_000)
    assert (mine.total_steps, mine.num_envs, mine.num_evals, mine.spread) == (40_000, 8192, 3, "global")
    cpu = PPOConfig.layered(recipe=recipe, preset="cpu")  # a machine's preset sizes the recipe down
    assert (cpu.total_steps, cpu.num_envs, cpu.spread) == (200_000, 16, "global")
    ant = CRLConfig.layered(recipe=recipes.read()["ant_nav"], agent="ant")
    assert (ant.total_steps, ant.hidden, ant.num_evals) == (14_000_000, (256,) * 9, 7)  # with the ant preset


@pytest.mark.parametrize("text,phrase", [
    ("f:\n  algo: ppo\n  stpes: 10\n", ":3: recipe 'f': unknown key 'stpes'; did you mean 'steps'? Keys: extends, algo,"),
    ("f:\n  algo: ppp\n", ":2: recipe 'f': algo must be one of crl, icrl, ppo, sac, td3 (did you mean 'ppo'?), not 'ppp'"),
    ("f:\n  algo: crl\n  steps: -5\n", ":3: recipe 'f': steps must be a whole count above 0, not -5"),
    ("f:\n  algo: crl\n  preset: laptop\n", ":3: recipe 'f': preset must be one of cpu, not 'laptop'"),
    ("f:\n  algo: crl\n  set: [ppo.num_evals=2]\n", ":3: recipe 'f': set item 'ppo.num_evals=2' is not crl's"),
    ("f:\n  extends: g\n", ":2: recipe 'f': extends 'g', which has no recipe. Recipes: f."),
    ("f:\n  extends: g\ng:\n  extends: f\n", "extends forms a cycle: f -> g -> f"),
    ("f:\n  steps: 10\n", ":1: recipe 'f' names no algo; choose one of crl,"),
    ("f:\n  algo: crl\n  measured: {figure: '0.5'}\n", "measured must be a mapping of figure, seeds, data (and a detail, if any), each a text"),
    ("f:\n  algo: crl\n  measured: {figure: '0.5', seeds: s, data: d, detial: x}\n", "measured must be a mapping of"),
    ("f:\n  algo: ppo\n  reward: shaped\n", ":3: recipe 'f': reward must be one of dense, not 'shaped'"),
    ("f:\n  algo: ppo\n  backend: wrap\n", ":3: recipe 'f': backend must be one of mjx, warp (did you mean 'warp'?), "
                                              "not 'wrap'"),
    ("f:\n  algo: ppo\n  fall: flipped\n", ":3: recipe 'f': fall must be a mapping, as a spec's episode.fall writes "
                                             "it ({kind: flipped, grace_steps: 50}), not 'flipped'"),
    ("f:\n  algo: ppo\n  fall: {kind: flip, grace_steps: 50}\n",
     ":3: recipe 'f': fall.kind: unknown kind 'flip': one of 'flipped', 'height_band', 'never'; did you mean 'flipped'?"),
    ("f:\n  algo: ppo\n  fall: {grace_steps: 50}\n",
     ":3: recipe 'f': fall: the key 'kind' is required here: one of 'flipped', 'height_band', 'never'"),
    ("f:\n  algo: ppo\n  fall: {kind: flipped, grace: 50}\n", ":3: recipe 'f': fall.grace: unknown key 'grace'; did you "
                                                               "mean 'grace_steps'? Allowed keys here: kind, tilt_deg, "
                                                               "grace_steps."),
    ("f:\n  algo: ppo\n\n  fall: {kind: flipped, grace_steps: '50'}\n",
     ":4: recipe 'f': fall.grace_steps: '50' is text, not a number"),
])
def test_a_wrong_recipe_is_one_sentence_at_its_line(tmp_path, text, phrase):
    path = tmp_path / "recipes.yaml"
    path.write_text(text)
    with pytest.raises(RecipeError) as caught:
        recipes.read(path)
    assert phrase in str(caught.value) and str(caught.value).startswith(str(path)) and "\n" not in str(caught.value)


def test_a_recipe_setting_its_trainer_refuses_is_reported_at_the_recipe(tmp_path):
    path = tmp_path / "recipes.yaml"
    path.write_text("f:\n  algo: crl\n  set: [crl.repr_dimm=3]\n")
    with pytest.raises(ConfigError) as caught:
        CRLConfig.layered(recipe=recipes.read(path)["f"])
    assert str(caught.value).startswith(f"{path}:1: recipe 'f': crl.repr_dimm=3: unknown config key 'repr_dimm'; "
                                        "did you mean 'repr_dim'?")
