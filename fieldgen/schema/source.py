"""Reading one YAML file into plain data plus the position of every key.

PyYAML's composer keeps marks on every node; we walk the node tree once to
record where each key path starts and to reject duplicate keys, which plain
`yaml.safe_load` would silently let the last one win.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import yaml

from fieldgen.schema.errors import Problem, SpecError, format_path

Pos = tuple[Path, int, int]


@dataclass
class Source:
    """Data read from YAML, with the file position of every key path."""

    data: dict
    positions: dict[tuple, Pos] = field(default_factory=dict)

    def position(self, parts: tuple) -> Pos | None:
        """The position of the deepest key path prefix that exists."""
        for n in range(len(parts), -1, -1):
            if parts[:n] in self.positions:
                return self.positions[parts[:n]]
        return None

    def problem(self, parts: tuple, message: str) -> Problem:
        pos = self.position(parts)
        if pos is None:
            return Problem(None, None, None, format_path(parts), message)
        return Problem(pos[0], pos[1], pos[2], format_path(parts), message)


def read_yaml(path: Path) -> Source:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SpecError([Problem(path, None, None, "", "no such file")]) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError([Problem(path, None, None, "", f"cannot read the file: {exc}")]) from None
    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            raise SpecError([Problem(path, 1, 1, "", "the file is empty; a field needs at least 'name:'")])
        if not isinstance(node, yaml.MappingNode):
            kind = {yaml.SequenceNode: "a list", yaml.ScalarNode: "a single value"}.get(type(node), "not a mapping")
            raise SpecError([_at(path, node, (), f"the document is {kind}; a field spec is a mapping of sections")])
        problems: list[Problem] = []
        positions: dict[tuple, Pos] = {(): _pos(path, node)}
        _walk(path, node, (), positions, problems)
        if problems:
            raise SpecError(problems)
        data = loader.construct_document(node)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        what = getattr(exc, "problem", None) or str(exc)
        line, col = (mark.line + 1, mark.column + 1) if mark else (None, None)
        raise SpecError([Problem(path, line, col, "", f"YAML syntax error: {what}")]) from None
    finally:
        loader.dispose()
    return Source(data, positions)


def _pos(path: Path, node: yaml.Node) -> Pos:
    return (path, node.start_mark.line + 1, node.start_mark.column + 1)


def _at(path: Path, node: yaml.Node, parts: tuple, message: str) -> Problem:
    return Problem(path, node.start_mark.line + 1, node.start_mark.column + 1, format_path(parts), message)


def _walk(path: Path, node: yaml.Node, parts: tuple, positions: dict, problems: list) -> None:
    if isinstance(node, yaml.MappingNode):
        seen: dict = {}
        for key_node, value_node in node.value:
            key = key_node.value if isinstance(key_node, yaml.ScalarNode) else None
            if key is None:
                problems.append(_at(path, key_node, parts, "keys must be plain names"))
                continue
            here = parts + (key,)
            if key in seen:
                first = seen[key]
                problems.append(_at(path, key_node, here, f"duplicate key '{key}' (first given on line {first})"))
                continue
            seen[key] = key_node.start_mark.line + 1
            positions[here] = _pos(path, key_node)
            _walk(path, value_node, here, positions, problems)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            positions[parts + (i,)] = _pos(path, item)
            _walk(path, item, parts + (i,), positions, problems)
