"""What fieldgen may do to folders: replace only what it wrote, one writer at a time, and every replace whole
or not at all, whatever stops the process."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fieldgen import files
from fieldgen.cli import app

runner = CliRunner()
BUILD = files.Output("fieldgen build", ("scene.xml", "field.json", "preview.png"), "field.json", record_keys=("spec",))
POLICY = files.Output("fieldgen export", ("policy.json", "params.msgpack"), "policy.json", "-o",
                      record_keys=("observation_names",))


def listing(folder: Path) -> dict[str, bytes]:
    """Every file under `folder` (hidden ones included) with its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def fill_with(**contents: str):
    def fill(staging: Path) -> None:
        for name, text in contents.items():
            (staging / name).write_text(text)
    return fill


def one_line(output: str) -> str:
    return " ".join(output.split())


# -- 1. fieldgen replaces only what it wrote ---------------------------------------------------------------

# the records of folders written before ownership records were kept, as fieldgen wrote them (their keys)
EARLIER_POLICY = '{"algorithm": "crl", "observation_names": ["x"]}'
EARLIER_RUN = '{"algo": "crl", "config": {}, "seeds": [0]}'

@pytest.mark.parametrize("make,phrase", [
    (lambda f: (f.mkdir(), (f / "notes.txt").write_text("mine")),
     "is not a folder fieldgen export wrote (it holds notes.txt); fieldgen replaces only what it wrote itself"),
    (lambda f: (f.mkdir(), (f / "sub").mkdir(), (f / "a").write_text(""), (f / "b").write_text(""),
                (f / "c").write_text("")), "(it holds a, b, c and 1 more)"),
    (lambda f: f.write_text("a file of mine"), "is a file, not a folder fieldgen export wrote"),
    (lambda f: (f.with_name("target").mkdir(), (f.with_name("target") / "x").write_text("x"),
                f.symlink_to(f.with_name("target"))), "is a link, not a folder fieldgen export wrote"),
    (lambda f: (f.mkdir(), (f / "policy.json").write_text(EARLIER_POLICY), (f / "README.md").write_text("mine")),
     "holds README.md, which fieldgen export did not write; it replaces the folder whole, so move that out"),
    (lambda f: (f.mkdir(), (f / "policy.json").write_text('{"mine": 1}')),
     "is not a folder fieldgen export wrote (it holds policy.json)"),
    (lambda f: (f.mkdir(), files.mark(f, BUILD), (f / "scene.xml").write_text("<mujoco/>")),
     "was written by fieldgen build, not fieldgen export"),
], ids=["user_folder", "many_files", "file", "link", "added_file", "users_file_of_the_records_name",
        "other_kind"])
def test_a_folder_fieldgen_did_not_write_is_refused_and_kept(tmp_path, make, phrase):
    folder = tmp_path / "out"
    make(folder)
    before = listing(tmp_path)
    with pytest.raises(files.NotOurs) as caught:
        files.replace_folder(folder, fill_with(**{"policy.json": "new"}), POLICY)
    assert phrase in str(caught.value) and str(caught.value).startswith(str(folder))
    assert listing(tmp_path) == before and sorted(p.name for p in tmp_path.iterdir()) == sorted(
        p.name for p in tmp_path.iterdir() if not p.name.startswith("."))


@pytest.mark.parametrize("make", [
    lambda f: None,
    lambda f: f.mkdir(),
    lambda f: (f.mkdir(), (f / "policy.json").write_text(EARLIER_POLICY), (f / "params.msgpack").write_text("old")),
    lambda f: (f.mkdir(), files.mark(f, POLICY), (f / "policy.json").write_text("old")),
], ids=["absent", "empty", "written_before_records", "ours"])
def test_what_fieldgen_wrote_is_replaced_and_marked_as_its_own(tmp_path, make):
    folder = tmp_path / "out"
    make(folder)
    files.replace_folder(folder, fill_with(**{"policy.json": "new"}), POLICY)
    assert sorted(p.name for p in folder.iterdir()) == [files.OWNER, "policy.json"]
    assert (folder / "policy.json").read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    files.replace_folder(folder, fill_with(**{"policy.json": "newer"}), POLICY)  # its own record: again
    assert (folder / "policy.json").read_text() == "newer"


