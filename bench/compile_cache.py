"""Seconds a whole `fieldgen train` command takes with JAX's persistent compilation cache cold and
then warm, against the cache turned off, measured in the same run.

The three runs are the same command into fresh run folders: cache off (the reference), cache on
and empty (each program compiled, then written), cache on and filled by that run (each program
read back). The difference is what a second seed, a resume or a repeated run saves.

    python bench/compile_cache.py --field point_nav --steps 40000 --envs 16 --evals 2
    python bench/compile_cache.py --field build/ant_nav --steps 2000000 --envs 1024 --json out.jsonl
"""

from __future__ import annotations

import os
import subprocess
import tempfile
import time

from fieldgen.env.throughput import run_arguments, run_command
from fieldgen.files import append_jsonl


def timed_run(args, out: str, cache: str | None) -> float:
    command = run_command(args, out, "--no-videos")
    env = dict(os.environ, JAX_COMPILATION_CACHE_DIR=cache or "", JAX_ENABLE_COMPILATION_CACHE=str(cache is not None))
    started = time.perf_counter()
    subprocess.run(command, env=env, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started


def main() -> None:
    args = run_arguments(__doc__).parse_args()
    with tempfile.TemporaryDirectory(prefix="fieldgen-cache-bench-") as work:
        seconds = {"off": timed_run(args, f"{work}/off", None)}
        seconds["cold"] = timed_run(args, f"{work}/cold", f"{work}/cache")
        seconds["warm"] = timed_run(args, f"{work}/warm", f"{work}/cache")
    for name, s in seconds.items():
        print(f"{name:5s} {s:7.1f} s   {seconds['off'] / s:.2f}x the run without the cache")
    append_jsonl(args.json, {"field": args.field, "algo": args.algo, "steps": args.steps, "envs": args.envs,
                             "evals": args.evals, **{f"{k}_seconds": v for k, v in seconds.items()}})


if __name__ == "__main__":
    main()
