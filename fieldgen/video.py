"""Frames as a video file: MP4 through imageio's ffmpeg plugin (imageio-ffmpeg ships the encoder), the
default where that encoder is installed, or a GIF kept small: one palette of a few colours for every
frame, no dithering (which would change most pixels between frames), and at most GIF_FPS frames a second."""

from __future__ import annotations

import io
import math
import warnings
from typing import Literal, get_args

import numpy as np

Format = Literal["mp4", "gif"]
FORMATS: tuple[str, ...] = get_args(Format)
GIF_COLOURS = 32  # the scenes are a few flat colours under shading: 32 keep them, 256 mostly add noise
GIF_FPS = 10.0
SLOWEST_FPS = 1.0  # a slower field plays faster than its own time: ffmpeg and GIF cannot hold a frame for hours


class VideoError(Exception):
    """A video format this machine cannot write."""


def encoder_installed() -> bool:
    """Whether imageio's ffmpeg plugin finds an ffmpeg to encode MP4 with."""
    try:
        import imageio_ffmpeg

        imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):
        return False
    return True


def choose(fmt: str | None) -> str:
    """The format to write: `fmt`, or by default mp4 where its encoder is installed and gif otherwise."""
    if fmt is None:
        return "mp4" if encoder_installed() else "gif"
    if fmt not in FORMATS:
        raise VideoError(f"unknown video format '{fmt}'; choose one of: {', '.join(FORMATS)}")
    if fmt == "mp4" and not encoder_installed():
        raise VideoError("mp4 videos need imageio-ffmpeg's encoder, which is not installed here: "
                         "pip install imageio-ffmpeg==0.8.1 (fieldgen's own dependencies include it), "
                         "or pass --video-format gif")
    return fmt


def encode(frames: list[np.ndarray], fps: float, fmt: str) -> tuple[bytes, int]:
    """The video file's bytes and how many frames it holds (a GIF may keep fewer than it was given)."""
    fps = max(fps, SLOWEST_FPS)
    return _mp4(frames, fps) if fmt == "mp4" else _gif(frames, fps)


def _mp4(frames: list[np.ndarray], fps: float) -> tuple[bytes, int]:
    import imageio.v3 as iio

    # ffmpeg runs as a child process that execs at once, which JAX's warning against forking it does not concern.
    warnings.filterwarnings("ignore", message=r"os\.fork\(\) was called", category=RuntimeWarning, module="subprocess")
    buf = io.BytesIO()
    iio.imwrite(buf, np.stack(frames), extension=".mp4", fps=fps)
    return buf.getvalue(), len(frames)


def _gif(frames: list[np.ndarray], fps: float) -> tuple[bytes, int]:
    from PIL import Image

    stride = max(1, math.ceil(fps / GIF_FPS - 1e-9))
    kept = frames[::stride]
    sample = np.concatenate(kept[:: max(1, len(kept) // 8)], axis=0)  # a few frames spread over the episode
    palette = Image.fromarray(sample).quantize(GIF_COLOURS, method=Image.Quantize.FASTOCTREE,
                                               dither=Image.Dither.NONE)
    images = [Image.fromarray(f).quantize(palette=palette, dither=Image.Dither.NONE) for f in kept]
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], duration=1000 * stride / fps,
                   loop=0, optimize=True)
    return buf.getvalue(), len(images)
