"""One run over two processes, a device each and joined by jax.distributed, against the same run in one
process over both devices: does it train as fast, and exactly the same?

The same `fieldgen train` command runs twice, each time in a run folder of its own: once in one process
that sees both devices (`CUDA_VISIBLE_DEVICES=0,1`), then as two processes that each see one
(`CUDA_VISIBLE_DEVICES=0` and `=1`, with `--coordinator 127.0.0.1:PORT --num-processes 2 --process-id I`,
PORT a free one). Where CUDA_VISIBLE_DEVICES already names GPUs, its first two stand for 0 and 1. On a
CPU (`--platform cpu`, or `auto` where JAX finds no GPU) each process gets its devices from XLA instead
(`--xla_force_host_platform_device_count`), and the two processes exchange through gloo, as
tests/run/test_distributed.py runs them. The reference, measured in the same run, is the one process:
the rate of the two is printed as a ratio to it.

Speed is env steps per second of the training chunks, all seeds counted: the mean of `steps_per_second`
in the run's metrics.jsonl (each chunk timed alone, every compile done before the first) over the chunks
after the first, or over the first where it is the only one. A chunk also waits for the checkpoint of the
evaluation before it (`fieldgen train` writes it while the next chunk trains; across processes it is first
gathered from every device), so a chunk that trains for less time than a checkpoint takes to gather and
write measures the checkpoint: two seeds of CRL's ant preset hold gigabytes (their replay buffers). The defaults (6M env
steps, one evaluation) give one chunk of about 4.9M env steps a seed. The whole processes' wall clock, start and
compiles included, is printed beside it. Sameness is the largest absolute difference of each logged
metric over every row (timings left out: fieldgen.run.record.TIMINGS) and of each array of
`learner.msgpack` (what the run learned), and whether the two `checkpoint.msgpack` files hold the same
bytes. --json appends a row per layout (a difference is null where one run lacks the metric or array, or
the two cannot be compared: no numbers, or other shapes).

A GPU need not give the same bits twice for the same program (XLA's scatters add in whatever order
their threads come), and an RL run grows the smallest difference into another run. `--control` trains the
one process a second time, so that a difference between the layouts can be read beside the one that the
same layout shows with itself; XLA_FLAGS in this script's environment reaches every process (e.g.
`--xla_gpu_deterministic_ops=true`, for runs that should match bit for bit).

    python bench/two_processes_vs_one.py --field build/ant_nav --envs 1024 --json out.jsonl
    python bench/two_processes_vs_one.py --field point_nav --steps 1900 --envs 8 --evals 2 \\
        --set crl.hidden=[32,32] --set crl.min_replay_rows=100 --set crl.max_replay_rows=400   # a CPU, tiny
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from fieldgen.env.throughput import run_arguments, run_command
from fieldgen.files import append_jsonl
from fieldgen.run import distributed, record

LAYOUTS = {"one process": [[0, 1]], "two processes": [[0], [1]],  # layout -> the devices of each process
           "one process again": [[0, 1]]}  # the control: trained only with --control


@dataclasses.dataclass
class Trained:
    """One layout's run: its folder, the commands that trained it, and how long they took in all."""

    layout: str
    folder: Path
    commands: list[str]
    process_seconds: float


def platform_of(choice: str) -> tuple[str, str]:
    """The platform the runs train on and its device's kind, asked of JAX in a process of its own (this one
    keeps off the GPUs the runs will use); a GPU platform needs two GPUs."""
    if choice == "cpu":
        return "cpu", "cpu"
    found = subprocess.run([sys.executable, "-c", "import jax; d = jax.devices(); "
                            "print(jax.default_backend(), len(d), d[0].device_kind, sep='|')"],
                           capture_output=True, text=True)
    if found.returncode != 0:
        sys.exit(f"error: JAX could not start here: {(found.stderr.strip().splitlines() or ['no output'])[-1]}")
    backend, count, kind = found.stdout.strip().splitlines()[-1].split("|")
    if backend != "gpu":
        if choice == "gpu":
            sys.exit(f"error: --platform gpu: JAX finds no GPU here (its backend is {backend})")
        return "cpu", "cpu"
    if int(count) < 2:
        sys.exit(f"error: JAX sees {count} GPU here; the comparison needs two (CUDA_VISIBLE_DEVICES names them)")
    return "gpu", kind


