"""The layers of the package, read from the code's own import statements: build time never reaches run
time, the environment knows nothing of curricula or trainers, and the trainers know the environment only
through its contract. A module that breaks a rule fails here, naming the import."""

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


RULES = [  # (folder, modules it must not import, what the rule keeps apart)
    (ROOT / "fieldgen" / "schema", ("jax", "mujoco", "fieldgen.compile", "fieldgen.env", "fieldgen.run",
                                    "fieldgen.agents", "fieldgen.curriculum"), "reading a spec needs no simulator"),
    (ROOT / "fieldgen" / "compile", ("fieldgen.env", "fieldgen.run", "fieldgen.agents", "fieldgen.curriculum"),
     "build time never reaches run time"),
    (ROOT / "fieldgen" / "env", ("fieldgen.curriculum", "fieldgen.run", "fieldgen.agents"),
     "the environment plays the variants it is given, not why they were chosen"),
    (ROOT / "agents", ("fieldgen.compile", "fieldgen.env.field", "fieldgen.env.make", "fieldgen.run",
                       "fieldgen.curriculum", "fieldgen.schema"), "trainers know the environment through its contract"),
]


@pytest.mark.parametrize("folder,forbidden,why", RULES, ids=[r[0].name for r in RULES])
def test_no_module_imports_across_its_layer(folder, forbidden, why):
    broken = [f"{path.relative_to(ROOT)} imports {module}" for path in _files(folder) for module in sorted(imports(path))
              if any(module == f or module.startswith(f + ".") for f in forbidden)]
    assert not broken, f"{why}: " + "; ".join(broken)


def test_the_import_reader_sees_relative_and_nested_imports(tmp_path, monkeypatch):
    """The rules above hold only if the reader finds every import: relative ones, and those inside functions."""
    folder = tmp_path / "fieldgen" / "env"
    folder.mkdir(parents=True)
    module = folder / "probe.py"
    module.write_text("from ..curriculum import schedule\n\ndef f():\n    from fieldgen.run import record\n")
    monkeypatch.setitem(PACKAGES, "fieldgen", tmp_path / "fieldgen")
    assert {"fieldgen.curriculum", "fieldgen.curriculum.schedule", "fieldgen.run.record"} <= imports(module)