def test_build_into_a_users_folder_is_refused_in_one_paragraph(tmp_path):
    """`fieldgen build --out DIR` where DIR/<name> is a folder of the user's: refused before compiling."""
    mine = tmp_path / "point_nav"
    mine.mkdir()
    (mine / "todo.txt").write_text("mine")
    result = runner.invoke(app, ["build", "point_nav", "--out", str(tmp_path), "--no-preview"])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert f"{mine} is not a folder fieldgen build wrote (it holds todo.txt)" in one_line(result.output)
    assert listing(tmp_path) == {"point_nav/todo.txt": b"mine"}


def test_curriculum_force_over_a_users_folder_is_refused(tmp_path):
    """`--force` replaces a curriculum fieldgen wrote; a folder of the user's is refused with or without it, and
    a curriculum folder the user put a file of their own into is kept whole."""
    stages = ["--stage", "task.target.radius=1", "--stage", "task.target.radius=2"]
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    for force in ([], ["--force"]):
        result = runner.invoke(app, ["curriculum", "point_nav", *stages, "-o", str(mine), *force])
        assert result.exit_code == 1 and "is not a folder fieldgen curriculum wrote (it holds notes.txt)" in \
            one_line(result.output), result.output
    assert listing(mine) == {"notes.txt": b"mine"}
    ours = tmp_path / "ours"
    assert runner.invoke(app, ["curriculum", "point_nav", *stages, "-o", str(ours)]).exit_code == 0
    (ours / "sheet.png").write_bytes(b"drawn by the user")
    result = runner.invoke(app, ["curriculum", "point_nav", *stages, "-o", str(ours), "--force"])
    assert result.exit_code == 1 and "holds sheet.png, which fieldgen curriculum did not write" in one_line(result.output)
    assert (ours / "sheet.png").read_bytes() == b"drawn by the user"


def test_train_into_a_users_folder_of_the_runs_name_is_refused(tmp_path, tiny_crl_args):
    mine = tmp_path / "point_nav-crl-0"
    mine.mkdir()
    (mine / "metrics.jsonl").write_text("my own numbers\n")
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--prepare", *tiny_crl_args])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert f"{mine} is not a folder fieldgen train wrote (it holds metrics.jsonl)" in one_line(result.output)
    assert listing(tmp_path) == {"point_nav-crl-0/metrics.jsonl": b"my own numbers\n"}


def test_a_single_file_is_replaced_only_where_the_same_command_wrote_it(tmp_path):
    """Before: every command wrote its files over whatever was there (a user's image, another command's summary)."""
    mine, ours = tmp_path / "mine.png", tmp_path / "ours.png"
    mine.write_bytes(b"drawn by the user")
    with pytest.raises(files.NotOurs, match=f"{mine} is not a file fieldgen wrote; fieldgen replaces only what it "
                                            "wrote itself: move it aside or choose another -o"):
        files.write_file(mine, b"render", files.RENDER)
    files.write_file(ours, b"first", files.RENDER)
    files.write_file(ours, b"second", files.RENDER)  # its own: replaced
    assert ours.read_bytes() == b"second" and mine.read_bytes() == b"drawn by the user"
    with pytest.raises(files.NotOurs, match=f"{ours} was written by fieldgen render, not fieldgen eval"):
        files.write_file(ours, b"{}", files.EVAL)
    (tmp_path / "folder.png").mkdir()
    with pytest.raises(files.NotOurs, match="is a folder, not a file fieldgen render wrote"):
        files.write_file(tmp_path / "folder.png", b"", files.RENDER)
    # a folder marked keeps its files' record
    files.mark(tmp_path, files.Output("fieldgen build", (), "field.json", record_keys=("spec",)))
    files.write_file(ours, b"third", files.RENDER)
    assert ours.read_bytes() == b"third" and list(tmp_path.glob(".*.tmp")) == []


