"""The JSON Schema of a field spec, for editors that check YAML as it is typed.

It is committed beside this module as `fieldgen.schema.json` (shipped as package data) so that a
bundled field's first line, `# yaml-language-server: $schema=...`, can point at it; a test keeps
the file equal to what the models generate.
"""

from __future__ import annotations

import json
from pathlib import Path

from fieldgen.schema.models import FieldSpec

SCHEMA_FILE = Path(__file__).with_name("fieldgen.schema.json")
SCHEMA_ID = "urn:fieldgen:field-spec"  # a name, not a place: editors find the file by the modeline's path
DIALECT = "https://json-schema.org/draft/2020-12/schema"


def json_schema() -> dict:
    """Draft 2020-12: a spec file as written, `extends` and spans as a single number included."""
    return {"$schema": DIALECT, "$id": SCHEMA_ID, **_as_written(FieldSpec.model_json_schema())}


def _as_written(node):
    """The models' schema loosened to what a file that `extends` another may say: a choice (a target kind,
    a spawn mode, a fall rule) may leave its `kind`/`mode` to the base, so a choice is any of its forms
    (each still closed to unknown keys) and its tag is optional; a named entry may be null (removed)."""
    if isinstance(node, list):
        return [_as_written(x) for x in node]
    if not isinstance(node, dict):
        return node
    node = {k: _as_written(v) for k, v in node.items()}
    if "discriminator" in node or "oneOf" in node:
        node.pop("discriminator", None)
        node["anyOf"] = node.pop("oneOf")
    tags = {k for k, v in node.get("properties", {}).items() if "const" in v}
    if tags and "required" in node:
        node["required"] = [k for k in node["required"] if k not in tags]
        if not node["required"]:
            del node["required"]
    for pattern, entry in node.get("patternProperties", {}).items():
        node["patternProperties"][pattern] = {"anyOf": [entry, {"type": "null"}]}
    return node


def schema_text() -> str:
    return json.dumps(json_schema(), indent=1) + "\n"
