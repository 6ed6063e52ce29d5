"""The command line as a user meets it: exit codes, messages, files written."""

from __future__ import annotations

import json
import re
from pathlib import Path

import imageio.v3 as iio
import pytest
from typer.testing import CliRunner

from fieldgen.cli import app
from fieldgen.schema import bundled_fields
from fieldgen.schema.errors import shown_text, shown_value

runner = CliRunner()


def test_validate_ok_and_bad(write_spec):
    ok = runner.invoke(app, ["validate", "fields/soccer_v2.yaml", "v2_wide_goalie"])
    assert ok.exit_code == 0, ok.output
    bad = write_spec("extends: soccer_v2\nname: b\nobstacles:\n  goalie: {widht: 4}\n")
    result = runner.invoke(app, ["validate", str(bad)])
    assert result.exit_code == 1
    assert f"{bad}:4:" in result.output and "did you mean 'width'" in result.output
    assert "Traceback" not in result.output


def test_commands_keep_compiled_programs_in_a_cache_the_user_can_move(tmp_path, monkeypatch):
    """Every command points JAX's persistent compilation cache at ~/.cache/fieldgen/xla (XDG_CACHE_HOME
    honoured) before JAX loads, unless JAX_COMPILATION_CACHE_DIR already names a folder."""
    import os

    monkeypatch.delenv("JAX_COMPILATION_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert runner.invoke(app, ["validate", "point_nav"]).exit_code == 0
    assert os.environ["JAX_COMPILATION_CACHE_DIR"] == str(tmp_path / "fieldgen" / "xla")
    monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", str(tmp_path / "mine"))
    assert runner.invoke(app, ["validate", "point_nav"]).exit_code == 0
    assert os.environ["JAX_COMPILATION_CACHE_DIR"] == str(tmp_path / "mine")


def test_commands_turn_xla_fusion_autotuning_off_unless_the_user_sets_it(monkeypatch):
    """Every command adds fieldgen's XLA defaults to XLA_FLAGS before JAX starts a backend, keeping the
    user's own flags, and leaves a default the user set alone."""
    import os

    monkeypatch.setenv("XLA_FLAGS", "--xla_dump_to=/tmp/x")
    assert runner.invoke(app, ["validate", "point_nav"]).exit_code == 0
    assert os.environ["XLA_FLAGS"] == "--xla_dump_to=/tmp/x --xla_gpu_experimental_enable_fusion_autotuner=false"
    monkeypatch.setenv("XLA_FLAGS", "--xla_gpu_experimental_enable_fusion_autotuner=true")
    assert runner.invoke(app, ["validate", "point_nav"]).exit_code == 0
    assert os.environ["XLA_FLAGS"] == "--xla_gpu_experimental_enable_fusion_autotuner=true"


def test_an_xla_flags_file_is_left_as_named_and_one_that_cannot_be_read_is_one_line(tmp_path, monkeypatch):
    """XLA reads a value that does not start with - as a file of flags: the defaults added to it named another
    file, and XLA aborted the command as JAX started, as it does where the file is missing."""
    import os

    flags = tmp_path / "xla flags.txt"
    flags.write_text("--xla_dump_to=/tmp/x\n")
    monkeypatch.setenv("XLA_FLAGS", str(flags))
    assert runner.invoke(app, ["validate", "point_nav"]).exit_code == 0
    assert os.environ["XLA_FLAGS"] == str(flags)
    monkeypatch.setenv("XLA_FLAGS", "garbage")
    result = runner.invoke(app, ["validate", "point_nav"])
    assert result.exit_code == 1 and os.environ["XLA_FLAGS"] == "garbage"
    assert result.output.startswith("error: XLA_FLAGS='garbage' does not start with --, so XLA reads it as the name "
                                    "of a file of flags, and no such file can be read here;"), result.output


@pytest.mark.parametrize("flags, said", [
    ("--xla_gpu_autotune_levl=0", "XLA_FLAGS names --xla_gpu_autotune_levl=0 (did you mean "
                                  "'--xla_gpu_autotune_level'?), which XLA does not know. Correct or drop it,"),
    ("--xla_dump_to=/tmp/x --xla_no_such_flag --xla_nor_this=1", "XLA_FLAGS names --xla_no_such_flag, "
                                                                  "--xla_nor_this=1, which XLA does not know."),
    ("--xla_gpu_autotune_level=abc", "XLA_FLAGS names --xla_gpu_autotune_level=abc, a value XLA cannot read as that "
                                     "flag's kind. Correct it,"),
    ("FILE", "the file of flags that XLA_FLAGS names (FILE) holds --xla_no_such_flag, which XLA does not know."),
])
def test_flags_xla_would_refuse_are_one_paragraph_before_anything_is_written(tmp_path, monkeypatch, flags, said):
    """XLA ends the process that names a flag it does not know, or a value it cannot read, as JAX starts: one line of
    its log, mid-command. Asked of XLA in a process of its own first, the command says which and stops."""
    file = tmp_path / "flags.txt"
    file.write_text("--xla_no_such_flag\n")
    monkeypatch.setenv("XLA_FLAGS", flags.replace("FILE", str(file)))
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["train", "point_nav", "--steps", "2000000", "--out", "runs"])
    assert result.exit_code == 1 and not (tmp_path / "runs").exists()
    assert result.output.startswith("error: XLA would end the command as JAX starts: "), result.output
    assert said.replace("FILE", str(file)) in " ".join(result.output.split()), result.output
    assert "(XLA_FLAGS=--help python -c 'import jax; jax.devices()' lists the flags XLA knows" in " ".join(
        result.output.split())


