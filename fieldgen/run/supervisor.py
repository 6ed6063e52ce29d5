"""A process of a run over several processes, other than process 0, trains in a child of itself.

Process 0 holds the run's coordination service. When it dies, JAX's client in every other process ends that
process at once from a thread of its own, with a C++ stack trace and no say for fieldgen (the client's callback
for it cannot be set from Python). So such a process runs the same command as a child and relays its output;
when the child ends that way, the parent says in one line that process 0 stopped and how to go on, with the
words the child left for it once it knew its run (fieldgen.run.distributed.stopped words it). The child's own
watcher may notice first and say that very line, just before JAX ends it: a parent whose child said an error line
of its own says none, so the line comes once whichever notices first. The child dies with its parent (a launcher
that kills the parent kills the training), and Ctrl-C reaches the child as it reaches the parent.
"""

from __future__ import annotations

import ctypes
import os
import re
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

from fieldgen.command import fieldgen_command
from fieldgen.run.distributed import stopped

WORDS = "FIELDGEN_WORDS_IF_COORDINATOR_LOST"  # set in the child: where it leaves its line for the parent
RANKS = ("SLURM_PROCID", "OMPI_COMM_WORLD_RANK")  # a launcher's process id, before JAX is joined
LOST = ("Polled an error from coordination service", "Failed to send RPC to coordination service",
        "Terminating process because the JAX distributed service")  # JAX's words when the service is gone
PR_SET_PDEATHSIG = 1
COLOURS = re.compile(r"\x1b\[[0-9;]*m")  # a terminal's colours, which a child may print where they are forced


def needed(process_id: int | None) -> bool:
    """Whether this process should train in a supervised child: it is not process 0 (as given, or as its
    launcher numbers it), and it is not that child already."""
    if WORDS in os.environ:
        return False
    if process_id is None:
        ranks = [os.environ[r] for r in RANKS if r in os.environ]
        return bool(ranks) and ranks[0] != "0"
    return process_id != 0


def supervise(process_id: int | None = None, count: int | None = None) -> int:
    """Run this command again as a child, relay what it prints, and return the exit status to end with; this
    process's id and the run's process count, where given, name them should process 0 stop before the child
    left its words."""
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        return _relay(process_id, count)
    finally:  # the caller (a test, a program calling fieldgen's app) keeps its own handlers
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)


def _relay(process_id: int | None, count: int | None) -> int:
    with tempfile.TemporaryDirectory(prefix="fieldgen-supervisor-") as folder:
        words = Path(folder) / "words"
        child = subprocess.Popen(fieldgen_command(*sys.argv[1:]), stderr=subprocess.PIPE,
                                 env={**os.environ, WORDS: str(words)}, preexec_fn=_die_with_parent, text=True,
                                 errors="replace")
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # the terminal's Ctrl-C reaches the child itself
        signal.signal(signal.SIGTERM, lambda *_: child.send_signal(signal.SIGTERM))
        lost = told = False  # JAX ends the child as process 0 is gone; the child said why it stops
        for line in child.stderr:
            lost = lost or any(phrase in line for phrase in LOST)
            if not lost:
                told = told or COLOURS.sub("", line).startswith("error:")
                sys.stderr.write(line)
                sys.stderr.flush()
        status = child.wait()
        if lost and status != 0:
            if not told:
                said = words.read_text() if words.exists() else stopped([0], process_id, count)
                print(f"error: {said}", file=sys.stderr)
            return 1
        return status if status >= 0 else 128 - status


def leave_words(line: str) -> None:
    """In a supervised child, the line its parent says if process 0 stops (nothing elsewhere)."""
    path = os.environ.get(WORDS)
    if path:
        Path(path).write_text(line)


def _die_with_parent() -> None:
    """In the child before it starts: end when the parent ends (Linux; elsewhere the child outlives it)."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):
        pass
