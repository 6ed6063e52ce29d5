"""A scene built for one of brax's pipelines: brax's joint-spring parameters in it, and a puck's floor
friction as a floor contact, since brax ignores joint frictionloss. An MJX scene carries neither."""

from __future__ import annotations

import pytest

from fieldgen.compile.artifact import compile_spec
from fieldgen.compile.contacts import candidate_pairs
from fieldgen.compile.pipelines import REFERENCE_ANT
from fieldgen.schema import load_spec, resolve_spec_path


def numerics(model) -> dict[str, float]:
    return {model.numeric(i).name: float(model.numeric(i).data[0]) for i in range(model.nnumeric)}


def puck_floor(model) -> tuple[float, bool]:
    """(the puck's slide frictionloss, whether the ball and the floor are a candidate contact pair)."""
    return float(model.joint("ball_x").frictionloss[0]), ("floor", "ball") in candidate_pairs(model)


@pytest.mark.parametrize("backend", ["spring", "positional", "generalized"])
def test_brax_scene_carries_the_reference_parameters_and_a_floor_contact(backend):
    model = compile_spec(load_spec(resolve_spec_path("soccer_v1"), backend)).model()
    assert {k: numerics(model)[k] for k in REFERENCE_ANT} == REFERENCE_ANT
    assert puck_floor(model) == (0.0, True)


def test_mjx_scene_is_unchanged():
    spec = load_spec(resolve_spec_path("soccer_v1"))
    model = compile_spec(spec).model()
    assert not set(REFERENCE_ANT) & set(numerics(model))
    friction, touches = puck_floor(model)
    # the floor's Coulomb friction on a puck pressed down by its weight alone: mu m g on each slide
    weight = spec.ball.mass * -model.opt.gravity[2]
    assert friction == pytest.approx(max(spec.ball.friction, spec.field.friction) * weight, rel=1e-6) and not touches


def test_a_warp_scene_is_the_mjx_scene():
    for field in ("soccer_v1", "ant_nav"):
        mjx, warp = (compile_spec(load_spec(resolve_spec_path(field), backend)) for backend in ("mjx", "warp"))
        assert warp.spec.sim.backend == "warp" and warp.xml == mjx.xml


def test_gear_override_reaches_the_motors():
    model = compile_spec(load_spec(resolve_spec_path("soccer_v2_positional"))).model()
    assert set(model.actuator_gear[:, 0]) == {200.0}
