"""The built artifact: scene.xml + field.json (+ preview.png) in build/<name>/.

Loading an artifact needs mujoco and pydantic only, never dm_control, so a
machine without dm_control can run fields built elsewhere. A build is written
as a whole folder and swapped in (fieldgen.files.replace_folder), and field.json
carries the input hash and the digest of the scene.xml beside it, so neither an
interrupted build nor a scene from another spec is ever taken for a cache hit.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import mujoco
from pydantic import ValidationError

from fieldgen.files import replace_folder, write_atomic
from fieldgen.version import VERSION
from fieldgen.compile.contacts import candidate_pairs
from fieldgen.compile.layout import Layout, observation_layout
from fieldgen.schema.models import FieldSpec

# Bump when field.json or scene.xml change shape in a way loaders must know about.
ARTIFACT_FORMAT = 1
SCENE, META, PREVIEW = "scene.xml", "field.json", "preview.png"
# The modules whose code decides the scene: a change to any of them invalidates cached builds.
_COMPILER_MODULES = ("compile/agents.py", "compile/artifact.py", "compile/contacts.py", "compile/scene.py",
                     "compile/layout.py", "compile/pipelines.py", "schema/geometry.py", "schema/models.py")


def _compiler_digest() -> str:
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for name in _COMPILER_MODULES:
        digest.update((root / name).read_bytes())
    return digest.hexdigest()[:16]


COMPILER_DIGEST = _compiler_digest()


class ArtifactError(Exception):
    """A build directory that is missing, incomplete or from an incompatible version."""


@dataclass(frozen=True)
class Artifact:
    spec: FieldSpec
    xml: str
    hash: str

    def model(self) -> mujoco.MjModel:
        return mujoco.MjModel.from_xml_string(self.xml)

    def metadata(self) -> dict:
        model = self.model()
        layout: Layout = observation_layout(self.spec, model)
        pairs = candidate_pairs(model)
        return {
            "fieldgen_version": VERSION,
            "artifact_format": ARTIFACT_FORMAT,
            "compiler_digest": COMPILER_DIGEST,
            "hash": self.hash,
            "scene_sha256": scene_digest(self.xml),
            "name": self.spec.name,
            "observation": layout.to_json(),
            "state_dim": layout.state_dim,
            "goal_indices": list(layout.goal_indices),
            "action_size": int(model.nu),
            "model": {k: int(getattr(model, k)) for k in ("nbody", "ngeom", "nq", "nv", "nu")},
            "episode_length": self.spec.episode.length,
            "reward": [t.model_dump(exclude_none=True) for t in self.spec.task.reward],
            "success": self.spec.task.success.model_dump(),
            "contact_pairs": [list(p) for p in pairs],
            "spec": self.spec.model_dump(mode="json"),
        }


def spec_hash(spec: FieldSpec) -> str:
    """Content hash of the resolved spec and the compiler code that reads it."""
    canonical = json.dumps(spec.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(f"{COMPILER_DIGEST}\n{canonical}".encode()).hexdigest()[:16]


def compile_spec(spec: FieldSpec) -> Artifact:
    """Spec -> MJCF via dm_control.mjcf (imported here: only building needs it)."""
    from fieldgen.compile.scene import build_scene

    return Artifact(spec, build_scene(spec).to_xml_string(), spec_hash(spec))


def scene_digest(xml: str | bytes) -> str:
    return hashlib.sha256(xml.encode() if isinstance(xml, str) else xml).hexdigest()


def is_current(out_dir: Path, digest: str) -> bool:
    """Whether out_dir holds the build of inputs hashing to `digest`, its scene.xml the one field.json names."""
    try:
        meta = json.loads((out_dir / META).read_text())
        xml = (out_dir / SCENE).read_text()
    except (OSError, ValueError):
        return False
    return isinstance(meta, dict) and meta.get("hash") == digest and meta.get("scene_sha256") == scene_digest(xml)


def write_artifact(artifact: Artifact, out_dir: Path, preview: bytes | None = None) -> None:
    """out_dir made anew with the artifact's files, in one swap (a failed write keeps the old build)."""

    def fill(folder: Path) -> None:
        write_atomic(folder / SCENE, artifact.xml.encode())
        if preview is not None:
            write_atomic(folder / PREVIEW, preview)
        write_atomic(folder / META, (json.dumps(artifact.metadata(), indent=1) + "\n").encode())

    replace_folder(out_dir, fill)


def load_artifact(out_dir: str | Path) -> Artifact:
    out_dir = Path(out_dir)
    try:
        meta, scene = (out_dir / META).read_bytes(), (out_dir / SCENE).read_bytes()
    except FileNotFoundError as exc:
        raise ArtifactError(f"{out_dir} is not a built field: {Path(exc.filename).name} is missing; "
                            "run `fieldgen build` on its spec") from None
    except OSError as exc:
        raise ArtifactError(f"{out_dir} cannot be read as a built field ({exc}); rebuild it with `fieldgen build`") from None
    try:
        meta = json.loads(meta)
    except ValueError as exc:
        raise ArtifactError(f"{out_dir / META} is not valid JSON ({exc}); rebuild the field") from None
    if not isinstance(meta, dict) or meta.get("artifact_format") != ARTIFACT_FORMAT:
        found = meta.get("artifact_format") if isinstance(meta, dict) else None
        raise ArtifactError(f"{out_dir} has artifact format {found}, "
                            f"this fieldgen reads format {ARTIFACT_FORMAT}; rebuild the field")
    mismatch = (f"{out_dir / SCENE} is not the scene {out_dir / META} describes (an interrupted, mixed-up or "
                "damaged build); rebuild the field with `fieldgen build --force`")
    if "scene_sha256" in meta and meta["scene_sha256"] != scene_digest(scene):
        raise ArtifactError(mismatch)
    try:
        xml = scene.decode()
    except UnicodeDecodeError:
        raise ArtifactError(mismatch) from None
    damaged = f"{out_dir / META} was edited or damaged ({{}}); rebuild the field with `fieldgen build --force`"
    if not isinstance(meta.get("hash"), str) or "spec" not in meta:
        raise ArtifactError(damaged.format("it lacks the spec or its hash"))
    try:
        spec = FieldSpec.model_validate(meta["spec"])
    except ValidationError as exc:
        error = exc.errors()[0]
        raise ArtifactError(damaged.format(f"spec.{'.'.join(map(str, error['loc']))}: {error['msg']}")) from None
    return Artifact(spec, xml, meta["hash"])
