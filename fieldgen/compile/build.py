"""`fieldgen build`: spec file -> build/<name>/, reusing a current build (cache hit by hash)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from fieldgen.compile.artifact import BUILD, Artifact, compile_spec, current_build, spec_hash, write_artifact
from fieldgen.files import claim, locked, remove_leftovers
from fieldgen.schema import load_spec

DEFAULT_OUT = Path("build")


@dataclass(frozen=True)
class BuildResult:
    out_dir: Path
    artifact: Artifact
    cache_hit: bool
    seconds: float


def build(spec_path: str | Path, out_root: Path = DEFAULT_OUT, preview: bool = True, force: bool = False) -> BuildResult:
    start = time.perf_counter()
    spec = load_spec(spec_path)
    out_dir = out_root / spec.name
    with locked(out_dir):  # one build of a field at a time: another's staging folder is no leftover
        remove_leftovers(out_root, spec.name)  # of a build of this field that was killed midway
        cached = None if force else current_build(out_dir, spec_hash(spec))
        if cached is not None:
            return BuildResult(out_dir, cached, True, time.perf_counter() - start)
        claim(out_dir, BUILD)  # before compiling: a folder of the user's is refused at once
        artifact = compile_spec(spec)
        image = None
        if preview:
            from fieldgen.render import png_bytes, preview as render_preview

            image = png_bytes(render_preview(artifact.model()))
        write_artifact(artifact, out_dir, image)
    return BuildResult(out_dir, artifact, False, time.perf_counter() - start)