def test_a_file_changed_since_fieldgen_wrote_it_is_the_users(tmp_path):
    """Before: a figure fieldgen wrote, then replaced by the user's own of the same name (or edited), was written
    over, the record saying only which command had written that name."""
    ours = tmp_path / "compare.png"
    files.write_file(ours, [b"fieldgen's ", b"figure"], files.RENDER)  # written in pieces, digested whole
    files.write_file(ours, b"again", files.RENDER)  # unchanged since: replaced
    ours.write_bytes(b"the user's own figure")
    with pytest.raises(files.NotOurs, match=f"{ours} has changed since fieldgen render wrote it"):
        files.check_file(ours, files.RENDER)
    with pytest.raises(files.NotOurs, match="has changed since"):
        files.write_file(ours, b"render", files.RENDER)
    assert ours.read_bytes() == b"the user's own figure"
    # a record kept before digests were: the command's name alone, as before
    record = json.loads((tmp_path / files.OWNER).read_text())
    del record["digests"]
    (tmp_path / files.OWNER).write_text(json.dumps(record))
    files.write_file(ours, b"render", files.RENDER)
    assert ours.read_bytes() == b"render"


def test_a_runs_own_files_and_a_sweeps_summary_are_no_other_commands(tmp_path):
    """Before: `fieldgen eval` wrote its summary over a sweep's summary.json beside the runs, or over a run's
    run.json given as --summary."""
    from fieldgen.run import record

    run = tmp_path / "point_nav-crl-0"
    run.mkdir()
    files.mark(run, record.RUN_FOLDER)
    (run / "run.json").write_text("{}")
    (run / "metrics.jsonl").write_text("")
    for name in ("run.json", "metrics.jsonl"):
        with pytest.raises(files.NotOurs, match=f"{run / name} was written by fieldgen train, not fieldgen eval"):
            files.check_file(run / name, files.EVAL)
    files.write_file(run / "summary.json", b"{}", files.EVAL)
    files.write_file(run / "summary.json", b"{}", files.EVAL)
    files.write_file(tmp_path / "summary.json", b"{}", files.SWEEP)
    with pytest.raises(files.NotOurs, match="summary.json was written by fieldgen sweep, not fieldgen eval"):
        files.check_file(tmp_path / "summary.json", files.EVAL)


def test_files_written_before_records_listed_them_stay_fieldgens(tmp_path):
    """A run folder whose record names no files (an earlier fieldgen), or that has no record, keeps eval's
    summary.json and render's levels.png as theirs; a sweep folder with no record, its summary beside its
    sweep.json."""
    run, sweep = tmp_path / "run", tmp_path / "sweep"
    run.mkdir()
    sweep.mkdir()
    (run / files.OWNER).write_text('{"written_by": "fieldgen train", "fieldgen_version": "0.1.0"}\n')
    for name in ("run.json", "summary.json", "levels.png", "notes.png"):
        (run / name).write_text("earlier")
    for name in ("sweep.json", "summary.json", "summary.md"):
        (sweep / name).write_text('{"runs": []}' if name == "sweep.json" else "earlier")
    assert [files.writer_of(run / n) for n in ("run.json", "summary.json", "levels.png", "notes.png")] == \
        ["fieldgen train", "fieldgen eval", "fieldgen render", None]
    files.write_file(run / "summary.json", b"{}", files.EVAL)
    files.write_file(sweep / "sweep.json", b"{}", files.SWEEP)  # the record made now lists the summary too
    files.write_file(sweep / "summary.md", b"table", files.SWEEP)
    with pytest.raises(files.NotOurs, match="notes.png is not a file fieldgen wrote"):
        files.write_file(run / "notes.png", b"", files.RENDER)
    oldest = tmp_path / "oldest"  # a run folder from before any record: its run.json tells its kind
    oldest.mkdir()
    for name in ("run.json", "summary.json", "notes.json"):
        (oldest / name).write_text(EARLIER_RUN if name == "run.json" else "earlier")
    assert [files.writer_of(oldest / n) for n in ("run.json", "summary.json", "notes.json")] == \
        ["fieldgen train", "fieldgen eval", None]


