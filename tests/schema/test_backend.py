"""sim.backend: each pipeline's physics step by default, and what a pipeline cannot simulate refused
by `fieldgen validate` with the key named, before anything compiles."""

from __future__ import annotations

import dataclasses
import typing

import pytest
from typer.testing import CliRunner

from fieldgen.cli import app
from fieldgen.schema import SpecError, load_spec, resolve_spec_path
from fieldgen.schema.backends import BACKENDS, BRAX
from fieldgen.schema.models import SimSection

runner = CliRunner()


@pytest.mark.parametrize("backend, dt, substeps, iterations", [
    ("mjx", 0.01, 5, 1), ("warp", 0.01, 5, 1), ("spring", 0.005, 10, 1), ("positional", 0.005, 10, 1), ("generalized", 0.01, 5, 4)])
def test_each_backend_steps_as_its_reference_does(write_spec, backend, dt, substeps, iterations):
    spec = load_spec(write_spec(f"name: x\nsim: {{backend: {backend}}}\n"))
    assert (spec.episode.physics_dt, spec.episode.substeps, spec.sim.iterations) == (dt, substeps, iterations)


def test_a_physics_step_the_spec_sets_is_kept(write_spec):
    spec = load_spec(write_spec("name: x\nsim: {backend: spring}\nepisode: {physics_dt: 0.01}\n"))
    assert spec.episode.physics_dt == 0.01


def test_another_backend_brings_its_own_defaults_but_keeps_what_the_spec_set():
    spring = load_spec(resolve_spec_path("ant_nav"), "spring")
    assert (spring.sim.backend, spring.episode.physics_dt) == ("spring", 0.005)
    generalized = load_spec(spring, "generalized")
    assert (generalized.episode.physics_dt, generalized.sim.iterations) == (0.01, 4)
    v1 = load_spec(resolve_spec_path("soccer_v1"), "positional")  # soccer_v1 sets physics_dt itself
    assert v1.episode.physics_dt == 0.01


@pytest.mark.parametrize("text, line, key, phrase", [
    ("name: x\nsim: {backend: positional, cone: elliptic}\n", 2, "sim.cone", "only the pyramidal friction cone"),
    ("name: x\nsim:\n  backend: generalized\n  euler_damping: true\n", 4, "sim.euler_damping", "MJX's"),
    ("name: x\nagent: {kind: point}\nball: {enabled: false}\ntask: {success: {kind: agent_near_target}}\n"
     "sim:\n  backend: spring\n", 6, "sim.backend", "ignores joint damping"),
])
def test_what_a_backend_cannot_simulate_is_refused_with_the_key(write_spec, text, line, key, phrase):
    path = write_spec(text)
    with pytest.raises(SpecError) as info:
        load_spec(path)
    [problem] = info.value.problems
    assert (problem.line, problem.path) == (line, key) and phrase in problem.message
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 1 and f"{path}:{line}" in result.output and key in result.output
    assert "Traceback" not in result.output


def test_the_same_field_on_mjx_or_generalized_is_fine(write_spec):
    for backend in ("mjx", "generalized"):
        load_spec(write_spec(f"name: x\nextends: point_nav\nsim: {{backend: {backend}}}\n"))


def test_an_unknown_backend_lists_the_choices(write_spec):
    with pytest.raises(SpecError) as info:
        load_spec(write_spec("name: x\nsim: {backend: bullet}\n"))
    message = info.value.problems[0].message
    assert all(name in message for name in ("mjx", "warp", "spring", "positional", "generalized"))


def test_the_schema_offers_exactly_the_registered_backends():
    assert typing.get_args(SimSection.model_fields["backend"].annotation) == tuple(BACKENDS)
    assert "mjx" not in BRAX and set(BRAX) < set(BACKENDS)


def test_warp_is_mjx_of_another_implementation(write_spec):
    assert (BACKENDS["mjx"].mjx_impl, BACKENDS["warp"].mjx_impl) == ("jax", "warp") and "warp" not in BRAX
    assert all(BACKENDS[name].mjx_impl is None for name in BRAX)
    spec = load_spec(write_spec(POINT_ON + "sim: {backend: warp, cone: elliptic, euler_damping: true}\n"))
    assert spec.sim.backend == "warp"  # everything MJX simulates
    assert "warp (MuJoCo Warp through MJX" in SimSection.model_fields["backend"].description


POINT_ON = "name: x\nagent: {kind: point}\nball: {enabled: false}\ntask: {success: {kind: agent_near_target}}\n"


def test_a_point_agent_is_sent_to_the_backends_the_registry_says_damp_joints(write_spec, monkeypatch):
    def message(backend):
        with pytest.raises(SpecError) as info:
            load_spec(write_spec(POINT_ON + f"sim: {{backend: {backend}}}\n"))
        return info.value.problems[0].message

    assert message("spring") == ("brax's spring pipeline ignores joint damping, which is what slows the point agent "
                                 "(agent.kind: point) on its slides; use backend mjx, warp or generalized, or agent.kind: ant")
    monkeypatch.setitem(BACKENDS, "generalized", dataclasses.replace(BACKENDS["generalized"], joint_damping=False))
    assert message("generalized").endswith("use backend mjx or warp, or agent.kind: ant")


def test_the_defaults_a_backend_brings_are_the_registry_s(write_spec, monkeypatch):
    monkeypatch.setitem(BACKENDS, "generalized", dataclasses.replace(
        BACKENDS["generalized"], defaults={("sim", "ls_iterations"): 7}))
    spec = load_spec(write_spec("name: x\nsim: {backend: generalized}\n"))
    assert (spec.sim.ls_iterations, spec.sim.iterations) == (7, 1)
