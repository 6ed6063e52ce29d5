"""`fieldgen sweep`: a file expands into `fieldgen train` runs, handed to a local queue or to SLURM (tested
through submitit's local executor), resumed when started again, and summarized over seeds once done.

Most tests read hand-made run folders (run.json and metrics.jsonl are all status and summary read), so that
only the end-to-end ones train."""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import submitit  # before any CliRunner: its logger keeps the stderr it finds at import
from typer.testing import CliRunner

from tiny_runs import TINY_CRL
from fieldgen.cli import app
from fieldgen.sweep import launch, plan, status

runner = CliRunner()

TINY_SET = "\n".join(f"  crl.{k}: {json.dumps(list(v) if isinstance(v, tuple) else v)}"
                     for k, v in TINY_CRL.items() if k not in ("total_steps", "num_envs"))


def sweep_file(folder: Path, body: str = "", name: str = "sweep.yaml", seeds: int = 2, grid: str = "") -> Path:
    """The tiny CRL run's settings in `set`, less those `grid` varies (a key goes in one of them)."""
    path = folder / name
    varied = {line.partition(":")[0].strip() for line in grid.splitlines()}
    fixed = "\n".join(line for line in TINY_SET.splitlines() if line.partition(":")[0].strip() not in varied)
    path.write_text(f"fields: [point_nav]\nalgorithms: [crl]\nseeds: {seeds}\nsteps: {TINY_CRL['total_steps']}\n"
                    f"envs: {TINY_CRL['num_envs']}\nout: {folder / 'out'}\nset:\n{fixed}\n"
                    + (f"grid:\n{grid}\n" if grid else "") + body)
    return path


def hand_made(run: plan.PlannedRun, evals: int, success: float, num_evals: int = 2, field: dict | None = None) -> None:
    """A run folder as fieldgen train leaves it after `evals` evaluations (no checkpoint: nothing reads one);
    `field` stands for the resolved spec it records (its name alone by default)."""
    run.folder.mkdir(parents=True, exist_ok=True)
    (run.folder / "run.json").write_text(json.dumps({"algo": run.algo, "config": {"num_evals": num_evals,
                                                                                   "eval_envs": 8},
                                                     "observation": {}, "seeds": [run.seed],
                                                     "field": field or {"name": run.field}}))
    rows = [{"eval": e, "seed": run.seed, "env_steps": 800 + 480 * e, "success_any": success * e / num_evals,
             "time_at_goal": 10.0 * success, "closest_distance": 1.0, "wall_seconds": float(e)}
            for e in range(evals + 1)]
    (run.folder / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))


def test_a_sweep_expands_into_the_train_commands_a_user_would_type(tmp_path):
    path = sweep_file(tmp_path, grid="  crl.repr_dim: [8, 16]\n  crl.energy: [norm, l2]", seeds=2)
    sweep = plan.load(path)
    assert len(sweep.runs) == 8  # 2 x 2 points x 2 seeds
    first = sweep.runs[0]
    assert first.id == "crl.repr_dim=8,crl.energy=norm/point_nav-crl-0"
    assert first.folder == tmp_path / "out" / first.id
    words = plan.shell(first.command()).split()
    assert words[:8] == ["fieldgen", "train", "point_nav", "--algo", "crl", "--seed", "0", "--out"]
    assert "crl.repr_dim=8" in words and "crl.energy=norm" in words and "'crl.hidden=[32,32]'" in words
    assert words[-1] == "--no-videos" and "--resume" not in words
    lines = launch.dry_run(sweep)
    assert lines[0].startswith("#") and len(lines) == 9 and not (tmp_path / "out").exists()  # nothing written
    hand_made(first, 1, 0.5)  # started: it is continued from its folder
    assert first.command() == ("train", "--resume", str(first.folder), "--no-videos")


def test_a_sweep_through_the_automatic_curriculum_plans_its_sampler_settings_and_folders(tmp_path):
    """`curriculum: auto` with `sampler.KEY` in set and grid: each run's command carries --curriculum auto,
    --levels and --sampler, and its planned folder is the one that command writes (<field>-auto-<algo>-<seed>)."""
    path = tmp_path / "sweep.yaml"
    path.write_text(f"fields: [point_soccer]\nalgorithms: [crl]\nseeds: 1\nsteps: 20k\nenvs: 8\n"
                    f"out: {tmp_path / 'out'}\ncurriculum: auto\nlevels: 3\nset:\n  sampler.prior: 4\n"
                    "grid:\n  sampler.replaced: [4, 8]\n")
    sweep = plan.load(path)
    assert [r.id for r in sweep.runs] == ["sampler.replaced=4/point_soccer-auto-crl-0",
                                          "sampler.replaced=8/point_soccer-auto-crl-0"]
    run = sweep.runs[1]
    words = run.command()
    assert " ".join(words[8:]).startswith("--curriculum auto --levels 3 --steps 20000 --envs 8 --sampler prior=4 "
                                          "--sampler replaced=8")
    assert run.label == "crl sampler.replaced=8"
    made = runner.invoke(app, [*words, "--prepare"])
    assert made.exit_code == 0, made.output
    assert json.loads((run.folder / "run.json").read_text())["sampler"]["replaced"] == 8
    assert json.loads((run.folder / "run.json").read_text())["sampler"]["prior"] == 4.0