def test_a_jax_platform_this_machine_cannot_start_is_one_line_and_sets_nothing_up(tmp_path, monkeypatch):
    """JAX says so wherever it first starts, mid-command: a RuntimeError, or for CUDA without JAX's plugin an empty
    AssertionError, each a traceback once."""
    import os
    import subprocess
    import sys

    import jax

    proc = subprocess.run([sys.executable, "-m", "fieldgen", "train", "point_nav", "--prepare", "--out",
                           str(tmp_path / "runs")], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "JAX_PLATFORMS": "rocm", "COLUMNS": "400"})
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.startswith("error: JAX_PLATFORMS=rocm names a platform JAX cannot start here ("), proc.stderr
    assert "unset JAX_PLATFORMS for JAX to use what this machine has, or set JAX_PLATFORMS=cpu" in proc.stderr
    assert not (tmp_path / "runs").exists()

    def no_plugin(*args, **kwargs):
        raise AssertionError

    monkeypatch.setenv("JAX_PLATFORMS", "cuda")
    monkeypatch.setattr(jax, "devices", no_plugin)
    monkeypatch.setattr("fieldgen.run.session.field_spec", no_plugin)
    result = runner.invoke(app, ["train", "point_nav", "--prepare", "--out", str(tmp_path / "runs")])
    assert result.exit_code == 1 and result.output.startswith(
        "error: JAX_PLATFORMS=cuda names a platform JAX cannot start here (JAX has no plugin for it here);"), result.output


def test_unknown_field_name_is_a_clear_error():
    result = runner.invoke(app, ["build", "socer_v2"])
    assert result.exit_code == 1
    assert "neither a file nor a bundled field" in result.output and "Traceback" not in result.output
    assert "did you mean 'soccer_v2'?" in result.output and "ant_ball" not in result.output  # not all 24 names


def test_settings_after_one_set_are_answered_with_a_set_each():
    result = runner.invoke(app, ["train", "point_nav", "--set", "ppo.num_evals=2", "ppo.discount=0.99"])
    assert result.exit_code == 2
    assert "give each setting its own --set: --set ppo.discount=0.99" in re.sub(r"[\s│]+", " ", result.output)
    plain = runner.invoke(app, ["train", "point_nav", "extra"])
    assert plain.exit_code == 2 and "--set" not in plain.output


def test_a_mistyped_path_or_a_curriculum_index_is_answered_with_what_was_meant(tmp_path, monkeypatch):
    """A path to a file that is not there gets the nearest file of its folder; a curriculum's curriculum.yaml,
    which reads as a field with five unknown keys, gets its folder; so do a run's and a build's records."""
    import shutil
    from pathlib import Path

    curriculum = tmp_path / "to_far"
    shutil.copytree(Path(__file__).parents[1] / "curricula" / "point_nav_to_far", curriculum)
    (tmp_path / "my_nav.yaml").write_text("extends: point_nav\nname: my_nav\n")
    monkeypatch.chdir(tmp_path)
    cases = [
        (["validate", "my_nva.yaml"], "'my_nva.yaml' is not a file; did you mean 'my_nav.yaml'?"),
        (["build", "fields/my_nav.yaml"], "'fields/my_nav.yaml' is not a file: there is no folder fields"),
        # commands that take folders too say which, where nothing is at the path
        (["view", "gone/old_run"], "'gone/old_run' is not a file or folder: there is no folder gone"),
        (["compare", "runs/old"], "'runs/old' is not a file or folder: name a field's YAML file, a bundled field or "
                                  "a build folder, or run folders to compare"),
        (["compare", "old_run"], "'old_run' is neither a file, a folder nor a bundled field."),
        (["train", "./my_nva.yaml"], "'./my_nva.yaml' is not a file or folder; did you mean 'my_nav.yaml'?"),
        (["build", "to_far/curriculum.yaml"], "to_far/curriculum.yaml lists the stages of a curriculum, not a "
                                              "field: give the curriculum's folder, to_far, to validate, build"),
        (["train", "to_far/curriculum.yaml"], "give the curriculum's folder, to_far"),
        # the records fieldgen writes beside a run and a build, which read as a spec with some 25 unknown keys
        (["render", "runs/r/run.json"], "runs/r/run.json is the record of a run, not a field spec; runs/r is a run "
                                        "folder, not a field (a YAML file, bundled name or build folder); the field "
                                        "that run trained on is its copy runs/r/field"),
        (["validate", "b/point_nav/field.json"], "b/point_nav/field.json is the record of a built field, not a field "
                                                 "spec: give its folder, b/point_nav"),
    ]
    cases += [(["validate", "runs/r"], "runs/r is a run folder, not a field (a YAML file, bundled name or build "
                                       "folder); the field that run trained on is its copy runs/r/field"),
              (["build", "runs/r"], "runs/r is a run folder, not a field")]
    (tmp_path / "runs" / "r").mkdir(parents=True)
    (tmp_path / "runs" / "r" / "run.json").write_text("{}")
    (tmp_path / "b" / "point_nav").mkdir(parents=True)
    (tmp_path / "b" / "point_nav" / "field.json").write_text("{}")
    for args, phrase in cases:
        result = runner.invoke(app, args)
        message = " ".join(result.output.split())
        assert result.exit_code == 1 and phrase in message and "unknown key" not in message, message
    checked = runner.invoke(app, ["validate", "to_far", "my_nav.yaml"])
    assert checked.exit_code == 0 and "to_far: 4 stages, point_nav_to_far_s01 to point_nav_to_far_s04" in " ".join(
        checked.output.split()), checked.output


