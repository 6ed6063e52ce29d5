"""XLA options every `fieldgen` command starts with, unless the user's own XLA_FLAGS names them.

XLA's fusion autotuner times large reductions on the GPU with each of its code generators. For CRL
on the ant at a large batch it kept compiling long past the time the whole run takes without it, and
the ant preset starts and trains as fast either way (bench/results/README.md). XLA reads XLA_FLAGS
when JAX first starts a backend, so this runs before."""

from __future__ import annotations

import os
import re

DEFAULTS = {"xla_gpu_experimental_enable_fusion_autotuner": "false"}


def flag_file(flags: str) -> str | None:
    """The file XLA reads its flags from, where XLA_FLAGS is not flags itself: XLA takes a value whose first
    character past any whitespace is not '-' as the name of a file of flags (the whole value, spaces and all)."""
    return flags if flags.strip() and not flags.lstrip().startswith("-") else None


def apply() -> None:
    """Add each default to XLA_FLAGS that the user's flags do not already set; a file of flags named there is
    left as it is named (a flag added to its name would name another file, and XLA would abort)."""
    flags = os.environ.get("XLA_FLAGS", "")
    if flag_file(flags) is not None:
        return
    named = set(re.findall(r"--(\w+)", flags))
    added = [f"--{name}={value}" for name, value in DEFAULTS.items() if name not in named]
    if added:
        os.environ["XLA_FLAGS"] = " ".join([flags, *added]).strip()


def problem(environ=os.environ) -> str | None:
    """Why XLA would abort the command as JAX starts (a file of flags XLA_FLAGS names that cannot be read), in a
    sentence; None where it would not."""
    path = flag_file(environ.get("XLA_FLAGS", ""))
    if path is None or (os.path.isfile(path) and os.access(path, os.R_OK)):
        return None
    return (f"XLA_FLAGS={path!r} does not start with --, so XLA reads it as the name of a file of flags, and no "
            f"such file can be read here; give flags as --name=value (such as --xla_dump_to=/tmp/xla), name a "
            "readable file that holds them, or unset XLA_FLAGS")
