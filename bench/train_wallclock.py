"""Wall-clock cost of a whole `fieldgen train` run beside the rate of its training chunks alone.

Each code root given runs the same `fieldgen train` command in a subprocess (its folder first on
PYTHONPATH): a folder holding an installed fieldgen, e.g. an earlier version's wheel installed
with `pip install --no-deps --target DIR`; "." is the fieldgen this Python imports. The reference, measured in the same run, is the mean of the training chunks' own
env steps per second (`steps_per_second` in metrics.jsonl): what training would reach if
evaluations, checkpoints and videos cost nothing. The end-to-end rate counts everything between
the first and the last evaluation row (`wall_seconds`); start-up is reported apart: the `wall_seconds`
(from training's start) of the first and second evaluation rows, the second after the first chunk,
so that both hold every compile, each run compiling from an empty cache as a machine's first run does. With several roots the later ones are also printed as a ratio to the first.

    python bench/train_wallclock.py --field build/soccer_v1 --steps 12000000 --evals 4
    pip install --no-deps --target /tmp/previous fieldgen-previous.whl
    python bench/train_wallclock.py --field build/soccer_v1 --roots /tmp/previous,. --json out.jsonl
    python bench/train_wallclock.py --field build/ant_nav --steps 5000000 --evals 10 --seeds 4 --no-videos
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from fieldgen.run import record
from fieldgen.env.throughput import run_arguments, run_command
from fieldgen.files import append_jsonl


def run_once(root: Path, args) -> dict:
    """One `fieldgen train` run with `root`'s code; its end-to-end and chunk rates."""
    with tempfile.TemporaryDirectory(prefix="fieldgen-wallclock-") as out:
        command = run_command(args, out, "--seeds", str(args.seeds), *([] if args.videos else ["--no-videos"]))
        paths = [] if str(root) == "." else [str(root.resolve())]
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([*paths, os.environ.get("PYTHONPATH", "")]),
               "JAX_COMPILATION_CACHE_DIR": str(Path(out) / "xla-cache")}
        started = time.perf_counter()
        done = subprocess.run(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if done.returncode != 0:
            said = (done.stderr.strip().splitlines() or ["(no output)"])[-1]
            sys.exit(f"error: {root}: fieldgen train ended with status {done.returncode}: {said} "
                     f"(its command: {' '.join(command)})")
        total = time.perf_counter() - started
        run = next(p for p in Path(out).iterdir() if p.name != "xla-cache")  # the one run folder
        rows = record.read_metrics(run)
        checkpoint = (run / record.CHECKPOINT).stat().st_size
    timed = [r for r in rows if r["eval"] >= 1]
    first, last = timed[0], timed[-1]
    end_to_end = (last["env_steps"] - first["env_steps"]) / (last["wall_seconds"] - first["wall_seconds"])
    chunks = sum(r["steps_per_second"] for r in timed[1:]) / len(timed[1:])
    return {"end_to_end_steps_per_second": end_to_end, "chunk_steps_per_second": chunks,
            "ratio_to_chunks": end_to_end / chunks, "process_seconds": total, "checkpoint_bytes": checkpoint,
            "first_eval_seconds": rows[0]["wall_seconds"], "second_eval_seconds": first["wall_seconds"]}


def main() -> None:
    parser = run_arguments(__doc__)
    parser.add_argument("--roots", default=".", help="comma-separated folders holding an installed fieldgen; '.': this Python's")
    parser.add_argument("--videos", action=argparse.BooleanOptionalAction, default=True)
    parser.add_argument("--seeds", type=int, default=1, help="seeds trained at once (vmapped), each one's replay "
                        "buffer in the checkpoint; env steps/s are a seed's")
    args = parser.parse_args()
    first = None
    for root in [Path(r) for r in args.roots.split(",")]:
        result = run_once(root, args)
        first = first or result
        over_first = result["end_to_end_steps_per_second"] / first["end_to_end_steps_per_second"]
        print(f"{str(root):>24s} {args.algo} {args.envs} envs: "
              f"{result['end_to_end_steps_per_second']:>10,.0f} env steps/s end to end; chunks alone {result['chunk_steps_per_second']:>10,.0f}; ratio "
              f"{result['ratio_to_chunks']:.3f}; over the first root {over_first:.2f}; "
              f"evaluations 0 and 1 at {result['first_eval_seconds']:.0f} and {result['second_eval_seconds']:.0f} s, "
              f"{result['process_seconds']:.0f} s in all; checkpoint {result['checkpoint_bytes'] / 1e9:.2f} GB",
              flush=True)
        append_jsonl(args.json, {"root": str(root), "field": args.field, "algo": args.algo, "envs": args.envs,
                                 "seeds": args.seeds,
                                 "steps": args.steps, "evals": args.evals, "videos": args.videos,
                                 "over_first_root": over_first, **result})


if __name__ == "__main__":
    main()
