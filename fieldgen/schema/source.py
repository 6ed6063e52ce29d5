"""Reading one YAML file into plain data plus the position of every key.

PyYAML's composer keeps marks on every node; we walk the node tree once to
record where each key path starts and to reject duplicate keys, which plain
`yaml.safe_load` would silently let the last one win.

Specs travel between people, so reading one is bounded: a regular file of at most
MAX_BYTES, nesting at most MAX_DEPTH deep, at most MAX_NODES values once aliases
are expanded (an alias "bomb" is refused before it is built), no character YAML
refuses, and no key that is not a plain string. Other YAML files fieldgen reads (a
curriculum's curriculum.yaml, a sweep file, a --config file) are read the same way.
"""

from __future__ import annotations

import re
import stat
import unicodedata
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from fieldgen.limits import MAX_DIGITS
from fieldgen.schema.errors import Problem, SpecError, format_path, shown_text

Pos = tuple[Path, int, int]
MAX_BYTES = 1_000_000  # a spec is a few kilobytes; a megabyte is a mistake or an attack
MAX_DEPTH = 32  # a spec nests four or five levels
MAX_NODES = 30_000  # values after expanding aliases; 1,000 obstacles with every key set have about 16,000
_STR = "tag:yaml.org,2002:str"
_MERGE = "tag:yaml.org,2002:merge"


@dataclass
class Source:
    """Data read from YAML, with the file position of every key path."""

    data: dict
    positions: dict[tuple, Pos] = field(default_factory=dict)
    files: tuple[Path, ...] = ()  # the files it was read from, each over the one before (`extends`)

    def written_last(self, paths: tuple[tuple, ...]) -> tuple:
        """Of key paths whose values conflict, the one set in the latest of the files read (the spec a person
        edits comes after the files it extends); of paths set in one file, or in none, the first."""
        rank = {file: n for n, file in enumerate(self.files)}

        def order(parts: tuple) -> int:
            pos = self.positions.get(parts)
            return rank.get(pos[0], -1) if pos is not None else -1

        return max(paths, key=order)  # max keeps the first of equals

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


class SpecLoader(yaml.CSafeLoader if yaml.__with_libyaml__ else yaml.SafeLoader):
    """YAML as PyYAML's safe loader reads it (through libyaml where PyYAML has it: large specs load much
    faster), and floats as YAML 1.2 writes them: `1e-7` and `2e6` are numbers (YAML 1.1
    wants a dot, `1.0e-7`, and would read them as text)."""


SpecLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"), list("-+0123456789"))


def _bounded_int(loader: yaml.constructor.SafeConstructor, node: yaml.ScalarNode) -> int:
    """An integer of at most MAX_DIGITS digits: Python converts no more than 4,300, and no setting needs a
    hundred, so a longer one is refused at its line rather than in a traceback."""
    digits = sum(c.isdigit() for c in node.value)
    if digits > MAX_DIGITS:
        raise yaml.constructor.ConstructorError(None, None, f"a number of {digits:,} digits; a number here has at "
                                                f"most {MAX_DIGITS}", node.start_mark)
    return loader.construct_yaml_int(node)


SpecLoader.add_constructor("tag:yaml.org,2002:int", _bounded_int)


def read_yaml(path: Path, document: str = "a field spec", needs: str = "a field needs at least 'name:'") -> Source:
    """The file as data and key positions; `document` (what the file is) and `needs` (what it cannot go
    without) word the complaints about a file that holds no mapping."""
    text = _read_text(path, document)
    _refuse_characters(path, text)
    loader = SpecLoader(text)
    try:
        _refuse_depth(path, text, document)
        node = loader.get_single_node()
        if node is None:
            raise SpecError([Problem(path, 1, 1, "", f"the file is empty; {needs}")])
        if not isinstance(node, yaml.MappingNode):
            kind = {yaml.SequenceNode: "a list", yaml.ScalarNode: "a single value"}.get(type(node), "not a mapping")
            raise SpecError([_at(path, node, (), f"the document is {kind}; {document} is a mapping of sections")])
        problems: list[Problem] = []
        positions: dict[tuple, Pos] = {(): _pos(path, node)}
        _bounded(path, node, document)
        _merge_keys(path, node, (), problems, set())
        _walk(path, node, (), positions, problems)
        if problems:
            raise SpecError(problems)
        data = loader.construct_document(node)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        what = getattr(exc, "problem", None) or str(exc)
        line, col = (mark.line + 1, mark.column + 1) if mark else (None, None)
        if mark and _indented_with_tab(text, mark.line):
            what = f"{what}: the line is indented with a tab, and YAML indents with spaces alone; replace the tab " \
                   "with spaces"
        said = what if isinstance(exc, yaml.constructor.ConstructorError) else f"YAML syntax error: {what}"
        raise SpecError([Problem(path, line, col, "", said)]) from None
    finally:
        loader.dispose()
    return Source(data, positions, (path,))


