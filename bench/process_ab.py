"""One benchmark command in processes that differ only in their environment: XLA's options, or the
fieldgen they import. Which one trains faster, as a ratio to the first, measured in the same run?

XLA reads its options once, when JAX starts its backend, and a process imports one fieldgen, so each
arm of the comparison needs processes of its own. Every arm runs `bench/train_throughput.py` with the
same arguments (those after `--`), once a round, the arms in turn within each round (A B A B ...), so
that a machine that warms up or slows down over the run weighs on every arm alike. An arm is
`NAME: KEY=VALUE ...`: XLA_FLAGS and PYTHONPATH add to what this process's environment holds (the
flags after it, the path before it), any other variable is set. The first arm is the reference; each
arm's figure is the median over rounds of each row's `train_steps_per_second`, printed as a ratio to
the reference's same row. --json appends a row per arm and benchmark row. Each round of each arm prints
its rates as it ends, and a stop (Ctrl-C, or the TERM of a time limit) still prints the table and writes
the rows over the rounds that ended, marked as incomplete, then exits with status 130.

    python bench/process_ab.py --arm 'default:' \\
        --arm 'loops as graphs: XLA_FLAGS=--xla_gpu_enable_command_buffer=FUSION,CUBLAS,CUBLASLT,CUSTOM_CALL,CUDNN,CONDITIONAL,WHILE' \\
        -- --fields build/ant_nav --algos crl --envs 1024 --devices 1 --iterations 3
    pip install --no-deps --target /tmp/before fieldgen-before.whl
    python bench/process_ab.py --arm 'before: PYTHONPATH=/tmp/before' --arm 'now:' --rounds 2 -- --fields build/ant_nav --algos crl
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from fieldgen.files import append_jsonl

BENCH = Path(__file__).resolve().parent / "train_throughput.py"
KEYS = ("field", "algo", "envs", "seeds", "devices")  # what names a row of train_throughput
ADDED = {"XLA_FLAGS": lambda new, old: " ".join(filter(None, [old, new])),
         "PYTHONPATH": lambda new, old: os.pathsep.join(filter(None, [new, old]))}


def arm(text: str) -> tuple[str, dict[str, str]]:
    """`NAME: KEY=VALUE ...` as its name and variables (argparse's type: a bad arm is its error)."""
    name, colon, rest = text.partition(":")
    if not colon or not name.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: write an arm as 'NAME: KEY=VALUE ...' (e.g. 'default:' or "
                                         "'graphs: XLA_FLAGS=--xla_gpu_graph_min_graph_size=1')")
    variables = {}
    for item in rest.split():
        key, equals, value = item.partition("=")
        if not equals or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", key):
            raise argparse.ArgumentTypeError(f"{text!r}: {item!r} is not KEY=VALUE (a variable's name, '=', its value)")
        variables[key] = value
    return name.strip(), variables


def environment(variables: dict[str, str], base: dict[str, str]) -> dict[str, str]:
    """`base` with an arm's variables: XLA_FLAGS and PYTHONPATH added to, the others set."""
    env = dict(base)
    for key, value in variables.items():
        env[key] = ADDED[key](value, base.get(key, "")) if key in ADDED else value
    return env


def row_name(row: dict) -> tuple:
    return tuple(row.get(k) for k in KEYS)


def medians(rows: list[dict]) -> dict[tuple, float]:
    """Each benchmark row's median `train_steps_per_second` over the rounds."""
    rates: dict[tuple, list[float]] = {}
    for row in rows:
        rates.setdefault(row_name(row), []).append(row["train_steps_per_second"])
    return {name: statistics.median(values) for name, values in rates.items()}


def run_arm(name: str, variables: dict[str, str], arguments: list[str], folder: Path, round_: int) -> list[dict]:
    """One round of one arm: train_throughput in a process of its own; its rows."""
    out = folder / f"{len(list(folder.iterdir()))}.jsonl"
    command = [sys.executable, str(BENCH), *arguments, "--json", str(out)]
    print(f"round {round_ + 1}, {name}: {' '.join(f'{k}={v}' for k, v in variables.items())} "
          f"{' '.join(command[1:])}", flush=True)
    done = subprocess.run(command, env=environment(variables, dict(os.environ)), capture_output=True, text=True)
    if done.returncode != 0 or not out.exists():
        said = (done.stderr.strip() or done.stdout.strip() or "(no output)").splitlines()[-1]
        sys.exit(f"error: arm {name!r}, round {round_ + 1}: train_throughput ended with status {done.returncode}: {said}")
    rows = [json.loads(line) for line in out.read_text().splitlines() if line.strip()]
    for row in rows:
        print(f"  {' '.join(str(v) for v in row_name(row))}: {row['train_steps_per_second']:,.0f} env steps/s",
              flush=True)
    return rows


def stop(signum, frame):
    """A TERM (a time limit's) stops the comparison as Ctrl-C does: the rounds that ended are reported."""
    raise KeyboardInterrupt


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--arm", type=arm, action="append", required=True, metavar="'NAME: KEY=VALUE ...'",
                        help="one side of the comparison; the first is the reference")
    parser.add_argument("--rounds", type=int, default=2, help="runs of each arm, the arms in turn within a round")
    parser.add_argument("--json", type=Path)
    parser.add_argument("arguments", nargs=argparse.REMAINDER, help="-- then train_throughput's arguments")
    args = parser.parse_args()
    arguments = args.arguments[1:] if args.arguments[:1] == ["--"] else args.arguments
    names = [name for name, _ in args.arm]
    if len(set(names)) != len(names):
        parser.error(f"--arm names repeat ({', '.join(names)}): give each arm a name of its own")
    if len(args.arm) < 2 or args.rounds < 1:
        parser.error("compare at least two --arm, in at least one round")
    if "--json" in arguments:
        parser.error("give --json before '--': the arms' own rows are read from files of this script's")
    rows: dict[str, list[dict]] = {name: [] for name in names}
    complete, before = True, signal.signal(signal.SIGTERM, stop)
    with tempfile.TemporaryDirectory(prefix="fieldgen-ab-") as scratch:
        try:
            for round_ in range(args.rounds):
                for name, variables in args.arm:
                    rows[name] += run_arm(name, variables, arguments, Path(scratch), round_)
        except KeyboardInterrupt:  # subprocess.run has ended the arm's process
            complete = False
            print(f"stopped in round {round_ + 1}, arm {name!r}: the table holds the rounds that ended", flush=True)
        finally:
            signal.signal(signal.SIGTERM, before)
    reference = medians(rows[names[0]])
    print(f"\n{'arm':<20s} {'row':<40s} {'env steps/s (median)':>21s} {'rounds':>7s} {'/ ' + names[0]:>12s}")
    for (name, variables) in args.arm:
        if not rows[name]:
            print(f"{name:<20s} (no round ended)")
        for key, rate in medians(rows[name]).items():
            ratio = rate / reference[key] if key in reference else None
            count = sum(row_name(r) == key for r in rows[name])
            label = " ".join(str(v) for v in key)
            print(f"{name:<20s} {label:<40s} {rate:>21,.0f} {count:>7d} "
                  f"{'-' if ratio is None else f'{ratio:.3f}':>12s}")
            append_jsonl(args.json, {"arm": name, "variables": variables, **dict(zip(KEYS, key)),
                                     "train_steps_per_second": rate, "rounds": count,
                                     "rates": [r["train_steps_per_second"] for r in rows[name] if row_name(r) == key],
                                     "reference": names[0], "over_reference": ratio, "complete": complete,
                                     "arguments": arguments})
    if not complete:
        sys.exit(130)


if __name__ == "__main__":
    main()
