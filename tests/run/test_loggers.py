"""Logging where researchers look: TensorBoard event files and Weights & Biases (offline) get every number
of each evaluation and its video; a log that is not a terminal gets a plain line per evaluation."""

from __future__ import annotations

import json
import re
import struct
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
from typer.testing import CliRunner

from fieldgen.cli import app
from fieldgen.run import loggers

runner = CliRunner()
ROWS = [{"eval": 1, "seed": s, "env_steps": 1000, "success_any": 0.25 + s, "critic_loss": 3.5, "entropy": 1.2,
         "term_ball_progress": -0.5, "steps_per_second": 2000.0, "stage": 0,
         "variants": {"success_any": [0.5, 0.125]}} for s in (0, 1)]


def events(folder: Path) -> list:
    """The events of a TensorBoard folder, read from its TFRecord files (length, its CRC, data, its CRC)."""
    from tensorboardX.proto.event_pb2 import Event

    found = []
    for path in sorted(folder.glob("events.out.tfevents.*")):
        data, at = path.read_bytes(), 0
        while at < len(data):
            (length,) = struct.unpack("<Q", data[at:at + 8])
            event = Event()
            event.ParseFromString(data[at + 12:at + 12 + length])
            found.append(event)
            at += 16 + length
    return [e for e in found if e.HasField("summary")]


def scalars_of(folder: Path) -> dict[str, list[tuple[int, float]]]:
    out: dict = {}
    for event in events(folder):
        for value in event.summary.value:
            if value.HasField("simple_value"):
                out.setdefault(value.tag, []).append((event.step, value.simple_value))
    return out


def a_gif(path: Path) -> Path:
    frames = np.zeros((3, 12, 16, 3), np.uint8)
    frames[:, :, :8] = 200
    iio.imwrite(path, frames, extension=".gif")
    return path


def test_tensorboard_gets_every_number_per_seed_and_the_video(tmp_path):
    logger = loggers.open_logger("tensorboard", tmp_path, [0, 1], {})
    logger.rows(ROWS)
    logger.video(a_gif(tmp_path / "eval_001.gif"), 1000)
    logger.close()
    seed0, seed1 = (scalars_of(tmp_path / "tensorboard" / f"seed_{s}") for s in (0, 1))
    assert seed0 == {"success_any": [(1000, 0.25)], "critic_loss": [(1000, 3.5)],
                     "entropy": [(1000, pytest.approx(1.2))], "term_ball_progress": [(1000, -0.5)],
                     "steps_per_second": [(1000, 2000.0)], "stage": [(1000, 0.0)],
                     "variants.success_any.1": [(1000, 0.5)], "variants.success_any.2": [(1000, 0.125)]}
    assert seed1["success_any"] == [(1000, 1.25)]
    images = [(e.step, v) for e in events(tmp_path / "tensorboard" / "seed_0") for v in e.summary.value
              if v.HasField("image")]
    assert len(images) == 1 and images[0][0] == 1000 and images[0][1].tag == "video"
    image = images[0][1].image
    assert (image.height, image.width) == (12, 16)
    assert image.encoded_image_string == (tmp_path / "eval_001.gif").read_bytes()


def test_wandb_offline_gets_every_number_and_the_video(tmp_path, monkeypatch):
    pytest.importorskip("wandb")
    monkeypatch.setenv("WANDB_MODE", "offline")
    monkeypatch.setenv("WANDB_SILENT", "true")
    logger = loggers.open_logger("wandb", tmp_path, [0, 1], {"algo": "crl", "num_envs": 8})
    logger.rows(ROWS)
    logger.video(a_gif(tmp_path / "eval_001.gif"), 1000)
    summary = dict(logger.run.summary)
    config = dict(logger.run.config)
    logger.close()
    assert summary["seed_0/success_any"] == 0.25 and summary["seed_1/success_any"] == 1.25
    assert summary["seed_0/critic_loss"] == 3.5 and summary["seed_1/variants.success_any.2"] == 0.125
    assert summary["env_steps"] == 1000 and config == {"algo": "crl", "num_envs": 8}
    [run] = (tmp_path / "wandb").glob("offline-run-*")
    [video] = (run / "files" / "media" / "videos").glob("*.gif")
    assert video.read_bytes() == (tmp_path / "eval_001.gif").read_bytes()
    log = next(run.glob("run-*.wandb")).read_bytes()
    assert all(name.encode() in log for name in ("seed_0/entropy", "seed_1/steps_per_second", "term_ball_progress"))