def _indented_with_tab(text: str, line: int) -> bool:
    """Whether a tab stands among the leading blanks of line `line` (0-based): PyYAML's own words for it
    ("found character that cannot start any token") name no tab."""
    lines = text.splitlines()
    if line >= len(lines):
        return False
    row = lines[line]
    return "\t" in row[:len(row) - len(row.lstrip(" \t"))]


def _read_text(path: Path, document: str) -> str:
    """The file's text, if it is a regular file of at most MAX_BYTES in UTF-8."""
    try:
        info = path.stat()
    except FileNotFoundError:
        raise SpecError([Problem(path, None, None, "", "no such file")]) from None
    except OSError as exc:
        raise SpecError([Problem(path, None, None, "", f"cannot read the file: {exc.strerror}")]) from None
    if not stat.S_ISREG(info.st_mode):
        what = "a folder" if stat.S_ISDIR(info.st_mode) else "not a regular file (a device, pipe or socket)"
        raise SpecError([Problem(path, None, None, "", f"this is {what}; {document} is a YAML file")])
    if info.st_size > MAX_BYTES:
        raise SpecError([Problem(path, None, None, "", f"the file has {info.st_size:,} bytes; {document} may have "
                                 f"at most {MAX_BYTES:,}")])
    try:
        with path.open("rb") as f:
            raw = f.read(MAX_BYTES + 1)
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        return _fail(Problem(path, line, None, "", "the file is not UTF-8 text"))
    except OSError as exc:
        return _fail(Problem(path, None, None, "", f"cannot read the file: {exc.strerror}"))


def _fail(problem: Problem):
    raise SpecError([problem])


def _refuse_characters(path: Path, text: str) -> None:
    """YAML refuses control characters (NUL, BEL, ESC...): where, and which, in one line."""
    found = yaml.reader.Reader.NON_PRINTABLE.search(text)
    if found:
        before = text[: found.start()]
        line, col = before.count("\n") + 1, found.start() - (before.rfind("\n") + 1) + 1
        char = found.group()
        raise SpecError([Problem(path, line, col, "", f"character U+{ord(char):04X} "
                                 f"({unicodedata.name(char, 'a control character')}) is not allowed in YAML; "
                                 "delete it or write it as an escape inside double quotes")])


def _refuse_depth(path: Path, text: str, document: str) -> None:
    """Refuse nesting past MAX_DEPTH from the parser's events, before anything is built: PyYAML's
    composer recurses once a level, and its scanner slows with every bracket left open. The refusal names
    the key path it got to, as every other problem does."""
    events = SpecLoader(text)
    open_: list[list] = []  # per open collection: [is a mapping, items begun in it, the last key]
    try:
        while (event := events.get_event()) is not None and not isinstance(event, yaml.StreamEndEvent):
            if isinstance(event, yaml.CollectionEndEvent):
                open_.pop()
                continue
            if not isinstance(event, yaml.NodeEvent):
                continue
            if open_:
                level = open_[-1]
                if level[0] and level[1] % 2 == 0:  # a mapping's key
                    level[2] = event.value if isinstance(event, yaml.ScalarEvent) else "?"
                level[1] += 1
            if isinstance(event, yaml.CollectionStartEvent):
                open_.append([isinstance(event, yaml.MappingStartEvent), 0, None])
                if len(open_) > MAX_DEPTH:
                    parts = tuple(level[2] if level[0] else level[1] - 1 for level in open_[:-1])
                    raise SpecError([_at(path, event, parts, f"{document} nests deeper than {MAX_DEPTH} levels; "
                                                             "it needs a few")])
    finally:
        events.dispose()


def _pos(path: Path, node: yaml.Node) -> Pos:
    return (path, node.start_mark.line + 1, node.start_mark.column + 1)


def _at(path: Path, node: yaml.Node, parts: tuple, message: str) -> Problem:
    return Problem(path, node.start_mark.line + 1, node.start_mark.column + 1, format_path(parts), message)


