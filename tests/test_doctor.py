"""`fieldgen doctor`: each part of the machine checked, what mends a missing one, and a failing status only
where fieldgen cannot work as it should."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from fieldgen import doctor
from fieldgen.cli import app

runner = CliRunner()


def test_doctor_on_this_machine_steps_a_field_and_reports_every_part_as_json():
    result = runner.invoke(app, ["doctor", "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.output)
    checks = {c["name"]: c for c in report["checks"]}
    assert report["passed"] and set(checks) >= {"fieldgen", "JAX", "MuJoCo and MJX", "Warp physics", "Rendering",
                                                "Videos", "Viewer", "Compile cache", "extra: onnx"}
    assert checks["MuJoCo and MJX"]["status"] == doctor.OK and "point_nav built and stepped" in \
        checks["MuJoCo and MJX"]["detail"]
    assert all(c["status"] in (doctor.OK, doctor.NOTE) for c in report["checks"])


def test_an_nvidia_gpu_that_jax_does_not_use_is_a_problem_naming_the_plugin(monkeypatch):
    import jax

    monkeypatch.setattr(jax, "default_backend", lambda: "cpu")
    monkeypatch.delenv("JAX_PLATFORMS", raising=False)
    found = doctor.check_jax(gpu_present=lambda: True)
    assert found.status == doctor.PROBLEM and "an NVIDIA GPU that JAX does not use" in found.detail
    assert f"jax[cuda12]=={jax.__version__}" in found.remedy
    assert doctor.check_jax(gpu_present=lambda: False).status == doctor.NOTE  # a CPU machine: slow, not broken
    monkeypatch.setenv("JAX_PLATFORMS", "cpu")  # the CPU asked for
    assert doctor.check_jax(gpu_present=lambda: True).status == doctor.NOTE


def test_a_problem_fails_the_command_and_says_how_to_mend_it(monkeypatch):
    broken = doctor.Check("MuJoCo and MJX", doctor.PROBLEM, "point_nav could not be built and stepped: boom",
                          "reinstall fieldgen's pins")
    monkeypatch.setattr(doctor, "check_physics", lambda: broken)
    result = runner.invoke(app, ["doctor"])
    assert result.exit_code == 1 and "problem" in result.output
    assert "MuJoCo and MJX: reinstall fieldgen's pins" in " ".join(result.output.split())


def test_what_is_missing_is_a_note_with_its_install_line(monkeypatch):
    from fieldgen import render

    monkeypatch.setattr(doctor, "version", lambda name: None)
    extras = {c.name: c for c in doctor.check_extras()}
    assert extras["extra: wandb"].status == doctor.NOTE
    assert extras["extra: wandb"].remedy.startswith("pip install -c requirements.lock -e '.[wandb]'")
    assert doctor.check_warp().status == doctor.NOTE and "not installed" in doctor.check_warp().detail

    def no_gl(model, size):
        raise render.RenderError("mujoco cannot render on this machine (no EGL or OSMesa library was found)")

    monkeypatch.setattr(render, "renderer", no_gl)
    drawing = doctor.check_rendering()
    assert drawing.status == doctor.NOTE and "training is not affected" in drawing.detail
    assert drawing.remedy.startswith("mujoco cannot render on this machine")


@pytest.mark.parametrize("value", ["false", "0"])
def test_a_compile_cache_turned_off_is_said(monkeypatch, value):
    monkeypatch.setenv("JAX_ENABLE_COMPILATION_CACHE", value)
    assert doctor.check_cache().status == doctor.NOTE


def test_a_jax_that_cannot_start_the_platform_named_says_to_unset_it(monkeypatch):
    import jax

    def refused():
        raise RuntimeError("Unknown backend: 'cuda' requested, but no platforms that are instances of cuda are present")

    monkeypatch.setattr(jax, "devices", refused)
    monkeypatch.setenv("JAX_PLATFORMS", "cuda")
    found = doctor.check_jax()
    assert found.status == doctor.PROBLEM and found.detail.startswith("cannot start: RuntimeError: Unknown backend")
    assert found.remedy.startswith("JAX_PLATFORMS=cuda names a platform JAX cannot start here (Unknown backend")
    assert found.remedy.endswith("unset JAX_PLATFORMS for JAX to use what this machine has, or set JAX_PLATFORMS=cpu")
