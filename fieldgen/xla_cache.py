"""XLA's compiled programs kept on disk between commands: a second `fieldgen train` of the same
shapes (another seed, a resume, an evaluation of the run) starts without compiling them again."""

from __future__ import annotations

import os
from pathlib import Path


def enable() -> None:
    """Point JAX's persistent compilation cache at ~/.cache/fieldgen/xla (under XDG_CACHE_HOME where
    set), unless JAX_COMPILATION_CACHE_DIR names another folder; JAX_ENABLE_COMPILATION_CACHE=false
    turns it off. JAX reads both when it is imported, so this runs before."""
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", str(base / "fieldgen" / "xla"))
