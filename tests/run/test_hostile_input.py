"""What a careless or hostile user hands fieldgen besides a field spec (a damaged run folder, a record nested past
Python's parser, settings in run.json that build no trainer, an --out where a file is in the way): one sentence
naming the file, exit status 1, never a traceback, and nothing of the user's lost."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fieldgen import files
from fieldgen.cli import app
from fieldgen.run import record
from tiny_runs import as_if_learned

runner = CliRunner()

DEEP = "[" * 100_000 + "]" * 100_000  # JSON that Python's parser gives up on with RecursionError, not ValueError


def said(result) -> str:
    """The command's output as one line, wherever the console wrapped it."""
    return " ".join(result.output.split())


def refused(result, phrase: str) -> None:
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert " ".join(phrase.split()) in said(result), result.output


def edit_config(run: Path, **changes) -> None:
    saved = json.loads((run / record.RUN).read_text())
    saved["config"].update(changes)
    (run / record.RUN).write_text(json.dumps(saved))


@pytest.mark.parametrize("command", [["train", "--resume"], ["export", "-o", "POLICY"], ["eval", "--no-video"],
                                     ["compare"], ["view"]], ids=lambda c: c[0])
def test_a_run_json_nested_too_deep_to_parse_is_one_sentence(tmp_path, monkeypatch, command):
    """Before: every command that opens a run died in a RecursionError traceback on such a run.json (each first
    asks whether it is a self-play run, then reads the record)."""
    monkeypatch.setenv("DISPLAY", ":99")  # `fieldgen view` reads the run before it opens a window
    run = tmp_path / "run"
    run.mkdir()
    (run / record.RUN).write_text(DEEP)
    arguments = [str(tmp_path / word) if word == "POLICY" else word for word in command]
    result = runner.invoke(app, [*arguments, str(run)])
    refused(result, f"{run / record.RUN} cannot be read as a run record (it is not JSON: nested deeper than any "
                    "record fieldgen writes); it was edited or damaged: restore it from a copy, or start the run "
                    "again in a new folder")


@pytest.mark.parametrize("text,phrase", [
    ("", "cannot be read as a run record (it is empty); it was edited or damaged"),
    ("{not json", ("cannot be read as a run record (it is not JSON: Expecting property name enclosed in double "
                   "quotes: line 1 column 2 (char 1)); it was edited or damaged: restore it from a copy")),
    (None, ("cannot be read (Is a directory); make it the readable file fieldgen train wrote, or name another run "
            "folder")),
], ids=["empty", "broken", "folder"])
def test_a_run_json_that_is_no_json_says_what_it_is_and_what_to_do(tmp_path, text, phrase):
    """Before: the parser's words alone, cut mid-sentence, with no way on; a folder in its place read as errno 21."""
    run = tmp_path / "run"
    run.mkdir()
    if text is None:
        (run / record.RUN).mkdir()
    else:
        (run / record.RUN).write_text(text)
    refused(runner.invoke(app, ["export", str(run), "-o", str(tmp_path / "policy")]), f"{run / record.RUN} {phrase}")


def test_a_metrics_line_nested_too_deep_is_a_damaged_row(tmp_path):
    """Before: RecursionError. Inside the file it is a damaged row; as the last line, a torn one, dropped."""
    row = json.dumps({"eval": 0, "seed": 0, "env_steps": 800})
    (tmp_path / record.METRICS).write_text(f"{DEEP}\n{row}\n")
    with pytest.raises(record.RunError, match=r"metrics.jsonl:1 is not a metrics row \(not JSON\)"):
        record.read_metrics(tmp_path)
    (tmp_path / record.METRICS).write_text(f"{row}\n{DEEP}\n")
    assert [r["eval"] for r in record.read_metrics(tmp_path)] == [0]


