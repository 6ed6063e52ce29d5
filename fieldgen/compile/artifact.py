"""The built artifact: scene.xml + field.json (+ preview.png) in build/<name>/.

Loading an artifact needs mujoco and pydantic only, never dm_control, so a
machine without dm_control can run fields built elsewhere. A build is written
as a whole folder and swapped in (fieldgen.files.replace_folder), and field.json
carries the input hash, the digest of the scene.xml beside it and the digest of its own
other keys, so neither an interrupted build, a scene from another spec nor an edited
field.json is ever taken for a cache hit or loaded.
"""

from __future__ import annotations

import functools
import hashlib
import json
import pkgutil
import sys
from dataclasses import dataclass
from importlib.machinery import ModuleSpec
from pathlib import Path

import mujoco
from pydantic import ValidationError

from fieldgen.files import Output, parsed_json, replace_folder, write_atomic
from fieldgen.version import VERSION
from fieldgen.compile.contacts import candidate_pairs
from fieldgen.compile.layout import Layout, observation_layout, team_layout
from fieldgen.schema.models import FieldSpec
from fieldgen.source_imports import imports

# Bump when field.json or scene.xml change shape in a way loaders must know about.
ARTIFACT_FORMAT = 2  # 2: field.json holds record_sha256
SCENE, META, PREVIEW = "scene.xml", "field.json", "preview.png"
BUILD = Output("fieldgen build", (SCENE, META, PREVIEW), META, record_keys=("spec",))
# The compiler: this package, and every module of fieldgen its modules import. Their sources are part of
# every build's hash, so a change to any of them invalidates cached builds.
_COMPILER_PACKAGE = "fieldgen.compile"


def _find_spec(name: str) -> ModuleSpec | None:
    """Where `name` is imported from, found as the import system finds it but without running any module
    (importlib.util.find_spec imports the parent packages; reading the compiler's imports must load nothing)."""
    loaded = sys.modules.get(name)
    if loaded is not None and loaded.__spec__ is not None:
        return loaded.__spec__
    parent, _, _ = name.rpartition(".")
    locations = None
    if parent:
        parent_spec = _find_spec(parent)
        if parent_spec is None or parent_spec.submodule_search_locations is None:
            return None
        locations = parent_spec.submodule_search_locations
    for finder in sys.meta_path:
        spec = finder.find_spec(name, locations) if hasattr(finder, "find_spec") else None
        if spec is not None:
            return spec
    return None


def _imported_modules(name: str, spec: ModuleSpec) -> set[str]:
    """The fieldgen modules `name`'s import statements name, a function's included, read without running it.

    `from P import n` names the submodule P.n where there is one, else P (whose code defines n). A package
    only passed through (fieldgen in `import fieldgen.render`) is not named: its code decides nothing here,
    and fieldgen/__init__.py imports fieldgen.env lazily, for `fieldgen.make`."""
    package = name if spec.submodule_search_locations is not None else name.rpartition(".")[0]
    named = set()
    for module, member in imports(Path(spec.origin), package):
        submodule = f"{module}.{member}"
        named.add(submodule if member and _is_fieldgen(module) and _find_spec(submodule) else module)
    return {n for n in named if _is_fieldgen(n)}


def _is_fieldgen(name: str) -> bool:
    return name == "fieldgen" or name.startswith("fieldgen.")


@functools.cache
def compiler_modules() -> dict[str, Path]:
    """The source file of each module whose code decides a build, by name: the compiler package's modules
    and, transitively, the fieldgen modules they import."""
    package = _find_spec(_COMPILER_PACKAGE)
    pending = [_COMPILER_PACKAGE] + [f"{_COMPILER_PACKAGE}.{module.name}"
                                     for module in pkgutil.iter_modules(package.submodule_search_locations)]
    found: dict[str, Path] = {}
    while pending:
        name = pending.pop()
        spec = None if name in found else _find_spec(name)
        if spec is not None and spec.has_location:
            found[name] = Path(spec.origin)
            pending.extend(_imported_modules(name, spec))
    return dict(sorted(found.items()))