def gpus() -> list[str]:
    """The GPUs the runs take: the first two of those CUDA_VISIBLE_DEVICES names, else GPUs 0 and 1."""
    named = [g for g in os.environ.get("CUDA_VISIBLE_DEVICES", "").split(",") if g.strip()]
    return (named or ["0", "1"])[:2]


def train(layout: str, args, platform: str, out: Path, logs: Path) -> Trained:
    """Train the benchmark's run in `layout`'s processes, into a run folder under `out`, their output in
    `logs`."""
    groups = LAYOUTS[layout]
    port = distributed.free_port()
    shown, processes = [], []
    began = time.perf_counter()
    for index, devices in enumerate(groups):
        joined = [] if len(groups) == 1 else ["--coordinator", f"127.0.0.1:{port}", "--num-processes",
                                              str(len(groups)), "--process-id", str(index)]
        command = run_command(args, out, "--seeds", str(args.seeds), "--no-videos", *joined)
        own = [gpus()[i] for i in devices] if platform == "gpu" else devices
        variables = distributed.only_devices(platform, own)
        shown.append(" ".join([*(f"{k}={shlex.quote(v)}" for k, v in variables.items()), shlex.join(command)]))
        log = logs / f"{layout.replace(' ', '_')}-{index}.log"
        with log.open("w") as output:
            processes.append((subprocess.Popen(command, env={**os.environ, **variables}, stdout=output,
                                               stderr=subprocess.STDOUT), log))
    try:
        while True:  # the first process to fail is the one to name: the others wait for it until JAX aborts them
            states = [process.poll() for process, _ in processes]
            failed = next((i for i, state in enumerate(states) if state not in (None, 0)), None)
            if failed is not None:
                log = processes[failed][1]
                kept = f"its output: {log}" if args.out else "--out DIR keeps the processes' output"
                sys.exit(f"error: {layout}: process {failed} ended with status {states[failed]}: {cause(log)} (its "
                         f"command: {shown[failed]}; {kept})")
            if all(state == 0 for state in states):
                break
            if time.perf_counter() - began > args.timeout:
                sys.exit(f"error: {layout}: the run did not end within --timeout {args.timeout} s")
            time.sleep(0.5)
    finally:
        for process, _ in processes:  # ours alone, whichever did not end
            if process.poll() is None:
                process.kill()
                process.wait()
    seconds = time.perf_counter() - began
    folder = next(p for p in out.iterdir() if p.is_dir())  # the one run folder (the logs are beside `out`)
    return Trained(layout, folder, shown, seconds)


FATAL = re.compile(r"^(F\d{4} |error: |\w+(Error|Exception): )|Check failed")  # XLA's fatal log lines, ours, Python's


def cause(log: Path) -> str:
    """The line of a process's output that says why it ended: the first fatal one (an XLA abort prints a
    stack of frames after it), else its last line."""
    lines = [line.strip() for line in log.read_text(errors="replace").splitlines() if line.strip()]
    return next((line for line in lines if FATAL.search(line)), lines[-1] if lines else "(no output)")


def chunk_rate(rows: list[dict], seeds: int) -> float:
    """Env steps per second of the training chunks, all seeds counted: the mean over the chunks after the
    first (the first where it is the only one) of their `steps_per_second`, which counts one seed's."""
    chunks = sorted({r["eval"]: r["steps_per_second"] for r in rows if "steps_per_second" in r}.items())
    timed = [rate for _, rate in (chunks[1:] or chunks)]
    return seeds * sum(timed) / len(timed)


