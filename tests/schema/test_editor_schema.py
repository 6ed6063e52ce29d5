"""The JSON Schema editors check specs against: current, and accepting every spec fieldgen ships or writes."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest
import yaml

from fieldgen import curriculum
from fieldgen.schema import bundled_fields
from fieldgen.schema.editor import SCHEMA_FILE, json_schema

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted([*bundled_fields().values(), *ROOT.glob("curricula/*/stage_*.yaml"), *ROOT.glob("bench/fields/*.yaml")])
VALIDATOR = jsonschema.Draft202012Validator(json_schema())


def test_the_committed_schema_is_what_the_models_generate():
    assert json.loads(SCHEMA_FILE.read_text()) == json_schema(), \
        "regenerate it: fieldgen schema > fieldgen/schema/fieldgen.schema.json"
    jsonschema.Draft202012Validator.check_schema(json_schema())
    assert json_schema()["$schema"] == "https://json-schema.org/draft/2020-12/schema" and json_schema()["$id"]


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_every_shipped_spec_validates_and_points_editors_at_the_schema(path):
    assert [e.message for e in VALIDATOR.iter_errors(yaml.safe_load(path.read_text()))] == []
    modeline = path.read_text().splitlines()[0]
    assert modeline.startswith("# yaml-language-server: $schema=")
    assert (path.parent / modeline.split("$schema=")[1]).resolve() == SCHEMA_FILE.resolve()


def test_spans_are_a_number_or_a_pair_and_typos_fail():
    named = {"name": "mine", "extends": "soccer_v1"}
    assert VALIDATOR.is_valid({**named, "ball": {"spawn": {"x": 0, "y": [4, 6]}},
                               "task": {"target": {"kind": "ring", "radius": 5}}})
    assert VALIDATOR.is_valid({**named, "task": {"target": {"radius": 5}}})  # the kind left to the base
    assert not VALIDATOR.is_valid({**named, "ball": {"spawn": {"x": [1, 2, 3]}}})
    assert not VALIDATOR.is_valid({**named, "goal": {"widht": 3}})
    assert not VALIDATOR.is_valid({**named, "task": {"target": {"kind": "circle"}}})
    assert not VALIDATOR.is_valid({**named, "task": {"target": {"radius": 5, "x": 1}}})  # no one kind has both


def test_a_generated_curriculum_validates_and_points_at_the_schema(tmp_path):
    base = bundled_fields()["soccer_v1"]
    c = curriculum.write(tmp_path / "c", "soccer_v1", base, "start_states", curriculum.start_states(base, 3.0, 3),
                         curriculum.Promotion())
    for path in c.spec_paths():
        test_every_shipped_spec_validates_and_points_editors_at_the_schema(path)


def test_editors_refuse_what_the_loader_refuses():
    named = {"name": "mine", "extends": "soccer_v1"}
    for section, values in {"episode": {"length": True}, "goal": {"width": "3"}, "walls": {"enabled": 1},
                            "sim": {"max_contacts": 0}}.items():
        assert not VALIDATOR.is_valid({**named, section: values}), (section, values)
    assert not VALIDATOR.is_valid({**named, "episode": {"physics_dt": 5e-324}})
    assert not VALIDATOR.is_valid({**named, "obstacles": {f"o{i}": {"x": i % 400} for i in range(1001)}})
    assert VALIDATOR.is_valid({**named, "obstacles": {f"o{i}": {"x": i % 400} for i in range(1000)}})
