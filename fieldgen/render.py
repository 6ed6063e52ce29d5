"""Images of a field with mujoco's offscreen renderer (headless through EGL)."""

from __future__ import annotations

import io

import imageio.v3 as iio
import mujoco
import numpy as np

CAMERAS = ("top", "follow")
SIZE = (480, 640)  # height, width; the top camera frames the field for this aspect


def render_pose(model: mujoco.MjModel, qpos: np.ndarray | None = None, camera: str = "top",
                size: tuple[int, int] = SIZE) -> np.ndarray:
    """One RGB frame of the model at `qpos` (default: the `home` keyframe)."""
    data = mujoco.MjData(model)
    data.qpos[:] = model.key("home").qpos if qpos is None else qpos
    mujoco.mj_forward(model, data)
    with mujoco.Renderer(model, height=size[0], width=size[1]) as renderer:
        renderer.update_scene(data, camera=camera, scene_option=_scene_option())
        return renderer.render()


def preview(model: mujoco.MjModel) -> np.ndarray:
    """The top-down view and the view from the agent's start, side by side."""
    return np.concatenate([render_pose(model, camera=c) for c in CAMERAS], axis=1)


def render_rollout(model: mujoco.MjModel, qpos: np.ndarray, mocap_pos: np.ndarray, camera: str = "follow",
                   size: tuple[int, int] = (240, 320)) -> list[np.ndarray]:
    """Frames of a recorded rollout: qpos [T, nq] and mocap_pos [T, nmocap, 3]."""
    data = mujoco.MjData(model)
    frames = []
    with mujoco.Renderer(model, height=size[0], width=size[1]) as renderer:
        for q, m in zip(qpos, mocap_pos):
            data.qpos[:], data.mocap_pos[:] = q, m
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera=camera, scene_option=_scene_option())
            frames.append(renderer.render())
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
