"""YAML file -> validated FieldSpec: `extends:` merging, then every problem at once.

Maps merge by key, lists are replaced whole, and a key set to null is removed
(back to its default; an inherited obstacle deleted). Each merged key remembers the
file and line it came from, so an error in an inherited value points at the
base file that set it.
"""

from __future__ import annotations

import itertools
from importlib import resources
from pathlib import Path

from pydantic import ValidationError

from fieldgen.schema import messages
from fieldgen.schema.checks import Among, physics_problems
from fieldgen.schema.errors import Problem, SpecError, shown_text
from fieldgen.schema.models import FieldSpec
from fieldgen.schema.source import Source, read_yaml
from fieldgen.suggest import did_you_mean



def bundled_fields() -> dict[str, Path]:
    """Bundled field names -> their YAML files: the package data `fieldgen.fields`, which is the
    repository's fields/ folder in a checkout and a folder of the installed package otherwise."""
    folder = Path(str(resources.files("fieldgen.fields")))
    return {p.stem: p for p in sorted(folder.glob("*.yaml"))}


def bundled_names_where(keep) -> list[str]:
    """The bundled fields whose spec `keep(spec)` accepts, in name order: what an error can offer in place of
    a field that cannot serve (a bundled spec that does not load is left out, not raised)."""
    names = []
    for name, path in bundled_fields().items():
        try:
            spec = load_spec(path)
        except SpecError:
            continue
        if keep(spec):
            names.append(name)
    return names


def resolve_spec_path(ref: str, relative_to: Path | None = None) -> Path:
    """A bundled name, or a path (relative to `relative_to`'s folder if given)."""
    looks_like_path = "/" in ref or ref.endswith((".yaml", ".yml"))
    if not looks_like_path:
        bundled = bundled_fields()
        if ref in bundled:
            return bundled[ref]
    path = Path(ref)
    if relative_to is not None and not path.is_absolute():
        path = relative_to.parent / path
    return path


def _refuse_unknown_name(path: Path) -> None:
    """A bare name that is neither a file nor a bundled field, with the nearest bundled one (a typo of one)."""
    if len(path.parts) == 1 and not path.suffix and not path.exists():
        near = did_you_mean(str(path), bundled_fields()) or "."
        raise SpecError([Problem(path, None, None, "", f"neither a file nor a bundled field{near} `fieldgen list` "
                                                       "shows the bundled fields")])


def load_spec(path: str | Path | FieldSpec, backend: str | None = None, changes: dict | None = None) -> FieldSpec:
    """Load, merge and validate a field spec; raises SpecError listing every problem. `backend`
    replaces its sim.backend, with that pipeline's defaults for whatever the spec leaves out; `changes`
    (keys as a spec writes them, e.g. {"task": {"reward": "dense"}}) merge over it as over what it extends."""
    if isinstance(path, FieldSpec):
        source = Source(path.model_dump(mode="json", exclude_unset=True))
    else:
        _refuse_unknown_name(Path(path))
        source = _load_merged(Path(path), ())
    if backend is not None:
        source = merge(source, Source({"sim": {"backend": backend}}))
    if changes:
        source = merge(source, Source(changes))
    return validate(source)


def validate(source: Source) -> FieldSpec:
    try:
        spec = FieldSpec.model_validate(source.data)
    except ValidationError as exc:
        problems = messages.problems(source, exc.errors())
        renamed = _validly_named(source.data, exc.errors())
        if renamed is not None:  # only names are wrong: the rest's sense is checked too, under names that are right
            data, written = renamed
            try:
                problems += _physics(source, FieldSpec.model_validate(data), written)
            except ValidationError:
                pass  # a check of the whole spec that the names kept from running: it runs once they are fixed
        raise SpecError(problems) from None
    problems = _physics(source, spec)
    if problems:
        raise SpecError(problems)
    return spec


PLACEHOLDER = "unnamed"  # stands in for a name that is wrong while the rest of the spec is checked


def _validly_named(data: dict, errors: list[dict]) -> tuple[dict, dict] | None:
    """The spec's data with a placeholder for each name that is wrong (the field's, an obstacle's), and each
    obstacle placeholder -> the name written; None where anything but a name is wrong."""
    wrong = set()
    for error in errors:
        loc = error["loc"]
        if loc == ("name",):
            continue
        if len(loc) == 3 and loc[0] == "obstacles" and loc[2] == "[key]":  # pydantic's location of a mapping's key
            wrong.add(loc[1])
            continue
        return None
    taken = set(data.get("obstacles") or ())
    placeholders = (f"{PLACEHOLDER}_{i}" for i in itertools.count() if f"{PLACEHOLDER}_{i}" not in taken)
    written, obstacles = {}, {}
    for name, obstacle in (data.get("obstacles") or {}).items():
        if name in wrong:
            placeholder = next(placeholders)
            written[placeholder], name = name, placeholder
        obstacles[name] = obstacle
    return {**data, "name": PLACEHOLDER, **({"obstacles": obstacles} if written else {})}, written


