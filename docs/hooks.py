"""MkDocs hooks: the pages that are generated from the code rather than written by hand.

- the field DSL reference, from the JSON Schema that `fieldgen schema` prints (fieldgen.schema.editor) and
  the reward-term registry (fieldgen.schema.terms);
- the CLI reference, from the typer application behind `fieldgen` (its commands, arguments and options);
- the results pages, mirrored from bench/results/ (each folder's README and its files), so a reader of the
  site and a reader of the repository see the same record.

A page holds a generated part between `<!-- generated: NAME -->` and `<!-- end of generated: NAME -->`,
written there by `python docs/hooks.py` (so the repository shows what the site does) and made anew at every
build; tests/test_docs.py checks that the written part is the code's own and that every key of the schema and
every option of the app appears, so the references cannot drift from the code.
"""

from __future__ import annotations

import json
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"


# --- the field DSL -----------------------------------------------------------------------------------


def _ref(schema: dict, node: dict) -> tuple[str | None, dict]:
    """The $defs name and definition a node points at, or (None, node)."""
    if "$ref" in node:
        name = node["$ref"].rsplit("/", 1)[1]
        return name, schema["$defs"][name]
    return None, node


def _type(schema: dict, node: dict) -> str:
    """A key's type as a reader writes it in YAML."""
    name, node = _ref(schema, node)
    if name:
        return "mapping (below)"
    if "enum" in node:
        return "one of " + ", ".join(f"`{v}`" for v in node["enum"])
    if "const" in node:
        return f"`{node['const']}`"
    if "anyOf" in node:
        kinds = [_type(schema, n) for n in node["anyOf"] if n.get("type") != "null"]
        text = " or ".join(dict.fromkeys(kinds))
        return text + (" or null" if any(n.get("type") == "null" for n in node["anyOf"]) else "")
    kind = node.get("type")
    if kind == "array":
        if "prefixItems" in node:
            return "[" + ", ".join(_type(schema, n) for n in node["prefixItems"]) + "]"
        return "list of " + _type(schema, node.get("items", {}))
    if kind == "object":
        return "mapping of names to mappings (below)"
    return {"number": "number", "integer": "integer", "boolean": "boolean", "string": "text"}.get(kind, str(kind))


def _range(node: dict) -> str:
    """Bounds on a value (numbers, lengths of lists and text), from the schema's keywords."""
    parts = []
    for key, sign in (("exclusiveMinimum", ">"), ("minimum", "≥"), ("exclusiveMaximum", "<"), ("maximum", "≤")):
        if key in node:
            parts.append(f"{sign} {node[key]:g}")
    for key, sign in (("minItems", "≥"), ("maxItems", "≤"), ("maxProperties", "≤")):
        if key in node and not ("prefixItems" in node and key in ("minItems", "maxItems")):
            parts.append(f"{sign} {node[key]} entries")
    if "maxLength" in node:
        parts.append(f"≤ {node['maxLength']} characters")
    if "pattern" in node:
        parts.append(f"matches `{node['pattern']}`")
    for sub in node.get("anyOf", []):
        inner = _range(sub)
        if inner:
            parts.append(inner)
    return ", ".join(dict.fromkeys(parts))


def _value(value) -> str:
    return "`" + json.dumps(value) + "`" if value is not None else "`null`"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _choice_label(schema: dict, node: dict) -> str:
    """A choice's form by its tag (`kind: ring`, `mode: region`), or its $defs name."""
    name, node = _ref(schema, node)
    for key, prop in node.get("properties", {}).items():
        if "const" in prop:
            return f"{key}: {prop['const']}"
    return name or "value"


def _listed(node: dict) -> dict:
    """The list a key holds, where it holds one: the node itself, or its list among the choices (task.reward's
    terms, or `dense`)."""
    return next((n for n in [node, *node.get("anyOf", [])] if n.get("type") == "array"), {})


