"""bench/kernel_trace.py reads what XLA ran from a JAX profiler trace (one written here), and
bench/train_throughput.py's kernel table reads it the same way."""

from __future__ import annotations

import gzip
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
import kernel_trace  # noqa: E402
from train_throughput import kernel_table  # noqa: E402

sys.path.remove(str(ROOT / "bench"))


def kernel(name: str, ts: float, dur: float, pid: int = 1) -> dict:
    return {"ph": "X", "pid": pid, "tid": 7, "ts": ts, "dur": dur, "name": name}


def write_trace(folder: Path, events: list[dict]) -> None:
    where = folder / "plugins" / "profile" / "run"
    where.mkdir(parents=True)
    meta = [{"ph": "M", "pid": 1, "name": "process_name", "args": {"name": "/device:GPU:0"}},
            {"ph": "M", "pid": 2, "name": "process_name", "args": {"name": "/host:CPU"}}]
    with gzip.open(where / "perfetto_trace.json.gz", "wt") as f:
        json.dump({"traceEvents": meta + events}, f)


def test_device_kernels_are_read_from_the_newest_trace(tmp_path):
    write_trace(tmp_path, [kernel("gemm_fusion_dot_3", 0, 10), kernel("loop_add_fusion_12", 5, 2),
                           kernel("PjitFunction(chunk)", 0, 50, pid=2), kernel("loop_add_fusion_12", 20, 0)])
    kernels = kernel_trace.device_kernels(kernel_trace.trace_events(tmp_path))
    assert [k["name"] for k in kernels] == ["gemm_fusion_dot_3", "loop_add_fusion_12"]
    assert kernel_trace.busy_us(kernels) == 10 and kernel_trace.span_us(kernels) == 10


def test_a_cpu_trace_gives_its_host_operations_without_control_flow():
    def op(name, ts, dur):
        return {**kernel(name, ts, dur, pid=2), "args": {"hlo_op": name, "hlo_module": "jit_chunk"}}

    events = [op("while.12", 0, 100), op("ynn_fusion.1", 1, 30), op("add_fusion", 40, 5), kernel("python", 0, 200, 2)]
    assert [e["name"] for e in kernel_trace.host_ops(events)] == ["ynn_fusion.1", "add_fusion"]


def test_the_kernel_table_lists_the_device_kernels_by_time(tmp_path):
    write_trace(tmp_path, [kernel("gemm_fusion_dot_3", 0, 6), kernel("loop_add_fusion_12", 8, 2),
                           kernel("loop_add_fusion_12", 10, 2), kernel("PjitFunction(chunk)", 0, 50, pid=2)])
    assert kernel_table(tmp_path).splitlines() == [
        "3 kernels in 0.000 s; device idle 16.7% of it",
        "  50.0%        1 x      6.0 us  gemm_fusion_dot_3",
        "  33.3%        2 x      2.0 us  loop_add_fusion_12"]


def test_without_device_kernels_the_table_says_why(tmp_path):
    write_trace(tmp_path, [kernel("PjitFunction(chunk)", 0, 50, pid=2)])
    assert kernel_table(tmp_path) == "no device kernels in the trace (a CPU backend traces host threads only)"
