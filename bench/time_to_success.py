"""Wall-clock time from `fieldgen train` starting to the first evaluation that reaches a success rate.

Each setting is one `fieldgen train` command run alone, one after another (timings of runs that
share a GPU say nothing). The clock starts before the process does, so imports, building the
environment and every compile count, as a user waiting for the result sees it. The run's
metrics.jsonl is read as it grows; once an evaluation's success_any reaches the threshold the
run is stopped (`--keep-going` lets it finish). The first setting is the reference: later ones
are also printed as a ratio of its time.

    python bench/time_to_success.py --field build/ant_nav --steps 10M --threshold 0.6 \\
        --setting 'b256=--config configs/crl_ant.yaml' \\
        --setting 'b1024=--config configs/crl_ant.yaml --set crl.batch_size=1024' --json out.jsonl
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from fieldgen.env.throughput import append_jsonl


def first_passing(metrics: Path, threshold: float) -> dict | None:
    """The first evaluation row whose success_any reaches `threshold`, of the rows written so far."""
    if not metrics.exists():
        return None
    for line in metrics.read_text().splitlines():
        try:
            row = json.loads(line)
        except json.JSONDecodeError:  # a row being written
            break
        if row.get("success_any", 0.0) >= threshold:
            return row
    return None


def run_setting(name: str, options: list[str], args) -> dict:
    with tempfile.TemporaryDirectory(prefix="fieldgen-tts-") as out:
        command = [sys.executable, "-m", "fieldgen.cli", "train", args.field, "--algo", args.algo,
                   "--steps", args.steps, "--seed", str(args.seed), "--out", out, "--no-videos", *options]
        started = time.perf_counter()
        proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        passed, seconds = None, None
        while proc.poll() is None:
            runs = list(Path(out).iterdir())
            passed = first_passing(runs[0] / "metrics.jsonl", args.threshold) if runs else None
            if passed is not None:
                seconds = time.perf_counter() - started
                if not args.keep_going:
                    proc.terminate()
                break
            time.sleep(0.5)
        proc.wait()
        total = time.perf_counter() - started
        runs = list(Path(out).iterdir())
        if passed is None and runs:  # it ended: judge every row it wrote
            passed = first_passing(runs[0] / "metrics.jsonl", args.threshold)
            seconds = None if passed is None else total
        if passed is None and proc.returncode:
            raise SystemExit(f"{name}: fieldgen train failed:\n{proc.stderr.read()[-2000:]}")
        last = {}
        if runs and (runs[0] / "metrics.jsonl").exists():
            rows = [json.loads(x) for x in (runs[0] / "metrics.jsonl").read_text().splitlines() if x.strip()]
            last = rows[-1] if rows else {}
    return {"setting": name, "options": " ".join(options), "field": args.field, "seed": args.seed,
            "threshold": args.threshold, "seconds_to_threshold": seconds,
            "env_steps_at_threshold": None if passed is None else passed["env_steps"],
            "success_at_threshold": None if passed is None else passed["success_any"],
            "last_env_steps": last.get("env_steps"), "last_success_any": last.get("success_any"),
            "seconds_total": total}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--field", required=True, help="a build folder, bundled name or YAML file")
    parser.add_argument("--algo", default="crl")
    parser.add_argument("--steps", default="10M")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threshold", type=float, default=0.6)
    parser.add_argument("--setting", action="append", required=True,
                        help="NAME=OPTIONS for fieldgen train; the first is the reference")
    parser.add_argument("--keep-going", action="store_true", help="let each run finish after it passes")
    parser.add_argument("--json", type=Path, help="append one JSON object per setting")
    args = parser.parse_args()
    reference = None
    for item in args.setting:
        name, _, options = item.partition("=")
        result = run_setting(name, shlex.split(options), args)
        seconds = result["seconds_to_threshold"]
        if reference is None:
            reference = seconds
        result["ratio_to_reference"] = None if seconds is None or reference is None else seconds / reference
        shown = "not reached" if seconds is None else (
            f"{seconds:.1f} s at {result['env_steps_at_threshold']:,} steps"
            + ("" if result["ratio_to_reference"] is None else f" ({result['ratio_to_reference']:.2f}x the reference)"))
        print(f"{name}: success_any >= {args.threshold}: {shown}; last {result['last_success_any']} "
              f"at {result['last_env_steps']} steps", flush=True)
        if args.json:
            append_jsonl(args.json, result)


if __name__ == "__main__":
    main()