@functools.cache
def compiler_digest() -> str:
    """The digest of the compiler's sources, found and read once per process (a build's hash includes it)."""
    digest = hashlib.sha256()
    for name, path in compiler_modules().items():
        source = path.read_bytes()
        digest.update(f"{name}\n{len(source)}\n".encode() + source)
    return digest.hexdigest()[:16]


class ArtifactError(Exception):
    """A build directory that is missing, incomplete or from an incompatible version: `problem` says what is
    wrong, `str()` adds how a build folder is made whole (`remedy`); a run's own copy of its field, which
    `fieldgen build` does not write, is mended otherwise (fieldgen.run.record.field_copy_error)."""

    def __init__(self, problem: str, remedy: str):
        self.problem, self.remedy = problem, remedy
        super().__init__(f"{problem}; {remedy}")


@dataclass(frozen=True)
class Artifact:
    spec: FieldSpec
    xml: str
    hash: str

    def model(self) -> mujoco.MjModel:
        return mujoco.MjModel.from_xml_string(self.xml)

    def metadata(self) -> dict:
        """field.json: what the build is, sealed by the digest of all of it (record_digest)."""
        model = self.model()
        pairs = candidate_pairs(model)
        meta = {
            "fieldgen_version": VERSION,
            "artifact_format": ARTIFACT_FORMAT,
            "compiler_digest": compiler_digest(),
            "hash": self.hash,
            "scene_sha256": scene_digest(self.xml),
            "name": self.spec.name,
            **self._observed(model),
            "model": {k: int(getattr(model, k)) for k in ("nbody", "ngeom", "nq", "nv", "nu")},
            "episode_length": self.spec.episode.length,
            "reward": [t.model_dump(exclude_none=True) for t in self.spec.task.reward],
            "success": self.spec.task.success.model_dump(),
            "contact_pairs": [list(p) for p in pairs],
            "spec": self.spec.model_dump(mode="json"),
        }
        meta = json.loads(json.dumps(meta))  # as it reads back: tuples as lists
        return {**meta, RECORD_DIGEST: record_digest(meta)}

    def _observed(self, model: mujoco.MjModel) -> dict:
        """field.json's observation and action sizes: of the single agent, or of each agent of a team field (every
        agent observes as many entries and acts with as many), with the agents' names."""
        if self.spec.teams is None:
            layout: Layout = observation_layout(self.spec, model)
            return {"observation": layout.to_json(), "state_dim": layout.state_dim,
                    "goal_indices": list(layout.goal_indices), "action_size": int(model.nu)}
        team = team_layout(self.spec, model)
        return {"observation": team.to_json(), "state_dim": team.size, "goal_indices": [],
                "action_size": len(team.action_names), "agents": list(team.agents)}


RECORD_DIGEST = "record_sha256"


def record_digest(meta: dict) -> str:
    """The SHA-256 of field.json's keys other than RECORD_DIGEST, written canonically (sorted keys, no spaces)."""
    return hashlib.sha256(_canonical({k: v for k, v in meta.items() if k != RECORD_DIGEST}).encode()).hexdigest()


def _canonical(resolved: dict) -> str:
    return json.dumps(resolved, sort_keys=True, separators=(",", ":"))


def spec_hash(spec: FieldSpec) -> str:
    """Content hash of the resolved spec and the compiler code that reads it."""
    canonical = _canonical(spec.model_dump(mode="json"))
    return hashlib.sha256(f"{compiler_digest()}\n{canonical}".encode()).hexdigest()[:16]


def field_digest(resolved: dict) -> str:
    """The SHA-256 of a resolved spec (`FieldSpec.model_dump(mode="json")`, as run.json keeps it): what tells two
    fields apart where names do not (a bundled point_nav and a point_nav of your own), so that figures pool
    seeds of one field only."""
    return hashlib.sha256(_canonical(resolved).encode()).hexdigest()


