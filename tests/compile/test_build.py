"""Every bundled field compiles to MJCF that MuJoCo and MJX load; builds are reproducible and atomic."""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import imageio.v3 as iio
import mujoco
import numpy as np
import pytest

import fieldgen
from fieldgen.compile import artifact
from fieldgen.compile.artifact import ArtifactError, compile_spec, load_artifact
from fieldgen.compile.build import build
from fieldgen.compile.contacts import candidate_pairs
from fieldgen.render import preview
from mujoco import mjx
from fieldgen.schema import SpecError, bundled_fields, load_spec

FIELDS = sorted(bundled_fields())


@pytest.mark.parametrize("name", FIELDS)
def test_bundled_field_compiles_and_loads(name):
    spec = load_spec(bundled_fields()[name])
    artifact = compile_spec(spec)
    model = mujoco.MjModel.from_xml_string(artifact.xml)
    mjx.put_model(model)
    meta = artifact.metadata()
    agents = len(meta.get("agents", ["agent"]))
    assert model.nu == agents * (8 if spec.agent.kind == "ant" else 2)
    assert model.key("home").qpos.shape == (model.nq,)
    assert meta["observation"]["size"] == meta["state_dim"] + (2 if spec.teams is None else 0)
    assert spec.description and bundled_fields()[name].read_text().startswith("#")


def test_same_yaml_gives_byte_identical_scene_and_hash():
    a = compile_spec(load_spec("fields/soccer_v2.yaml"))
    b = compile_spec(load_spec("fields/soccer_v2.yaml"))
    assert a.xml == b.xml and a.hash == b.hash
    c = compile_spec(load_spec("fields/v2_wide_goalie.yaml"))
    assert c.hash != a.hash


def test_build_writes_artifact_then_hits_cache(tmp_path):
    first = build("fields/point_soccer.yaml", tmp_path, preview=False)
    assert not first.cache_hit
    files = sorted(p.name for p in first.out_dir.iterdir())
    assert files == [".fieldgen", "field.json", "scene.xml"]  # its ownership record; no temporary files left behind
    xml = (first.out_dir / "scene.xml").read_bytes()
    second = build("fields/point_soccer.yaml", tmp_path, preview=False)
    assert second.cache_hit and (second.out_dir / "scene.xml").read_bytes() == xml
    forced = build("fields/point_soccer.yaml", tmp_path, preview=False, force=True)
    assert not forced.cache_hit and (forced.out_dir / "scene.xml").read_bytes() == xml