def test_a_curriculum_records_the_fields_as_they_were_named(tmp_path, monkeypatch):
    """A bundled name stays a name in curriculum.yaml, its stage files and its messages, not the absolute path
    of the bundled file (which differs between installs)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "my_nav.yaml").write_text("extends: point_nav\nname: my_nav\nfield: {length: 12, width: 12}\n")
    made = runner.invoke(app, ["curriculum", "point_nav", "--to", "my_nav.yaml", "--stages", "3", "-o", "c"])
    assert made.exit_code == 0, made.output
    written = "".join(p.read_text() for p in sorted((tmp_path / "c").iterdir()))
    assert "from point_nav to my_nav.yaml" in written and str(bundled_fields()["point_nav"]) not in written
    refused = runner.invoke(app, ["curriculum", "point_soccer", "--start-near", "2", "--stages", "3", "--then",
                                  "soccer_v1", "-o", "d"])
    assert refused.exit_code == 1
    assert "point_soccer drives the point agent and soccer_v1 the ant" in " ".join(refused.output.split())


def test_build_reports_then_hits_cache(tmp_path):
    args = ["build", "point_soccer", "--out", str(tmp_path), "--no-preview"]
    first = runner.invoke(app, args)
    assert first.exit_code == 0, first.output
    assert "built point_soccer" in first.output and "contact pairs" in first.output
    assert (tmp_path / "point_soccer" / "scene.xml").is_file()
    second = runner.invoke(app, args)
    assert "cache hit point_soccer" in second.output



def test_build_where_a_file_stands_in_the_way_of_out_names_it_rather_than_space_or_permissions(tmp_path):
    (tmp_path / "afile").write_text("mine")
    result = runner.invoke(app, ["build", "point_nav", "--out", str(tmp_path / "afile" / "x"), "--no-preview"])
    said = " ".join(result.output.split())
    assert result.exit_code == 1 and f"{tmp_path / 'afile'} is a file, not a folder; move it aside or choose another " \
        "--out" in said and "free some space" not in said
    assert (tmp_path / "afile").read_text() == "mine"

def test_list_names_every_bundled_field():
    result = runner.invoke(app, ["list"])
    assert result.exit_code == 0
    for name in bundled_fields():
        assert name in result.output


def test_schema_is_json_schema_with_descriptions():
    result = runner.invoke(app, ["schema"])
    schema = json.loads(result.output)
    goal = schema["$defs"]["GoalSection"]["properties"]
    assert goal["width"]["description"] and goal["width"]["default"] == 4.0
    assert schema["additionalProperties"] is False


def test_render_top_and_follow(tmp_path):
    from fieldgen.render import LEGEND_HEIGHT

    images = {}
    for camera in ("top", "follow", "both"):
        out = tmp_path / f"{camera}.png"
        result = runner.invoke(app, ["render", "point_soccer", "-o", str(out), "--camera", camera])
        assert result.exit_code == 0, result.output
        images[camera] = iio.imread(out)
        assert images[camera].std() > 10  # a picture, not a blank frame
    top = images["top"].shape[1]
    # point_soccer is longer than wide; one view alone has the legend too, in more rows where it is narrow
    assert top < 480 and images["top"].shape[0] > 480 + LEGEND_HEIGHT and images["top"].shape[2] == 3
    assert images["follow"].shape == (480 + LEGEND_HEIGHT, 640, 3)
    assert images["both"].shape == (480 + LEGEND_HEIGHT, top + 640, 3)
    result = runner.invoke(app, ["render", "point_soccer", "--camera", "side"])
    assert result.exit_code == 1 and "unknown camera 'side'" in result.output


def test_render_refuses_a_file_name_that_says_another_format(tmp_path, monkeypatch):
    """A PNG written under .jpg or .txt would be read as something it is not."""
    monkeypatch.chdir(tmp_path)
    for name in ("sheet.jpg", "field.txt", "noending"):
        result = runner.invoke(app, ["render", "point_soccer", "-o", name])
        said = " ".join(result.output.split())
        assert result.exit_code == 1 and "writes PNG images" in said and not (tmp_path / name).exists(), said
        assert f"such as {Path(name).with_suffix('.png')}" in said


def test_the_gl_back_end_is_one_the_machine_has():
    from fieldgen import headless_gl

    assert headless_gl(lambda lib: f"lib{lib}.so.1") == "egl"
    assert headless_gl(lambda lib: "libOSMesa.so.8" if lib == "OSMesa" else None) == "osmesa"
    assert headless_gl(lambda lib: None) == "disable"  # mujoco still imports; only drawing fails


def test_a_mujoco_gl_that_would_break_mujocos_import_is_named_with_what_to_do(monkeypatch):
    from fieldgen import gl_problem

    egl_only = lambda lib: "libEGL.so.1" if lib == "EGL" else None  # noqa: E731
    assert gl_problem({}, egl_only, "Linux") is None  # fieldgen picks
    assert gl_problem({"MUJOCO_GL": "egl"}, egl_only, "Linux") is None
    assert gl_problem({"MUJOCO_GL": "glfw"}, egl_only, "Linux") is None  # imports; drawing says what is wrong
    missing = gl_problem({"MUJOCO_GL": "osmesa"}, egl_only, "Linux")
    assert "names OSMesa, whose library is not installed here" in missing and "apt install libosmesa6" in missing
    assert "set MUJOCO_GL=egl (installed here)" in missing and "unset MUJOCO_GL" in missing
    assert "no back end mujoco knows: set it to egl, osmesa, glfw, glx or disable" in gl_problem(
        {"MUJOCO_GL": "bogus"}, egl_only, "Linux")
    assert gl_problem({"MUJOCO_GL": "bogus"}, egl_only, "Darwin") is None  # mujoco's own values differ there
    monkeypatch.setenv("MUJOCO_GL", "bogus")  # a command says so before anything imports mujoco
    result = runner.invoke(app, ["validate", "point_nav"])
    assert result.exit_code == 1 and "MUJOCO_GL=bogus is no back end mujoco knows" in " ".join(result.output.split())


def test_a_machine_that_cannot_render_is_told_what_to_install(tmp_path, monkeypatch):
    import mujoco

    def no_opengl(*args, **kwargs):
        raise AttributeError("module 'mujoco.rendering.classic.gl_context' has no attribute 'GLContext'")

    monkeypatch.setattr(mujoco, "Renderer", no_opengl)
    monkeypatch.setenv("MUJOCO_GL", "disable")
    build = runner.invoke(app, ["build", "point_soccer", "--out", str(tmp_path)])
    assert build.exit_code == 1 and "Traceback" not in build.output
    assert "no EGL or OSMesa library was found" in build.output and "apt install libegl1" in build.output
    assert "fieldgen build point_soccer --no-preview" in build.output
    assert not (tmp_path / "point_soccer").exists()  # nothing half-built
    render = runner.invoke(app, ["render", "point_soccer", "-o", str(tmp_path / "x.png")])
    assert render.exit_code == 1 and "apt install libegl1" in render.output and not (tmp_path / "x.png").exists()


def test_every_command_has_help_with_an_example():
    for command in ("validate", "build", "render", "list", "schema", "bench", "train", "eval", "curriculum", "sweep"):
        result = runner.invoke(app, [command, "--help"])
        assert result.exit_code == 0 and "Example: fieldgen" in result.output


def test_counts_are_read_as_people_write_them(tmp_path):
    result = runner.invoke(app, ["train", "point_nav", "--steps", "50M", "--envs", "4", "--prepare",
                                 "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    config = json.loads((tmp_path / "point_nav-crl-0" / "run.json").read_text())["config"]
    assert (config["total_steps"], config["num_envs"]) == (50_000_000, 4)
    from fieldgen.counts import count

    assert count("1e15") == 10**15  # the largest, as docs/guarantees.md and the config's own range say
    with pytest.raises(ValueError, match=r"'1000000000000001' is not a positive whole count \(at most 1e\+15\)"):
        count("1000000000000001")
    for bad in ("5X", "0", "1.5", "-2M"):
        result = runner.invoke(app, ["train", "point_nav", "--steps", bad, "--prepare", "--out", str(tmp_path)])
        message = " ".join(result.output.split())
        assert result.exit_code == 2 and f"'{bad}' is not a positive whole count" in message, result.output
        assert "Traceback" not in result.output
    for bad in ("0", "-3"):
        result = runner.invoke(app, ["eval", str(tmp_path / "point_nav-crl-0"), "--episodes", bad])
        assert result.exit_code == 2 and f"'{bad}' is not a positive whole count" in " ".join(result.output.split())


def test_outputs_that_cannot_be_written_and_folders_that_are_not_fields_are_clear_errors(tmp_path):
    """A file where a folder should be: render and curriculum say what they could not write, and write
    nothing; compare says the folder it was given is not a built field."""
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    cases = [(["render", "point_nav", "-o", str(blocker / "x.png")], f"cannot write {blocker / 'x.png'}"),
             (["curriculum", "point_nav", "--stage", "task.target.radius=1", "--stage", "task.target.radius=2",
               "-o", str(blocker / "c")], f"cannot write {blocker / 'c'}"),
             (["compare", str(tmp_path)], f"{tmp_path} is not a built field")]
    for args, phrase in cases:
        result = runner.invoke(app, args)
        message = " ".join(result.output.split())
        assert result.exit_code == 1 and phrase in message and "Traceback" not in message, result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


def test_a_key_given_twice_in_one_stage_is_refused(tmp_path):
    """One --stage is one variant: a key twice in it cannot be an override, and the last was taken without a word."""
    result = runner.invoke(app, ["curriculum", "point_nav", "--stage", "task.target.radius=1 task.target.radius=2",
                                 "--stage", "task.target.radius=3", "-o", str(tmp_path / "out")])
    message = " ".join(result.output.split())
    assert result.exit_code != 0 and "Traceback" not in message, result.output
    assert "--stage 'task.target.radius=2': task.target.radius is given twice; give each key once" in message
    assert not (tmp_path / "out").exists()


def test_a_later_set_overrides_an_earlier_one(tmp_path):
    """A script's defaults, then the user's own --set: the later one wins, as the help says."""
    result = runner.invoke(app, ["train", "point_nav", "--set", "crl.batch_size=256", "--set", "crl.batch_size=128",
                                 "--prepare", "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert json.loads((tmp_path / "point_nav-crl-0" / "run.json").read_text())["config"]["batch_size"] == 128


def test_version_and_python_dash_m():
    from fieldgen.version import VERSION

    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0 and result.output.strip() == f"fieldgen {VERSION}"
    import subprocess
    import sys

    for module in ("fieldgen", "fieldgen.cli"):
        proc = subprocess.run([sys.executable, "-m", module, "--version"], capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0 and proc.stdout.strip() == f"fieldgen {VERSION}", proc.stderr


def test_help_reads_as_command_lines_do():
    """No Python types beside parameters: flags alone, values by metavar, choices listed."""
    import re

    from fieldgen.agents.registry import ALGORITHMS

    for command in ([], ["train"], ["eval"], ["render"], ["build"], ["curriculum"], ["compare"], ["bench"],
                    ["validate"], ["videos"], ["sweep"]):
        result = runner.invoke(app, [*command, "--help"], env={"COLUMNS": "200"})
        assert result.exit_code == 0, result.output
        assert not re.search(r"<(bool|str|int|float|path|list\[\w+\])>", result.output), result.output
    train = runner.invoke(app, ["train", "--help"], env={"COLUMNS": "200"}).output
    assert re.search(rf"--algo +{re.escape('|'.join(ALGORITHMS))} ", train) and re.search(r"--set +KEY=VALUE ", train)
    assert re.search(r"--seed +SEED ", train) and re.search(r"--videos +--no-videos +write", train)
    assert "[SPEC]" in train
    render = runner.invoke(app, ["render", "--help"], env={"COLUMNS": "200"}).output
    assert re.search(r"--camera +top\|follow\|both ", render)
    root = runner.invoke(app, ["--help"], env={"COLUMNS": "200"}).output
    assert "--install-completion" in root and "--version" in root


def test_help_fits_a_terminal_of_80_columns():
    """Each option's help wraps beside it at word boundaries with room to read, a choice is never split, the
    examples stay whole on their lines and the prose wraps to the terminal."""
    for command in (["train"], ["eval"], ["compare"], ["curriculum"], ["sweep"], []):
        result = runner.invoke(app, [*command, "--help"], env={"COLUMNS": "80"})
        assert result.exit_code == 0, result.output
        lines = result.output.splitlines()
        assert all(len(line) <= 80 for line in lines if not line.lstrip().startswith("Example:")), result.output
    train = runner.invoke(app, ["train", "--help"], env={"COLUMNS": "80"}).output
    assert re.search(r"--logger none\|tensorboard\|wandb\n", train), train
    assert re.search(r"--init-from RUN +start from the networks another run learned\n", train), train
    assert "  Example: fieldgen train soccer_v2 --init-from runs/soccer_v1-crl-0 --seed 1\n" in train
    assert "  Resumes exactly after an interrupt (--resume). A curriculum run moves to the\n  next stage" in train
    wide = runner.invoke(app, ["train", "--help"], env={"COLUMNS": "200"}).output
    assert "A curriculum run moves to the next stage when its promotion rule is met and reports" in wide


def test_help_gives_the_defaults_of_steps_and_envs_the_configs_hold():
    """--help loads no trainer, so it says them in words: checked here against the configs."""
    from fieldgen.agents.registry import ALGORITHMS, trainer
    from fieldgen.cli.training import ENVS, STEPS

    defaults = {a: (trainer(a).config().total_steps, trainer(a).config().num_envs) for a in ALGORITHMS}
    assert defaults == {a: (50_000_000, 2048) if a == "ppo" else (10_000_000, 1024) for a in ALGORITHMS}
    assert {(c.total_steps, c.num_envs) for c in (trainer(a).config.layered(preset="cpu") for a in ALGORITHMS)} == \
        {(200_000, 16)}
    assert (STEPS, ENVS) == ("[default: 10M, ppo 50M; --preset cpu 200k]", "[default: 1024, ppo 2048; --preset cpu 16]")
    train = " ".join(runner.invoke(app, ["train", "--help"], env={"COLUMNS": "80"}).output.split())
    assert f"2e6 {STEPS}" in train and f"parallel environments {ENVS}" in train


def test_choices_are_checked_before_anything_loads_and_complete_in_the_shell():
    import subprocess
    import sys

    from fieldgen import render
    from fieldgen.agents.registry import ALGORITHMS
    from fieldgen.cli.training import CAMERAS

    assert CAMERAS == render.CAMERAS
    bad = runner.invoke(app, ["eval", "no/such/run", "--camera", "side"])
    assert bad.exit_code == 1 and "unknown camera 'side'. Choose one of: top, follow." in bad.output
    assert "no/such/run" not in bad.output  # refused before the run folder is looked at
    env = {"COMP_WORDS": "fieldgen train --algo ", "COMP_CWORD": "3", "_FIELDGEN_COMPLETE": "complete_bash"}
    code = "from fieldgen.cli import app; app(prog_name='fieldgen')"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**__import__("os").environ, **env})
    assert proc.stdout.split() == list(ALGORITHMS), proc.stderr


def test_the_algorithm_choices_are_the_trainers_registry():
    """--algo offers, completes and checks exactly the algorithms the registry can load."""
    from fieldgen.agents import registry
    from fieldgen.agents.config import RunConfig

    def subclasses(cls):
        return [c for sub in cls.__subclasses__() for c in (sub, *subclasses(sub))]

    import typing

    train = next(c for c in app.registered_commands if c.callback.__name__ == "train").callback
    (option,) = typing.get_type_hints(train, include_extras=True)["algo"].__metadata__
    assert option.metavar == "|".join(registry.ALGORITHMS)
    configs = {c.algo: c for c in subclasses(RunConfig) if "algo" in vars(c)}
    assert sorted(registry.ALGORITHMS) == sorted(configs)
    for name in registry.ALGORITHMS:
        assert registry.trainer(name).config is configs[name] and callable(registry.trainer(name).make_train)
    bad = runner.invoke(app, ["train", "point_nav", "--algo", "tdd3"])
    assert bad.exit_code == 1 and "unknown algorithm 'tdd3'; did you mean 'td3'? Choose one of: " \
        f"{', '.join(registry.ALGORITHMS)}." in " ".join(bad.output.split()), bad.output


def test_the_command_line_starts_without_jax():
    """--help, completion and the choices need no trainer, physics or renderer: none of them is imported."""
    import subprocess
    import sys

    code = ("import sys\nfrom fieldgen.cli import app\n"
            "for args in (['--help'], ['train', '--help'], ['compare', '--help'], ['render', '--help'],\n"
            "             ['sweep', '--help']):\n"
            "    try:\n        app(args, prog_name='fieldgen')\n    except SystemExit:\n        pass\n"
            "print(' '.join(m for m in ('jax', 'mujoco', 'dm_control', 'brax') if m in sys.modules) or 'none')\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[-1] == "none", proc.stdout[-500:]


def test_a_video_format_this_machine_cannot_write_is_refused_before_anything_loads(tmp_path, monkeypatch):
    import imageio_ffmpeg

    def missing():
        raise RuntimeError("No ffmpeg exe could be found")

    monkeypatch.setattr(imageio_ffmpeg, "get_ffmpeg_exe", missing)
    for args in (["train", "point_nav", "--out", str(tmp_path)], ["eval", str(tmp_path / "run")],
                 ["videos", str(tmp_path / "run")]):
        result = runner.invoke(app, [*args, "--video-format", "mp4"])
        assert result.exit_code == 1 and "Traceback" not in result.output, result.output
        assert "mp4 videos need imageio-ffmpeg's encoder" in result.output and "--video-format gif" in result.output
    assert not any(tmp_path.iterdir())  # no run folder begun
    unknown = runner.invoke(app, ["videos", str(tmp_path), "--video-format", "avi"])
    assert unknown.exit_code == 1 and "unknown video format 'avi'. Choose one of: mp4, gif." in unknown.output


def test_validate_says_when_a_moved_goal_leaves_a_wall_across_the_goal_line(write_spec):
    """soccer_v2 with its goal moved to 15 ahead keeps a front wall across the whole field at 20: it validates,
    and validate now says so (before: a bare "ok")."""
    moved = write_spec("extends: soccer_v2\nname: moved\ngoal: {distance: 15}\n")
    result = runner.invoke(app, ["validate", str(moved), "soccer_v2"])
    message = "".join(result.output.split())  # the console may fold a long path anywhere: compare without spaces
    said = (f"ok {moved}: moved note: the goal stands 15 ahead, off the goal line at 20, so the front wall there runs "
            "the field's whole width with no mouth in it; to play into a goal on the goal line, set goal.distance: 20 "
            "(or field.length: 30); for no wall there, walls.front: false")
    assert result.exit_code == 0 and "".join(said.split()) in message
    assert message.endswith("oksoccer_v2:soccer_v2")  # its goal is on the goal line: nothing to say


def test_a_child_fieldgen_started_in_a_checkout_runs_the_installed_package(tmp_path):
    """A sweep's runs and a run's supervised processes start `fieldgen` as a child; from a checkout's top
    folder its own fieldgen/ (no fieldgen.agents there) must not shadow the installed package."""
    import subprocess

    from fieldgen.command import fieldgen_command

    shadow = tmp_path / "fieldgen"
    shadow.mkdir()
    (shadow / "__init__.py").write_text("raise ImportError('the checkout was imported, not the package')\n")
    done = subprocess.run(fieldgen_command("--version"), cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "the checkout was imported" not in done.stderr, done.stderr


TOO_LONG = "q" * 5000  # longer than any file system takes for a name


@pytest.mark.parametrize("command", [
    ["validate", f"{TOO_LONG}.yaml"], ["build", TOO_LONG], ["train", f"{TOO_LONG}.yaml"],
    ["train", "--resume", TOO_LONG],
    ["eval", TOO_LONG], ["render", f"{TOO_LONG}.yaml"], ["validate", "loop.yaml"], ["build", "loop.yaml"]])
def test_a_path_the_system_refuses_is_one_line_naming_it(tmp_path, monkeypatch, command):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "loop.yaml").symlink_to("loop.yaml")  # a link to itself: no file behind it
    result = runner.invoke(app, command)
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output[-2000:]
    (line,) = result.output.strip().splitlines()
    said = "q" * 280 + "... (5,00" if TOO_LONG in command[-1] else "loop.yaml: Too many levels of symbolic links"
    assert line.startswith("error: ") and said in line and len(line) < 500, line
    assert ("choose a shorter one" in line) == (TOO_LONG in command[-1])  # the limit named where it was the cause


DIGITS = "9" * 5000
SHOWN = shown_text(DIGITS)  # as a message echoes it: '9999... (5,000 characters)'


@pytest.mark.parametrize("args,phrase", [
    (["train", "point_soccer", "--curriculum", "auto", "--levels", "1e20"], "--levels 1e20: the automatic "
                                                                            "curriculum's levels"),
    (["train", "point_soccer", "--curriculum", "auto", "--levels", "1000000"], "is a whole number from 2 to 64"),
    (["train", "point_nav", "--num-processes", "99999999999"], "--num-processes 99999999999: the processes of one "
                                                               "run is a whole number from 1 to 65,536"),
    (["train", "point_nav", "--coordinator-timeout", "99999999999"], "--coordinator-timeout 99999999999: the seconds "
                                                                     "to wait"),
    (["train", "point_nav", "--process-id", "-1"], "--process-id -1: a process's id"),
    (["train", "point_nav", "--seed", "2.5"], "--seed 2.5: a seed (a random key takes 32 bits) is a whole number "
                                              "from 0 to 4,294,967,295"),
    (["train", "point_nav", "--seeds", "0"], "--seeds 0: seeds trained at once is a whole number from 1 to 65,536"),
    (["compare", "point_nav", "--seeds", "1e9"], "--seeds 1e9: seeds trained at once"),
    (["eval", "runs/none", "--seed", "-1"], "--seed -1: a seed"),
    (["export", "runs/none", "-o", "x", "--seed", DIGITS], f"--seed {SHOWN}: a seed"),
    (["curriculum", "point_nav", "--to", "point_nav", "--stages", "99999999999", "-o", "c"], "--stages 99999999999: "
                                                                                               "a curriculum's stages"),
    (["curriculum", "point_nav", "--to", "point_nav", "--then", "point_nav", "--then-stages", "99999999999", "-o", "c"],
     "--then-stages 99999999999: the stages each --then adds is a whole number from 1 to 1,000"),
    (["bench", "point_nav", "--steps", "1e14"], "--steps 1e14: the steps of a timed rollout"),
    (["train", "point_soccer", "--curriculum", "auto", "--sampler", f"prior={DIGITS}"],
     f"--sampler prior={shown_value(DIGITS)}: prior must be at most 1,000"),
    (["train", "point_nav", "--set", f"crl.repr_dim={DIGITS}"], "is not a YAML value: a number of 5,000 digits; a "
                                                                "number here has at most 100"),
])
def test_every_number_is_checked_against_its_stated_range_before_work_starts(tmp_path, monkeypatch, args, phrase):
    """A number past its range (fieldgen.limits) is one line stating the range, before anything is written or
    waited for: never a traceback, a preparation without end, or a wait of three thousand years."""
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, [*args, *(["--prepare"] if args[0] == "train" else [])])
    said = result.output[result.output.find("error:"):]  # after any line on the recipe a run starts from
    message = " ".join(said.split())
    assert result.exit_code == 1 and message.startswith("error:") and phrase in message, result.output
    assert len(said.strip().splitlines()) <= 3 and "Traceback" not in result.output and len(message) < 600
    assert not any(tmp_path.iterdir())  # nothing written



def test_a_number_a_launchers_variable_holds_is_named_by_the_variable(tmp_path, monkeypatch):
    """FIELDGEN_NUM_PROCESSES=abc, which a job script set, was said as --num-processes abc, a flag never typed."""
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["train", "point_nav", "--prepare"], env={"FIELDGEN_NUM_PROCESSES": "abc"})
    assert result.exit_code == 1 and "FIELDGEN_NUM_PROCESSES=abc (--num-processes): the processes of one run is a " \
        "whole number" in " ".join(result.output.split()), result.output
    assert not any(tmp_path.iterdir())

def test_bench_of_a_curriculum_or_run_folder_names_what_it_is_and_the_field_to_give(tmp_path):
    """Read as a build folder, either was one whose field.json is missing, to be built with `fieldgen build`."""
    made = runner.invoke(app, ["curriculum", "point_nav", "--vary", "field.length=10,12", "-o", str(tmp_path / "c")])
    assert made.exit_code == 0, made.output
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text("{}")
    for folder, phrase in ((tmp_path / "c", f"{tmp_path / 'c'} is a curriculum folder: fieldgen bench takes one field, "
                                            f"such as one of its stages"),
                           (run, f"{run} is a run folder, not a field: fieldgen bench takes one field (a YAML file, "
                                 f"bundled name or build folder); the field that run trained on is its copy {run / 'field'}")):
        result = runner.invoke(app, ["bench", str(folder)])
        message = " ".join(result.output.split())
        assert result.exit_code == 1 and message.startswith(f"error: {phrase}"), result.output
        assert "fieldgen build" not in message


def test_a_number_of_thousands_of_digits_in_a_spec_is_refused_at_its_line(write_spec):
    spec = write_spec(f"extends: point_nav\nname: big\nfield: {{length: {DIGITS}}}\n")
    result = runner.invoke(app, ["validate", str(spec)])
    assert result.exit_code == 1 and f"{spec}:3:17: a number of 5,000 digits; a number here has at most 100" in \
        " ".join(result.output.split()) and "Traceback" not in result.output, result.output
    steps = runner.invoke(app, ["train", "point_nav", "--steps", DIGITS, "--prepare"])
    assert steps.exit_code == 2 and "(5,000 characters)' is not a positive whole count" in steps.output, steps.output


def test_levels_of_a_field_rather_than_a_run_says_what_it_draws(tmp_path):
    result = runner.invoke(app, ["render", "point_nav", "--levels", "-o", str(tmp_path / "a.png")])
    said = " ".join(result.output.split())
    assert result.exit_code == 1 and "point_nav is a field, not a run folder: fieldgen render RUN --levels" in said
    assert "is missing" not in said and not (tmp_path / "a.png").exists()


def test_a_printed_command_names_a_folder_with_spaces_or_a_leading_dash_as_a_shell_reads_it(tmp_path):
    """The commands fieldgen prints to go on are pasted into a shell: a folder named 'my runs' or '-cu' is quoted
    (or led by ./) so that the pasted command names it (before: 'fieldgen train --resume my runs/...' gave two
    arguments, and 'fieldgen build -cu' an unknown option)."""
    import shlex

    runs = tmp_path / "my runs é"
    result = runner.invoke(app, ["train", "point_nav", "--out", str(runs), "--prepare"])
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())
    pasted = shlex.split(said.split("start it with: ", 1)[1])
    assert pasted == ["fieldgen", "train", "--resume", str(runs / "point_nav-crl-0")], said
    from fieldgen.suggest import shell

    assert shlex.split(shell("-cu")) == ["./-cu"] and shell("runs/a") == "runs/a"


@pytest.mark.parametrize("argv,said", [
    (["validate", ""], "word 2 of the command line after fieldgen is empty (''), as a shell variable unset or empty "
                       "gives it (fieldgen validate \"$VAR\"); give the name or path it stands for"),
    (["train", "--no-videos", ""], "word 3 of the command line after fieldgen is empty"),  # a flag takes no value
    (["train", "point_nav", "--out", ""], "--out is given an empty value (''), as a shell variable unset or empty "
                                          "gives it (--out \"$VAR\"); give it the value it stands for"),
    (["eval", "runs/x", "--summary="], "--summary is given an empty value"),
    (["train", "point_nav", "--set", "crl.repr_dim="], None),  # an empty value of a key is the config's to judge
    (["train", "point_nav", "--bogus", ""], None),  # an option the command lacks: click's own error names it
])
def test_an_empty_word_on_the_command_line_is_named_where_a_path_read_it_as_this_folder(argv, said):
    """`fieldgen train "$FIELD"` with FIELD unset gave '', which a path reads as '.': errors then spoke of '.'."""
    from fieldgen.cli.app import empty_argument

    assert empty_argument(argv) == said if said is None or said.endswith("stands for") else said in empty_argument(argv)


def test_the_installed_command_refuses_an_empty_word_before_it_starts():
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "fieldgen", "eval", ""], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and proc.stderr.startswith("error: word 2 of the command line after fieldgen is empty")