def compile_spec(spec: FieldSpec) -> Artifact:
    """Spec -> MJCF via dm_control.mjcf (imported here: only building needs it)."""
    from fieldgen.compile.scene import build_scene

    return Artifact(spec, build_scene(spec).to_xml_string(), spec_hash(spec))


def scene_digest(xml: str | bytes) -> str:
    return hashlib.sha256(xml.encode() if isinstance(xml, str) else xml).hexdigest()


def current_build(out_dir: Path, digest: str) -> Artifact | None:
    """The build in out_dir if it is whole (load_artifact's checks) and of inputs hashing to `digest`, its
    spec included: the hash it records is no proof of the spec beside it."""
    try:
        artifact = load_artifact(out_dir)
    except ArtifactError:
        return None
    return artifact if artifact.hash == digest == spec_hash(artifact.spec) else None


def write_artifact(artifact: Artifact, out_dir: Path, preview: bytes | None = None) -> None:
    """out_dir made anew with the artifact's files, in one swap (a failed write keeps the old build)."""

    def fill(folder: Path) -> None:
        write_atomic(folder / SCENE, artifact.xml.encode())
        if preview is not None:
            write_atomic(folder / PREVIEW, preview)
        write_atomic(folder / META, (json.dumps(artifact.metadata(), indent=1) + "\n").encode())

    replace_folder(out_dir, fill, BUILD)


def load_artifact(out_dir: str | Path) -> Artifact:
    out_dir = Path(out_dir)
    try:
        meta, scene = (out_dir / META).read_bytes(), (out_dir / SCENE).read_bytes()
    except FileNotFoundError as exc:
        raise ArtifactError(f"{out_dir} is not a built field: {Path(exc.filename).name} is missing",
                            "run `fieldgen build` on its spec") from None
    except OSError as exc:
        raise ArtifactError(f"{out_dir} cannot be read as a built field ({exc})",
                            "rebuild it with `fieldgen build`") from None
    try:
        meta = parsed_json(meta)
    except ValueError as exc:
        raise ArtifactError(f"{out_dir / META} is not valid JSON ({exc})", "rebuild the field") from None
    if not isinstance(meta, dict) or meta.get("artifact_format") != ARTIFACT_FORMAT:
        found = meta.get("artifact_format") if isinstance(meta, dict) else None
        raise ArtifactError(f"{out_dir} has artifact format {found}, this fieldgen reads format {ARTIFACT_FORMAT}",
                            "rebuild the field")
    mismatch = (f"{out_dir / SCENE} is not the scene {out_dir / META} describes (an interrupted, mixed-up or "
                "damaged build)")
    damaged = f"{out_dir / META} was edited or damaged ({{}})"
    force = "rebuild the field with `fieldgen build --force`"
    if meta.get(RECORD_DIGEST) != record_digest(meta):
        raise ArtifactError(damaged.format(f"its {RECORD_DIGEST} is not the digest of the rest of it"
                                           if RECORD_DIGEST in meta else f"it lacks {RECORD_DIGEST}"), force)
    if meta.get("scene_sha256") != scene_digest(scene):
        raise ArtifactError(mismatch, force)
    try:
        xml = scene.decode()
    except UnicodeDecodeError:
        raise ArtifactError(mismatch, force) from None
    if not isinstance(meta.get("hash"), str) or "spec" not in meta:
        raise ArtifactError(damaged.format("it lacks the spec or its hash"), force)
    try:
        spec = FieldSpec.model_validate(meta["spec"])
    except ValidationError as exc:
        error = exc.errors()[0]
        raise ArtifactError(damaged.format(f"spec.{'.'.join(map(str, error['loc']))}: {error['msg']}"),
                            force) from None
    return Artifact(spec, xml, meta["hash"])
