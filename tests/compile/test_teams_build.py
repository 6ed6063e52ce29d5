"""Team fields build each agent under its own names in its side's colour, with a goal at each end; single-agent
fields build exactly as they did before teams existed."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from fieldgen.compile.artifact import compile_spec
from fieldgen.compile.bodies import SIDE_RGBA
from fieldgen.schema import bundled_fields, load_spec

# field.json's keys that change with any edit of the compiler's code or the version, not with what a build holds
VOLATILE = ("fieldgen_version", "compiler_digest", "hash", "record_sha256")
RECORDED = Path(__file__).with_name("single_agent_builds.json")


def build_digests(name: str) -> dict:
    """The SHA-256 of a bundled field's scene.xml, and of its field.json as written (key order included) without
    VOLATILE: what a single-agent field must keep while the compiler learns new things."""
    meta = compile_spec(load_spec(bundled_fields()[name])).metadata()
    kept = {k: v for k, v in meta.items() if k not in VOLATILE}
    return {"field_json_sha256": hashlib.sha256(json.dumps(kept, indent=1).encode()).hexdigest(),
            "scene_sha256": meta["scene_sha256"]}


def test_single_agent_fields_build_byte_identical_to_before_teams():
    """The digests in single_agent_builds.json were taken from builds of the compiler before team fields; a change
    meant to alter a single-agent scene records new ones (`python tests/compile/test_teams_build.py`)."""
    recorded = json.loads(RECORDED.read_text())
    singles = [n for n, p in bundled_fields().items() if load_spec(p).teams is None]
    assert set(recorded) <= set(singles)
    changed = [name for name in recorded if build_digests(name) != recorded[name]]
    assert not changed, f"these single-agent fields no longer build as before: {changed}"


@pytest.mark.parametrize("name,agents", [("soccer_1v1", ("home0", "away0")),
                                         ("soccer_2v2", ("home0", "home1", "away0", "away1"))])
def test_each_team_agent_has_its_own_names_colour_and_kickoff(name, agents):
    artifact = compile_spec(load_spec(bundled_fields()[name]))
    model = artifact.model()
    meta = artifact.metadata()
    assert meta["agents"] == list(agents) and meta["action_size"] == 2
    assert [model.actuator(i).name for i in range(model.nu)] == [f"{a}_agent_{c}" for a in agents for c in "xy"]
    for agent in agents:
        rgba = model.geom(f"{agent}_agent").rgba
        np.testing.assert_allclose(rgba, SIDE_RGBA[agent[:4]], atol=1e-6)
    home = model.key("home").qpos
    for i, agent in enumerate(agents):
        x, y = home[model.joint(f"{agent}_agent_x").qposadr[0]], home[model.joint(f"{agent}_agent_y").qposadr[0]]
        assert (y < 0) == agent.startswith("home") and x == pytest.approx(-home[model.joint(
            f"{'away' if agent.startswith('home') else 'home'}{agent[-1]}_agent_x").qposadr[0]])
    for side, y in (("away", 1), ("home", -1)):
        assert np.sign(model.geom(f"{side}_goal_area").pos[1]) == y
    assert model.nmocap == 0  # a match's targets are the goals: no target marker
    assert ("away0_agent", "home0_agent") in {tuple(sorted(p)) for p in meta["contact_pairs"]}


def test_an_ant_team_faces_the_goal_each_side_attacks(write_spec):
    spec = load_spec(write_spec("extends: soccer_1v1\nname: ants\nagent: {kind: ant}\nfield: {length: 16, width: 10}\n"
                                "goal: {distance: 8}\n"))
    model = compile_spec(spec).model()
    home = model.key("home").qpos
    np.testing.assert_allclose(home[model.joint("home0_root").qposadr[0]:][3:7], (1, 0, 0, 0))
    np.testing.assert_allclose(home[model.joint("away0_root").qposadr[0]:][3:7], (0, 0, 0, 1))
    assert model.nu == 16 and model.actuator(8).name.startswith("away0_")


def test_the_preview_shows_both_sides_in_their_colours_and_names_them():
    from fieldgen.render import RenderError, legend, preview

    model = compile_spec(load_spec(bundled_fields()["soccer_1v1"])).model()
    try:
        image = preview(model)
    except RenderError as exc:
        pytest.skip(str(exc))
    for rgba in SIDE_RGBA.values():
        near = np.abs(image.astype(int) - (np.asarray(rgba[:3]) * 255).astype(int)).max(axis=-1) < 40
        assert near.sum() > 20
    from fieldgen import render

    names = [model.geom(i).name for i in range(model.ngeom) if model.geom_rgba[i][3] > 0]
    shown = [label for label, by in render.LEGEND.items() if any(n in by or any(
        n.startswith(s) for s in by if s.endswith("_")) for n in names)]
    assert shown[:2] == ["home", "away"] and "agent" not in shown and legend(model, 640).shape[1] == 640


if __name__ == "__main__":  # record the digests anew, after a change meant to alter single-agent scenes
    singles = [n for n, p in bundled_fields().items() if load_spec(p).teams is None]
    RECORDED.write_text(json.dumps({n: build_digests(n) for n in singles}, indent=1, sort_keys=True) + "\n")