@pytest.mark.parametrize("record", ["{}", '{"my": "notes"}', "[]", "not json", '{"algo": "crl"}'])
def test_a_users_file_of_a_records_name_marks_no_folder_as_fieldgens(tmp_path, record):
    """A folder without an ownership record counts as an earlier fieldgen's only where its record file holds what
    that command writes there: a run.json of the user's beside their summary.json leaves the summary theirs."""
    folder = tmp_path / "project"
    folder.mkdir()
    (folder / "run.json").write_text(record)
    (folder / "summary.json").write_text('{"my": "summary"}')
    assert files.writer_of(folder / "summary.json") is None and files.writer_of(folder / "run.json") is None
    with pytest.raises(files.NotOurs, match="summary.json is not a file fieldgen wrote"):
        files.write_file(folder / "summary.json", b"{}", files.EVAL)
    assert (folder / "summary.json").read_text() == '{"my": "summary"}' and not (folder / files.OWNER).exists()


def test_render_replaces_its_own_image_and_refuses_a_users(tmp_path, monkeypatch):
    """Before: `fieldgen render -o` and `render --levels` wrote over a user's image (levels.png in a run folder)."""
    from fieldgen.run import record

    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.png").write_bytes(b"drawn by the user")
    result = runner.invoke(app, ["render", "point_nav", "-o", "mine.png"])
    assert result.exit_code == 1 and one_line(result.output) == ("error: mine.png is not a file fieldgen wrote; "
                                                                 "fieldgen replaces only what it wrote itself: move it "
                                                                 "aside or choose another -o"), result.output
    assert (tmp_path / "mine.png").read_bytes() == b"drawn by the user"
    for _ in range(2):
        result = runner.invoke(app, ["render", "point_nav"])
        assert result.exit_code == 0 and (tmp_path / "field.png").read_bytes()[:4] == b"\x89PNG", result.output
    run = tmp_path / "point_nav-crl-0"
    run.mkdir()
    files.mark(run, record.RUN_FOLDER)
    (run / "levels.png").write_bytes(b"the user's")
    result = runner.invoke(app, ["render", str(run), "--levels"])
    assert result.exit_code == 1 and f"error: {run / 'levels.png'} is not a file fieldgen wrote" in \
        one_line(result.output), result.output
    assert (run / "levels.png").read_bytes() == b"the user's"


def test_a_sweep_whose_out_reaches_a_users_folder_is_refused_before_anything_trains(tmp_path):
    """Before: the sweep trained its runs, then wrote its summary over the user's summary.md and summary.json."""
    mine = tmp_path / "notes"
    mine.mkdir()
    (mine / "summary.md").write_text("my notes")
    path = tmp_path / "sweep.yaml"
    path.write_text(f"fields: [point_nav]\nalgorithms: [crl]\nseeds: 1\nsteps: 14000\nenvs: 8\nout: {mine}\n")
    for status in ([], ["--status"]):
        result = runner.invoke(app, ["sweep", str(path), *status])
        assert result.exit_code == 1 and one_line(result.output) == (
            f"error: {mine / 'summary.md'} is not a file fieldgen wrote; fieldgen replaces only what it wrote "
            "itself: move it aside or choose another out: (or --out)"), result.output
    assert listing(mine) == {"summary.md": b"my notes"}


