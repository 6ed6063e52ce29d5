"""Specs as people (and hostile people) write them: characters YAML refuses, numbers at the edges,
choices, odd keys and `extends` paths each give one problem in the spec's words, at its line."""

from __future__ import annotations

import typing

import pytest
import yaml
from pydantic import BaseModel
from typer.testing import CliRunner

from fieldgen.cli import app
from fieldgen.schema import FieldSpec, SpecError, load_spec
from fieldgen.schema.errors import format_path


def problem_of(path):
    with pytest.raises(SpecError) as info:
        load_spec(path)
    (p,) = info.value.problems
    return p


@pytest.mark.parametrize("char", ["\x00", "\x07", "\x1b"])
def test_a_character_yaml_refuses_is_one_line_with_its_place(write_spec, char):
    p = problem_of(write_spec(f"name: x\ndescription: 'été{char}'\n"))
    assert (p.line, p.col) == (2, 18) and f"U+{ord(char):04X}" in p.message and "not allowed in YAML" in p.message
    base = write_spec(f"name: base\ngoal:\n  width: 3{char}\n", "base.yaml")
    p = problem_of(write_spec("extends: base.yaml\nname: x\n"))
    assert (p.file, p.line, p.col) == (base, 3, 11)


def test_spec_text_prints_as_written(write_spec):
    spec = write_spec('name: "[/x]"\ngoal:\n  "[lowercase]": 1\nobstacles:\n  "[link=https://x.example]a[/link]": {}\n')
    result = CliRunner().invoke(app, ["validate", str(spec)])
    assert result.exit_code == 1 and "Traceback" not in result.output and "\x1b]8;" not in result.output
    assert f"{spec}:1:1: name: a name is lower-case letters, digits, _ and -, beginning with a letter or digit, such " \
           "as 'x' (got '[/x]')" in " ".join(result.output.split())
    assert f"{spec}:3:3: goal.[lowercase]: unknown key '[lowercase]'." in result.output
    assert "obstacles.[link=https://x.example]a[/link]:" in result.output


LONG = "q" * 5000


@pytest.mark.parametrize("text", [
    f"name: {LONG}\n",                                        # a value
    f"name: x\ntask:\n  target: {{kind: {LONG}}}\n",          # a choice's name
    f"name: x\nextends: {LONG}.yaml\n",                      # what it extends
    f"name: x\nball:\n  enabled: {LONG}\n",                   # a switch
    f"name: x\ngoal:\n  width: {LONG}\n",                     # a number
    f"name: x\ngoal:\n  {LONG[:1000]}: 1\n",                 # a key (YAML's longest plain key)
    f"name: x\n{LONG[:1000]}: 1\n{LONG[:1000]}: 2\n",          # a key given twice
    "name: x\n\u202e: 1\ngoal: {width: '\u202e'}\n",      # characters that reorder a terminal's line
])
def test_a_problem_echoes_the_spec_in_a_line_at_most(write_spec, text):
    result = CliRunner().invoke(app, ["validate", str(write_spec(text))])
    assert result.exit_code == 1 and "Traceback" not in result.output
    lines = [line for line in result.output.splitlines() if line.startswith("  ")]
    assert lines and all(len(line) < 1000 for line in lines) and LONG[:100] not in result.output, result.output[:2000]
    assert "\u202e" not in result.output
    assert ("characters)" in result.output) != ("\\u202e" in result.output)


def plain(tp):
    while typing.get_origin(tp) is typing.Annotated:
        tp = typing.get_args(tp)[0]
    return tp


def number_keys(model=FieldSpec, path=(), needs=()):
    """(key path, what the path needs around it) for every key of the spec that takes a number."""
    for name, field in model.model_fields.items():
        tp, here = field.annotation, path + (name,)
        tp = plain(tp)
        args = [plain(a) for a in (typing.get_args(tp) or (tp,)) if a is not type(None)]
        models = [a for a in args if isinstance(a, type) and issubclass(a, BaseModel)]
        if typing.get_origin(tp) in (dict, list):
            inner = typing.get_args(tp)[-1]
            key = "o" if typing.get_origin(tp) is dict else 0
            yield from number_keys(inner, here + (key,), needs + ((here + (key,), {"term": "upright"}),))
        elif models:
            for m in models:
                tag = {k: typing.get_args(f.annotation)[0] for k, f in m.model_fields.items()
                       if typing.get_origin(f.annotation) is typing.Literal and k in ("kind", "mode")}
                yield from number_keys(m, here, needs + ((here, tag),))
        elif any(a in (int, float, tuple) or typing.get_origin(a) is tuple for a in args):
            yield here, needs


def spec_with(path, value, needs) -> dict:
    data: dict = {"name": "x"}
    for where, entries in needs + ((path, value),):
        node = data
        for part, nxt in zip(where, where[1:] + (None,)):
            if nxt is None:
                if isinstance(entries, dict):
                    node = node.setdefault(part, {}) if isinstance(node, dict) else node[part]
                    node.update(entries)
                else:
                    node[part] = entries
            else:
                default = [{}] if isinstance(nxt, int) else {}
                node = node.setdefault(part, default) if isinstance(node, dict) else node[part]
    return data


NUMBER_KEYS = list(number_keys())


