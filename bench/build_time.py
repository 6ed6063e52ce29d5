"""Build time of a field (YAML -> scene.xml + field.json, no JAX compilation), stage by stage.

Prints each stage's median over --repeats runs and the ratio of the whole
build to a reference measured in the same run: MuJoCo compiling the finished
scene.xml, the one step no build can skip.

    python bench/build_time.py fields/soccer_v2.yaml
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from fieldgen.compile.artifact import compile_spec, write_artifact
from fieldgen.render import png_bytes, preview
from fieldgen.schema import load_spec


def timed(fn, repeats: int):
    times, value = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), value


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("spec", nargs="?", default="fields/soccer_v2.yaml")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()

    load_s, spec = timed(lambda: load_spec(args.spec), args.repeats)
    compile_s, artifact = timed(lambda: compile_spec(spec), args.repeats)
    with tempfile.TemporaryDirectory() as tmp:
        write_s, _ = timed(lambda: write_artifact(artifact, Path(tmp)), args.repeats)
    reference_s, model = timed(artifact.model, args.repeats)
    preview_s, _ = timed(lambda: png_bytes(preview(model)), max(1, args.repeats // 3))
    build_s = load_s + compile_s + write_s

    print(f"{spec.name}: median of {args.repeats} runs")
    print(f"  load + validate + checks   {load_s * 1e3:8.1f} ms")
    print(f"  mjcf scene -> scene.xml    {compile_s * 1e3:8.1f} ms")
    print(f"  field.json + scene.xml     {write_s * 1e3:8.1f} ms  (includes an MjModel compile for the layout)")
    print(f"  build total                {build_s * 1e3:8.1f} ms  = {build_s / reference_s:.1f}x the reference")
    print(f"  reference: MjModel compile {reference_s * 1e3:8.1f} ms")
    print(f"  preview.png (2 renders)    {preview_s * 1e3:8.1f} ms  (optional: --no-preview)")


if __name__ == "__main__":
    main()