def test_eval_writes_no_summary_over_a_sweeps_or_a_runs_own_files(tmp_path, monkeypatch):
    """Before: `fieldgen eval` of a sweep's runs wrote over the sweep's summary.json beside them, and --summary
    RUN/run.json replaced the run's record."""
    from types import SimpleNamespace

    from fieldgen.run import evaluate, record

    runs = [tmp_path / f"point_nav-crl-{seed}" for seed in (0, 1)]
    for run in runs:
        run.mkdir()
        files.mark(run, record.RUN_FOLDER)
        (run / "run.json").write_text("{}")
    files.write_file(tmp_path / "summary.json", b"the sweep's", files.SWEEP)
    opened = SimpleNamespace(config=SimpleNamespace(eval_envs=8, eval_actions="mean"),
                             env=SimpleNamespace(spec=SimpleNamespace(name="point_nav")), judged=None)
    monkeypatch.setattr(evaluate, "open_runs", lambda folders, field: [opened] * len(folders))
    monkeypatch.setattr(evaluate, "check_memory", lambda run, episodes: None)
    monkeypatch.setattr(evaluate, "evaluate", lambda *a, **k: pytest.fail("evaluated before refusing"))
    result = runner.invoke(app, ["eval", *map(str, runs), "--no-video"])
    assert result.exit_code == 1 and one_line(result.output) == (
        f"error: {tmp_path / 'summary.json'} was written by fieldgen sweep, not fieldgen eval; it replaces only its "
        "own files: move it aside or choose another --summary"), result.output
    result = runner.invoke(app, ["eval", str(runs[0]), "--no-video", "--summary", str(runs[0] / "run.json")])
    assert result.exit_code == 1 and f"{runs[0] / 'run.json'} was written by fieldgen train, not fieldgen eval" in \
        one_line(result.output), result.output
    assert (tmp_path / "summary.json").read_bytes() == b"the sweep's" and (runs[0] / "run.json").read_text() == "{}"


# -- 2. one writer at a time -------------------------------------------------------------------------------

HOLDER = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    from fieldgen import files
    files.take(Path(sys.argv[1]))
    print("held", flush=True)
    time.sleep(60)
