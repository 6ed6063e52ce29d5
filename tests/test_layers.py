"""The layers of the package, read from the code's own import statements: build time never reaches run
time, the environment knows nothing of curricula or trainers, and the trainers know environments and curricula
only through their contracts. Each layer lists what it may import: a module that imports anything else of
fieldgen fails here, naming the import."""

from __future__ import annotations

from pathlib import Path

import pytest

from fieldgen import source_imports

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"fieldgen": ROOT / "fieldgen", "fieldgen.agents": ROOT / "agents"}


def _module_name(path: Path) -> str:
    for package, folder in sorted(PACKAGES.items(), key=lambda item: -len(str(item[1]))):
        if path.is_relative_to(folder):
            parts = path.relative_to(folder).with_suffix("").parts
            return ".".join((package, *(p for p in parts if p != "__init__")))
    raise ValueError(path)


def imports(path: Path) -> set[str]:
    """Every module `path` imports, anywhere in it, with relative imports resolved; `from m import n` names
    both m and m.n (n may be a submodule)."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    return {f"{module}.{member}" if member else module for module, member in source_imports.imports(path, package)} | \
        {module for module, _ in source_imports.imports(path, package)}


def _files(folder: Path):
    return sorted(p for p in folder.rglob("*.py") if "__pycache__" not in p.parts)


# Each layer's files may import, of fieldgen, their own package and the modules listed here alone (a module named
# takes in what lies under it; "fieldgen" alone is the package's face, `fieldgen.make`); a rule on a file is read
# before the rule on its folder. Outside fieldgen, the modules a layer may never load.
FIELDGEN = ("fieldgen",)
BELOW_CURRICULA = ("fieldgen.schema", "fieldgen.compile", "fieldgen.env", "fieldgen.files", "fieldgen.render",
             "fieldgen.cameras", "fieldgen.suggest", "fieldgen.limits", "fieldgen.command", "fieldgen.video",
             "fieldgen.version")
RULES = [  # (folder or file, the fieldgen modules it may import, modules outside fieldgen it may not, why)
    ("fieldgen/schema", ("fieldgen.suggest", "fieldgen.limits"), ("jax", "mujoco"), "reading a spec needs no simulator"),
    ("fieldgen/compile", ("fieldgen.schema", "fieldgen.files", "fieldgen.render", "fieldgen.cameras",
                          "fieldgen.source_imports", "fieldgen.version"), (), "build time never reaches run time"),
    ("fieldgen/render.py", ("fieldgen.cameras",), (), "the drawings are below the build that marks what they draw"),
    ("fieldgen/env", ("fieldgen.schema", "fieldgen.compile", "fieldgen.render", "fieldgen.cameras", "fieldgen.command"),
     (),
     "the environment plays the variants it is given, not why they were chosen"),
    ("fieldgen/curriculum/contract.py", ("fieldgen.env.contract",), (),
     "all the trainers know of curricula, beside the environment contract"),
    ("fieldgen/curriculum", FIELDGEN + BELOW_CURRICULA, (),
     "a curriculum chooses what environments play, not who trains"),
    ("agents", ("fieldgen.env.contract", "fieldgen.curriculum.contract", "fieldgen.suggest", "fieldgen.limits"), (),
     "trainers know environments and curricula through their contracts alone"),
    ("agents/config.py", ("fieldgen.agents", "fieldgen.env.contract", "fieldgen.suggest", "fieldgen.limits", "fieldgen.schema.source",
                          "fieldgen.schema.errors", "fieldgen.counts", "fieldgen.curriculum.section"), (),
     "the settings read a --set value as a spec's values are read, a count as the command line's, and echo it as a "
     "spec's problems do; a config file's section beside theirs is a curriculum's, named where it is read"),
    ("agents/recipes.py", ("fieldgen.agents", "fieldgen.suggest", "fieldgen.schema.models", "fieldgen.schema.messages",
                           "fieldgen.schema.source"), (),
     "a recipe's fall rule is read, refused and said as a spec's episode.fall is"),
    ("fieldgen/sweep", FIELDGEN + BELOW_CURRICULA + ("fieldgen.curriculum", "fieldgen.agents", "fieldgen.run",
                                               "fieldgen.counts", "fieldgen.stops"), (),
     "a sweep runs the command, and is below the command line"),
]


def rule_of(path: Path):
    """The rule of the longest folder or file that holds `path`; None for a file no rule names."""
    held = [rule for rule in RULES if path == ROOT / rule[0] or path.is_relative_to(ROOT / rule[0])]
    return max(held, key=lambda rule: len(rule[0]), default=None)


def _covers(modules, module: str) -> bool:
    """Whether `module` is one of `modules` or lies under one; "fieldgen" alone is the package's face, not all
    that lies under it."""
    return any(module == m or (m != "fieldgen" and module.startswith(m + ".")) for m in modules)


def crossings(path: Path) -> list[str]:
    """Each import of `path` that its layer's rule does not allow: a folder's files may import its own modules
    too, a file named by a rule only what the rule lists."""
    where, allowed, forbidden, _ = rule_of(path)
    own = () if where.endswith(".py") else (_module_name(ROOT / where / "__init__.py"),)
    return [f"{path.relative_to(ROOT)} imports {module}" for module in sorted(imports(path))
            if (module.split(".")[0] == "fieldgen" and not _covers(own + allowed, module))
            or _covers(forbidden, module)]


@pytest.mark.parametrize("rule", RULES, ids=[r[0] for r in RULES])
def test_no_module_imports_across_its_layer(rule):
    where, _, _, why = rule
    files = [ROOT / where] if where.endswith(".py") else _files(ROOT / where)
    broken = [line for path in files if rule_of(path) is rule for line in crossings(path)]
    assert not broken, f"{why}: " + "; ".join(broken)


def test_the_rules_forbid_what_they_do_not_list():
    """An allow-list: an import of fieldgen that no rule names fails, as one a rule forbids does."""
    rule = rule_of(ROOT / "agents" / "loop.py")
    assert rule[0] == "agents"
    assert not _covers(rule[1], "fieldgen.env.mjx_physics") and _covers(rule[1], "fieldgen.env.contract")
    assert rule_of(ROOT / "fieldgen" / "curriculum" / "contract.py")[0] == "fieldgen/curriculum/contract.py"
    assert not _covers(rule_of(ROOT / "fieldgen" / "sweep" / "plan.py")[1], "fieldgen.cli.app")
    assert not _covers(rule_of(ROOT / "fieldgen" / "render.py")[1], "fieldgen.compile.cameras")


def test_the_import_reader_sees_relative_and_nested_imports(tmp_path, monkeypatch):
    """The rules above hold only if the reader finds every import: relative ones, and those inside functions."""
    folder = tmp_path / "fieldgen" / "env"
    folder.mkdir(parents=True)
    module = folder / "probe.py"
    module.write_text("from ..curriculum import schedule\n\ndef f():\n    from fieldgen.run import record\n")
    monkeypatch.setitem(PACKAGES, "fieldgen", tmp_path / "fieldgen")
    assert {"fieldgen.curriculum", "fieldgen.curriculum.schedule", "fieldgen.run.record"} <= imports(module)