def test_records_nested_too_deep_read_as_no_record(tmp_path):
    """An ownership record or a sweep run's start and end records nested past the parser: no record (a file of
    the folder is then no one's, a run's start unknown), as any other damaged one; before, RecursionError."""
    from fieldgen.sweep import status

    (tmp_path / files.OWNER).write_text(DEEP)
    (tmp_path / "summary.json").write_text("{}")
    assert files.writer_of(tmp_path / "summary.json") is None
    with pytest.raises(files.NotOurs, match="is not a file fieldgen wrote"):
        files.check_file(tmp_path / "summary.json", files.EVAL)
    (tmp_path / "run.started").write_text(DEEP)
    assert status._read(tmp_path / "run.started") is None


def test_parsed_json_says_every_unreadable_text_is_a_value_error():
    assert files.parsed_json(b'{"a": [1]}') == {"a": [1]}
    for text in (DEEP, "{", b"\xff\xfe", ""):
        with pytest.raises(ValueError):
            files.parsed_json(text)


@pytest.fixture
def prepared(tmp_path, tiny_crl_args) -> Path:
    """A tiny CRL run on point_nav set up with --prepare (its fields and run.json written, nothing trained)."""
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path / "runs"), "--prepare", *tiny_crl_args])
    assert result.exit_code == 0, result.output
    return tmp_path / "runs" / "point_nav-crl-0"


def test_a_run_json_whose_settings_build_no_trainer_is_refused_as_a_new_runs_are(prepared):
    """Each value in range alone, together too few steps for one iteration: a new run with them is refused, and
    one edited into run.json was a ValueError traceback from the trainer once the run opened."""
    edit_config(prepared, total_steps=100)
    refused(runner.invoke(app, ["train", "--resume", str(prepared)]),
            f"{prepared / record.RUN} holds no usable config (100 env steps (--steps or crl.total_steps) are too few:")


def test_a_run_folder_given_to_train_as_its_field_says_to_resume_it(tmp_path, prepared):
    """Read as a build folder, a run folder named as the field to train was one whose field.json is missing, with
    `fieldgen build` to run on its spec."""
    result = runner.invoke(app, ["train", str(prepared), "--prepare", "--out", str(tmp_path / "again")])
    refused(result, f"{prepared} is a run folder, not a field: continue it with fieldgen train --resume {prepared}, "
                    f"or train its field anew from the run's own copy, {prepared / 'field'}")
    assert not (tmp_path / "again").exists()


def test_a_trained_run_whose_settings_build_no_trainer_cannot_be_exported_or_viewed(tmp_path, monkeypatch, prepared):
    """What reads a trained run's policy (export, view, eval) builds its trainer: refused where it opens. The run
    has learned as far as export and view can tell (tiny_runs.as_if_learned): the refusal comes from its record,
    before what it learned is read, so training it first (most of a minute) would add nothing here."""
    monkeypatch.setenv("DISPLAY", ":99")
    run = as_if_learned(prepared)
    edit_config(run, num_envs=10**12)
    phrase = f"{run / record.RUN} holds no usable config (--steps"
    refused(runner.invoke(app, ["export", str(run), "-o", str(tmp_path / "policy")]), phrase)
    refused(runner.invoke(app, ["view", str(run)]), phrase)
    assert not (tmp_path / "policy").exists()