""")


@pytest.fixture
def held(tmp_path):
    """held(folder) -> a process of its own that locked `folder` (as a fieldgen command writing it does)."""
    started = []

    def hold(folder: Path) -> subprocess.Popen:
        process = subprocess.Popen([sys.executable, "-c", HOLDER, str(folder), "hold"], stdout=subprocess.PIPE,
                                   text=True)
        started.append(process)
        assert process.stdout.readline() == "held\n"
        return process

    yield hold
    for process in started:
        process.kill()
        process.wait()


def in_use(folder: Path, process: subprocess.Popen) -> str:
    return f"{folder} is in use by process {process.pid} since "


@pytest.mark.parametrize("command,folder", [
    (["build", "point_nav", "--out", "{tmp}", "--no-preview"], "point_nav"),
    (["curriculum", "point_nav", "--stage", "task.target.radius=1", "--stage", "task.target.radius=2", "-o",
      "{tmp}/c"], "c"),
    (["train", "point_nav", "--out", "{tmp}", "--prepare", "{tiny}"], "point_nav-crl-0"),
], ids=["build", "curriculum", "train"])
def test_a_folder_another_process_writes_is_refused_and_left_alone(tmp_path, held, command, folder, tiny_crl_args):
    process = held(tmp_path / folder)
    args = [a.replace("{tmp}", str(tmp_path)) for a in command]
    result = runner.invoke(app, [x for a in args for x in (tiny_crl_args if a == "{tiny}" else [a])])
    message = one_line(result.output)
    assert result.exit_code == 1 and "Traceback" not in message, result.output
    assert in_use(tmp_path / folder, process) in message and "-c" in message and "wait for that one to end" in message
    assert not (tmp_path / folder).exists()


def test_two_trainings_of_one_run_folder_are_one_at_a_time(tmp_path, held, tiny_crl_args):
    """The second `fieldgen train` of a run folder (a new run of other settings, or --resume) is refused while
    the first holds it, and writes nothing there; once the first is killed, its lock is gone."""
    prepared = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--prepare", *tiny_crl_args])
    assert prepared.exit_code == 0, prepared.output
    run = tmp_path / "point_nav-crl-0"
    before = listing(run)
    process = held(run)
    for command in (["train", "--resume", str(run), "--no-videos"],
                    ["train", "point_nav", "--out", str(tmp_path), "--prepare", *tiny_crl_args, "--set", "crl.repr_dim=16"]):
        result = runner.invoke(app, command)
        assert result.exit_code == 1 and in_use(run, process) in one_line(result.output), result.output
        assert listing(run) == before
    process.kill()
    process.wait()
    again = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--prepare", *tiny_crl_args,
                                "--set", "crl.repr_dim=16"])
    assert again.exit_code == 0, again.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["point_nav-crl-0"]  # no lock file left


def test_a_lock_is_recovered_from_a_killed_holder_and_nests_in_one_process(tmp_path, held):
    folder = tmp_path / "out"
    process = held(folder)
    with pytest.raises(files.InUse, match=f"process {process.pid} since .* \\(-c .* hold\\)"):
        files.take(folder)
    process.send_signal(signal.SIGKILL)
    process.wait()
    assert (tmp_path / ".out.lock").exists()  # a killed process leaves its file, but no lock
    with files.locked(folder), files.locked(folder):
        files.replace_folder(folder, fill_with(**{"policy.json": "new"}), POLICY)
        assert (tmp_path / ".out.lock").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


# -- 3. a replace is whole or nothing ----------------------------------------------------------------------

# `fieldgen ...` stopped by a signal at one moment of a replace: "unlink", the first file the process deletes
# (the old folder's, once replaced); "swap", just before the new folder takes the old one's place; "aside",
# where names cannot be exchanged at once, between moving the old folder aside and moving the new one in.
STOPPED_AT = textwrap.dedent("""
    import os, signal, sys
    from pathlib import Path
    from fieldgen import files
    from fieldgen.cli import app

    signal.signal(signal.SIGINT, signal.default_int_handler)  # even where this process was started ignoring it
    signal.signal(signal.SIGHUP, signal.SIG_DFL)  # likewise where it was started under nohup
    moment, sig, target = sys.argv[1], getattr(signal, sys.argv[2]), sys.argv[3]
    real_unlink, real_replace = os.unlink, os.replace

    def unlink(path, *args, **kwargs):
        real_unlink(path, *args, **kwargs)
        if moment == "unlink" and str(path).endswith((".yaml", ".fieldgen")):  # a file of a curriculum
            os.kill(os.getpid(), sig)

    def replace(src, dst, *args, **kwargs):
        real_replace(src, dst, *args, **kwargs)
        if moment == "aside" and Path(src).name == target and ".old" in Path(dst).name:
            os.kill(os.getpid(), sig)

    os.unlink = unlink
    if moment == "swap":
        real_swap = files._swap
        def swap(staging, folder):
            os.kill(os.getpid(), sig)
            real_swap(staging, folder)
        files._swap = swap
    if moment == "aside":
        files._exchange = lambda a, b: False
        files.os.replace = replace
    app(sys.argv[4:], prog_name="fieldgen")
