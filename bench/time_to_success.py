"""Wall-clock time from `fieldgen train` starting to the first evaluation that reaches a success rate.

Each setting is one `fieldgen train` command run alone, one after another (timings of runs that
share a GPU say nothing); with --together all start at once, to rank settings by the env steps they
need in one sitting. The clock starts before the process does, so imports, building the
environment and every compile count, as a user waiting for the result sees it (each run with an
empty compilation cache, unless --warm-cache). The run's
metrics.jsonl is read as it grows; once an evaluation's success_any reaches the threshold the
run is stopped (`--keep-going` lets it finish). The first setting is the reference: later ones
are also printed as a ratio of its time.

    python bench/time_to_success.py --field build/ant_nav --steps 10M --threshold 0.6 --seeds 0,1 \\
        --setting 'b1024=' --setting 'b2048=--set crl.batch_size=2048' --runs tts --limit 300 --json out.jsonl

A setting's options may begin with environment variables for its run, as in a shell:
`--setting 'plain=' --setting 'no-fusion-tuning=XLA_FLAGS=--xla_gpu_experimental_enable_fusion_autotuner=false'`.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from fieldgen.env.throughput import train_command
from fieldgen.files import append_jsonl


def first_passing(metrics: Path | None, threshold: float) -> dict | None:
    """The first evaluation row whose success_any reaches `threshold`, of the rows written so far."""
    if metrics is None or not metrics.exists():
        return None
    for line in metrics.read_text().splitlines():
        try:
            row = json.loads(line)
        except json.JSONDecodeError:  # a row being written
            break
        if row.get("success_any", 0.0) >= threshold:
            return row
    return None


def environment_variables(options: list[str]) -> tuple[dict[str, str], list[str]]:
    """A setting's leading NAME=VALUE words, as a shell takes them, and the options after them."""
    count = 0
    while count < len(options) and re.fullmatch(r"[A-Z_][A-Z0-9_]*=.*", options[count]):
        count += 1
    return dict(word.split("=", 1) for word in options[:count]), options[count:]


class Attempt:
    """One `fieldgen train` of a setting and seed, into RUNS/NAME-sSEED, stopped once it passes (or at
    --limit seconds)."""

    def __init__(self, name: str, options: list[str], seed: int, runs: Path, args, share: int):
        self.name, self.options, self.seed, self.args, self.share = name, options, seed, args, share
        self.out = runs / f"{name}-s{seed}"
        shutil.rmtree(self.out, ignore_errors=True)
        variables, train_options = environment_variables(options)
        command = train_command(args.field, args.algo, self.out, "--steps", args.steps, "--seed", str(seed),
                                "--no-videos", *train_options)
        env = dict(os.environ, **variables)
        if not args.warm_cache:  # every run compiles everything, as the first run on a machine does
            env["JAX_COMPILATION_CACHE_DIR"] = str(self.out / "xla-cache")
        if share > 1:  # runs side by side split the GPU's memory
            env.setdefault("XLA_PYTHON_CLIENT_MEM_FRACTION", f"{0.9 / share:.2f}")
        self.out.mkdir(parents=True)
        self.log = self.out / "stderr.log"  # a file, not a pipe: a chatty run must never block on a full pipe
        self.started = time.perf_counter()
        with self.log.open("w") as log:
            self.proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=log, text=True, env=env)
        self.passed, self.seconds, self.stopped = None, None, False

    @property
    def metrics(self) -> Path | None:
        return next(self.out.glob("*/metrics.jsonl"), None)

    def poll(self) -> bool:
        """Whether the run is over: ended, passed (and stopped, unless --keep-going) or out of time."""
        if self.proc.poll() is not None:
            return True
        if self.passed is None:
            self.passed = first_passing(self.metrics, self.args.threshold)
            if self.passed is not None:
                self.seconds = time.perf_counter() - self.started
                if not self.args.keep_going:
                    return self.stop()
        if self.args.limit and time.perf_counter() - self.started > self.args.limit:
            return self.stop()
        return False

    def stop(self) -> bool:
        self.proc.terminate()
        self.stopped = True
        return True

    def result(self) -> dict:
        self.proc.wait()
        total = time.perf_counter() - self.started
        shutil.rmtree(self.out / "xla-cache", ignore_errors=True)
        metrics, passed, seconds = self.metrics, self.passed, self.seconds
        if passed is None:  # it ended: judge every row it wrote
            passed = first_passing(metrics, self.args.threshold)
            seconds = None if passed is None else total
        if passed is None and self.proc.returncode and not self.stopped:
            raise SystemExit(f"{self.name}: fieldgen train failed:\n{self.log.read_text()[-2000:]}")
        rows = [json.loads(x) for x in metrics.read_text().splitlines() if x.strip()] if metrics else []
        last = rows[-1] if rows else {}
        return {"setting": self.name, "options": " ".join(self.options), "field": self.args.field, "seed": self.seed,
                "threshold": self.args.threshold, "seconds_to_threshold": seconds,
                "env_steps_at_threshold": None if passed is None else passed["env_steps"],
                "success_at_threshold": None if passed is None else passed["success_any"],
                "last_env_steps": last.get("env_steps"), "last_success_any": last.get("success_any"),
                "seconds_total": total, "runs_sharing_the_gpu": self.share, "metrics": str(metrics) if metrics else None}