def test_an_unknown_logger_is_refused_before_anything_loads(tmp_path):
    result = runner.invoke(app, ["train", "point_nav", "--logger", "tensorbord", "--out", str(tmp_path)])
    assert result.exit_code == 1 and "unknown logger 'tensorbord'; did you mean 'tensorboard'?" in result.output
    assert not any(tmp_path.iterdir())


@pytest.mark.slow
def test_train_logs_to_tensorboard_and_prints_a_line_per_evaluation(tmp_path, tiny_crl_args):
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--logger", "tensorboard",
                                 *tiny_crl_args])
    assert result.exit_code == 0, result.output
    lines = re.findall(r"^point_nav ([\d,]+) of 1,760 steps \(\d+%\)  .*success 0\.\d\d", result.output, re.M)
    assert lines == ["800", "1,280", "1,760"], result.output  # one per evaluation, as they come
    run = tmp_path / "point_nav-crl-0"
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    logged = scalars_of(run / "tensorboard" / "seed_0")
    for name in ("success_any", "time_at_goal", "critic_loss", "actor_loss", "entropy", "steps_per_second"):
        assert logged[name] == [(r["env_steps"], pytest.approx(r[name])) for r in rows if name in r], name
    assert set(logged) == set().union(*(loggers.scalars(r) for r in rows))
    videos = [e.step for e in events(run / "tensorboard" / "seed_0") for v in e.summary.value if v.HasField("image")]
    assert videos == [r["env_steps"] for r in rows]
    assert iio.imread(run / "success.png").shape[:2] == (720, 1500)  # four panels, three a row


@pytest.mark.slow
def test_train_logs_to_wandb_offline(tmp_path, monkeypatch, tiny_crl_args):
    pytest.importorskip("wandb")
    monkeypatch.setenv("WANDB_MODE", "offline")
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--logger", "wandb", "--no-videos",
                                 *tiny_crl_args])
    assert result.exit_code == 0, result.output
    [run] = (tmp_path / "point_nav-crl-0" / "wandb").glob("offline-run-*")
    log = next(run.glob("run-*.wandb")).read_bytes()
    assert all(name.encode() in log for name in ("success_any", "critic_loss", "entropy", "steps_per_second"))


def test_a_log_that_is_not_a_terminal_gets_a_line_per_evaluation():
    import io

    from rich.console import Console

    from fieldgen.run.progress import display

    log = io.StringIO()
    with display(Console(file=log, width=60)) as bar:  # a file: no live display, which would print only at the end
        task = bar.add_task("point_nav", total=1900, completed=0, rate="compiling...", stats="")
        bar.update(task, completed=800, rate="", stats="success 0.00  at goal 0.0")
        assert log.getvalue() == "point_nav 800 of 1,900 steps (42%)  success 0.00  at goal 0.0\n"
        bar.update(task, completed=1280, rate="6 steps/s, 2 min left", stats="success 0.25  at goal 3.0  critic 4.363")
        bar.update(task, total=1760, rate="814 steps/s")  # the end: no new evaluation, no line
    assert log.getvalue().splitlines()[1:] == [
        "point_nav 1,280 of 1,900 steps (67%)  6 steps/s, 2 min left  success 0.25  at goal 3.0  critic 4.363"]


def test_wandb_not_installed_is_one_sentence_before_anything_is_written(tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "wandb", None)  # what an install without the extra finds
    result = runner.invoke(app, ["train", "point_nav", "--logger", "wandb", "--out", str(tmp_path)])
    assert result.exit_code == 1 and "pip install 'fieldgen[wandb]'" in result.output, result.output
    assert "Traceback" not in result.output and not any(tmp_path.iterdir())


def test_a_rows_place_is_not_logged_as_a_measurement():
    row = dict(ROWS[0], eval=3, env_steps=5000, refilled_from=4000)
    logged = loggers.scalars(row)
    assert "success_any" in logged and "variants.success_any.2" in logged
    assert not {"eval", "seed", "env_steps", "refilled_from"} & set(logged)
