"""What XLA ran in a JAX profiler trace: the perfetto_trace.json.gz that
`jax.profiler.trace(folder, create_perfetto_trace=True)` writes, read by the benchmarks that profile.

On a GPU the trace holds each kernel on a `/device:` process; a CPU backend traces host threads
only, where XLA's CPU runtime marks each operation it runs (its thunks) with the HLO op's name.
"""

from __future__ import annotations

import gzip
import json
import re
from pathlib import Path

CONTROL_FLOW = re.compile(r"(while|conditional|call)(\.\d+)?$")


def trace_events(profile: Path) -> list[dict]:
    """The events of the newest trace under `profile`."""
    traces = list(profile.rglob("perfetto_trace.json.gz"))
    if not traces:
        raise FileNotFoundError(f"no perfetto_trace.json.gz under {profile}")
    trace = json.load(gzip.open(max(traces, key=lambda p: p.stat().st_mtime)))
    return trace["traceEvents"] if isinstance(trace, dict) else trace


def device_kernels(events: list[dict]) -> list[dict]:
    """The timed events of the trace's `/device:` processes: the kernels a GPU ran."""
    devices = {e["pid"] for e in events if e.get("ph") == "M" and e.get("name") == "process_name"
               and e["args"]["name"].startswith("/device:")}
    return [e for e in events if e.get("ph") == "X" and e["pid"] in devices and e.get("dur")]


def host_ops(events: list[dict]) -> list[dict]:
    """The timed events that name an HLO op: the operations XLA's CPU runtime ran, less its control flow
    (a while loop's event spans the operations of its body, which are events of their own)."""
    return [e for e in events if e.get("ph") == "X" and e.get("dur") and "hlo_op" in e.get("args", {})
            and not CONTROL_FLOW.match(e["args"]["hlo_op"])]


def busy_us(kernels: list[dict]) -> float:
    """Microseconds in which at least one of `kernels` ran: the union of their intervals, over all streams."""
    busy, end = 0.0, None
    for e in sorted(kernels, key=lambda e: e["ts"]):
        start, stop = e["ts"], e["ts"] + e["dur"]
        if end is None or start > end:
            busy, end = busy + stop - start, stop
        elif stop > end:
            busy, end = busy + stop - end, stop
    return busy


def span_us(kernels: list[dict]) -> float:
    """Microseconds from the first kernel's start to the last one's end."""
    return max(e["ts"] + e["dur"] for e in kernels) - min(e["ts"] for e in kernels)
