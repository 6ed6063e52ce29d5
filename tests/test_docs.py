"""The documentation cannot drift from the code: its references are generated from the schema and the typer
app (docs/hooks.py) and must cover every key and option, the API reference (mkdocstrings, from the docstrings)
must document every entry point, and every code block marked runnable runs.

A block is marked by a line `<!-- runnable -->` (run by the default suite) or `<!-- runnable: slow -->`
(compiles or trains: run with `-m slow`) right before its fence. A page's blocks run in order in one
temporary folder, so a later block may use what an earlier one wrote.
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import click
import pytest
import typer

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
MARKER = re.compile(r"^<!-- runnable(?:: (?P<tag>\w+))? -->\n```(?P<lang>\w+)[^\n]*\n(?P<code>.*?)^```", re.M | re.S)


def hooks():
    spec = importlib.util.spec_from_file_location("docs_hooks", DOCS / "hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def runnable_blocks(page: Path) -> list[tuple[bool, str, str]]:
    """(slow, language, code) of each marked block, in page order; a marker without a fence after it fails."""
    text = page.read_text()
    blocks = [(m["tag"] == "slow", m["lang"], m["code"]) for m in MARKER.finditer(text)]
    assert len(blocks) == text.count("<!-- runnable"), f"{page.name}: a runnable marker not followed by a fence"
    for slow, lang, _ in blocks:
        assert lang in ("bash", "python"), f"{page.name}: runnable blocks are bash or python, not {lang}"
    return blocks


PAGES = sorted(p for p in DOCS.rglob("*.md") if "<!-- runnable" in p.read_text())


def run_blocks(page: Path, folder: Path, include_slow: bool) -> None:
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    for slow, lang, code in runnable_blocks(page):
        if slow and not include_slow:
            continue
        command = ["bash", "-euo", "pipefail", "-c", code] if lang == "bash" else [sys.executable, "-c", code]
        done = subprocess.run(command, cwd=folder, env=env, capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, f"{page.name}: this block failed:\n{code}\n{done.stdout}\n{done.stderr}"


def test_some_pages_have_runnable_blocks_and_each_is_well_formed():
    assert DOCS / "getting-started.md" in PAGES
    for page in PAGES:
        runnable_blocks(page)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_the_quick_runnable_blocks_of_a_page_run(page, tmp_path):
    run_blocks(page, tmp_path, include_slow=False)


@pytest.mark.slow
@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_runnable_block_of_a_page_runs(page, tmp_path):
    run_blocks(page, tmp_path, include_slow=True)


def test_a_failing_runnable_block_fails_the_test(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("<!-- runnable -->\n```bash\nfieldgen validate no_such_field\n```\n")
    with pytest.raises(AssertionError, match="this block failed"):
        run_blocks(page, tmp_path, include_slow=False)


def _rows(text: str) -> dict[str, list[str]]:
    """The cells of every table row, by the row's first cell (several rows may share one: keys repeat)."""
    rows: dict[str, list[str]] = {}
    for line in text.splitlines():
        if line.startswith("| `"):
            cells = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
            rows.setdefault(cells[0], []).append(" | ".join(cells[1:]))
    return rows


def _objects(schema: dict):
    """Every mapping the schema describes: the spec itself and each definition."""
    yield schema
    yield from schema["$defs"].values()


def test_the_dsl_reference_gives_every_key_with_its_default_range_and_description():
    from fieldgen.schema.editor import json_schema

    schema = json_schema()
    text = hooks().dsl_reference()
    rows = _rows(text)
    for key, prop in schema["properties"].items():
        if "$ref" in prop or key == "obstacles":  # a section: a heading with its description, its keys below
            assert f"## `{key}`" in text and prop["description"][1:] in text, key
    for node in _objects(schema):
        for key, prop in node.get("properties", {}).items():
            if node is schema and ("$ref" in prop or key == "obstacles"):
                continue
            assert f"`{key}`" in rows, f"{key} is missing from the DSL reference"
            description = prop.get("description", "").replace("|", "\\|")
            matching = [r for r in rows[f"`{key}`"] if description in r]
            assert matching, f"{key}: no row carries its description"
            if "default" in prop:
                assert any(f"`{json.dumps(prop['default'])}`" in r for r in matching), key
            if "maximum" in prop:
                assert any(f"≤ {prop['maximum']:g}" in r for r in matching), key