def test_a_curriculum_sweeps_summary_is_of_its_field_not_of_every_level(tmp_path):
    """An automatic curriculum's rows hold success over all its levels and, under `variants`, on each; the
    summary over seeds is of the last level, the field itself, as `fieldgen compare` judges curricula."""
    path = tmp_path / "sweep.yaml"
    path.write_text(f"fields: [point_soccer]\nalgorithms: [crl]\nseeds: 2\nsteps: 20k\nenvs: 8\n"
                    f"out: {tmp_path / 'out'}\ncurriculum: auto\n")
    sweep = plan.load(path)
    for run, on_field in zip(sweep.runs, (0.25, 0.5)):
        hand_made(run, 2, 0.9)
        rows = [json.loads(line) for line in (run.folder / "metrics.jsonl").read_text().splitlines()]
        for row in rows:
            row["variants"] = {"success_any": [0.9, on_field], "time_at_goal": [50.0, 5.0]}
        (run.folder / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    result = runner.invoke(app, ["sweep", str(path), "--status"])
    assert result.exit_code == 0 and "2 done" in result.output, result.output
    group = json.loads((sweep.folder / status.SUMMARY).read_text())["groups"][0]["summary"]
    assert group["success_any"]["per_seed"] == {"0": 0.25, "1": 0.5}
    assert group["time_at_goal"]["per_seed"] == {"0": 5.0, "1": 5.0}


def test_dry_run_on_the_command_line_shows_each_command_and_the_backend(tmp_path):
    path = sweep_file(tmp_path, "backend: slurm\nslurm: {partition: gpu, time: 90}\n", seeds=1)
    result = runner.invoke(app, ["sweep", str(path), "--dry-run", "--gpus-per-task", "2"])
    assert result.exit_code == 0, result.output
    assert "one SLURM job array" in result.output and "2 GPU(s) each, 90 min" in result.output
    assert "partition gpu" in result.output and "fieldgen train point_nav --algo crl --seed 0" in result.output
    assert "each run stops at an evaluation 5 min before its task's end" in result.output
    assert result.output.rstrip().endswith("--no-videos --time-limit 85m")  # slurm.stop_before's default, 5


def test_the_repository_sweep_file_the_docs_show_plans_its_runs(tmp_path):
    """`fieldgen sweep --help` and docs/scale.md start from sweeps/point_nav.yaml: it is there and plans."""
    path = Path(__file__).resolve().parents[2] / "sweeps" / "point_nav.yaml"
    result = runner.invoke(app, ["sweep", str(path), "--dry-run", "--out", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    commands = [line for line in result.output.splitlines() if line.startswith("fieldgen train")]
    assert len(commands) == 50  # 2 fields x (4 CRL settings + SAC) x 5 seeds
    assert sum("point_nav_far.yaml --algo sac" in c for c in commands) == 5
    assert not (tmp_path / "out").exists()
    docs = (path.parents[1] / "docs" / "scale.md").read_text()
    assert path.read_text().split("\nfields:")[1] in docs  # the page shows the file as it is


def test_a_task_too_short_for_the_runs_stop_names_the_time_given_on_the_command_line(tmp_path):
    """--time 5 against slurm.stop_before's default 5: the option given is named, not a key of the file."""
    path = sweep_file(tmp_path, "backend: slurm\nslurm: {partition: gpu}\n", seeds=1)
    result = runner.invoke(app, ["sweep", str(path), "--dry-run", "--time", "5"])
    assert result.exit_code == 1, result.output
    assert ("slurm.stop_before: 5 minutes (its default) before the end of a task of 5 minutes (--time 5) leaves its "
            "run no time to train: give --time more minutes than 5") in " ".join(result.output.split())


@pytest.mark.parametrize("body,phrase", [
    ("grid:\n  crl.repr_dimm: [8, 16]\n", ":7:3: grid.crl.repr_dimm: unknown config key 'repr_dimm'; did you mean "
                                          "'repr_dim'?"),
    ("grid:\n  crl.repr_dim: []\n", ":7:3: grid.crl.repr_dim: at least 1 item here (got 0)"),
    ("grid:\n  sac.her: [0.5]\n", "grid.sac.her: 'sac' is not among the sweep's algorithms (crl)"),
    ("grid:\n  crl.repr_dim: [8, -1]\n", "grid.crl.repr_dim: crl.repr_dim must be greater than 0, not -1"),
    ("backend: slurmm\n", ":6:1: backend: Input should be 'local' or 'slurm' (got 'slurmm'; did you mean 'slurm'?)"),
    ("fields: [point_nav, nowhere.yaml]\n", "fields[1]: 'nowhere.yaml' is neither a file nor a folder"),
    ("algorithms: [crll]\n", "did you mean 'crl'?"),
    ("seeds: 0\n", "seeds: Input should be greater than or equal to 1"),
    ("steps: lots\n", "steps: 'lots' is not a positive whole count"),
    ("out: ''\n", "out: String should have at least 1 character (got '')"),
    ("colour: red\n", "unknown key 'colour'"),
    ("backend: slurm\nslurm: {time: 30, stop_before: 30}\n", ":7:19: slurm.stop_before: 30 minutes before the end of a "
                                                              "task of 30 minutes (slurm.time) leaves its run no time"),
    ("backend: slurm\nslurm: {stop_before: -1}\n", "slurm.stop_before: Input should be greater than or equal to 0"),
    ("grid:\n  sampler.replaced: [4]\n", ":7:3: grid.sampler.replaced: sets the automatic curriculum's level sampler; "
                                         "add curriculum: auto to the sweep"),
    ("levels: 3\n", ":6:1: levels: 3 levels of the automatic curriculum: add curriculum: auto to the sweep"),
    ("curriculum: auto\ngrid:\n  sampler.replacd: [4]\n", ":8:3: grid.sampler.replacd: replacd=4: unknown key "
                                                          "'replacd'; did you mean 'replaced'?"),
    ("curriculum: auto\nset:\n  sampler.kept: 2\n", ":8:3: set.sampler.kept: kept=2: kept must be at most 1.0 (of a "
                                                     "level's episode counts"),
    ("curriculum: manual\n", "curriculum: Input should be 'auto'"),
    ("curriculum: auto\nlevels: 1000000\n", ":7:1: levels: Input should be less than or equal to 64"),
    ("backend: slurm\nslurm: {time: 1000000000000}\n", "slurm.time: Input should be less than or equal to 525600"),
    ("backend: slurm\nslurm: {requeues: 99999999999}\n", "slurm.requeues: Input should be less than or equal to 1000"),
    ("seeds: 1000000000\n", "seeds: Input should be less than or equal to 65536"),
    (f"steps: {'9' * 5000}\n", ":4:8: a number of 5,000 digits; a number here has at most 100"),
    # the point's folder name fits, the log named after it and the run does not
    (f"grid:\n  crl.hidden: [[{','.join(['32'] * 80)}]]\n", ":6:1: grid: names a folder or log of run "
                                                         "crl.hidden=_32,32,32,"),
])
def test_bad_sweep_files_are_one_line_at_the_key(tmp_path, body, phrase):
    path = tmp_path / "sweep.yaml"
    base = {"fields": "[point_nav]", "algorithms": "[crl]", "seeds": "2", "steps": "14000", "envs": "8"}
    given = body.partition(":")[0]  # a key of the base given otherwise takes its line
    path.write_text("".join(f"{k}: {v}\n" if k != given else body for k, v in base.items())
                    + ("" if given in base else body))
    result = runner.invoke(app, ["sweep", str(path), "--out", str(tmp_path / "out")])
    assert result.exit_code == 1
    assert result.output.startswith(f"error: {path}") and phrase in result.output, result.output
    assert len(result.output.strip().splitlines()) == 1 and "Traceback" not in result.output
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("body,phrase", [
    ("set:\n  crl.batch_size: 64\n  crl.repr_dim: 16\ngrid:\n  crl.repr_dim: [8, 32]\n",
     ":8:3: set.crl.repr_dim: grid varies crl.repr_dim too, so every run would take the grid's value, never this "
     "one: keep the key in set or in grid, not both"),
    ("curriculum: auto\nset:\n  sampler.kept: 0.5\ngrid:\n  sampler.kept: [0.25, 0.75]\n",
     ":8:3: set.sampler.kept: grid varies sampler.kept too"),
])
def test_a_set_key_the_grid_varies_too_is_refused_at_the_key(tmp_path, body, phrase):
    """Every run took the grid's value of a key that set also gave, and the set value was dropped unsaid."""
    path = tmp_path / "sweep.yaml"
    path.write_text("fields: [point_nav]\nalgorithms: [crl]\nseeds: 2\nsteps: 1900\nenvs: 8\n" + body)
    result = runner.invoke(app, ["sweep", str(path), "--dry-run", "--out", str(tmp_path / "out")])
    assert result.exit_code == 1 and result.output.startswith(f"error: {path}") and phrase in result.output, \
        result.output
    assert len(result.output.strip().splitlines()) == 1 and "fieldgen train" not in result.output
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("body,phrase", [
    ("seeds: [0, 3, 0]\n", ":3:15: seeds[2]: seed 0 is listed twice (items 0 and 2); list each once"),
    ("fields: [point_nav, soccer_1v1]\n", ":1:21: fields[1]: 'soccer_1v1' is a team field: it trains by self-play, "
                                         "whose learner is ppo, and the sweep's algorithms list crl; sweep team "
                                         "fields in a file of their own with algorithms: [ppo]"),
    ("algorithms: [crl, crl]\n", ":2:19: algorithms[1]: algorithm crl is listed twice"),
    ("grid:\n  crl.repr_dim: [8, 16, 8]\n", ":7:25: grid.crl.repr_dim[2]: value 8 is listed twice (items 0 and 2)"),
    ("grid:\n  crl.repr_dim: [8, 16, \"8\"]\n", ":7:25: grid.crl.repr_dim[2]: \"8\" sets what item 0 sets (8): the "
                                               "same run is planned twice"),  # before: two folders, one run
    ("fields: [point_nav, mine.yaml]\n", ":1:21: fields[1]: 'mine.yaml' is the field point_nav, as 'point_nav' "
                                        "(fields[0]) is: their runs would share folders and a summary"),
    ("local: {gpus: [1, 1]}\n", ":6:19: local.gpus[1]: GPU 1 is listed twice (items 0 and 1); list each once, or "
                                "two runs at a time share that GPU"),
])
def test_a_sweep_that_would_plan_one_run_twice_is_refused_at_the_key(tmp_path, body, phrase):
    """Two entries that plan the same run folder would train it twice, or count one seed twice in a summary."""
    (tmp_path / "mine.yaml").write_text("extends: point_nav\nname: point_nav\nfield: {length: 12, width: 12}\n")
    path = tmp_path / "sweep.yaml"
    base = {"fields": "[point_nav]", "algorithms": "[crl]", "seeds": "2", "steps": "14000", "envs": "8"}
    given = body.partition(":")[0]
    path.write_text("".join(f"{k}: {v}\n" if k != given else body for k, v in base.items())
                    + ("" if given in base else body))
    result = runner.invoke(app, ["sweep", str(path), "--dry-run", "--out", str(tmp_path / "out")])
    assert result.exit_code == 1 and result.output.startswith(f"error: {path}") and phrase in result.output, \
        result.output
    assert len(result.output.strip().splitlines()) == 1 and "fieldgen train" not in result.output


@pytest.mark.parametrize("last,phrase", [
    ({"success_any": 7.5}, "metrics.jsonl:3 is not a metrics row (success_any is 7.5, outside its range (from 0 to 1))"),
    ({"success_any": float("nan")}, "metrics.jsonl:3 is not a metrics row (success_any is NaN: it was not measured)"),
    ({"variants": {"success_any": [0.5, float("nan")]}}, "seed 1's success_any is NaN: it was not measured"),
])
def test_status_computes_no_summary_over_a_seed_whose_success_cannot_be_a_rate(tmp_path, last, phrase):
    """A seed edited to 7.5, or NaN where nothing was measured, is named, not averaged into the figure."""
    path = sweep_file(tmp_path, seeds=2)
    sweep = plan.load(path)
    for run in sweep.runs:
        hand_made(run, 2, 0.5)
    metrics = sweep.runs[1].folder / "metrics.jsonl"
    rows = [json.loads(line) for line in metrics.read_text().splitlines()]
    rows[-1].update(last)
    metrics.write_text("".join(json.dumps(r) + "\n" for r in rows))
    result = runner.invoke(app, ["sweep", str(path), "--status"])
    message = " ".join(result.output.split())
    assert phrase in message and "Traceback" not in message, result.output
    assert not (sweep.folder / status.SUMMARY).exists() and not (sweep.folder / status.TABLE).exists()


@pytest.mark.parametrize("key,value,least", [("num_evals", "2", 0), ("eval_envs", 0, 1)])
def test_a_run_json_whose_evaluation_counts_were_edited_fails_its_run_in_status_and_dry_run(tmp_path, key, value,
                                                                                           least):
    """A sweep reads whether a run is finished, and the episodes its figures are over, from run.json's config as
    it is: a count edited to text ended --status and --dry-run in a TypeError traceback, one of no episodes was
    summarized."""
    path = sweep_file(tmp_path, seeds=2)
    sweep = plan.load(path)
    for run in sweep.runs:
        hand_made(run, 2, 0.5)
    saved = json.loads((sweep.runs[1].folder / "run.json").read_text())
    saved["config"][key] = value
    (sweep.runs[1].folder / "run.json").write_text(json.dumps(saved))
    result = runner.invoke(app, ["sweep", str(path), "--status"])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and "Traceback" not in message, result.output
    assert f"{sweep.runs[1].folder / 'run.json'} is not a run record: config.{key} should be a whole number from " \
           f"{least} up, not {value!r}" in message
    assert not (sweep.folder / status.SUMMARY).exists()
    result = runner.invoke(app, ["sweep", str(path), "--dry-run"])
    assert result.exit_code == 0 and result.output.splitlines()[-1].startswith("fieldgen train --resume"), result.output


def test_status_does_not_pool_seeds_of_a_field_edited_between_their_runs(tmp_path):
    """Seeds are pooled by their field's digest, not its name: a field file edited between two seeds' runs
    gives two fields of one name."""
    path = sweep_file(tmp_path, seeds=2)
    sweep = plan.load(path)
    hand_made(sweep.runs[0], 2, 0.5, field={"name": "point_nav", "task": {"target": {"radius": 2}}})
    hand_made(sweep.runs[1], 2, 0.5, field={"name": "point_nav", "task": {"target": {"radius": 4}}})
    result = runner.invoke(app, ["sweep", str(path), "--status"])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and "no summary of point_nav (crl)" in message, result.output
    assert "trained on fields of that name that differ" in message and "Traceback" not in message
    assert not (sweep.folder / status.SUMMARY).exists()


def test_a_sweep_of_a_million_runs_is_refused_before_it_is_planned(tmp_path):
    """The runs are counted from the file's lists before any is planned: a million of them is one line, not
    gigabytes of plans before the first line of a dry run."""
    import tracemalloc

    path = sweep_file(tmp_path, seeds=1000, grid=f"  crl.repr_dim: {list(range(1, 1001))}")
    tracemalloc.start()
    try:
        with pytest.raises(plan.SweepError, match=r"plans 1,000,000 runs .*a sweep runs at most 10,000: split it"):
            plan.load(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 100_000_000, f"{peak:,} bytes"
    result = runner.invoke(app, ["sweep", str(path), "--dry-run", "--time", "1e12"])
    assert result.exit_code == 1 and result.output.startswith("error: --time 1e12: the minutes of a SLURM task") \
        and "from 1 to 525,600" in result.output, result.output


def test_the_slurm_backend_without_submitit_or_sbatch_is_one_line(tmp_path, monkeypatch):
    path = sweep_file(tmp_path, "backend: slurm\n", seeds=1)
    monkeypatch.setitem(sys.modules, "submitit", None)  # as if not installed
    result = runner.invoke(app, ["sweep", str(path)])
    assert result.exit_code == 1 and result.output.startswith("error: the slurm backend needs submitit, which is not "
                                                              "installed: pip install 'fieldgen[slurm]'")
    monkeypatch.delitem(sys.modules, "submitit")
    monkeypatch.setattr(shutil, "which", lambda name: None)
    result = runner.invoke(app, ["sweep", str(path)])
    assert result.exit_code == 1 and "sbatch is not on PATH" in result.output and len(result.output.splitlines()) == 1


def test_the_local_queue_gives_each_gpu_one_run_at_a_time_and_skips_finished_runs(tmp_path, monkeypatch):
    sweep = plan.load(sweep_file(tmp_path, "local: {gpus: [0, 3]}\n", seeds=5))
    hand_made(sweep.runs[4], 2, 1.0)  # finished before: not run again
    running, seen = {}, []

    def fake(folder, run, environment=None, on_start=None):
        gpu = environment["CUDA_VISIBLE_DEVICES"]
        assert gpu not in running, "two runs on one GPU"
        running[gpu] = run.id
        time.sleep(0.05)
        seen.append((run.seed, gpu))
        del running[gpu]
        return 0

    monkeypatch.setattr(launch, "execute", fake)
    results = launch.run_local(sweep, lambda line: None)
    assert sorted(seed for seed, _ in seen) == [0, 1, 2, 3] and {gpu for _, gpu in seen} == {"0", "3"}
    assert [code for _, code in results] == [0] * 4
    recorded = json.loads((sweep.folder / plan.PLAN).read_text())["runs"]
    assert recorded[sweep.runs[0].id] == list(sweep.runs[0].start)


def test_gpus_come_from_the_file_cuda_visible_devices_or_none(monkeypatch):
    assert launch.gpus([1, 2]) == ["1", "2"]
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "2,5")
    assert launch.gpus("auto") == ["2", "5"]
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "")
    assert launch.gpus("auto") == []


def test_status_tells_done_failed_stopped_and_waiting_then_summarizes_once_all_are_done(tmp_path):
    path = sweep_file(tmp_path, grid="  crl.repr_dim: [8, 16]", seeds=2)
    sweep = plan.load(path)
    a, b, c, d = sweep.runs
    hand_made(a, 2, 1.0)
    hand_made(b, 1, 0.5)  # stopped after its first evaluation
    (sweep.folder / launch.LOGS).mkdir(parents=True)
    launch.log_path(sweep.folder, b, ".started").write_text(json.dumps({"host": "elsewhere-not-here", "pid": 1}))
    launch.log_path(sweep.folder, b, ".ended").write_text(json.dumps({"exit": -9, "why": ""}))
    launch.log_path(sweep.folder, c, ".log").write_text("$ fieldgen train ...\nerror: --steps 10 is too few\n")
    launch.log_path(sweep.folder, c, ".ended").write_text(json.dumps({"exit": 1, "why": launch.why(
        launch.log_path(sweep.folder, c, ".log"), 1)}))
    result = runner.invoke(app, ["sweep", str(path), "--status"])
    assert result.exit_code == 1, result.output  # a run failed: the sweep's status says so, as make reads it
    found = {s.run.id: (s.state, s.detail) for s in status.states(sweep)}
    assert found[a.id] == ("done", "evaluation 2 of 2, 1,760 env steps")
    assert found[b.id][0] == "failed" and found[c.id] == ("failed", "error: --steps 10 is too few")
    assert found[d.id] == ("waiting", "not started")
    assert "1 done, 2 failed, 1 waiting" in result.output and not (sweep.folder / status.SUMMARY).exists()
    launch.log_path(sweep.folder, b, ".ended").unlink()  # no end recorded: its process, elsewhere, may still run
    assert (status.states(sweep)[1].state, status.states(sweep)[1].detail) == (
        "running", "evaluation 1 of 2, 1,280 env steps, on elsewhere-not-here")
    ended = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    launch.log_path(sweep.folder, b, ".started").write_text(json.dumps({"host": socket.gethostname(),
                                                                         "pid": int(ended.stdout)}))
    assert (status.states(sweep)[1].state, status.states(sweep)[1].detail) == (
        "stopped", "evaluation 1 of 2, 1,280 env steps; start the sweep again to continue it")
    for run, success in ((b, 0.5), (c, 0.25), (d, 0.75)):
        hand_made(run, 2, success)
    result = runner.invoke(app, ["sweep", str(path), "--status"])
    assert result.exit_code == 0 and "4 done" in result.output, result.output
    summary = json.loads((sweep.folder / status.SUMMARY).read_text())
    by_setting = {g["setting"]: g["summary"] for g in summary["groups"]}
    assert list(by_setting) == ["crl crl.repr_dim=8", "crl crl.repr_dim=16"]
    assert by_setting["crl crl.repr_dim=8"]["success_any"]["per_seed"] == {"0": 1.0, "1": 0.5}
    assert by_setting["crl crl.repr_dim=8"]["success_any"]["iqm"] == pytest.approx(0.75)  # two seeds: their mean
    assert by_setting["crl crl.repr_dim=16"]["episodes"] == 8 and by_setting["crl crl.repr_dim=16"]["actions"] == "mean"
    assert "| point_nav | crl crl.repr_dim=16 | 2 | 1,760 | 0.500 [" in (sweep.folder / status.TABLE).read_text()
    assert (sweep.folder / "summary-point_nav.png").stat().st_size > 10_000


def test_a_run_whose_run_json_was_lost_is_failed_with_the_way_on_not_sent_round_in_a_circle(tmp_path):
    """Its checkpoint is there, its record of settings and seeds is not: neither --resume nor a new start can use
    the folder, so status and `fieldgen train` both say what can (restore run.json, or move the folder away)."""
    path = sweep_file(tmp_path, seeds=1)
    (run,) = plan.load(path).runs
    hand_made(run, 1, 0.5)
    (run.folder / "learner.msgpack").write_bytes(b"learnt")
    (run.folder / "run.json").unlink()
    ((state, detail),) = [(s.state, s.detail) for s in status.states(plan.load(path))]
    assert state == "failed" and detail.startswith(f"{run.folder} holds a run's checkpoint but not its run.json")
    assert f"(mv {run.folder} {run.folder}.old) to train it anew" in detail
    result = runner.invoke(app, ["train", "point_nav", "--algo", "crl", "--seed", "0", "--out", str(run.folder.parent),
                                 "--steps", "5000", "--envs", "4", "--no-videos"])
    assert result.exit_code == 1 and "holds a run's checkpoint but not its run.json" in result.output, result.output
    assert (run.folder / "learner.msgpack").read_bytes() == b"learnt"  # nothing of the user's folder is touched


def test_status_exits_zero_when_done_one_when_a_run_failed_and_75_while_runs_wait(tmp_path):
    """`--status` tells failed from waiting in its exit status too, for scripts that poll it: 75 (sysexits'
    "try again later") while no run failed and some are still to come."""
    path = sweep_file(tmp_path, seeds=2)
    sweep = plan.load(path)
    waiting = runner.invoke(app, ["sweep", str(path), "--status"])
    assert waiting.exit_code == 75 and "2 waiting" in waiting.output, waiting.output
    hand_made(sweep.runs[0], 2, 0.5)
    assert runner.invoke(app, ["sweep", str(path), "--status"]).exit_code == 75
    log = launch.log_path(sweep.folder, sweep.runs[1], ".log")
    log.parent.mkdir(parents=True)
    log.write_text("error: --steps 10 is too few\n")
    launch._write_json(launch.log_path(sweep.folder, sweep.runs[1], ".ended"), {"exit": 1, "why": launch.why(log, 1)})
    failed = runner.invoke(app, ["sweep", str(path), "--status"])
    assert failed.exit_code == 1 and "1 done, 1 failed" in failed.output, failed.output
    assert "point_nav-crl-1 failed: error: --steps 10 is too few" in failed.output
    hand_made(sweep.runs[1], 2, 0.25)
    done = runner.invoke(app, ["sweep", str(path), "--status"])
    assert done.exit_code == 0 and "2 done" in done.output, done.output


def test_a_sweep_whose_every_run_failed_exits_one(tmp_path):
    """A run refused before it compiles (a replay buffer shorter than an episode) fails fast; the sweep that ran it
    says so in its exit."""
    path = sweep_file(tmp_path, seeds=1)
    path.write_text(path.read_text().replace("crl.max_replay_rows: 400", "crl.max_replay_rows: 60"))
    result = runner.invoke(app, ["sweep", str(path)])
    too_few = "max_replay_rows 60 must hold min_replay_rows (100) and one episode (100 steps)"
    assert result.exit_code == 1 and "1 failed" in result.output and too_few in result.output, \
        result.output
    assert "Traceback" not in result.output


def test_a_sweep_folder_removed_while_a_run_trains_is_one_line_and_not_success(tmp_path, monkeypatch):
    """Its runs' records cannot be written: the queue stops, and the sweep says what happened and exits 1,
    with no traceback from the thread that ran the run."""
    path = sweep_file(tmp_path, seeds=2)
    folder = plan.load(path).folder
    monkeypatch.setattr(launch, "fieldgen_command", lambda *words: [sys.executable, "-c",
                                                                     f"import shutil; shutil.rmtree({str(folder)!r})"])
    result = runner.invoke(app, ["sweep", str(path)])
    assert result.exit_code == 1, result.output
    assert result.output.rstrip().splitlines()[-1].startswith(f"error: the sweep's folder {folder} was removed while "
                                                              "its runs trained")
    assert "Traceback" not in result.output and "starts point_nav-crl-1" not in result.output


def test_a_sweep_file_changed_under_started_runs_is_refused(tmp_path):
    path = sweep_file(tmp_path, seeds=1)
    sweep = plan.load(path)
    launch.record_plan(sweep)
    hand_made(sweep.runs[0], 1, 0.0)
    path.write_text(path.read_text().replace("steps: 1900", "steps: 3800"))
    result = runner.invoke(app, ["sweep", str(path)])
    assert result.exit_code == 1 and "was started as `fieldgen train point_nav" in result.output
    assert "--steps 1900" in result.output and "now plans" in result.output


def test_a_sweep_folder_moved_whole_goes_on_where_a_changed_setting_is_still_refused(tmp_path):
    """Its runs were started with --out naming the old folder: that alone is no change of plan."""
    path = sweep_file(tmp_path, seeds=1, grid="  crl.repr_dim: [8, 16]")
    sweep = plan.load(path)
    launch.record_plan(sweep)
    for run in sweep.runs:
        hand_made(run, 2, 0.5)
    moved = tmp_path / "moved"
    shutil.move(sweep.folder, moved)
    result = runner.invoke(app, ["sweep", str(path), "--out", str(moved), "--status"])
    assert result.exit_code == 0 and "2 done" in result.output, result.output
    path.write_text(path.read_text().replace("steps: 1900", "steps: 3800"))
    result = runner.invoke(app, ["sweep", str(path), "--out", str(moved), "--status"])
    assert result.exit_code == 1 and "now plans" in result.output, result.output
    assert not plan._same_start(["train", "--out", "/a/crl.repr_dim=8"], ("train", "--out", str(moved / "crl.repr_dim=16")),
                                moved)  # another grid point's folder is another run


def test_two_sweep_files_of_one_name_are_refused_one_folder_unless_the_file_was_moved(tmp_path, monkeypatch):
    """sweeps/nav/sweep.yaml and sweeps/soccer/sweep.yaml both take runs/sweep-sweep: the second merged its runs
    into the first's plan, logs and summary, each --status replacing the other's summary.json."""
    monkeypatch.chdir(tmp_path)
    first, second = tmp_path / "nav" / "sweep.yaml", tmp_path / "soccer" / "sweep.yaml"
    for path, field in ((first, "point_nav"), (second, "point_soccer")):
        path.parent.mkdir()
        path.write_text(f"fields: [{field}]\nalgorithms: [crl]\nseeds: 1\nsteps: 14000\nenvs: 8\n")
    launch.record_plan(plan.load(first))
    result = runner.invoke(app, ["sweep", str(second), "--dry-run"])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and message.startswith(f"error: {second}: {tmp_path / 'runs' / 'sweep-sweep'} holds "
                                                        f"the sweep of {first.absolute()}, another sweep file"), message
    moved = tmp_path / "moved" / "sweep.yaml"  # the first file itself, moved: its sweep goes on
    moved.parent.mkdir()
    first.rename(moved)
    result = runner.invoke(app, ["sweep", str(moved), "--dry-run"])
    assert result.exit_code == 0 and "fieldgen train point_nav" in result.output, result.output


@pytest.mark.parametrize("edit,phrase", [
    (lambda plan_: {**plan_, "runs": []}, "runs: Input should be an object"),
    (lambda plan_: {**plan_, "runs": {"point_nav-crl-0": "fieldgen train"}}, "runs.point_nav-crl-0: Input should be a "
     "valid array"),
    (lambda plan_: {**plan_, "jobs": {"point_nav-crl-0": 7}}, "jobs.point_nav-crl-0: Input should be a valid string"),
    (lambda plan_: [plan_], "Input should be an object"),
], ids=["runs_list", "command_text", "job_number", "list"])
def test_a_hand_edited_sweep_json_is_one_line_naming_it(tmp_path, edit, phrase):
    """Before: an AttributeError or TypeError traceback from the plan's check, or --status reading past it."""
    path = sweep_file(tmp_path, seeds=1)
    sweep = plan.load(path)
    launch.record_plan(sweep)
    recorded = sweep.folder / plan.PLAN
    recorded.write_text(json.dumps(edit(json.loads(recorded.read_text()))))
    for args in ([], ["--status"]):
        result = runner.invoke(app, ["sweep", str(path), *args])
        message = " ".join(result.output.split())
        assert result.exit_code == 1 and "Traceback" not in message, result.output
        assert f"{recorded}: is not a plan fieldgen sweep wrote ({phrase}" in message, message
        assert "move it aside to plan the sweep anew" in message


def test_a_slurm_task_requeued_after_its_time_limit_continues_its_run(tmp_path):
    """submitit's checkpointing protocol: the requeued task is the same task with the same run, and a run
    whose folder exists goes on from it (`--resume`)."""
    sweep = plan.load(sweep_file(tmp_path, "backend: slurm\n", seeds=1))
    task, run = launch.Task(sweep.folder), sweep.runs[0]
    again = task.checkpoint(run)
    assert isinstance(again, submitit.helpers.DelayedSubmission)
    assert again.function is task and again.args == (run,)
    hand_made(run, 1, 0.0)
    assert run.command()[:2] == ("train", "--resume")


def test_a_run_stopped_at_its_time_limit_outside_a_submitit_task_is_not_killed_but_told_to_start_again(tmp_path):
    """The task requeues itself with submitit's signal, which would kill a process without submitit's handler."""
    with pytest.raises(RuntimeError, match="no submitit task to requeue; start the sweep again"):
        launch.requeue_this_task()


def test_a_run_stopped_at_its_time_limit_is_shown_stopped_and_requeued_not_failed(tmp_path):
    sweep = plan.load(sweep_file(tmp_path, "backend: slurm\n", seeds=1))
    run = sweep.runs[0]
    hand_made(run, 1, 0.5)
    launch.record_plan(sweep, {run.id: "77_0"})
    log = launch.log_path(sweep.folder, run, ".log")
    log.parent.mkdir(parents=True)
    log.write_text("stopped at the time limit after evaluation 1 of 2\n")
    launch._write_json(launch.log_path(sweep.folder, run, ".started"), {"host": "elsewhere", "pid": 1})
    launch._write_json(launch.log_path(sweep.folder, run, ".ended"), {"exit": 75, "why": launch.why(log, 75)})
    [state] = status.states(sweep)
    assert state.state == status.STOPPED, state
    assert state.detail == ("evaluation 1 of 2, 1,280 env steps; stopped at its time limit, checkpointed: requeued as "
                            "job 77_0, else start the sweep again to continue it")


def test_the_slurm_path_through_submitits_local_executor_records_failures_and_skips_done_runs(tmp_path):
    """The job array, its tasks running `fieldgen train` and writing how they ended: a run refused before it
    compiles fails fast with its reason; a finished run is not submitted."""
    path = sweep_file(tmp_path, "backend: slurm\nslurm: {gpus_per_task: 0, time: 5, stop_before: 1}\n", seeds=2)
    path.write_text(path.read_text().replace("crl.max_replay_rows: 400", "crl.max_replay_rows: 60"))  # refused
    sweep = plan.load(path)
    hand_made(sweep.runs[1], 2, 1.0)
    jobs = launch.submit(sweep, cluster="local")
    assert len(jobs) == 1
    with pytest.raises(Exception):
        jobs[0].result()
    found = {s.run.id: s for s in status.states(sweep)}
    assert found[sweep.runs[0].id].state == "failed"
    assert "max_replay_rows 60 must hold min_replay_rows" in found[sweep.runs[0].id].detail
    assert found[sweep.runs[1].id].state == "done"
    assert json.loads((sweep.folder / plan.PLAN).read_text())["jobs"][sweep.runs[0].id] == jobs[0].job_id


@pytest.mark.slow
def test_a_local_sweep_trains_summarizes_and_started_again_only_reports(tmp_path):
    path = sweep_file(tmp_path, seeds=1)
    result = runner.invoke(app, ["sweep", str(path)])
    assert result.exit_code == 0, result.output
    assert "1 done" in result.output and (tmp_path / "out" / status.SUMMARY).is_file()
    metrics = (tmp_path / "out" / "point_nav-crl-0" / "metrics.jsonl").read_text()
    again = runner.invoke(app, ["sweep", str(path)])
    assert again.exit_code == 0 and "starts" not in again.output
    assert (tmp_path / "out" / "point_nav-crl-0" / "metrics.jsonl").read_text() == metrics


@pytest.mark.slow
def test_a_slurm_task_whose_run_stops_at_its_time_limit_requeues_itself_and_the_run_goes_on(tmp_path):
    """A run given 0.6 s stops after its first chunk (nothing is measured before it, so it runs) at an
    evaluation, checkpointed, with status 75; its task requeues itself through submitit's signal, and the
    requeued task resumes the run, which this time has no time for a chunk. That second time-out is one more
    than `requeues: 1` allows, so submitit ends the job, and the run is left stopped, not failed."""
    body = "backend: slurm\nslurm: {gpus_per_task: 0, time: 10, stop_before: 9.99, requeues: 1}\n"
    sweep = plan.load(sweep_file(tmp_path, body, seeds=1))
    [job] = launch.submit(sweep, cluster="local")
    with pytest.raises(Exception, match="timed-out too many times"):
        job.result()
    run = sweep.runs[0]
    commands = [line for line in launch.log_path(sweep.folder, run, ".log").read_text().splitlines()
                if line.startswith("$ fieldgen train")]
    assert len(commands) == 2 and all(c.endswith("--time-limit 0.01m") for c in commands), commands
    assert "--resume" not in commands[0] and "--resume" in commands[1]
    rows = [json.loads(line) for line in (run.folder / "metrics.jsonl").read_text().splitlines()]
    assert rows[-1]["eval"] == 1 and (run.folder / "checkpoint.msgpack").is_file()
    [state] = status.states(sweep)
    assert state.state == status.STOPPED and "stopped at its time limit, checkpointed" in state.detail


@pytest.mark.slow
def test_a_slurm_sweep_trains_through_submitits_local_executor(tmp_path):
    sweep = plan.load(sweep_file(tmp_path, "backend: slurm\nslurm: {gpus_per_task: 0, time: 10}\n", seeds=1))
    jobs = launch.submit(sweep, cluster="local")
    assert [job.result() for job in jobs] == [0]
    assert [s.state for s in status.states(sweep)] == ["done"]


def test_a_run_a_signal_stopped_says_which_and_how_to_go_on(tmp_path):
    """A run's exit status names what stopped it when its log says nothing with `error:`: Ctrl-C, kill or the
    job's end (SIGTERM), a closed terminal (SIGHUP), or a signal it could not catch."""
    log = tmp_path / "run.log"
    log.write_text("$ fieldgen train --resume runs/x\nstopped by SIGTERM; the last checkpoint is intact.\n")
    assert launch.why(log, 143) == "stopped by SIGTERM; start the sweep again to continue it"
    assert launch.why(log, 129) == "stopped by SIGHUP; start the sweep again to continue it"
    assert launch.why(log, 130) == "interrupted (Ctrl-C); start the sweep again to continue it"
    assert launch.why(log, -9) == "stopped by signal 9"


@pytest.mark.parametrize("body,phrase", [
    ("seeds: [-1]\n", "seeds[0]: Input should be greater than or equal to 0 (got -1)"),
    ("local: {gpus: [-1]}\n", "local.gpus[0]: Input should be greater than or equal to 0 (got -1)"),
])
def test_a_list_with_a_wrong_item_is_refused_at_the_item_alone(tmp_path, body, phrase):
    """seeds takes a number or a list, local.gpus 'auto' or a list: a list with a wrong item is one problem, at the
    item, not also "expected a whole number (got a list)" from the choice a list is not."""
    path = tmp_path / "sweep.yaml"
    path.write_text("fields: [point_nav]\nalgorithms: [crl]\n" + body)
    result = runner.invoke(app, ["sweep", str(path), "--dry-run", "--out", str(tmp_path / "out")])
    said = " ".join(result.output.split())
    assert result.exit_code == 1 and phrase in said and "got a list" not in said and "'auto'" not in said, said
    assert len(result.output.strip().splitlines()) == 1


@pytest.mark.parametrize("text,phrase", [
    ("- crl\n", "a config file is a mapping with one section, 'crl:', of config keys"),
    ("crl:\n  hiden: [64]\n", "c.yaml:2: unknown config key 'hiden'; did you mean 'hidden'?"),
    ("crl: {repr_dim: 32}\nsac: {her: 0.5}\n", "c.yaml:2: section 'sac:' is not read by this run"),
])
def test_a_config_file_every_run_would_refuse_is_refused_by_the_plan(tmp_path, text, phrase):
    """The runs read `config:` with --config: the plan reads it as they will, before any starts."""
    (tmp_path / "c.yaml").write_text(text)
    path = tmp_path / "sweep.yaml"
    path.write_text("fields: [point_nav]\nalgorithms: [crl]\nseeds: 1\nsteps: 1900\nenvs: 8\nconfig: c.yaml\n")
    result = runner.invoke(app, ["sweep", str(path), "--dry-run", "--out", str(tmp_path / "out")])
    assert result.exit_code == 1 and result.output.startswith(f"error: {path}:6:1: config: the crl runs read it "
                                                              "with --config and would stop: "), result.output
    assert phrase in result.output and "fieldgen train" not in result.output


@pytest.mark.parametrize("curriculum,text,phrase", [
    ("", "crl: {num_evals: 2}\nsampler:\n  replaced: 8\n", "c.yaml:2: sampler: sets how the automatic curriculum "
                                                             "draws its levels, and this sweep makes none"),
    ("curriculum: auto\n", "sampler:\n  replaced: 99\n", "c.yaml:1: sampler: replaced 99 is more than the "
                                                          "buffer's 32 levels"),
])
def test_a_config_files_sampler_section_is_read_by_the_plan_as_its_runs_will(tmp_path, curriculum, text, phrase):
    (tmp_path / "c.yaml").write_text(text)
    path = tmp_path / "sweep.yaml"
    path.write_text(f"fields: [point_soccer]\nalgorithms: [crl]\nseeds: 1\nsteps: 20k\nenvs: 8\nconfig: c.yaml\n"
                    f"{curriculum}")
    result = runner.invoke(app, ["sweep", str(path), "--dry-run", "--out", str(tmp_path / "out")])
    said = " ".join(result.output.split())
    assert result.exit_code == 1 and said.startswith(f"error: {path}:6:1: config: ") and phrase in said, said
    (tmp_path / "c.yaml").write_text("sampler:\n  replaced: 8\n")
    sweep = plan.load(path) if curriculum else None
    if sweep is not None:  # the file's sampler reaches the run through --config, as `fieldgen train` reads it
        made = runner.invoke(app, [*sweep.runs[0].command(), "--prepare"])
        assert made.exit_code == 0, made.output
        assert json.loads((sweep.runs[0].folder / "run.json").read_text())["sampler"]["replaced"] == 8


def test_a_field_beside_the_sweep_folder_is_named_without_dot_dot_and_a_plan_recorded_with_it_goes_on(tmp_path):
    """`fields: [../mine.yaml]` printed `.../sweeps/../mine.yaml` in every command; a sweep started that way
    still goes on."""
    (tmp_path / "mine.yaml").write_text("extends: point_nav\nname: mine\n")
    (tmp_path / "sweeps").mkdir()
    path = sweep_file(tmp_path / "sweeps", seeds=1).rename(tmp_path / "sweeps" / "s.yaml")
    path.write_text(path.read_text().replace("fields: [point_nav]", "fields: [../mine.yaml]"))
    sweep = plan.load(path)
    assert sweep.runs[0].start[1] == str((tmp_path / "mine.yaml").resolve())
    launch.record_plan(sweep)
    hand_made(sweep.runs[0], 2, 0.5)
    was = list(sweep.runs[0].start)
    was[1] = str(tmp_path / "sweeps" / ".." / "mine.yaml")
    record = json.loads((sweep.folder / "sweep.json").read_text())
    record["runs"][sweep.runs[0].id] = was
    (sweep.folder / "sweep.json").write_text(json.dumps(record))
    plan.check_plan(plan.load(path))  # the same file, written otherwise: no change of plan
    assert not plan._same_file("crl.repr_dim=8", "crl.repr_dim=16")


def test_a_grid_point_with_too_few_steps_for_its_runs_is_refused_before_any_run_starts(tmp_path):
    """Each run would stop at its start (on a cluster, after its wait in the queue): the plan says so, naming the
    point, where the others fit."""
    path = sweep_file(tmp_path, seeds=1, grid="  crl.num_evals: [2, 50]")
    result = runner.invoke(app, ["sweep", str(path), "--dry-run"])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and "sweep.yaml:4:1: steps: the crl runs on point_nav, crl.num_evals=50 would stop " \
                                     "at their start: 1,900 env steps" in message, result.output
    assert "are too few" in message and "crl.num_evals=2 " not in message
    # in the sweep file's own keys, not the command line's flags
    assert "(steps: or crl.total_steps)" in message and "--" not in message.split("would stop")[1], result.output
    path.write_text(path.read_text().replace("[2, 50]", "[2, 3]"))
    assert runner.invoke(app, ["sweep", str(path), "--dry-run"]).exit_code == 0