def _section(schema: dict, path: str, node: dict, defaults, out: list[str], depth: int) -> None:
    """A table of one mapping's keys, then a subsection for each key that is a mapping or a choice."""
    props = node.get("properties", {})
    required = set(node.get("required", []))
    nested = []
    out += ["| key | type | default | range | description |", "|---|---|---|---|---|"]
    for key, prop in props.items():
        if "default" in prop:
            default = _value(prop["default"])
        elif "const" in prop:
            default = _value(prop["const"])
        elif key in required:
            default = "required"
        elif isinstance(defaults, dict) and key in defaults and not isinstance(defaults[key], (dict, list)):
            default = _value(defaults[key])
        else:
            default = "see below"
        out.append(f"| `{key}` | {_cell(_type(schema, prop))} | {_cell(default)} | {_cell(_range(prop))} | "
                   f"{_cell(prop.get('description', ''))} |")
        sub_defaults = defaults.get(key) if isinstance(defaults, dict) else None
        ref, target = _ref(schema, prop)
        if ref:
            nested.append((f"{path}.{key}" if path else key, [(None, target)], sub_defaults, prop))
        elif "anyOf" in prop and any("$ref" in n for n in prop["anyOf"]):
            forms = [(_choice_label(schema, n), _ref(schema, n)[1]) for n in prop["anyOf"] if "$ref" in n]
            nested.append((f"{path}.{key}" if path else key, forms, sub_defaults, prop))
        elif "$ref" in _listed(prop).get("items", {}):
            item = _ref(schema, _listed(prop)["items"])[1]
            nested.append((f"{path}.{key}[]" if path else f"{key}[]", [(None, item)], None, prop))
    for sub_path, forms, sub_defaults, prop in nested:
        out += ["", f"{'#' * depth} `{sub_path}`", ""]
        if prop.get("description"):
            out += [prop["description"][0].upper() + prop["description"][1:] + ".", ""]
        if sub_defaults is not None and len(forms) > 1:
            out += [f"Default: {_value(sub_defaults)}.", ""]
        for label, target in forms:
            if len(forms) > 1:
                tag = next((p for p in target.get("properties", {}).values() if "const" in p), {})
                out += [f"**`{label}`**: {tag.get('description', target.get('description', ''))}", ""]
            _section(schema, sub_path, target, sub_defaults if len(forms) == 1 else None, out, depth + 1)
            out.append("")


def dsl_reference() -> str:
    """Every key of a field spec, section by section, from the schema `fieldgen schema` prints."""
    from fieldgen.schema.editor import json_schema
    from fieldgen.schema.models import FieldSpec
    from fieldgen.schema.terms import DENSE_REWARDS, MATCH_TERMS, TERMS

    schema = json_schema()
    defaults = FieldSpec.model_validate({"name": "example"}).model_dump(mode="json")
    out: list[str] = []
    top = {"properties": {k: v for k, v in schema["properties"].items() if _ref(schema, v)[0] is None
                          and k != "obstacles"}, "required": schema.get("required", [])}
    out += ["## Top level", ""]
    _section(schema, "", top, defaults, out, 3)
    for key, prop in schema["properties"].items():
        name, target = _ref(schema, prop)
        if key == "obstacles":
            entry = next(n for n in prop["patternProperties"].values())
            out += ["", "## `obstacles`", "", f"{prop['description'][0].upper()}{prop['description'][1:]}: a mapping "
                    f"from a name ({_range(prop['propertyNames']) or 'a plain name'}; {_range(prop)}) to a box.",
                    ""]
            _section(schema, "obstacles.NAME", _ref(schema, entry["anyOf"][0])[1], None, out, 3)
            continue
        if name is None:
            continue
        out += ["", f"## `{key}`", "", prop["description"][0].upper() + prop["description"][1:] + ".", ""]
        _section(schema, key, target, defaults.get(key), out, 3)
    out += _table("Reward terms", "The terms `task.reward` may name, from the registry `fieldgen/schema/terms.py`; the "
                  "reward is the sum of `weight * term`, and terms are signed so larger is better.",
                  ("term", "value", "needs"),
                  [(f"`{term}`", _cell(spec.description), ", ".join(
                      part for part, flag in (("a ball", spec.ball), ("a goal", spec.goal), ("a torso (ant)", spec.torso))
                      if flag) or "-") for term, spec in TERMS.items()])
    out += _table("Match reward terms", "The terms `task.reward` may name on a field with `teams`, from `MATCH_TERMS` "
                  "in `fieldgen/schema/terms.py`: each side's reward is the sum of `weight * term` read from its own "
                  "side, and a zero-sum term's values for the two sides sum to zero.",
                  ("term", "value", "zero-sum"),
                  [(f"`{term}`", _cell(spec.description), "yes" if spec.zero_sum else "-")
                   for term, spec in MATCH_TERMS.items()])
    out += _table("Dense rewards", "`task: {reward: dense}` stands for the terms generated for the task's success kind, "
                  "from `DENSE_REWARDS` in `fieldgen/schema/terms.py` (terms that need a torso only for the ant); on a "
                  "field with a solid obstacle, `ball_path_progress` stands in for `ball_progress`, so that a ball "
                  "pushed round a goalie progresses and one pushed into it does not. A success kind not listed has "
                  "none, and the spec lists its terms itself.",
                  ("success kind", "terms"),
                  [(f"`{kind}`", _cell(", ".join(_dense_term(t) for t in terms)))
                   for kind, terms in DENSE_REWARDS.items()])
    return "\n".join(out) + "\n"