def test_every_number_in_the_spec_refuses_a_boolean_and_quotes(write_spec):
    assert len(NUMBER_KEYS) > 40
    for path, needs in NUMBER_KEYS:
        for value, phrase in ((True, "true is not a number"), ("0.5", "'0.5' is text, not a number")):
            spec = write_spec(yaml.safe_dump(spec_with(path, value, needs)))
            with pytest.raises(SpecError) as info:
                load_spec(spec)
            assert [p.path for p in info.value.problems if phrase in p.message] == [format_path(path)], \
                (path, [str(p) for p in info.value.problems])


# (yaml text, line, key path, the whole message or its start)
EDGES = [
    ("name: x\nepisode: {physics_dt: 5e-324}\n", 2, "episode.physics_dt",
     "Input should be greater than or equal to 0.0001 (got 5e-324)"),
    ("name: x\nepisode: {physics_dt: 1e-7}\n", 2, "episode.physics_dt", "Input should be greater than or equal to 0.0001"),
    ("name: x\nepisode: {control_dt: 0.5, physics_dt: 0.0002}\n", 2, "episode.physics_dt",
     "2,500 physics steps per control step (control_dt 0.5 / physics_dt 0.0002); at most 1000: raise physics_dt "
     "to at least 0.0005"),
    ("name: x\nepisode: {length: true}\n", 2, "episode.length", "true is not a number"),
    ("name: x\nwalls: {enabled: 1}\n", 2, "walls.enabled", "1 is not true or false"),
    ("name: x\ntask:\n  reward:\n    - {term: success, weight: \"0.5\"}\n", 4, "task.reward[0].weight",
     "'0.5' is text, not a number; write it without quotes"),
    ("name: x\nsim: {max_contacts: 0}\n", 2, "sim.max_contacts", "Input should be greater than or equal to 1 (got 0)"),
    # choices: one problem per value, in the spec's words, at the key that is wrong
    ("name: x\nsim: {max_contacts: 12.5}\n", 2, "sim.max_contacts", "expected a whole number or 'auto' or 'all' (got 12.5)"),
    ("name: x\nsim: {max_contacts: lots}\n", 2, "sim.max_contacts", "'lots' is text, not a number or one of 'all', 'auto'"),
    ("name: x\ntask:\n  target: {kind: rign}\n", 3, "task.target.kind",
     "unknown kind 'rign': one of 'goal', 'ring', 'point'; did you mean 'ring'?"),
    ("name: x\ntask:\n  target: {radius: 3}\n", 3, "task.target", "the key 'kind' is required here: one of 'goal', 'ring', 'point'"),
    ("name: x\nball:\n  spawn: {mode: blob}\n", 3, "ball.spawn.mode", "unknown mode 'blob': one of 'region', 'toward_target'"),
    ("name: x\nepisode: {fall: never}\n", 2, "episode.fall", "expected a mapping (got 'never')"),
    ("name: x\nagent: {start: [1]}\n", 2, "agent.start", "expected a pair [a, b] (got 1 item)"),
    # keys that are not plain names, at their own line
    ("name: x\ngoal:\n  width: 3\n  1: 2\n", 4, "goal", "keys must be plain names, not '1'"),
    ("name: x\ngoal:\n  ? [a]\n  : 3\n", 3, "goal", "keys must be plain names, not a list or mapping"),
    ("name: x\nnull: 4\n", 2, "", "keys must be plain names, not 'null'"),
]


@pytest.mark.parametrize("text,line,path,message", EDGES)
def test_edges_choices_and_keys(write_spec, text, line, path, message):
    spec = write_spec(text)
    p = problem_of(spec)
    assert (p.file, p.line, p.path) == (spec, line, path)
    assert p.message.startswith(message), p.message
    assert ".int" not in p.message and "literal[" not in p.message


RULE = "'extends' takes a bundled field name ("


@pytest.mark.parametrize("ref,reason", [
    ("/etc/passwd", "'/etc/passwd' is an absolute path"),
    ("~/x.yaml", "'~/x.yaml' is an absolute path"),
    ("../../etc/hostname", "'../../etc/hostname' does not end in .yaml"),
    ("''", "it is empty"),
    ("[a]", "['a'] is not a name or a path"),
    ("folder.yaml", "'folder.yaml' is a folder"),
    ("../missing/base.yaml", "'../missing/base.yaml' is neither a bundled field nor a file"),
])
def test_extends_takes_bundled_names_and_relative_yaml_paths(write_spec, tmp_path, ref, reason):
    (tmp_path / "folder.yaml").mkdir()
    spec = write_spec(f"name: x\nextends: {ref}\n")
    p = problem_of(spec)
    assert (p.file, p.line, p.path) == (spec, 2, "extends")
    assert p.message.startswith(f"{reason}; {RULE}") and "relative path to a .yaml file" in p.message


def test_extends_never_echoes_another_files_contents(write_spec, tmp_path):
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "secret.yaml").write_text("root:x:0:0:root:/root:/bin/bash\nSECRET-TOKEN-123\n")
    p = problem_of(write_spec("name: x\nextends: other/secret.yaml\n"))
    assert "SECRET" not in str(p) and "root:x" not in str(p)
