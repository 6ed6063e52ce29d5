"""Seconds `fieldgen train` spends tracing and lowering each of a run's programs (start, evaluate, chunk)
before XLA compiles them: Python work that JAX's compilation cache cannot save, paid by every command
that starts or resumes a run. With `--against DIR` (a folder another fieldgen is installed into, `pip
install --no-deps --target DIR fieldgen-before.whl`) the same run's programs are lowered by that
fieldgen too, in the same command, the arms in turn (A B A B ...), and each program's seconds are
printed as a ratio to DIR's, the reference.

Each measurement is a process of its own that sets the run up (`--prepare`, into a temporary folder), traces
the training state's shapes (`shapes`, the start's trace that its lowering reuses) and lowers each program
without compiling or running it, on JAX's CPU backend unless JAX_PLATFORMS says otherwise (lowering is
Python's work either way).

    python bench/program_lowering.py --field bench/fields/soccer_v2_agent_goal.yaml --curriculum auto \\
        --seeds 3 --envs 64 --against /tmp/before --rounds 2 --json out.jsonl
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from fieldgen.files import append_jsonl

PROGRAMS = ("start", "evaluate", "chunk")  # lowered in this order; "shapes" is the trace of the state's shapes

# run in a process of its own: prepare the run, then lower its programs in the order training needs them
MEASURE = """
import json, sys, time
from typer.testing import CliRunner
from fieldgen.cli import app
from fieldgen.run.session import open_run
out, programs, arguments = sys.argv[1], sys.argv[2].split(","), sys.argv[3:]
done = CliRunner().invoke(app, ["train", *arguments, "--prepare", "--no-videos", "--out", out])
assert done.exit_code == 0, done.output
from pathlib import Path
import jax
from fieldgen.agents import loop
from fieldgen.agents.programs import Compiling
run = open_run(next(p for p in Path(out).iterdir() if p.is_dir()), to_train=True)
seconds = {}
def lowered_only(self, jitted, *args):
    began = time.perf_counter()
    self.out_info = jitted.lower(*args).out_info
    seconds[len(seconds)] = time.perf_counter() - began
Compiling.__init__ = lowered_only
import functools
began = time.perf_counter()
made = loop.Programs(run.trainers[0], loop.seed_keys(run.seeds), None, loop.evaluate,
                     functools.partial(loop.adapted, schedule=run.plan.schedule))
shapes = time.perf_counter() - began
print(json.dumps({"shapes": shapes, **{name: (made.prepare(name), seconds[len(seconds) - 1])[1] for name in programs}}))
"""


def measure(arguments: list[str], site: str | None) -> dict[str, float]:
    """Each program's lowering seconds, in a fresh process (with `site` first on its path, where given)."""
    env = dict(os.environ, JAX_PLATFORMS=os.environ.get("JAX_PLATFORMS", "cpu"))
    if site:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [site, env.get("PYTHONPATH", "")]))
    with tempfile.TemporaryDirectory(prefix="fieldgen-lowering-") as out:
        done = subprocess.run([sys.executable, "-P", "-c", MEASURE, out, ",".join(PROGRAMS), *arguments],
                              env=env, capture_output=True, text=True)
    if done.returncode != 0:
        said = (done.stderr.strip() or done.stdout.strip() or "(no output)").splitlines()[-1]
        sys.exit(f"error: lowering {'with ' + site if site else 'here'} ended with status {done.returncode}: {said}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--field", default="point_nav", help="what `fieldgen train` is given")
    parser.add_argument("--curriculum", choices=("auto",), help="as `fieldgen train --curriculum`")
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--envs", type=int, default=16)
    parser.add_argument("--against", type=Path, metavar="DIR", help="another fieldgen's install folder: the reference")
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    if min(args.seeds, args.envs, args.rounds) < 1:
        parser.error("--seeds, --envs and --rounds are positive")
    if args.against is not None and not (args.against / "fieldgen").is_dir():
        parser.error(f"--against {args.against}: no fieldgen installed there (pip install --no-deps --target "
                     f"{args.against} fieldgen-*.whl)")
    arguments = [args.field, "--seeds", str(args.seeds), "--envs", str(args.envs),
                 *(["--curriculum", args.curriculum] if args.curriculum else [])]
    arms = {"this": None, **({"against": str(args.against)} if args.against else {})}
    seconds: dict[str, list[dict]] = {name: [] for name in arms}
    for round_ in range(args.rounds):
        for name, site in reversed(arms.items()):  # the reference first
            seconds[name].append(measure(arguments, site))
            print(f"round {round_ + 1}, {name}: " + ", ".join(f"{p} {s:.1f} s" for p, s in seconds[name][-1].items()),
                  flush=True)
    print(f"\n{'program':<10s} " + " ".join(f"{name + ' (s, median)':>22s}" for name in arms) +
          (f" {'this / against':>15s}" if args.against else ""))
    for program in ("shapes", *PROGRAMS):
        median = {name: statistics.median(r[program] for r in rows) for name, rows in seconds.items()}
        ratio = median["this"] / median["against"] if args.against else None
        print(f"{program:<10s} " + " ".join(f"{median[name]:>22.1f}" for name in arms) +
              (f" {ratio:>15.3f}" if ratio is not None else ""))
        append_jsonl(args.json, {"program": program, "arguments": arguments, "rounds": args.rounds,
                                 **{f"{name}_seconds": median[name] for name in arms},
                                 "against": str(args.against) if args.against else None, "this_over_against": ratio})


if __name__ == "__main__":
    main()
