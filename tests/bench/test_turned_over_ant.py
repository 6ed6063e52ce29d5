"""turned_over_ant: where an ant dropped upside down comes to rest under each contact set."""

from __future__ import annotations

import sys
from pathlib import Path

from fieldgen.compile.artifact import compile_spec
from fieldgen.schema import bundled_fields, load_spec

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
import turned_over_ant  # noqa: E402

sys.path.remove(str(ROOT / "bench"))


def torso_height_at_rest(spec) -> float:
    model = compile_spec(spec).model()
    return float(turned_over_ant.rest(model).qpos[model.joint("root").qposadr[0] + 2])


def test_a_turned_over_ant_sinks_through_the_floor_under_pruned_contacts_and_lies_on_its_back_with_torso_floor(
        write_spec):
    """MuJoCo's own step: the contact set is the model's, whichever library steps it."""
    pruned = load_spec(bundled_fields()["ant_nav"])
    grounded = load_spec(write_spec("extends: ant_nav\nname: ant_nav_torso_floor\nsim: {contacts: torso_floor}\n"))
    assert torso_height_at_rest(pruned) < 0.0  # the torso under the floor, the ant on its feet from below
    assert torso_height_at_rest(grounded) > 0.2  # on its back: the torso's radius is 0.25