def metric_differences(rows: list[dict], others: list[dict]) -> dict[str, float]:
    """Each logged metric's largest absolute difference over the rows of two runs (timings left out); a
    metric one run lacks, or that differs where it is not a number, is infinitely different."""
    if len(rows) != len(others):
        return {"rows": math.inf}
    largest: dict[str, float] = {}
    for row, other in zip(rows, others):
        for key in sorted((row.keys() | other.keys()) - set(record.TIMINGS)):
            a, b = row.get(key), other.get(key)
            numbers = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in (a, b))
            gap = abs(a - b) if numbers else 0.0 if a == b else math.inf
            if numbers and math.isnan(gap):
                gap = 0.0 if math.isnan(a) and math.isnan(b) else math.inf
            largest[key] = max(largest.get(key, 0.0), gap)
    return largest


def learned_arrays(folder: Path) -> dict[str, object]:
    """The arrays of the run's `learner.msgpack` (what it learned, then how it drew its episodes), by their path."""
    import jax

    jax.config.update("jax_platforms", "cpu")  # this process leaves the GPUs to the runs
    from fieldgen.agents import checkpoint
    from fieldgen.run.session import learner_template, open_run

    contents = checkpoint.load(folder / record.LEARNER, *learner_template(open_run(folder, load_state=False)))
    return {jax.tree_util.keystr(path): leaf for path, leaf in jax.tree_util.tree_flatten_with_path(contents)[0]}


def array_differences(arrays: dict, others: dict) -> dict[str, float]:
    """Each array's largest absolute difference between two runs' states (infinite where one lacks it or
    their shapes differ)."""
    import numpy as np

    gaps = {}
    for name in sorted(arrays.keys() | others.keys()):
        a, b = arrays.get(name), others.get(name)
        if a is None or b is None or np.shape(a) != np.shape(b):
            gaps[name] = math.inf
        elif np.size(a):
            gaps[name] = float(np.max(np.abs(np.asarray(a, np.float64) - np.asarray(b, np.float64))))
        else:
            gaps[name] = 0.0
    return gaps


def largest(gaps: dict[str, float]) -> str:
    """The largest difference, and what it is of where there is one."""
    name = max(gaps, key=gaps.get)
    return f"{gaps[name]:g} ({name})" if gaps[name] else "0"


def finite(gap: float) -> float | None:
    """A difference as a JSON row holds it: null where the two could not be compared."""
    return gap if math.isfinite(gap) else None


@dataclasses.dataclass
class Sameness:
    """How far one run is from another: each metric's and each learned array's largest difference, and
    whether their checkpoints hold the same bytes."""

    metrics: dict[str, float]
    arrays: dict[str, float]
    same_checkpoint: bool

    @classmethod
    def of(cls, rows: dict[str, list[dict]], runs: dict[str, Trained], one: str, other: str) -> "Sameness":
        return cls(metric_differences(rows[one], rows[other]),
                   array_differences(learned_arrays(runs[one].folder), learned_arrays(runs[other].folder)),
                   (runs[one].folder / record.CHECKPOINT).read_bytes() == (runs[other].folder / record.CHECKPOINT).read_bytes())

    @property
    def identical(self) -> bool:
        return max(self.metrics.values()) == 0 and max(self.arrays.values()) == 0 and self.same_checkpoint

    def lines(self, rows: int) -> list[str]:
        return [f"metrics: {len(self.metrics)} over {rows} rows; largest difference {largest(self.metrics)}",
                f"learner: {len(self.arrays)} arrays; largest difference {largest(self.arrays)}",
                f"checkpoint.msgpack: {'the same bytes' if self.same_checkpoint else 'different bytes'}"]

    def row(self) -> dict:
        return {"identical": self.identical,
                "metrics_max_abs_difference": {k: finite(v) for k, v in self.metrics.items()},
                "learner_max_abs_difference": finite(max(self.arrays.values())),
                "checkpoint_same_bytes": self.same_checkpoint}


