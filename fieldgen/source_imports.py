"""What a Python source file imports, read from its statements without running it: the build cache's
digest follows the compiler's imports with it, and the layer tests check who imports whom."""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path


def imports(path: Path, package: str) -> list[tuple[str, str | None]]:
    """(module, None) for each `import module` and (module, name) for each `from module import name` anywhere in
    the file (a function's imports included), relative modules resolved against `package`, the package the file's
    module belongs to (its own name for a package's __init__.py)."""
    found: list[tuple[str, str | None]] = []
    for node in ast.walk(ast.parse(Path(path).read_bytes(), str(path))):
        if isinstance(node, ast.Import):
            found.extend((alias.name, None) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            module = importlib.util.resolve_name("." * node.level + (node.module or ""), package)
            found.extend((module, alias.name) for alias in node.names)
    return found
