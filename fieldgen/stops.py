"""The signals that stop a command as Ctrl-C does.

Ctrl-C (SIGINT) raises KeyboardInterrupt, which every command turns into one line on where it stands (a run's
last checkpoint intact, the write under way finished, the command that goes on). `kill`, a batch system ending or
preempting a job (SLURM sends SIGTERM, then SIGKILL some seconds later) and a closed terminal (SIGHUP) would kill
the process without a word; `catch` has them raise KeyboardInterrupt too, and the command exits with the shell's
status for the signal that stopped it, 128 + its number (130 for Ctrl-C, 143 for SIGTERM, 129 for SIGHUP).
"""

from __future__ import annotations

import signal
import sys
import threading
from typing import Callable

AS_CTRL_C = (signal.SIGTERM, signal.SIGHUP)
_received = [signal.SIGINT]  # the signal behind the last KeyboardInterrupt
_pending = [False]  # a stop signal came since the command began


def _stop(number: int, frame) -> None:
    _received[0] = signal.Signals(number)
    _pending[0] = True
    raise KeyboardInterrupt


def check() -> None:
    """Raise KeyboardInterrupt where a stop signal came and the command still runs: its KeyboardInterrupt was
    raised where Python drops exceptions (a garbage collector's callback, such as JAX's, or a `__del__`), which
    would have let a run go on to its end. A loop that trains calls this between its chunks."""
    if _pending[0]:
        raise KeyboardInterrupt


def catch() -> Callable[[], None]:
    """Have SIGTERM and SIGHUP stop this command as Ctrl-C does where they would kill it; a handler someone set
    stays, as does a signal the process was started ignoring (nohup's SIGHUP). A stop Python drops (`check`) is
    kept without the traceback Python prints for it. Returns what puts the handlers back, for whoever called the
    command (a test, a program running the app) to keep its own."""
    _received[0], _pending[0] = signal.SIGINT, False
    if threading.current_thread() is not threading.main_thread():
        return lambda: None
    default = {signal.SIGINT: signal.default_int_handler, **{sig: signal.SIG_DFL for sig in AS_CTRL_C}}
    taken = {sig: signal.signal(sig, _stop) for sig, handler in default.items() if signal.getsignal(sig) is handler}
    unraisable = sys.unraisablehook

    def dropped(report) -> None:
        """A stop raised where Python drops exceptions says nothing: `check` acts on it."""
        if not (_pending[0] and report.exc_type is KeyboardInterrupt):
            unraisable(report)

    if taken:
        sys.unraisablehook = dropped

    def give_back() -> None:
        for sig, handler in taken.items():
            if signal.getsignal(sig) is _stop:
                signal.signal(sig, handler)
        if sys.unraisablehook is dropped:
            sys.unraisablehook = unraisable

    return give_back


def status() -> int:
    """The exit status of a command the last KeyboardInterrupt stopped: 128 + the signal's number."""
    return 128 + int(_received[0])


def said() -> str:
    """How a command's one line on where it stands begins: 'interrupted' (Ctrl-C), or the signal that stopped it."""
    return "interrupted" if _received[0] == signal.SIGINT else f"stopped by {_received[0].name}"