def test_the_digest_covers_every_fieldgen_module_a_build_loads(tmp_path):
    """What building a field and its variants loads of fieldgen (but fieldgen/__init__.py, only passed
    through), seen in a fresh process, is all read by the digest, fieldgen/render.py among it; nothing of the
    environment, the runs or the trainers is."""
    code = ("import pathlib, sys\n"
            "from fieldgen.compile.build import build\n"
            "from fieldgen.compile.variants import compile_variants\n"
            "from fieldgen.schema import load_spec\n"
            f"build('fields/point_nav.yaml', pathlib.Path({str(tmp_path)!r}), preview=False)\n"
            "compile_variants([load_spec('fields/point_nav.yaml')])\n"
            "print(*sorted(m for m in sys.modules if m.startswith('fieldgen.')))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded = set(done.stdout.split())
    covered = set(artifact.compiler_modules())
    assert {"fieldgen.render", "fieldgen.compile.scene", "fieldgen.compile.variants"} <= loaded <= covered
    assert not [m for m in covered if m.startswith(("fieldgen.env", "fieldgen.run", "fieldgen.agents"))]


def test_the_digest_reads_every_form_of_import(tmp_path):
    """Relative imports, a package's submodule and imports inside functions all name what they run; a name
    that is no submodule names its package, whose code defines it; modules not of fieldgen are left out."""
    probe = tmp_path / "probe.py"
    probe.write_text("from . import scene\nfrom .layout import Layout\nfrom ..schema.models import FieldSpec\n"
                     "from fieldgen.schema import geometry, load_spec\nimport fieldgen.files\nimport numpy\n\n\n"
                     "def later():\n    from fieldgen import render\n")
    spec = importlib.util.spec_from_file_location("fieldgen.compile.probe", probe)
    assert artifact._imported_modules("fieldgen.compile.probe", spec) == {
        "fieldgen.compile.scene", "fieldgen.compile.layout", "fieldgen.schema.models", "fieldgen.schema.geometry",
        "fieldgen.schema", "fieldgen.files", "fieldgen.render"}


def test_an_edit_to_a_module_the_compiler_imports_is_a_rebuild(tmp_path):
    """The stale cache a hand-kept list of modules allowed: scene.py takes the markings' geom group from
    fieldgen/render.py, which the list left out, so a build made before an edit there was still served. The
    edit is made to a copy of the package, which a fresh process builds from."""
    source = tmp_path / "source"
    shutil.copytree(Path(fieldgen.__file__).parent, source / "fieldgen", ignore=shutil.ignore_patterns("__pycache__"))
    out = tmp_path / "build"
    spec = Path("fields/point_nav.yaml").resolve()
    marker = 'name="target" class="/" type="cylinder" contype="0" conaffinity="0" group="{}"'
    built = build(spec, out, preview=False)
    assert not built.cache_hit and marker.format(1) in built.artifact.xml

    def build_from_copy() -> bool:
        code = ("import pathlib\nfrom fieldgen.compile import build\n"
                f"result = build.build({str(spec)!r}, pathlib.Path({str(out)!r}), preview=False)\n"
                "print(build.__file__, result.cache_hit)\n")
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(source), os.environ.get("PYTHONPATH")]))}
        done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                              check=True)
        module, hit = done.stdout.split()[-2:]
        assert module.startswith(str(source))
        return hit == "True"

    assert build_from_copy()  # the same code, copied: the build is current
    render = source / "fieldgen" / "render.py"
    render.write_text(render.read_text().replace("MARKINGS, SIDE_VIEW = 1, 2", "MARKINGS, SIDE_VIEW = 3, 2"))
    assert not build_from_copy()
    assert marker.format(3) in (out / "point_nav" / "scene.xml").read_text()