def run_group(group: list[tuple[str, list[str], int]], runs: Path, args) -> list[dict]:
    """The settings of `group` (name, options, seed) started at once, each stopped on its own terms."""
    attempts = [Attempt(name, options, seed, runs, args, len(group)) for name, options, seed in group]
    running = list(attempts)
    while running:
        running = [a for a in running if not a.poll()]
        time.sleep(0.5)
    return [a.result() for a in attempts]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--field", required=True, help="a build folder, bundled name or YAML file")
    parser.add_argument("--algo", default="crl")
    parser.add_argument("--steps", default="10M")
    parser.add_argument("--seeds", default="0", help="comma-separated seeds, each a run of every setting")
    parser.add_argument("--threshold", type=float, default=0.6)
    parser.add_argument("--setting", action="append", required=True,
                        help="NAME=OPTIONS for fieldgen train; the first is the reference")
    parser.add_argument("--keep-going", action="store_true", help="let each run finish after it passes")
    parser.add_argument("--limit", type=float, default=0.0, help="stop a run that has not passed after this "
                        "many seconds (0: none)")
    parser.add_argument("--warm-cache", action="store_true", help="let runs share the user's compilation cache "
                        "(default: each run starts with an empty one, so compiling counts)")
    parser.add_argument("--together", action="store_true", help="start every setting and seed at once on the one "
                        "GPU: their env steps to the threshold compare, their seconds do not")
    parser.add_argument("--runs", type=Path, help="keep the run folders here (default: a temporary folder)")
    parser.add_argument("--json", type=Path, help="append one JSON object per setting and seed")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="fieldgen-tts-") as temporary:
        runs = args.runs or Path(temporary)
        items = [(name, shlex.split(options), seed) for seed in (int(s) for s in args.seeds.split(","))
                 for name, _, options in (item.partition("=") for item in args.setting)]
        groups = [items] if args.together else [[item] for item in items]
        reference = {}
        for group in groups:
            for result in run_group(group, runs, args):
                seed, seconds = result["seed"], result["seconds_to_threshold"]
                base = reference.setdefault(seed, seconds)
                result["ratio_to_reference"] = None if seconds is None or base is None else seconds / base
                shown = "not reached" if seconds is None else (
                    f"{seconds:.1f} s at {result['env_steps_at_threshold']:,} steps"
                    + ("" if result["ratio_to_reference"] is None else
                       f" ({result['ratio_to_reference']:.2f}x the reference)"))
                print(f"{result['setting']} seed {seed}: success_any >= {args.threshold}: {shown}; last "
                      f"{result['last_success_any']} at {result['last_env_steps']} steps "
                      f"after {result['seconds_total']:.0f} s", flush=True)
                if args.json:
                    append_jsonl(args.json, result)

if __name__ == "__main__":
    main()
