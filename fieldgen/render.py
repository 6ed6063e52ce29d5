"""Images of a field with mujoco's offscreen renderer (headless through EGL or OSMesa)."""

from __future__ import annotations

import contextlib
import io
import os

import imageio.v3 as iio
import mujoco
import numpy as np

CAMERAS = ("top", "follow")
SIZE = (480, 640)  # height, width; the top camera frames the field for this aspect


class RenderError(RuntimeError):
    """mujoco's renderer cannot start on this machine."""


@contextlib.contextmanager
def renderer(model: mujoco.MjModel, size: tuple[int, int]):
    """A mujoco.Renderer, or a RenderError that says what is missing instead of the back end's traceback."""
    try:
        context = mujoco.Renderer(model, height=size[0], width=size[1])
    except Exception as exc:  # noqa: BLE001 - each OpenGL back end fails in its own way
        backend = os.environ.get("MUJOCO_GL", "")
        why = "no EGL or OSMesa library was found" if backend == "disable" else f"MUJOCO_GL={backend}: {exc}"
        raise RenderError(
            f"mujoco cannot render on this machine ({why}); install EGL (Debian and Ubuntu: apt install "
            "libegl1) or OSMesa (libosmesa6), or set MUJOCO_GL to a back end that works here") from exc
    with context:
        yield context


def render_pose(model: mujoco.MjModel, qpos: np.ndarray | None = None, camera: str = "top",
                size: tuple[int, int] = SIZE) -> np.ndarray:
    """One RGB frame of the model at `qpos` (default: the `home` keyframe)."""
    data = mujoco.MjData(model)
    data.qpos[:] = model.key("home").qpos if qpos is None else qpos
    mujoco.mj_forward(model, data)
    with renderer(model, size) as r:
        r.update_scene(data, camera=camera, scene_option=_scene_option())
        return r.render()


def preview(model: mujoco.MjModel) -> np.ndarray:
    """The top-down view and the view from the agent's start, side by side."""
    return np.concatenate([render_pose(model, camera=c) for c in CAMERAS], axis=1)


def render_rollout(model: mujoco.MjModel, qpos: np.ndarray, mocap_pos: np.ndarray, camera: str = "follow",
                   size: tuple[int, int] = (240, 320)) -> list[np.ndarray]:
    """Frames of a recorded rollout: qpos [T, nq] and mocap_pos [T, nmocap, 3]."""
    data = mujoco.MjData(model)
    frames = []
    with renderer(model, size) as r:
        for q, m in zip(qpos, mocap_pos):
            data.qpos[:], data.mocap_pos[:] = q, m
            mujoco.mj_forward(model, data)
            r.update_scene(data, camera=camera, scene_option=_scene_option())
            frames.append(r.render())
    return frames


def gif_bytes(frames: list[np.ndarray], fps: float) -> bytes:
    buf = io.BytesIO()
    iio.imwrite(buf, np.stack(frames), extension=".gif", duration=1000 / fps, loop=0)
    return buf.getvalue()


def png_bytes(image: np.ndarray) -> bytes:
    buf = io.BytesIO()
    iio.imwrite(buf, image, extension=".png")
    return buf.getvalue()


def contact_sheet(images: list[np.ndarray], titles: list[str], columns: int = 3) -> bytes:
    """PNG bytes of images in a grid, each under its title."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = -(-len(images) // columns)
    cols = min(columns, len(images))
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.7 * rows), squeeze=False)
    for ax in axes.flat:
        ax.axis("off")
    for ax, image, title in zip(axes.flat, images, titles):
        ax.imshow(image)
        ax.set_title(title, fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    return buf.getvalue()


def _scene_option() -> mujoco.MjvOption:
    option = mujoco.MjvOption()
    option.geomgroup[:] = 1  # show the painted lines, goal region, net and target marker
    return option
