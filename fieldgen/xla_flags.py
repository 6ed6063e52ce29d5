"""XLA options every `fieldgen` command starts with, unless the user's own XLA_FLAGS names them.

XLA's fusion autotuner times large reductions on the GPU with each of its code generators. For CRL
on the ant at a large batch it kept compiling long past the time the whole run takes without it, and
the ant preset starts and trains as fast either way (bench/results/README.md). XLA reads XLA_FLAGS
when JAX first starts a backend, so this runs before."""

from __future__ import annotations

import functools
import os
import re
import subprocess
import sys

from fieldgen.suggest import did_you_mean

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
    """Why XLA would end the command as JAX starts, in a sentence: a file of flags XLA_FLAGS names that cannot be
    read, a flag XLA does not know, a value it cannot read (`refused`); None where it would not."""
    flags = environ.get("XLA_FLAGS", "")
    path = flag_file(flags)
    if path is not None and not (os.path.isfile(path) and os.access(path, os.R_OK)):
        return (f"XLA_FLAGS={path!r} does not start with --, so XLA reads it as the name of a file of flags, and no "
                f"such file can be read here; give flags as --name=value (such as --xla_dump_to=/tmp/xla), name a "
                "readable file that holds them, or unset XLA_FLAGS")
    return refused(flags) if flags.strip() else None


LISTED = "XLA_FLAGS=--help python -c 'import jax; jax.devices()' lists the flags XLA knows, each with its kind"


@functools.cache
def refused(flags: str) -> str | None:
    """What XLA would refuse of XLA_FLAGS=`flags` (its flags, or a file of them), asked of a JAX started on the CPU
    in a process of its own, since XLA ends the process it refuses flags in; None where XLA takes them."""
    said = _started(flags)
    if said is None:
        return None
    unknown = re.search(r"Unknown flags? in XLA_FLAGS: (.*)", said)
    if unknown:
        names = unknown.group(1).split()
        known = re.findall(r"^\s*--(\w+)=", _started("--help") or "", re.M)  # XLA lists its flags, then ends
        hints = [did_you_mean(name.split("=")[0].lstrip("-"), known, {k: f"--{k}" for k in known}, cutoff=0.8)
                 for name in names]
        named = ", ".join(f"{name} ({hint.removeprefix('; ')})" if hint else name for name, hint in zip(names, hints))
        return (f"XLA would end the command as JAX starts: {_source(flags)} {named}, which XLA does not know. "
                f"Correct or drop {'it' if len(names) == 1 else 'them'}, or unset XLA_FLAGS ({LISTED}).")
    value = re.search(r"Couldn't interpret value (.*) for flag (\w+)", said)
    if value:
        return (f"XLA would end the command as JAX starts: {_source(flags)} --{value.group(2)}={value.group(1)}, a "
                f"value XLA cannot read as that flag's kind. Correct it, or unset XLA_FLAGS ({LISTED}).")
    return None  # not the flags: the command goes on, and says what fails where it fails


def _source(flags: str) -> str:
    """Where the flags XLA refused are written."""
    path = flag_file(flags)
    return "XLA_FLAGS names" if path is None else f"the file of flags that XLA_FLAGS names ({path}) holds"


def _started(flags: str) -> str | None:
    """XLA's words where a JAX on the CPU with XLA_FLAGS=`flags` does not start, else None."""
    env = {**os.environ, "XLA_FLAGS": flags, "JAX_PLATFORMS": "cpu"}
    started = subprocess.run([sys.executable, "-c", "import jax; jax.devices()"], env=env, capture_output=True,
                             text=True)
    return None if started.returncode == 0 else started.stderr