def verdict(split: Sameness, control: Sameness | None) -> str:
    """Whether the two layouts trained the same run, read beside the control where there is one."""
    if split.identical:
        return "identical: yes"
    if control is None:
        return "identical: no (--control tells whether one process gives the same run twice here)"
    if control.identical:
        return "identical: no, while one process trained twice is: the split into processes changed the run"
    return (f"identical: no, nor is one process trained twice (largest learner difference "
            f"{largest(control.arrays)}): this platform does not repeat a run bit for bit, so the layouts cannot "
            "be told apart by sameness here")


def main() -> None:
    parser = run_arguments(__doc__)
    parser.set_defaults(field="build/ant_nav", steps=6_000_000, evals=1)
    parser.add_argument("--seeds", type=int, default=2, help="seeds trained at once (the run's --seeds)")
    parser.add_argument("--platform", choices=("auto", "cpu", "gpu"), default="auto")
    parser.add_argument("--timeout", type=float, default=3600, help="seconds each layout may take in all")
    parser.add_argument("--out", type=Path, help="keep both runs and the processes' output here "
                        "(default: a temporary folder, removed at the end)")
    parser.add_argument("--control", action="store_true", help="train the one process a second time and "
                        "report how far it is from the first, beside the layouts' difference")
    args = parser.parse_args()
    if min(args.seeds, args.envs, args.steps, args.evals) < 1:
        sys.exit("error: --seeds, --envs, --steps and --evals are positive")
    platform, kind = platform_of(args.platform)
    devices = f"GPUs {' and '.join(gpus())}" if platform == "gpu" else "two CPU devices"
    print(f"platform: {platform} ({kind}); devices: {devices}", flush=True)
    with tempfile.TemporaryDirectory(prefix="fieldgen-processes-") as scratch:
        root = args.out or Path(scratch)
        runs = {}
        for layout in list(LAYOUTS)[:3 if args.control else 2]:
            out = root / layout.replace(" ", "_")
            out.mkdir(parents=True, exist_ok=True)
            runs[layout] = train(layout, args, platform, out, root)
            print(f"{layout}: trained in {runs[layout].process_seconds:.0f} s", flush=True)
        rows = {name: record.read_metrics(run.folder) for name, run in runs.items()}
        rates = {name: chunk_rate(rows[name], args.seeds) for name in runs}
        split = Sameness.of(rows, runs, "one process", "two processes")
        control = Sameness.of(rows, runs, "one process", "one process again") if args.control else None
    ratio = rates["two processes"] / rates["one process"]
    print(f"\n{'layout':<14s} {'processes':>9s} {'env steps/s (chunks)':>21s} {'processes wall s':>17s}")
    for name, run in runs.items():
        print(f"{name:<14s} {len(LAYOUTS[name]):>9d} {rates[name]:>21,.0f} {run.process_seconds:>17.1f}")
    print(f"two processes / one process: {ratio:.3f} (env steps per second of the training chunks, from "
          f"steps_per_second in metrics.jsonl, compiles excluded)")
    print("\n".join(split.lines(len(rows["one process"]))))
    if control is not None:
        print("one process again, against the first:")
        print("\n".join(f"  {line}" for line in control.lines(len(rows["one process"]))))
    print(verdict(split, control))
    print("commands:")
    for run in runs.values():
        for command in run.commands:
            print(f"  {command}")
    for name, run in runs.items():
        append_jsonl(args.json, {
            "field": args.field, "algo": args.algo, "seeds": args.seeds, "envs": args.envs, "steps": args.steps,
            "evals": args.evals, "sets": args.set, "platform": platform, "device": kind, "layout": name,
            "processes": len(LAYOUTS[name]), "devices_per_process": [len(d) for d in LAYOUTS[name]],
            "chunk_steps_per_second": rates[name], "process_seconds": run.process_seconds,
            "over_one_process": rates[name] / rates["one process"], **split.row(),
            "control": None if control is None else control.row(), "commands": run.commands})


if __name__ == "__main__":
    main()