""")


def stopped(cwd: Path, moment: str, sig: str, target: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", STOPPED_AT, moment, sig, target, *args], cwd=cwd,
                          capture_output=True, text=True, timeout=120)


def curriculum(radius: str, *extra: str) -> list[str]:
    return ["curriculum", "point_nav", "--stage", "task.target.radius=1", "--stage", f"task.target.radius={radius}",
            "--stage", "task.target.radius=3", "-o", "cur", *extra]


@pytest.mark.parametrize("moment,sig", [("unlink", "SIGTERM"), ("unlink", "SIGKILL"), ("unlink", "SIGHUP"),
                                        ("unlink", "SIGINT"), ("swap", "SIGTERM"), ("swap", "SIGKILL"),
                                        ("swap", "SIGINT"), ("aside", "SIGKILL"), ("aside", "SIGTERM")])
def test_a_replace_stopped_at_any_moment_leaves_the_old_folder_or_the_new_one(tmp_path, monkeypatch, moment, sig):
    """`fieldgen curriculum --force` over a curriculum, stopped by a signal at each moment of the replace, leaves
    the old curriculum or the new one in place, whole, never a mix (the old one half deleted) nor a new one
    hidden for good; stopped beyond recall (SIGKILL) after moving the old one aside where names cannot be
    exchanged at once, it leaves the old one whole aside, and the next run puts it back. The next run of the
    command clears what the stopped one left and writes the new curriculum."""
    monkeypatch.chdir(tmp_path)
    assert runner.invoke(app, curriculum("2")).exit_code == 0
    cur = tmp_path / "cur"
    old = listing(cur)
    first = stopped(tmp_path, moment, sig, "cur", *curriculum("2.5", "--force"))
    assert first.returncode != 0 and "Traceback" not in first.stderr, first.stdout + first.stderr
    if moment == "aside" and sig == "SIGKILL":
        assert not cur.exists()
        aside = list(tmp_path.glob(".cur.*.old.tmp"))
        assert len(aside) == 1 and listing(aside[0]) == old
        left = old
    else:
        left = listing(cur)
    again = runner.invoke(app, curriculum("2.5", "--force"))
    assert again.exit_code == 0, again.output
    new = listing(cur)
    assert new != old and "radius: 2.5" in new["stage_02.yaml"].decode()
    assert left in (old, new)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cur"]  # the stopped replace's leftovers are cleared


def test_a_build_killed_as_it_swaps_keeps_the_old_build(tmp_path, write_spec):
    """The same replace under `fieldgen build --force`: killed just before the new build takes the old one's
    place, the old build stays a cache hit, and the next build clears the staging folder left."""
    out = tmp_path / "build"
    assert runner.invoke(app, ["build", "point_nav", "--out", str(out), "--no-preview"]).exit_code == 0
    old = listing(out / "point_nav")
    first = stopped(tmp_path, "swap", "SIGKILL", "point_nav", "build", "point_nav", "--out", str(out), "--no-preview",
                    "--force")
    assert first.returncode == -signal.SIGKILL and listing(out / "point_nav") == old
    assert [p.name for p in out.iterdir() if p.name.startswith(".point_nav.")] != []
    again = runner.invoke(app, ["build", "point_nav", "--out", str(out), "--no-preview"])
    assert again.exit_code == 0 and "cache hit" in again.output
    assert sorted(p.name for p in out.iterdir()) == ["point_nav"] and listing(out / "point_nav") == old


@pytest.mark.parametrize("command", [["build", "point_nav"], ["train", "point_nav", "--preset", "cpu", "--prepare"]],
                         ids=["build", "train"])
def test_a_loop_of_links_given_as_out_is_one_line(tmp_path, command):
    """Before: a StopIteration traceback, as the search for what stood in the folder's way found nothing."""
    loop = tmp_path / "loop"
    loop.symlink_to("loop")
    result = runner.invoke(app, [*command, "--out", str(loop)])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and "Traceback" not in message, result.output
    assert str(loop) in message and "a link that leads nowhere (a loop of links, or to nothing)" in message
    assert loop.is_symlink() and os.readlink(loop) == "loop"


def test_the_way_on_after_a_write_fails_is_chosen_by_the_systems_error(tmp_path):
    """Before: "free some space, fix the folder's permissions" whatever the system had said, even "No such file or
    directory" where no folder can be made (under /proc)."""
    import errno

    def error(code: int) -> OSError:
        return OSError(code, os.strerror(code))

    folder = tmp_path / "out"
    assert files.way_on(folder, "--out", error(errno.ENOSPC)) == \
        "No space left on device; free some space or choose another --out"
    assert files.way_on(folder, "-o", error(errno.EACCES)) == \
        "Permission denied; fix the folder's permissions or choose another -o"
    assert files.way_on(folder, "--out", error(errno.ENOENT)) == "No such file or directory; choose another --out"
    assert files.way_on(folder, "--out", error(errno.EROFS), said=True) == "choose another --out"
    assert files.way_on(folder, "--out") == "free some space, fix the folder's permissions or choose another --out"
    (tmp_path / "afile").write_text("mine")  # what stands in the way is said before any error's advice
    assert files.way_on(tmp_path / "afile" / "out", "--out", error(errno.ENOSPC)) == \
        f"{tmp_path / 'afile'} is a file, not a folder; move it aside or choose another --out"
