"""XLA options every `fieldgen` command starts with, unless the user's own XLA_FLAGS names them.

XLA's fusion autotuner times large reductions on the GPU with each of its code generators. For CRL
on the ant at a large batch it kept compiling long past the time the whole run takes without it, and
the ant preset starts and trains as fast either way (bench/results/README.md). XLA reads XLA_FLAGS
when JAX first starts a backend, so this runs before."""

from __future__ import annotations

import os
import re

DEFAULTS = {"xla_gpu_experimental_enable_fusion_autotuner": "false"}


def apply() -> None:
    """Add each default to XLA_FLAGS that the user's flags do not already set."""
    flags = os.environ.get("XLA_FLAGS", "")
    named = set(re.findall(r"--(\w+)", flags))
    added = [f"--{name}={value}" for name, value in DEFAULTS.items() if name not in named]
    if added:
        os.environ["XLA_FLAGS"] = " ".join([flags, *added]).strip()
