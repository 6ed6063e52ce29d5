"""A field on sim.backend warp where warp-lang is not installed: refused in one paragraph that names the field, the
key and the two ways on (install the warp extra, or sim.backend: mjx), before a run folder is written; building
and validating it need no Warp."""

from __future__ import annotations

import sys

import pytest
from typer.testing import CliRunner

from fieldgen.cli import app
from fieldgen.env import mjx_physics
from fieldgen.env.make import make
from fieldgen.schema.errors import SpecError

WARP_FIELD = "extends: point_nav\nname: point_nav_warp\nsim: {backend: warp}\n"


@pytest.fixture
def no_warp(monkeypatch):
    """`import warp` fails, as where warp-lang is not installed."""
    monkeypatch.setitem(sys.modules, "warp", None)


def test_making_a_warp_field_without_warp_lang_names_the_field_and_the_remedies(no_warp):
    with pytest.raises(mjx_physics.WarpMissing) as refused:
        make("point_nav", backend="warp")
    message = str(refused.value)
    assert isinstance(refused.value, SpecError)  # every command's refusal of a spec problem prints it
    assert "\n" not in message and message.startswith("point_nav: sim.backend: warp (MuJoCo Warp's kernels) needs "
                                                      "warp-lang, which is not installed here")
    assert "pip install -c requirements.lock -e '.[warp]'" in message and "sim.backend: mjx" in message
    make("point_nav")  # MJX's own implementation needs no Warp


def test_training_a_warp_field_without_warp_lang_is_one_paragraph_and_writes_no_run(no_warp, write_spec, tmp_path):
    spec = write_spec(WARP_FIELD)
    built = CliRunner().invoke(app, ["build", str(spec), "--out", str(tmp_path / "build"), "--no-preview"])
    assert built.exit_code == 0, built.output  # building is MuJoCo's and dm_control's, not Warp's
    runs = tmp_path / "runs"
    result = CliRunner().invoke(app, ["train", str(spec), "--algo", "ppo", "--steps", "2k", "--envs", "4",
                                      "--out", str(runs), "--no-videos"])
    assert result.exit_code == 1
    assert "Traceback" not in result.output
    assert "error: point_nav_warp: sim.backend: warp (MuJoCo Warp's kernels) needs warp-lang" in " ".join(
        result.output.split())
    assert not runs.exists() or not any(runs.iterdir())