def test_the_dsl_reference_lists_the_registered_reward_terms():
    from fieldgen.schema.terms import TERMS

    section = hooks().dsl_reference().split("## Reward terms", 1)[1].split("\n## ", 1)[0]
    rows = re.findall(r"^\| `(\w+)` \| (.+?) \|", section, re.MULTILINE)
    assert rows == [(name, term.description) for name, term in TERMS.items()]


def test_the_dsl_reference_lists_the_terms_reward_dense_stands_for():
    from fieldgen.schema.terms import DENSE_REWARDS

    section = hooks().dsl_reference().split("## Dense rewards", 1)[1]
    rows = dict(re.findall(r"^\| `(\w+)` \| (.+?) \|$", section, re.MULTILINE))
    assert list(rows) == list(DENSE_REWARDS)
    assert rows["ball_near_target"].startswith("`{term: ball_progress, weight: 10}`, `{term: agent_behind_ball")
    assert rows["agent_near_target"] == ("`{term: agent_progress}`, `{term: upright, band: [0.2, 1.0]}`, "
                                         "`{term: control_cost, weight: 0.5}`")


def test_the_cli_reference_gives_every_command_and_option():
    from fieldgen.cli import app

    text = hooks().cli_reference()
    group = typer.main.get_command(app)
    root = click.Context(group, info_name="fieldgen")
    for name, command in group.commands.items():
        assert f"## `fieldgen {name}`" in text
        section = text.split(f"## `fieldgen {name}`", 1)[1].split("\n## ", 1)[0]
        for param in command.get_params(click.Context(command, info_name=name, parent=root)):
            if param.name == "help":
                continue
            for opt in param.opts if param.param_type_name == "option" else ():
                assert f"`{opt}`" in section, f"fieldgen {name} {opt} is missing from the CLI reference"
            if getattr(param, "help", None):
                assert param.help.replace("|", "\\|") in section, f"fieldgen {name}: {param.name}'s help is missing"


def test_the_reference_pages_hold_their_generated_parts_as_the_code_makes_them():
    """Read on GitHub, a reference page shows what is written in it: the generated part written there is
    the one the code makes now (`python docs/hooks.py` writes it)."""
    made = hooks()
    for name in made.PAGES:
        text = (DOCS / name).read_text()
        assert made.render(text) == text, f"docs/{name} is out of date with the code: run python docs/hooks.py"
    both = (DOCS / "reference" / "dsl.md").read_text() + (DOCS / "reference" / "cli.md").read_text()
    assert "## `task.reward[]`" in both and "## `fieldgen train`" in both


def test_a_generated_part_is_made_anew_between_its_markers():
    render = hooks().render
    made = render("top\n<!-- generated: cli-reference -->\nbottom")
    assert made.startswith("top\n<!-- generated: cli-reference -->\n") and made.endswith(
        "\n<!-- end of generated: cli-reference -->\nbottom") and "## `fieldgen train`" in made
    stale = made.replace("## `fieldgen train`", "## `fieldgen old`")
    assert render(stale) == made


API = DOCS / "reference" / "api.md"
DIRECTIVE = re.compile(r"^::: (?P<name>[\w.]+)\n(?P<options>(?:    .*\n)*)", re.M)
# what code outside fieldgen imports, by the name it is imported under -> the object the API page documents
ENTRY_POINTS = {
    "fieldgen.make": "fieldgen.env.make.make",
    "fieldgen.FieldEnv": "fieldgen.env.field.FieldEnv",
    "fieldgen.load_policy": "fieldgen.policy_folder.load_policy",
    **{name: name for name in (
        "fieldgen.env.contract.Environment", "fieldgen.env.contract.State",
        "fieldgen.curriculum.contract.Schedule", "fieldgen.curriculum.contract.adapt",
        "fieldgen.brax.register", "fieldgen.brax.BraxField", "fieldgen.playground.PlaygroundField",
        "fieldgen.run.summary.iqm", "fieldgen.run.summary.interval", "fieldgen.run.summary.MetricSummary",
        "fieldgen.policy_onnx.model_bytes")},
}