def _bounded(path: Path, root: yaml.MappingNode, document: str) -> None:
    """Refuse a document that aliases would expand past MAX_NODES values or MAX_DEPTH levels (an alias
    "bomb", an alias inside the collection it names), measured on the node graph without expanding it."""
    sizes: dict[int, int | None] = {}

    def size(node: yaml.Node, depth: int) -> int:
        if id(node) in sizes and sizes[id(node)] is None:
            raise SpecError([_at(path, node, (), f"an alias refers to the collection it stands in, so {document} "
                                                 "would nest without end")])
        if depth > MAX_DEPTH:
            raise SpecError([_at(path, node, (), f"{document} nests deeper than {MAX_DEPTH} levels once its aliases "
                                                 "are expanded")])
        if id(node) not in sizes:
            sizes[id(node)] = None
            children = [n for pair in node.value for n in pair] if isinstance(node, yaml.MappingNode) else (
                node.value if isinstance(node, yaml.SequenceNode) else [])
            sizes[id(node)] = 1 + sum(size(child, depth + 1) for child in children)
        return sizes[id(node)]

    if size(root, 0) > MAX_NODES:
        key, _ = max(root.value, key=lambda pair: sizes[id(pair[1])])
        raise SpecError([_at(path, key, (key.value,) if isinstance(key.value, str) else (),
                             f"{document} holds {sizes[id(root)]:,} values, each alias counted as what it "
                             f"repeats, most of them here; at most {MAX_NODES:,} are allowed (it needs far fewer)")])


def _merge_keys(path: Path, node: yaml.Node, parts: tuple, problems: list, done: set) -> None:
    """YAML merge keys (`<<: *defaults`, `<<: [*a, *b]`) resolved in place, as YAML means them: the keys of the
    mappings named (of the first named first) come in under the mapping's own, which win; each key keeps the
    position it is written at, so a problem in a merged value points at the anchor that set it."""
    if id(node) in done or not isinstance(node, (yaml.MappingNode, yaml.SequenceNode)):
        return
    done.add(id(node))
    if isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _merge_keys(path, item, parts + (i,), problems, done)
        return
    own, merged = [], []
    for key_node, value_node in node.value:
        if key_node.tag != _MERGE:
            own.append((key_node, value_node))
            here = parts + (key_node.value,) if isinstance(key_node.value, str) else parts
            _merge_keys(path, value_node, here, problems, done)
            continue
        named = value_node.value if isinstance(value_node, yaml.SequenceNode) else [value_node]
        for source in named:
            if not isinstance(source, yaml.MappingNode):
                problems.append(_at(path, source, parts, "a merge key '<<' takes a mapping or a list of mappings, "
                                                         "such as <<: *defaults"))
                continue
            _merge_keys(path, source, parts, problems, done)
            merged.extend(source.value)
    if len(own) == len(node.value):
        return
    taken = {k.value for k, _ in own if isinstance(k, yaml.ScalarNode)}
    first = []
    for key_node, value_node in merged:
        if not (isinstance(key_node, yaml.ScalarNode) and key_node.value in taken):
            taken.add(key_node.value)
            first.append((key_node, value_node))
    node.value = first + own


def _walk(path: Path, node: yaml.Node, parts: tuple, positions: dict, problems: list) -> None:
    """Record key positions, refuse duplicate and non-string keys."""
    if isinstance(node, yaml.MappingNode):
        seen: dict = {}
        for key_node, value_node in node.value:
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag != _STR:
                shown = key_node.value if isinstance(key_node, yaml.ScalarNode) else "a list or mapping"
                problems.append(_at(path, key_node, parts, f"keys must be plain names, not {shown_text(repr(shown))}"
                                    if isinstance(shown, str) and shown != "a list or mapping"
                                    else "keys must be plain names, not a list or mapping"))
                continue
            key = key_node.value
            here = parts + (key,)
            if key in seen:
                first = seen[key]
                problems.append(_at(path, key_node, here, f"duplicate key '{shown_text(key)}' (first given on line "
                                    f"{first})"))
                continue
            seen[key] = key_node.start_mark.line + 1
            positions[here] = _pos(path, key_node)
            _walk(path, value_node, here, positions, problems)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            positions[parts + (i,)] = _pos(path, item)
            _walk(path, item, parts + (i,), positions, problems)