def _physics(source: Source, spec: FieldSpec, written: dict | None = None) -> list:
    """The spec's physics problems, at their lines; an obstacle checked under a placeholder (`written`:
    placeholder -> the name written) is named as written."""
    found = []
    for parts, message in physics_problems(spec):
        paths = list(parts) if isinstance(parts, Among) else [parts]  # conflicting keys: the one written last
        for placeholder, name in (written or {}).items():
            paths = [("obstacles", name, *p[2:]) if p[:2] == ("obstacles", placeholder) else p for p in paths]
            message = message.replace(f"'{placeholder}'", f"'{name}'")
        found.append(source.problem(source.written_last(tuple(paths)), message))
    return found


MAX_EXTENDS = 16  # files in one `extends` chain


def _load_merged(path: Path, chain: tuple[Path, ...]) -> Source:
    chain = chain + (path.resolve(),)
    source = read_yaml(path)
    parent_ref = source.data.get("extends")
    if parent_ref is None:
        return source
    parent_path = _extended(source, parent_ref, path)
    if parent_path.resolve() in chain:
        cycle = " -> ".join(str(p) for p in chain + (parent_path.resolve(),))
        raise SpecError([source.problem(("extends",), f"'extends' forms a cycle: {cycle}")])
    if len(chain) >= MAX_EXTENDS:
        raise SpecError([source.problem(("extends",), f"the 'extends' chain is longer than {MAX_EXTENDS} files")])
    parent = _load_merged(parent_path, chain)
    return merge(parent, source)


def lineage(path: Path) -> list[str]:
    """The name of the spec in `path`, then of each spec it extends, nearest first: the fields whose recipe
    it may take. A file that cannot be read ends the list; loading the spec says why."""
    names: list[str] = []
    seen: set[Path] = set()
    while path.resolve() not in seen and len(seen) < MAX_EXTENDS:
        seen.add(path.resolve())
        try:
            source = read_yaml(path)
            name, ref = source.data.get("name"), source.data.get("extends")
            if isinstance(name, str) and name not in names:
                names.append(name)
            if ref is None:
                break
            path = _extended(source, ref, path)
        except SpecError:
            break
    return names


def _extended(source: Source, ref, path: Path) -> Path:
    """The file `extends: ref` names: a bundled field, or a .yaml file by a path relative to this one.
    Absolute paths and files of other kinds are refused, so a spec someone shares cannot make fieldgen
    read a system file (/etc/passwd, /dev/zero) and print what it found there."""

    def refuse(reason: str):
        rule = f"'extends' takes a bundled field name ({', '.join(bundled_fields())}) or a relative path to a .yaml file"
        raise SpecError([source.problem(("extends",), f"{reason}; {rule}")])

    if not isinstance(ref, str) or not ref.strip():
        refuse("it is empty" if isinstance(ref, str) else f"{ref!r} is not a name or a path")
    shown = shown_text(ref)
    looks_like_path = "/" in ref or "\\" in ref or ref.endswith((".yaml", ".yml"))
    if looks_like_path and (Path(ref).is_absolute() or ref.startswith(("~", "\\"))):
        refuse(f"'{shown}' is an absolute path")
    if looks_like_path and not ref.endswith((".yaml", ".yml")):
        refuse(f"'{shown}' does not end in .yaml")
    parent = resolve_spec_path(ref, relative_to=path)
    try:
        parent.stat()
    except FileNotFoundError:
        pass  # said below, with the bundled names near it
    except OSError as exc:  # a name too long for the file system, a loop of links...
        refuse(f"'{shown}' cannot be a file here ({exc.strerror.lower()})")
    if not parent.exists():
        refuse(f"'{shown}' is neither a bundled field nor a file{did_you_mean(ref, bundled_fields())}")
    if not parent.is_file():
        refuse(f"'{shown}' is {'a folder' if parent.is_dir() else 'not a regular file'}")
    return parent


def merge(base: Source, child: Source) -> Source:
    """child's keys over base's, as `extends` merges a spec over its parent: null deletes a key."""
    data = _deep_merge(base.data, child.data)
    positions = dict(base.positions)
    for parts in list(positions):
        if parts and _replaced(child.data, parts):
            del positions[parts]
    positions.update(child.positions)
    return Source(data, positions, base.files + child.files)


def _deep_merge(base, child):
    if isinstance(base, dict) and isinstance(child, dict):
        out = dict(base)
        for key, value in child.items():
            if value is None:
                out.pop(key, None)  # null deletes: back to the default, or an inherited obstacle removed
            else:
                out[key] = _deep_merge(base[key], value) if key in base else value
        return out
    return child


def _replaced(child: dict, parts: tuple) -> bool:
    """Whether the child overrides this base key path with a non-mapping value."""
    node = child
    for part in parts:
        if not isinstance(node, dict) or part not in node:
            return False
        node = node[part]
        if not isinstance(node, dict):
            return True
    return False