def documented(text: str) -> dict[str, str]:
    """Every object the page's `::: name` directives document, with the directive's options: the name, and each
    of its `members` where it lists them; a module without a list documents all its public members (`name.*`)."""
    objects = {}
    for m in DIRECTIVE.finditer(text):
        objects[m["name"]] = m["options"]
        listed = re.search(r"^ +members: \[(.*)\]$", m["options"], re.M)
        members = [member.strip() for member in listed[1].split(",")] if listed else ["*"]
        for member in members:
            objects.setdefault(f"{m['name']}.{member}", "")
    return objects


def _object(dotted: str):
    module, _, name = dotted.rpartition(".")
    return getattr(importlib.import_module(module), name)


def test_what_fieldgen_serves_is_an_entry_point():
    """`fieldgen.make` and the other names fieldgen/__init__.py's __getattr__ serves lazily are all documented."""
    served = next(f for f in ast.parse((ROOT / "fieldgen" / "__init__.py").read_text()).body
                  if isinstance(f, ast.FunctionDef) and f.name == "__getattr__")
    names = {c.value for test in ast.walk(served) if isinstance(test, ast.Compare)
             for c in ast.walk(test) if isinstance(c, ast.Constant) and isinstance(c.value, str)}
    assert names and {f"fieldgen.{name}" for name in names} <= set(ENTRY_POINTS)


def test_the_api_reference_documents_every_entry_point_under_the_name_it_is_imported_by():
    objects = documented(API.read_text())
    for imported, source in ENTRY_POINTS.items():
        assert source in objects or source.rpartition(".")[0] + ".*" in objects, \
            f"the API reference does not document {imported}"
        assert _object(imported) is _object(source), f"{imported} is not {source}, which the API reference documents"
        if imported != source:  # re-exported: headed by the name it is imported under
            assert f"heading: {imported}\n" in objects[source], f"the API reference heads {source} other than {imported}"


def test_an_entry_point_left_off_the_api_reference_is_missed():
    text = API.read_text()
    assert "fieldgen.run.summary.MetricSummary" in documented(text)
    assert "fieldgen.run.summary.MetricSummary" not in documented(text.replace(", MetricSummary]", "]"))
    assert "fieldgen.env.contract.*" not in documented(text.replace("::: fieldgen.env.contract\n", ""))


MARKDOWN_LINK = re.compile(r"\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def test_every_relative_link_resolves_in_the_repository():
    """README, the docs and the results pages are read on GitHub and in editors as well as on the site: a
    relative link names a file of the repository (the site's hook maps bench/results/ to its own results/)."""
    pages = [ROOT / "README.md", *sorted(DOCS.rglob("*.md")), *sorted((ROOT / "bench" / "results").rglob("README.md"))]
    broken = []
    for page in pages:
        text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
        for target in MARKDOWN_LINK.findall(text):
            path = target.split("#")[0]
            if path and not re.match(r"[a-z]+:", path) and not (page.parent / path).exists():
                broken.append(f"{page.relative_to(ROOT)}: {target}")
    assert not broken, "\n".join(broken)


def test_the_site_links_results_where_it_mirrors_them():
    site_links = hooks().site_links
    assert site_links("[a](../bench/results/x/README.md)", 0) == "[a](results/x/README.md)"
    assert site_links("[a](../../bench/results/x/README.md#b)", 1) == "[a](../results/x/README.md#b)"
    assert site_links("[a](../bench/results/x/README.md)", 1) == "[a](../bench/results/x/README.md)"