def _table(title: str, intro: str, header: tuple[str, ...], rows: list[tuple[str, ...]]) -> list[str]:
    """A reference section: its heading, a paragraph, then a Markdown table of `rows` under `header`."""
    return (["", f"## {title}", "", intro, "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
            + ["| " + " | ".join(row) + " |" for row in rows])


def _dense_term(term: dict) -> str:
    """A generated term as a spec would write it: `{term: upright, band: [0.2, 1.0]}`."""
    shown = {k: list(v) if isinstance(v, tuple) else format(v, "g") if isinstance(v, float) else v
             for k, v in term.items()}
    return "`{" + ", ".join(f"{k}: {v}" for k, v in shown.items()) + "}`"


# --- the command line --------------------------------------------------------------------------------


def cli_reference() -> str:
    """Every command of `fieldgen` with its usage, description and parameters, from the typer app."""
    import click
    import typer

    from fieldgen.cli import app

    group = typer.main.get_command(app)
    root = click.Context(group, info_name="fieldgen")
    out = ["`SPEC` is a YAML path or a bundled field name (`fieldgen list`). `fieldgen --version` prints the "
           "version, `python -m fieldgen` is the same command, and `fieldgen --install-completion` adds tab "
           "completion to your shell.", ""]
    for name, command in group.commands.items():
        ctx = click.Context(command, info_name=name, parent=root)
        params = [p for p in command.get_params(ctx) if p.name != "help"]
        out += [f"## `fieldgen {name}`", "", "```text", f"fieldgen {name} {_usage(params)}", "```", ""]
        lines = (command.help or "").strip().splitlines()
        examples = [line.split(":", 1)[1].strip() for line in lines if line.startswith("Example:")]
        prose = [line for line in lines if not line.startswith("Example:")]
        out += ["\n".join(prose).strip(), ""]
        if examples:
            out += ["```bash", *examples, "```", ""]
        out += ["| parameter | value | default | description |", "|---|---|---|---|"]
        for param in params:
            if param.param_type_name == "argument":
                label = f"`{_metavar(param)}`"
            else:
                label = " / ".join(f"`{opt}`" for opt in (*param.opts, *param.secondary_opts))
            value = "" if getattr(param, "is_flag", False) else (param.metavar or "")
            if param.multiple:
                value += " (repeat)"
            default = param.default
            if getattr(param, "is_flag", False):
                shown = f"`{(param.opts if default else param.secondary_opts or ['off'])[0]}`"
            else:
                shown = "-" if default in (None, "") or param.required else f"`{default}`"
            out.append(f"| {_cell(label)} | {_cell(value)} | {_cell(shown)} | {_cell(getattr(param, 'help', '') or '')} |")
        out.append("")
    return "\n".join(out)


def _metavar(argument) -> str:
    return (argument.metavar or argument.name.upper()).strip("{}")


def _usage(params) -> str:
    """`[OPTIONS]` and the arguments as --help names them: SPEC... for several, [SPEC] where optional."""
    pieces = ["[OPTIONS]"]
    for param in params:
        if param.param_type_name == "argument":
            text = _metavar(param)
            text += "..." if param.nargs == -1 and not text.endswith("...") else ""
            pieces.append(text if param.required else f"[{text}]")
    return " ".join(pieces)


GENERATED = {"dsl-reference": dsl_reference, "cli-reference": cli_reference}
PAGES = ("reference/dsl.md", "reference/cli.md")  # the pages that hold generated parts


def render(markdown: str) -> str:
    """The page with each generated part made anew: what stands between `<!-- generated: NAME -->` and
    `<!-- end of generated: NAME -->` (a page may hold a marker alone, to be filled)."""
    for name, make in GENERATED.items():
        begin, end = f"<!-- generated: {name} -->", f"<!-- end of generated: {name} -->"
        if begin not in markdown:
            continue
        before, rest = markdown.split(begin, 1)
        after = rest.split(end, 1)[1] if end in rest else rest
        markdown = f"{before}{begin}\n{make().strip()}\n{end}{after}"
    return markdown


def write_pages() -> list[str]:
    """Each page with generated parts written with them made anew, so that the repository (GitHub, an editor)
    shows what the site does; the names of the pages that changed."""
    changed = []
    for name in PAGES:
        page = ROOT / "docs" / name
        text = page.read_text()
        made = render(text)
        if made != text:
            page.write_text(made)
            changed.append(name)
    return changed


# --- MkDocs events -----------------------------------------------------------------------------------


def result_folders() -> list[Path]:
    """The question folders of bench/results, in the order its index lists them."""
    index = (RESULTS / "README.md").read_text()
    folders = [p for p in RESULTS.iterdir() if p.is_dir() and (p / "README.md").exists()]
    return sorted(folders, key=lambda p: (index.find(f"({p.name}/"), p.name) if f"({p.name}/" in index
                  else (len(index), p.name))


def on_config(config):
    """One results page per question folder, in the nav under Results."""
    for entry in config["nav"]:
        if isinstance(entry, dict) and "Results" in entry:
            entry["Results"] = [*entry["Results"], {"All questions": "results/README.md"},
                                *[{_title(p): f"results/{p.name}/README.md"} for p in result_folders()]]
    return config


def _title(folder: Path) -> str:
    first = (folder / "README.md").read_text().splitlines()[0]
    return first.lstrip("# ").replace("`", "").strip()


def on_files(files, config):
    """bench/results/ mirrored under results/: every README as a page, every data file and plot beside it."""
    from mkdocs.structure.files import File

    for path in sorted(RESULTS.rglob("*")):
        if path.is_file():
            uri = "results/" + path.relative_to(RESULTS).as_posix()
            files.append(File.generated(config, uri, abs_src_path=str(path)))
    return files


def site_links(markdown: str, depth: int) -> str:
    """The page's links to bench/results/ as the site has them: a page `depth` folders below docs/ links to
    `../` * (depth + 1) + `bench/results/`, which resolves in the repository (GitHub, an editor), and the site
    mirrors that folder as `results/` (on_files)."""
    return markdown.replace("](" + "../" * (depth + 1) + "bench/results/", "](" + "../" * depth + "results/")


def on_page_markdown(markdown, page, config, files):
    if page.file.src_uri.startswith("results/"):  # a mirrored results page: its links stay within results/
        return render(markdown)
    return site_links(render(markdown), page.file.src_uri.count("/"))


if __name__ == "__main__":  # python docs/hooks.py: the reference pages' generated parts, written in place
    print("\n".join(f"wrote docs/{name}" for name in write_pages()) or "the reference pages are up to date")
