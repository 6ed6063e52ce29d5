"""Each list of names (reward terms, algorithms, backends, ...) is written once, in its registry: a
second copy of a list, in the code or in a message or help text, would fall out of step with it."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from fieldgen.agents.contrastive import ENERGIES, LOSSES
from fieldgen.agents.registry import ALGORITHMS
from fieldgen.cameras import CAMERAS
from fieldgen.run.loggers import LOGGERS
from fieldgen.schema.backends import BACKENDS
from fieldgen.schema.models import AGENT_CONTACTS
from fieldgen.schema.terms import TERMS
from fieldgen.video import FORMATS

ROOT = Path(__file__).resolve().parents[1]
SOURCES = sorted([*ROOT.glob("fieldgen/**/*.py"), *ROOT.glob("agents/**/*.py")])
# what each list names, and the one module that writes it
REGISTRIES = {
    "reward terms": (tuple(TERMS), "fieldgen/schema/terms.py"),
    "algorithms": (ALGORITHMS, "agents/choices.py"),
    "backends": (tuple(BACKENDS), "fieldgen/schema/backends.py"),
    "agent contacts": (tuple(AGENT_CONTACTS), "fieldgen/schema/models.py"),
    "cameras": (CAMERAS, "fieldgen/cameras.py"),
    "video formats": (FORMATS, "fieldgen/video.py"),
    "loggers": (LOGGERS, "fieldgen/run/loggers.py"),
    "energies": (ENERGIES, "agents/contrastive.py"),
    "contrastive losses": (LOSSES, "agents/contrastive.py"),
}


def _docstrings(tree: ast.AST) -> set[int]:
    """Docstrings explain (a module may describe the pipelines it steps); they are not lists the code reads."""
    kinds = (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)
    return {id(node.body[0].value) for node in ast.walk(tree) if isinstance(node, kinds) and node.body
            and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)}


def literals(source: str) -> list[tuple[int, set[str]]]:
    """(line, the strings it names together) of each literal of `source`: the string items of a tuple, list
    or set, a dict's string keys (a Literal[...] is a tuple), and the words of a string that is no docstring
    (a message, a help text, a description)."""
    tree = ast.parse(source)
    docstrings = _docstrings(tree)
    found = []
    for node in ast.walk(tree):
        items = (node.elts if isinstance(node, (ast.Tuple, ast.List, ast.Set))
                 else node.keys if isinstance(node, ast.Dict) else None)
        if items is not None:
            found.append((node.lineno, {i.value for i in items if isinstance(i, ast.Constant) and isinstance(i.value, str)}))
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            found.append((node.lineno, set(re.findall(r"\w+", node.value))))
    return found


def copies(names: tuple[str, ...], owner: str) -> list[str]:
    """Where a literal outside `owner` names three or more of `names` (all of them, where there are fewer)."""
    enough = min(3, len(names))
    return [f"{path.relative_to(ROOT)}:{line}: {', '.join(sorted(named & set(names)))}"
            for path in SOURCES if path.relative_to(ROOT).as_posix() != owner
            for line, named in literals(path.read_text()) if len(named & set(names)) >= enough]


@pytest.mark.parametrize("what", REGISTRIES)
def test_each_list_of_names_is_written_only_in_its_registry(what):
    names, owner = REGISTRIES[what]
    assert (ROOT / owner).exists()
    assert copies(names, owner) == [], f"{what} written outside {owner}: read them from it"


def test_a_copy_is_found_in_code_and_in_text_but_not_in_a_docstring():
    source = ('"""Steps spring, positional and generalized."""\n'
              'CHOICES = ("mjx", "spring", "positional")\n'
              'HELP = "one of: mjx, spring, generalized"\n'
              'SPLIT = {"spring": 1, "positional": 2}\n')
    names = set(BACKENDS)
    assert [line for line, named in literals(source) if len(named & names) >= 3] == [2, 3]