def test_build_with_preview_writes_png(tmp_path):
    result = build("fields/point_nav.yaml", tmp_path, preview=True)
    png = (result.out_dir / "preview.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    # read back, the file is the preview of the built scene, pixel for pixel
    np.testing.assert_array_equal(iio.imread(png), preview(load_artifact(result.out_dir).model()))


def test_field_json_describes_observation_and_task(tmp_path):
    result = build("fields/soccer_v2.yaml", tmp_path, preview=False)
    meta = json.loads((result.out_dir / "field.json").read_text())
    assert meta["state_dim"] == 31 and meta["goal_indices"] == [29, 30]  # the study's layout
    assert meta["observation"]["slices"] == {
        "agent_qpos": [0, 15], "agent_qvel": [15, 29], "ball_pos": [29, 31], "goal": [31, 33]}
    assert meta["spec"]["obstacles"]["goalie"]["width"] == 1.5
    assert meta["success"] == {"kind": "ball_near_target", "radius": 0.5}


def test_incomplete_or_corrupt_artifact_is_a_clear_error(tmp_path):
    result = build("fields/point_nav.yaml", tmp_path, preview=False)
    (result.out_dir / "field.json").write_text("{not json")
    with pytest.raises(ArtifactError, match="not valid JSON"):
        load_artifact(result.out_dir)
    (result.out_dir / "field.json").unlink()
    with pytest.raises(ArtifactError, match="field.json is missing"):
        load_artifact(result.out_dir)


@pytest.mark.parametrize("edit,phrase", [
    (lambda meta: meta.pop("spec"), "it lacks the spec or its hash"),
    (lambda meta: meta.update(hash=None), "it lacks the spec or its hash"),
    (lambda meta: meta["spec"]["episode"].update(length=-3),
     "spec.episode.length: Input should be greater than or equal to 1"),
])
def test_an_edited_field_json_is_a_clear_error(tmp_path, edit, phrase):
    """A field.json whose scene is intact but whose description was edited or damaged names the file, the key
    and what to do, rather than failing with a KeyError or pydantic's report."""
    result = build("fields/point_nav.yaml", tmp_path, preview=False)
    meta = json.loads((result.out_dir / "field.json").read_text())
    edit(meta)
    meta[artifact.RECORD_DIGEST] = artifact.record_digest(meta)  # sealed again, as a careful hand would
    (result.out_dir / "field.json").write_text(json.dumps(meta))
    with pytest.raises(ArtifactError) as caught:
        load_artifact(result.out_dir)
    assert str(caught.value) == (f"{result.out_dir / 'field.json'} was edited or damaged ({phrase}); rebuild the "
                                 "field with `fieldgen build --force`")


@pytest.mark.parametrize("edit,phrase", [
    (lambda meta: meta["spec"]["episode"].update(length=50), "its record_sha256 is not the digest of the rest of it"),
    (lambda meta: meta.update(state_dim=3), "its record_sha256 is not the digest of the rest of it"),
    (lambda meta: meta.pop("record_sha256"), "it lacks record_sha256"),
], ids=["spec", "derived", "no_digest"])
def test_an_edited_build_is_never_a_cache_hit(tmp_path, edit, phrase):
    """field.json edited to a spec still valid (a longer episode), or a value derived from it, or stripped of
    a digest: the build is refused as damaged, and `fieldgen build` builds it again instead of serving it."""
    result = build("fields/point_nav.yaml", tmp_path, preview=False)
    meta = json.loads((result.out_dir / "field.json").read_text())
    edit(meta)
    (result.out_dir / "field.json").write_text(json.dumps(meta))
    with pytest.raises(ArtifactError) as caught:
        load_artifact(result.out_dir)
    assert str(caught.value) == (f"{result.out_dir / 'field.json'} was edited or damaged ({phrase}); rebuild the "
                                 "field with `fieldgen build --force`")
    again = build("fields/point_nav.yaml", tmp_path, preview=False)
    assert not again.cache_hit and again.artifact.spec.episode.length == load_spec("fields/point_nav.yaml").episode.length
    assert load_artifact(result.out_dir).spec == again.artifact.spec


def test_a_scene_missing_its_digest_or_a_hash_that_is_not_the_specs_is_rebuilt(tmp_path):
    """Sealed, but recording no digest of its scene, or a hash its spec does not give: refused, or rebuilt."""
    result = build("fields/point_nav.yaml", tmp_path, preview=False)
    path = result.out_dir / "field.json"
    good = json.loads(path.read_text())
    meta = {k: v for k, v in good.items() if k != "scene_sha256"}
    path.write_text(json.dumps({**meta, artifact.RECORD_DIGEST: artifact.record_digest(meta)}))
    with pytest.raises(ArtifactError, match="scene.xml is not the scene .*field.json describes"):
        load_artifact(result.out_dir)
    meta = {**good, "spec": {**good["spec"], "episode": {**good["spec"]["episode"], "length": 50}}}
    path.write_text(json.dumps({**meta, artifact.RECORD_DIGEST: artifact.record_digest(meta)}))
    assert load_artifact(result.out_dir).spec.episode.length == 50  # whole as a record, yet not of its hash
    again = build("fields/point_nav.yaml", tmp_path, preview=False)
    assert not again.cache_hit and load_artifact(result.out_dir).spec.episode.length != 50


def test_a_build_interrupted_after_its_scene_never_serves_the_wrong_one(tmp_path, write_spec):
    """The failure a cache that trusts field.json allowed: a rebuild of one field into another's folder
    stopped after writing its scene.xml. The old field.json then names a scene it does not describe: it
    is no cache hit, and loading that folder says so. Killed builds' staging folders are cleared."""
    a = write_spec("extends: point_nav\nname: same_name\n", "a.yaml")
    b = write_spec("extends: point_nav\nname: same_name\nfield: {length: 30, width: 30}\n", "b.yaml")
    out = tmp_path / "build"
    built = build(a, out, preview=False)
    (built.out_dir / "scene.xml").write_text(compile_spec(load_spec(b)).xml)  # the half-done rebuild
    with pytest.raises(ArtifactError, match="scene.xml is not the scene .*field.json describes"):
        load_artifact(built.out_dir)
    (out / ".same_name.k1ll3d.tmp").mkdir()
    again = build(a, out, preview=False)
    assert not again.cache_hit and load_artifact(again.out_dir).xml == compile_spec(load_spec(a)).xml
    assert sorted(p.name for p in out.iterdir()) == ["same_name"]


@pytest.mark.parametrize("error", [(28, "No space left on device"), (13, "Permission denied")])
def test_a_full_disk_or_a_read_only_folder_keeps_the_old_build(tmp_path, monkeypatch, error):
    """A build that cannot be written is one sentence naming the folder and why, and the build that was
    there is untouched (a read-only --out is simulated: the tests may run as root, whom modes do not stop)."""
    from typer.testing import CliRunner

    from fieldgen import files
    from fieldgen.cli import app

    built = build("fields/point_nav.yaml", tmp_path, preview=False)
    before = {p.name: p.read_bytes() for p in built.out_dir.iterdir()}

    def refuse(*args, **kwargs):
        raise OSError(*error)

    monkeypatch.setattr(files.tempfile, "mkstemp", refuse)
    result = CliRunner().invoke(app, ["build", "point_nav", "--out", str(tmp_path), "--force", "--no-preview"])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert f"cannotwrite{built.out_dir}:{error[1]}".replace(" ", "") in "".join(result.output.split())
    assert {p.name: p.read_bytes() for p in built.out_dir.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["point_nav"]


def test_a_disk_that_fills_midway_keeps_the_old_build_whole(tmp_path, write_spec, monkeypatch):
    """The disk fills after the new scene.xml is written, at field.json: the old build stays as it was (its
    scene with its own field.json, a cache hit), and nothing of the new one is left."""
    import os

    from fieldgen import files

    a = write_spec("extends: point_nav\nname: same_name\n", "a.yaml")
    b = write_spec("extends: point_nav\nname: same_name\nfield: {length: 30, width: 30}\n", "b.yaml")
    out = tmp_path / "build"
    built = build(a, out, preview=False)
    before = {p.name: p.read_bytes() for p in built.out_dir.iterdir()}
    synced, real_fsync = [], os.fsync

    def fsync(fd):
        synced.append(fd)
        if len(synced) == 2:  # scene.xml went through; field.json does not
            raise OSError(28, "No space left on device")
        real_fsync(fd)

    monkeypatch.setattr(files.os, "fsync", fsync)
    with pytest.raises(files.WriteError) as caught:
        build(b, out, preview=False)
    monkeypatch.undo()
    assert len(synced) == 2
    assert str(caught.value) == f"cannot write {built.out_dir}: No space left on device"
    assert {p.name: p.read_bytes() for p in built.out_dir.iterdir()} == before
    assert sorted(p.name for p in out.iterdir()) == ["same_name"] and build(a, out, preview=False).cache_hit


@pytest.mark.parametrize("damage", [lambda xml: xml.replace(b"<geom", b"<gem ", 1),  # still text
                                    lambda xml: xml[:50] + b"\xff" + xml[51:]])  # no longer UTF-8
def test_a_damaged_scene_is_named_and_never_a_cache_hit(tmp_path, damage):
    result = build("fields/point_nav.yaml", tmp_path, preview=False)
    scene = result.out_dir / "scene.xml"
    scene.write_bytes(damage(scene.read_bytes()))
    with pytest.raises(ArtifactError) as caught:
        load_artifact(result.out_dir)
    assert str(caught.value).startswith(f"{scene} is not the scene {result.out_dir / 'field.json'} describes")
    assert not build("fields/point_nav.yaml", tmp_path, preview=False).cache_hit


def test_a_file_in_the_way_of_the_build_folder_is_named(tmp_path):
    from fieldgen.files import WriteError

    (tmp_path / "out").write_text("")
    with pytest.raises(WriteError) as caught:
        build("fields/point_nav.yaml", tmp_path / "out", preview=False)
    assert str(caught.value) == f"cannot write {tmp_path / 'out'}: a file is in the way of the folder"


def test_artifact_loads_without_dm_control(tmp_path):
    result = build("fields/point_soccer.yaml", tmp_path, preview=False)
    code = (
        "import sys; sys.modules['dm_control'] = None\n"
        "import fieldgen\n"
        f"env = fieldgen.make({str(result.out_dir)!r})\n"
        "print(env.observation_size, env.action_size)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split()[-2:] == ["8", "2"]


def pairs_by_role(name):
    model = compile_spec(load_spec(bundled_fields()[name])).model()
    return {tuple(sorted(p)) for p in candidate_pairs(model)}


def test_soccer_v2_prunes_contacts_to_pairs_that_matter():
    pairs = pairs_by_role("soccer_v2")
    names = {g for p in pairs for g in p}
    assert not any(n.endswith(("_aux", "_thigh", "_shin")) for n in names)  # leg capsules never collide
    assert ("ball", "wall_left") in pairs and ("obstacle_goalie", "torso") in pairs
    assert ("ball", "post_left") in pairs and ("back_left_foot", "floor") in pairs
    assert not any("crossbar" in p for p in names)  # 3.5 m up: nothing on the field reaches it
    assert ("ball", "floor") not in pairs  # the puck's floor friction is a joint frictionloss


def test_seed_field_reproduces_the_studys_contact_set():
    pairs = pairs_by_role("soccer_v2_seed")
    assert len(pairs) == 20
    assert not any(g.startswith(("wall", "obstacle", "post")) for p in pairs for g in p)
    assert ("back_left_foot", "front_left_foot") in pairs and ("ball", "floor") in pairs


def test_torso_floor_contacts_give_the_ant_s_torso_a_floor_pair_pruned_ones_leave_out(write_spec):
    """Where a turned-over ant then comes to rest: tests/bench/test_turned_over_ant.py."""
    pruned = load_spec(bundled_fields()["ant_nav"])
    grounded = load_spec(write_spec("extends: ant_nav\nname: ant_nav_torso_floor\nsim: {contacts: torso_floor}\n"))
    assert ("floor", "torso") in {tuple(sorted(p)) for p in candidate_pairs(compile_spec(grounded).model())}
    assert ("floor", "torso") not in {tuple(sorted(p)) for p in candidate_pairs(compile_spec(pruned).model())}


def test_torso_floor_contacts_on_a_point_agent_are_refused_at_the_key(write_spec):
    path = write_spec("extends: point_nav\nname: p\nsim: {contacts: torso_floor}\n")
    with pytest.raises(SpecError) as refused:
        load_spec(path)
    assert f"{path}:3:" in str(refused.value) and "sim.contacts: 'torso_floor' gives an ant's torso" in str(refused.value)


def test_an_ant_names_its_torso_orientation_as_the_environment_contract_does():
    """The evaluation's turned_over and bench/ball_endings.py find the torso by these
    names; a point has none."""
    from fieldgen.compile.layout import observation_layout
    from fieldgen.env.contract import torso_entries

    for name, has_torso in (("ant_nav", True), ("point_nav", False)):
        spec = load_spec(bundled_fields()[name])
        names = observation_layout(spec, compile_spec(spec).model()).names
        assert (torso_entries(names) is not None) == has_torso, name
