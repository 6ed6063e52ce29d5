"""Host memory and time of writing a checkpoint: in row-block pieces (`agents.checkpoint.pieces`)
against flax serializing the whole state in one call, the reference, measured in the same run.

Each way runs in a fresh process (peak memory is per process) on a state of one large float32
leaf, like CRL's replay buffer, written atomically to `--out`. Printed: the peak memory added by
writing, beyond the state itself, the seconds taken, and the ratios of the pieces to the whole.

    python bench/checkpoint_write.py --megabytes 1600 --out runs
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

from fieldgen.files import append_jsonl

WAYS = ("whole", "pieces")


def measure(way: str, megabytes: int, out: Path) -> dict:
    """Run in a process of its own: write a state of `megabytes` one way; peak memory added and seconds."""
    import jax
    import numpy as np
    from flax import serialization

    from fieldgen.agents import checkpoint
    from fieldgen.files import write_atomic

    rows = megabytes * 2**20 // (4 * 1024)
    state = {"buffer": np.random.default_rng(0).random((rows, 1024), dtype=np.float32), "step": np.int32(1)}
    path = out / f".checkpoint_write_{way}.msgpack"
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    began = time.perf_counter()
    if way == "whole":
        leaves = jax.tree.leaves(state)
        write_atomic(path, serialization.msgpack_serialize({str(i): x for i, x in enumerate(leaves)}))
    else:
        write_atomic(path, checkpoint.pieces(state))
    seconds = time.perf_counter() - began
    added = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024  # kB -> MB on Linux
    path.unlink()
    return {"way": way, "megabytes": megabytes, "added_peak_mb": added, "seconds": seconds}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--megabytes", type=int, default=400, help="size of the state's one large leaf")
    parser.add_argument("--out", type=Path, default=Path("runs"), help="where the checkpoints are written (then removed)")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--way", choices=WAYS, help=argparse.SUPPRESS)  # one measurement, in a child process
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.way:
        print(json.dumps(measure(args.way, args.megabytes, args.out)))
        return
    results = {}
    for way in WAYS:
        child = subprocess.run([sys.executable, __file__, "--way", way, "--megabytes", str(args.megabytes),
                                "--out", str(args.out)], check=True, capture_output=True, text=True)
        results[way] = json.loads(child.stdout.strip().splitlines()[-1])
        r = results[way]
        print(f"{way:>6}: {args.megabytes:,} MB state, +{r['added_peak_mb']:,.0f} MB peak memory while writing, "
              f"{r['seconds']:.2f} s")
    whole, pieces = results["whole"], results["pieces"]
    row = {"bench": "checkpoint_write", "megabytes": args.megabytes, "whole": whole, "pieces": pieces,
           "memory_ratio": pieces["added_peak_mb"] / max(whole["added_peak_mb"], 1.0),
           "time_ratio": pieces["seconds"] / whole["seconds"]}
    print(f"pieces / whole: memory added {row['memory_ratio']:.3f}, time {row['time_ratio']:.2f}")
    append_jsonl(args.json, row)


if __name__ == "__main__":
    main()
