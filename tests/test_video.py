"""Videos of episodes: MP4 keeps every frame; a GIF stays small; mp4 is the default only where it can be written."""

from __future__ import annotations

import io
import warnings

import imageio.v3 as iio
import jax
import numpy as np
import pytest
from PIL import Image

from fieldgen import video
from fieldgen.compile.artifact import compile_spec
from fieldgen.render import render_rollout
from fieldgen.schema import bundled_fields, load_spec

FPS = 20.0  # point_soccer's control rate


@pytest.fixture(scope="module")
def frames():
    """40 follow-view frames of point_soccer's point crossing towards the ball."""
    model = compile_spec(load_spec(bundled_fields()["point_soccer"])).model()
    qpos = np.repeat(model.key("home").qpos[None], 40, axis=0)
    qpos[:, 1] = np.linspace(-2.0, 1.0, 40)
    return render_rollout(model, qpos, np.repeat(model.body("target").pos[None, None], 40, axis=0))


def no_encoder(monkeypatch):
    import imageio_ffmpeg

    def missing():
        raise RuntimeError("No ffmpeg exe could be found")

    monkeypatch.setattr(imageio_ffmpeg, "get_ffmpeg_exe", missing)


def test_mp4_keeps_every_frame(frames):
    jax.numpy.zeros(1).block_until_ready()  # JAX running, as while training
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        data, count = video.encode(frames, FPS, "mp4")
    assert not caught  # nor a warning about starting ffmpeg from a JAX process
    assert data[4:8] == b"ftyp" and count == 40
    back = iio.imread(data, extension=".mp4", index=None)
    assert back.shape == (40, 240, 320, 3)
    assert np.abs(back.astype(int) - np.stack(frames)).mean() < 6  # lossy, but the same pictures


def test_gif_is_a_fraction_of_a_plain_gif(frames):
    plain = io.BytesIO()
    iio.imwrite(plain, np.stack(frames), extension=".gif", duration=1000 / FPS, loop=0)
    data, count = video.encode(frames, FPS, "gif")
    assert count == 20  # 20 frames a second drawn at 10
    assert len(data) < len(plain.getvalue()) / 4
    gif = Image.open(io.BytesIO(data))
    assert gif.n_frames == 20 and gif.info["duration"] == 100
    colours = set()
    for i in range(gif.n_frames):
        gif.seek(i)
        colours |= {c for _, c in gif.convert("RGB").getcolors(maxcolors=4096)}
    assert len(colours) <= video.GIF_COLOURS
    back = iio.imread(data, extension=".gif", index=None)[..., :3]
    assert np.abs(back.astype(int) - np.stack(frames[::2])).mean() < 6


def test_mp4_is_the_default_only_where_its_encoder_is_installed(monkeypatch):
    assert video.encoder_installed() and video.choose(None) == "mp4"
    assert video.choose("gif") == "gif"
    no_encoder(monkeypatch)
    assert video.choose(None) == "gif"
    with pytest.raises(video.VideoError, match="pip install imageio-ffmpeg.*or pass --video-format gif"):
        video.choose("mp4")
    with pytest.raises(video.VideoError, match="unknown video format 'avi'; choose one of: mp4, gif"):
        video.choose("avi")


@pytest.mark.parametrize("fmt", video.FORMATS)
def test_a_field_slower_than_a_frame_a_second_still_encodes(frames, fmt):
    """A spec may ask for 10 s control steps: the video plays at a frame a second, which both formats can hold."""
    data, count = video.encode(frames[:4], 1e-6, fmt)
    back = iio.imread(data, extension=f".{fmt}", index=None)
    assert count == 4 and len(back) == 4
    if fmt == "gif":
        assert Image.open(io.BytesIO(data)).info["duration"] == 1000
