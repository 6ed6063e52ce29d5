"""Side files a run reads besides its records: --config files and the episodes a run kept to draw later, read
within bounds and checked against what they claim to be, each problem one paragraph."""

from __future__ import annotations

import io

import numpy as np
import pytest
from typer.testing import CliRunner

from fieldgen.cli import app

runner = CliRunner()

BOMB = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{c}: &{c} [{', '.join([f'*{p}'] * 10)}]\n" for p, c in zip("abcdefgh", "bcdefghi")) + "crl: {seed: 1}\n"


@pytest.mark.parametrize("text,phrase", [
    (BOMB, "values, each alias counted as what it repeats, most of them here; at most 30,000 are allowed"),
    ("crl:\n  repr_dim: 8\n  repr_dim: 16\n", "config.yaml:3:3: crl.repr_dim: duplicate key 'repr_dim' (first given on "
     "line 2)"),
    ("- crl\n", "config.yaml:1:1: the document is a list; a config file is a mapping of sections"),
    ("", "config.yaml:1:1: the file is empty; a config file holds a section per algorithm, such as 'crl:'"),
    ("crl: {seed: 1}\n\x07", "character U+0007 (a control character) is not allowed in YAML"),
    ("crl:\n" + "  # padding\n" * 100_000, "a config file may have at most 1,000,000"),
], ids=["alias_bomb", "duplicate", "list", "empty", "control", "huge"])
def test_a_config_file_is_read_within_bounds(tmp_path, text, phrase):
    """Before: an alias bomb was expanded (minutes and gigabytes), a duplicate key silently took the last value."""
    config = tmp_path / "config.yaml"
    config.write_text(text)
    result = runner.invoke(app, ["train", "point_nav", "--config", str(config), "--prepare", "--out",
                                 str(tmp_path / "runs")])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and "Traceback" not in message, result.output
    assert f"error: --config {config}" in message and phrase in message and message.count(str(config)) == 1
    assert not (tmp_path / "runs").exists()


@pytest.fixture(scope="module")
def prepared(tmp_path_factory, tiny_crl_args):
    out = tmp_path_factory.mktemp("runs")
    result = runner.invoke(app, ["train", "point_nav", "--out", str(out), "--prepare", *tiny_crl_args])
    assert result.exit_code == 0, result.output
    return out / "point_nav-crl-0"


def kept(run, pack=np.savez, **changes) -> None:
    """videos/eval_000.npz as a machine that cannot render keeps it (`pack`: numpy's savez), with `changes`."""
    from fieldgen.run.session import open_run

    model = open_run(run, load_state=False).env.mj_model
    episode = {"field": "point_nav", "camera": "follow", "qpos": np.zeros((30, model.nq)),
               "mocap_pos": np.zeros((30, model.nmocap, 3)), "fps": 25.0,
               **{k: v(model) if callable(v) else v for k, v in changes.items()}}
    buf = io.BytesIO()
    pack(buf, **{k: v for k, v in episode.items() if v is not None})
    (run / "videos").mkdir(exist_ok=True)
    (run / "videos" / "eval_000.npz").write_bytes(buf.getvalue())


@pytest.mark.parametrize("changes,phrase", [
    ({"qpos": lambda m: np.zeros((30, m.nq + 1))}, "qpos should be [frames, "),
    ({"qpos": None}, "qpos should be [frames, "),
    ({"qpos": lambda m: np.zeros((0, m.nq))}, "with 1 to 1000 frames"),
    ({"qpos": lambda m: np.zeros((100_000, m.nq)), "mocap_pos": lambda m: np.zeros((100_000, m.nmocap, 3))},
     "with 1 to 1000 frames, not [100000, "),
    ({"mocap_pos": np.zeros((29, 1, 3))}, "mocap_pos should be [30, "),
    ({"qpos": lambda m: np.full((30, m.nq), np.nan)}, "its positions are not all finite numbers"),
    ({"mocap_pos": lambda m: np.full((30, m.nmocap, 3), "x")}, "its positions are not all finite numbers"),
    ({"fps": 0.0}, "fps should be one number above 0 and at most 10,000, not 0.0"),
    ({"fps": 1e300}, "fps should be one number above 0 and at most 10,000, not 1e+300"),
    ({"fps": np.array([1.0, 2.0])}, "fps should be one number above 0 and at most 10,000, not [1.0, 2.0]"),
    ({"camera": "overhead"}, "camera should be one of"),
], ids=["width", "no_qpos", "no_frames", "frames_to_fill_memory", "mocap", "nan", "mocap_text", "fps", "fps_huge",
        "fps_list", "camera"])
def test_a_damaged_kept_episode_is_named_not_drawn(prepared, changes, phrase):
    """Before: a wrong width or frame count was an error from inside the renderer, a NaN a video of nothing."""
    kept(prepared, **changes)
    result = runner.invoke(app, ["videos", str(prepared), "--video-format", "gif"])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and "Traceback" not in message, result.output
    assert f"{prepared / 'videos' / 'eval_000.npz'} is not an episode kept by fieldgen train: " in message
    assert phrase in message and "delete it or train again" in message


def test_a_kept_episode_that_unpacks_to_gigabytes_is_refused_unread(prepared):
    """Before: an .npz of half a megabyte packed from 512 MB of zeros was unpacked whole before any check."""
    kept(prepared, np.savez_compressed, qpos=np.zeros((8192, 8192)))
    assert (prepared / "videos" / "eval_000.npz").stat().st_size < 2**20
    result = runner.invoke(app, ["videos", str(prepared), "--video-format", "gif"])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and "Traceback" not in message, result.output
    assert f"{prepared / 'videos' / 'eval_000.npz'} unpacks to 536,8" in message and "delete it or train again" in message


def test_a_folder_where_a_kept_episodes_video_goes_is_named_not_taken_for_the_video(prepared):
    """Before: a folder named eval_000.gif was listed as the episode's video, already drawn."""
    kept(prepared)
    (prepared / "videos" / "eval_000.gif").mkdir()
    try:
        result = runner.invoke(app, ["videos", str(prepared), "--video-format", "gif"])
    finally:
        (prepared / "videos" / "eval_000.gif").rmdir()
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and "Traceback" not in message, result.output
    assert f"{prepared / 'videos' / 'eval_000.gif'} is a folder where the video of eval_000.npz goes; move it aside, " \
           "or draw the episodes as mp4 (--video-format)" in message