def test_a_damaged_learner_beside_a_whole_checkpoint_says_to_move_it_aside(tmp_path, prepared):
    """eval and export read what a run learned from learner.msgpack where it is there; cut short, it was to be
    restored or the run started again, though checkpoint.msgpack beside it holds the whole state."""
    run = as_if_learned(prepared)
    learner = (run / record.LEARNER).read_bytes()
    (run / record.LEARNER).write_bytes(learner[:len(learner) // 2])
    (run / record.CHECKPOINT).write_bytes(b"the whole state")  # never read: the learner is, and is refused
    (run / record.METRICS).write_text(json.dumps({"eval": 0, "seed": 0, "env_steps": 0, "success_any": 0.0}) + "\n")
    refused(runner.invoke(app, ["export", str(run), "-o", str(tmp_path / "policy")]),
            "or move learner.msgpack aside: what the run learned is then read from checkpoint.msgpack, which holds its "
            "whole state")
    assert not (tmp_path / "policy").exists()


def test_resume_refuses_to_train_again_over_evaluations_whose_checkpoints_are_gone(prepared):
    """A run whose checkpoint.msgpack and learner.msgpack were moved or deleted read as one never trained: resumed,
    it trained from the start and replaced its evaluations in metrics.jsonl without a word."""
    rows = [{"eval": k, "seed": 0, "env_steps": 800 * k, "success_any": 0.0} for k in (0, 1)]
    written = "".join(json.dumps(row) + "\n" for row in rows)
    (prepared / record.METRICS).write_text(written)
    refused(runner.invoke(app, ["train", "--resume", str(prepared)]),
            f"{prepared / record.METRICS} holds evaluations to 800 env steps, but the run has neither "
            "checkpoint.msgpack nor learner.msgpack to go on from (moved or deleted): put them back to continue it")
    assert (prepared / record.METRICS).read_text() == written


def test_ppo_minibatches_that_do_not_divide_a_batch_are_told_the_settings_that_do(tmp_path):
    """The refusal named the three settings and no value of any; a user had to work out the arithmetic."""
    result = runner.invoke(app, ["train", "point_nav", "--algo", "ppo", "--envs", "4", "--steps", "4000", "--prepare",
                                 "--out", str(tmp_path)])
    refused(result, "num_envs x unroll_length = 80 does not divide into 32 minibatches; change num_envs, "
                    "unroll_length or num_minibatches: --set ppo.num_minibatches=20, or --envs a multiple of 8")
    fixed = runner.invoke(app, ["train", "point_nav", "--algo", "ppo", "--envs", "8", "--steps", "4000", "--prepare",
                                "--out", str(tmp_path)])
    assert fixed.exit_code == 0, fixed.output


def test_evaluation_episodes_the_machine_cannot_hold_are_refused_before_training(tmp_path, tiny_crl_args):
    """Training checked its own state's memory, not its evaluations': eval_envs=1e12 compiled, trained a chunk and
    died in an OverflowError traceback at the first evaluation."""
    out = tmp_path / "runs"
    huge = [*tiny_crl_args, "--set", "crl.eval_envs=1e12", "--no-videos", "--out", str(out)]
    result = runner.invoke(app, ["train", "point_nav", *huge])
    refused(result, "evaluating 1,000,000,000,000 episodes of each of 1 seed at once needs about")
    assert "lower crl.eval_envs" in said(result)
    assert not (out / "point_nav-crl-0").exists()
    prepared = runner.invoke(app, ["train", "point_nav", "--prepare", *huge])
    assert prepared.exit_code == 0, prepared.output
    assert "note: evaluating 1,000,000,000,000 episodes" in said(prepared), prepared.output
    assert not (out / "point_nav-crl-0" / record.CHECKPOINT).exists()


def test_metrics_rows_of_a_seed_the_run_does_not_have_are_refused_by_every_reader(tmp_path, tiny_crl_args):
    """Before: compare refused a run whose rows were of seed 9 in place of one of its own, while export and eval
    (and a resume) read on as if the rows were the run's; rows of a seed beside the run's were dropped unsaid."""
    out = tmp_path / "runs"
    result = runner.invoke(app, ["train", "point_nav", "--seeds", "3", "--out", str(out), "--prepare", *tiny_crl_args])
    assert result.exit_code == 0, result.output
    run = out / "point_nav-crl-0to2"
    (run / record.CHECKPOINT).write_bytes(b"never read: the rows are refused first")
    for seeds in ([0, 1, 9], [0, 1, 2, 9]):
        (run / record.METRICS).write_text("".join(json.dumps({"eval": 0, "seed": s, "env_steps": 0, "success_any": 0.0,
                                                              "time_at_goal": 0.0}) + "\n" for s in seeds))
        phrase = (f"{run / record.METRICS}:{seeds.index(9) + 1} is not a metrics row (its seed 9 is not one of the run's seeds, 0, 1, 2); "
                  "the file was edited or damaged")
        for command in (["export", str(run), "-o", str(tmp_path / "policy")], ["eval", str(run), "--no-video"],
                        ["compare", str(run), "--out", str(tmp_path / "compare.png")],
                        ["train", "--resume", str(run), "--no-videos"]):
            refused(runner.invoke(app, command), phrase)
    assert not (tmp_path / "policy").exists() and not (tmp_path / "compare.png").exists()
    assert not list(run.glob("summary*"))


def test_a_run_whose_field_copy_is_a_file_says_so(prepared):
    (prepared / "field").rename(prepared / "field.moved")
    (prepared / "field").write_text("not a folder")
    refused(runner.invoke(app, ["train", "--resume", str(prepared)]),
            f"{prepared / 'field'} is a file, not a folder: the run's own copy of its field")


@pytest.mark.parametrize("blocker,what", [("file", "a file"),
                                          ("link", "a link that leads nowhere (a loop of links, or to nothing)")])
@pytest.mark.parametrize("below", ["", "sub"], ids=["out", "under_out"])
def test_an_out_where_a_file_is_in_the_way_names_it(tmp_path, tiny_crl_args, blocker, what, below):
    """Before: "a file is in the way of the folder; free some space, fix the folder's permissions", or the
    system's "Not a directory" about the run's folder, for a path under a file; neither named the file."""
    in_the_way = tmp_path / "in_the_way"
    if blocker == "file":
        in_the_way.write_text("mine")
    else:
        in_the_way.symlink_to(tmp_path / "nowhere")
    out = in_the_way / below if below else in_the_way
    result = runner.invoke(app, ["train", "point_nav", "--out", str(out), "--prepare", *tiny_crl_args])
    refused(result, f"cannot set up the run folder {out / 'point_nav-crl-0'}: {in_the_way} is {what}, not a folder; "
                    "move it aside or choose another --out")
    if blocker == "file":
        assert in_the_way.read_text() == "mine"


def test_a_sweeps_folder_where_a_file_is_in_the_way_names_it(tmp_path):
    """Before: "out/sweep.json: cannot be read (Not a directory); move it aside to plan the sweep anew", about a
    plan that was never there."""
    in_the_way = tmp_path / "results"
    in_the_way.write_text("mine")
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"fields: [point_nav]\nalgorithms: [crl]\nout: {in_the_way / 'sweep'}\n")
    refused(runner.invoke(app, ["sweep", str(sweep), "--dry-run"]),
            f"{sweep}:3:1: out: {in_the_way} is a file, not a folder, where the sweep's folder "
            f"{in_the_way / 'sweep'} goes; move it aside or choose another out:")
    refused(runner.invoke(app, ["sweep", str(sweep), "--status", "--out", str(in_the_way)]),
            f"{in_the_way}: is a file, not a folder, where the sweep's folder {in_the_way} goes; move it aside or "
            "choose another --out")
    assert in_the_way.read_text() == "mine"


@pytest.mark.parametrize("total", ["abc", None], ids=["text", "left_out"])
def test_resume_with_a_setting_refuses_it_whatever_run_json_holds_as_its_steps(prepared, total):
    """Before: the refusal of --steps quoted run.json's total_steps as a count, and died formatting one that was
    edited into text or left out (ValueError, TypeError)."""
    saved = json.loads((prepared / record.RUN).read_text())
    if total is None:
        del saved["config"]["total_steps"]
    else:
        saved["config"]["total_steps"] = total
    (prepared / record.RUN).write_text(json.dumps(saved))
    refused(runner.invoke(app, ["train", "--resume", str(prepared), "--steps", "5"]),
            f"--resume goes on with the settings {prepared} was set up with, which --steps cannot change")


def test_a_kept_episode_that_is_no_archive_is_refused_without_talk_of_pickles(prepared):
    """Before: numpy's words for a file it would read as a pickle: "load it unsafely using allow_pickle"."""
    (prepared / record.VIDEOS).mkdir()
    (prepared / record.VIDEOS / "eval_001.npz").write_bytes(b"\x80\x04 not a zip of arrays")
    result = runner.invoke(app, ["videos", str(prepared)])
    refused(result, f"{prepared / record.VIDEOS / 'eval_001.npz'} is not an episode kept by fieldgen train (not an "
                    ".npz archive); delete it or train again")
    assert "pickle" not in result.output


def test_eval_refuses_a_summary_where_a_file_is_in_the_folders_place(prepared, tmp_path):
    """Before: "there is no folder in_the_way to write it in", of a file that is there, with no way on."""
    in_the_way = tmp_path / "in_the_way"
    in_the_way.write_text("mine")
    summary = in_the_way / "sub" / "summary.json"
    refused(runner.invoke(app, ["eval", str(prepared), "--no-video", "--summary", str(summary)]),
            f"cannot write {summary}: {in_the_way} is a file, not a folder; move it aside or choose another --summary")
    assert in_the_way.read_text() == "mine"


def test_eval_refuses_a_summary_in_a_read_only_folder_before_evaluating(prepared, tmp_path, monkeypatch):
    """Before: every seed evaluated, then "cannot write PATH: Permission denied". The system's answer for the
    folder is the one a read-only disk gives (root's permissions would let root write it)."""
    folder = tmp_path / "read_only"
    folder.mkdir()
    access = os.access
    monkeypatch.setattr(files.os, "access", lambda path, mode: Path(path) != folder and access(path, mode))
    result = runner.invoke(app, ["eval", str(prepared), "--no-video", "--summary", str(folder / "s.json")])
    refused(result, f"cannot write {folder / 's.json'}: its folder is read-only or not the user's to write in; fix "
                    "the folder's permissions or choose another --summary")
    assert list(folder.iterdir()) == []


def test_a_sweeps_folder_that_cannot_be_made_says_what_to_do(tmp_path, monkeypatch):
    """Before: "DIR: Permission denied", the system's words alone. Root may write a read-only folder: there its
    mkdir is refused as the system refuses anyone else's."""
    parent = tmp_path / "read_only"
    parent.mkdir()
    parent.chmod(0o555)
    if os.geteuid() == 0:
        make = Path.mkdir

        def refused_below(self, *args, **kwargs):
            if parent in self.parents:
                raise PermissionError(errno.EACCES, "Permission denied", str(self))
            return make(self, *args, **kwargs)

        monkeypatch.setattr(Path, "mkdir", refused_below)
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text("fields: [point_nav]\nalgorithms: [crl]\nsteps: 2M\n")
    try:
        result = runner.invoke(app, ["sweep", str(sweep), "--out", str(parent / "sweep")])
    finally:
        parent.chmod(0o755)
    refused(result, f"{sweep}: cannot set up the sweep's folder {parent / 'sweep'}: Permission denied; fix the "
                    "folder's permissions or choose another --out")
    assert list(parent.iterdir()) == []


@pytest.mark.parametrize("damage,problem", [
    (lambda field: (field / "field.json").write_text("{}"), "has artifact format None, this fieldgen reads format"),
    (lambda field: (field / "scene.xml").unlink(), "is not a built field: scene.xml is missing"),
    (lambda field: (field / "field.json").write_text(DEEP), "field.json is not valid JSON (nested deeper than any"),
], ids=["edited", "scene_missing", "nested_too_deep"])
def test_a_run_whose_field_copy_is_damaged_is_set_up_again_not_rebuilt(prepared, damage, problem):
    """Before: the advice for a build folder ("run `fieldgen build`", "rebuild the field"), which never writes
    a run's copy; and a field.json nested past the parser was a RecursionError traceback."""
    damage(prepared / "field")
    result = runner.invoke(app, ["train", "--resume", str(prepared)])
    refused(result, problem)
    refused(result, f"; {prepared / 'field'} is the run's own copy of its field: set the run up again with the "
                    "fieldgen train command that made it, or restore the folder from a copy")
    assert "fieldgen build" not in said(result) and "rebuild" not in said(result)


GIANT = "9" * 90


@pytest.mark.parametrize("written,phrase", [
    ("--set crl.num_envs=1e400", "crl.num_envs must be a whole number from 1 to 1,000,000,000,000,000, not 1e400"),
    (f"--set crl.total_steps={GIANT}", "crl.total_steps must be a whole number from 1 to 1,000,000,000,000,000, "
                                       f"not {GIANT[:28]}...{GIANT[:29]}"),
    (f"crl:\n  repr_dim: {GIANT}\n", f"config.yaml:2: crl.repr_dim must be a whole number from 1 to "
                                     f"1,000,000,000,000,000, not {GIANT[:28]}...{GIANT[:29]}"),
    ("crl:\n  batch_size: 1.0e+400\n", "config.yaml:2: crl.batch_size must be a whole number from 1 to "
                                       "1,000,000,000,000,000, not 1.0e+400"),
], ids=["set_past_a_float", "set_giant", "file_giant", "file_past_a_float"])
def test_a_giant_config_number_is_one_line_with_its_range(tmp_path, written, phrase):
    """Before: "must be a finite number, not inf"; a giant count quoted whole in a later check of the steps or
    the batch; and a giant network width an OverflowError traceback once the run was already prepared."""
    if written.startswith("--set"):
        settings = written.split(" ")
    else:
        (tmp_path / "config.yaml").write_text(written)
        settings = ["--config", str(tmp_path / "config.yaml")]
    result = runner.invoke(app, ["train", "point_nav", "--prepare", "--out", str(tmp_path / "runs"), *settings])
    refused(result, phrase)
    assert GIANT not in said(result) and not (tmp_path / "runs").exists()


def test_an_out_folder_whose_name_is_too_long_says_the_limit_and_what_to_do(tmp_path):
    result = runner.invoke(app, ["train", "point_nav", "--steps", "100", "--out", str(tmp_path / ("a" * 300))])
    said = " ".join(result.output.split())
    assert result.exit_code == 1 and "Traceback" not in said, result.output
    assert "File name too long; a folder's or file's name holds at most 255 bytes" in said
    assert "choose a shorter one" in said and not os.listdir(tmp_path)  # nothing made


def test_compare_refuses_a_run_json_naming_an_algorithm_fieldgen_has_not(prepared, tmp_path):
    """Every command that opens the run refused it, but compare, which reads only run.json and metrics.jsonl,
    tabled and plotted the damaged run under the name it was edited to."""
    (prepared / record.METRICS).write_text(json.dumps({"eval": 0, "seed": 0, "env_steps": 0, "success_any": 0.5,
                                                       "time_at_goal": 1.0}) + "\n")
    edit = json.loads((prepared / record.RUN).read_text())
    edit["algo"] = "foo"
    (prepared / record.RUN).write_text(json.dumps(edit))
    plot = tmp_path / "compare.png"
    result = runner.invoke(app, ["compare", str(prepared), "-o", str(plot)])
    refused(result, f"{prepared / record.RUN} is not a run record: algo should be one of this fieldgen's algorithms, "
                    "crl, icrl, ppo, sac, td3, not 'foo' (edited or damaged)")
    assert not plot.exists()


@pytest.mark.parametrize("blocker", ["file", "loop"])
def test_export_into_a_folder_a_file_or_a_dead_link_is_in_the_way_of_says_to_move_it(tmp_path, prepared, blocker):
    """Said as a full disk or a permission once: free some space, fix the folder's permissions."""
    run = as_if_learned(prepared)
    (run / record.METRICS).write_text(json.dumps({"eval": 0, "seed": 0, "env_steps": 0}) + "\n")
    in_the_way = tmp_path / "in the way"
    if blocker == "file":
        in_the_way.write_text("mine")
    else:
        in_the_way.symlink_to(in_the_way)
    result = runner.invoke(app, ["export", str(run), "-o", str(in_the_way / "policy")])
    what = "a file" if blocker == "file" else "a link that leads nowhere (a loop of links, or to nothing)"
    refused(result, f"{in_the_way} is {what}, not a folder; move it aside or choose another -o")
    assert "free some space" not in result.output
    assert in_the_way.is_symlink() or in_the_way.read_text() == "mine"


def test_a_jax_enable_x64_set_for_other_work_leaves_a_commands_programs_in_float32(tmp_path, prepared, monkeypatch):
    """Tracing the run's trainer with 64-bit numbers on was a TypeError traceback (a scan's carry turned float64)."""
    import jax

    run = as_if_learned(prepared)
    (run / record.METRICS).write_text(json.dumps({"eval": 0, "seed": 0, "env_steps": 0}) + "\n")
    monkeypatch.setenv("JAX_ENABLE_X64", "1")
    jax.config.update("jax_enable_x64", True)  # as JAX loads where the variable is set
    try:
        result = runner.invoke(app, ["export", str(run), "-o", str(tmp_path / "policy")])
    finally:
        jax.config.update("jax_enable_x64", False)
    assert result.exit_code == 0, (result.output, result.exception)
    assert (tmp_path / "policy" / "params.msgpack").is_file()


@pytest.mark.parametrize("command", [["train", "--resume"], ["eval", "--no-video"], ["export", "-o", "POLICY"],
                                     ["videos"], ["compare", "RUN"]], ids=lambda c: c[0])
def test_a_run_named_by_a_link_that_leads_nowhere_is_called_that_not_missing(tmp_path, prepared, command):
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    args = [str(tmp_path / "policy") if a == "POLICY" else str(prepared) if a == "RUN" else a for a in command]
    refused(runner.invoke(app, [*args, str(loop)]),
            f"{loop} is a link that leads nowhere (a loop of links, or to nothing), not a run folder")


@pytest.mark.parametrize("command", [["eval", "--no-video"], ["export", "-o", "POLICY"], ["train", "--resume"],
                                     ["videos"]], ids=lambda c: c[0])
def test_a_policy_or_a_build_named_as_a_run_says_which_command_wrote_it(tmp_path, command):
    """Before: an exported policy's folder (or a build's) named where a run goes was 'not a training run: run.json is
    missing', with a setup cut short to set up again: as if it were a run, not another command's folder."""
    from fieldgen.policy_folder import POLICY

    policy = tmp_path / "policies" / "point_nav"
    policy.mkdir(parents=True)
    files.mark(policy, POLICY)
    built = runner.invoke(app, ["build", "point_nav", "--out", str(tmp_path / "build")])
    assert built.exit_code == 0, built.output
    for folder, writer in ((policy, "fieldgen export"), (tmp_path / "build" / "point_nav", "fieldgen build")):
        arguments = [str(tmp_path / "exported") if word == "POLICY" else word for word in command]
        refused(runner.invoke(app, [*arguments, str(folder)]),
                f"{folder} was written by {writer}, not fieldgen train: it is no training run; name the folder "
                "fieldgen train wrote (runs/<field>-<algo>-<seed>)")
    assert not (tmp_path / "exported").exists()


def test_a_run_json_listing_a_seed_twice_is_not_a_run_record(prepared):
    """Before: eval said "seed 0 is in both RUN and RUN", export and a resume blamed the checkpoint's shapes on the
    config, and compare tabled one seed as two."""
    saved = json.loads((prepared / record.RUN).read_text())
    saved["seeds"] = [0, 0]
    (prepared / record.RUN).write_text(json.dumps(saved))
    for command in (["train", "--resume"], ["eval", "--no-video"], ["compare"]):
        refused(runner.invoke(app, [*command, str(prepared)]),
                f"{prepared / record.RUN} is not a run record: seeds should list each seed once (seed 0 more than "
                "once), not [0, 0] (edited or damaged)")


@pytest.mark.parametrize("command,option", [
    (["render", "point_nav", "-o", "FILE.png"], "-o"),
    (["render", "RUN", "--levels", "-o", "FILE.png"], "-o"),
    (["compare", "RUN", "-o", "FILE.png"], "-o"),
    (["aggregate", "summary.json", "--summary", "FILE.json"], "--summary"),
], ids=["render", "render_levels", "compare", "aggregate"])
def test_a_file_named_in_a_folder_that_is_not_there_says_so_before_any_work(tmp_path, command, option):
    """Before: render drew the field, then "cannot write PATH: No such file or directory"; compare, eval and
    aggregate each said it in words of their own (aggregate's named no folder at all)."""
    missing, run = tmp_path / "missing", tmp_path / "run"
    run.mkdir()
    (run / record.RUN).write_text("{}")  # never read: the file to write is checked first
    arguments = [str(missing / "out.png") if w == "FILE.png" else str(missing / "out.json") if w == "FILE.json"
                 else str(run) if w == "RUN" else w for w in command]
    written = missing / Path(command[-1]).name.replace("FILE", "out")
    refused(runner.invoke(app, arguments), f"cannot write {written}: there is no folder {missing} to write it in; "
                                           f"make it, or choose another {option}")
    assert not missing.exists()


@pytest.mark.parametrize("args,phrase", [
    (["--config", "bat\u202ech_size: 1"], "unknown config key 'bat\\u202ech_size'; did you mean 'batch_size'?"),
    (["--config", "eval_actions: \"me\u202ean\""], "unknown eval_actions 'me\\u202ean'; choose one of mean, sampled"),
    (["--set", "crl.bat\u202ech_size=1"], "unknown config key 'bat\\u202ech_size'"),
    (["--set", "crl.eval_actions=" + "k" * 5000], "unknown eval_actions 'kkkk"),
    (["--set", "x" * 5000 + "=1"], "(5,002 characters)"),
], ids=["config_key", "config_value", "set_key", "set_long_value", "set_long_item"])
def test_a_config_key_or_value_is_echoed_escaped_and_cut(tmp_path, args, phrase):
    """Before: a config key or choice was echoed raw: a right-to-left mark reordered the terminal's line, and 5,000
    characters of a --set value were printed whole."""
    if args[0] == "--config":
        (tmp_path / "config.yaml").write_text(f"crl:\n  {args[1]}\n")
        args = ["--config", str(tmp_path / "config.yaml")]
    result = runner.invoke(app, ["train", "point_nav", "--prepare", "--out", str(tmp_path / "runs"), *args])
    refused(result, phrase)
    assert "\u202e" not in result.output and "k" * 100 not in result.output and "x" * 100 not in result.output
    assert len(said(result)) < 1200


@pytest.mark.parametrize("blocker,phrase", [
    ("success.png", "success.png is a folder where the run writes its plot; move it aside, then continue with "
                    "fieldgen train --resume"),
    ("metrics.csv", "metrics.csv is a folder where the run writes its metrics as CSV; move it aside"),
    ("videos", "videos is a file where the run keeps its videos; move it aside, or continue without videos: "
               "fieldgen train --resume"),
])
def test_something_where_a_run_writes_its_own_files_is_refused_before_training(prepared, blocker, phrase):
    """Before: the run trained a chunk, then failed at its first write advising to free some space."""
    path = prepared / blocker
    path.mkdir() if blocker != "videos" else path.write_text("notes of the user's")
    result = runner.invoke(app, ["train", "--resume", str(prepared)])
    refused(result, phrase)
    assert not (prepared / record.CHECKPOINT).exists() and not (prepared / record.LEARNER).exists()
    assert path.is_dir() if blocker != "videos" else path.read_text() == "notes of the user's"
