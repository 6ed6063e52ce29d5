"""Images of a field with mujoco's offscreen renderer (headless through EGL or OSMesa)."""

from __future__ import annotations

import contextlib
import io
import math
import os

import imageio.v3 as iio
import mujoco
import numpy as np

from fieldgen.compile.cameras import CAMERAS, TOP

HEIGHT = 480  # of a still; videos are drawn half as high
PERSPECTIVE_ASPECT = 4 / 3
# Geom groups beside the bodies' 0: floor markings (lines, the goal area, the target) are drawn in every
# view; the goal's volume and net only in perspective ones, since from above they would veil the goal
# area and the target.
MARKINGS, SIDE_VIEW = 1, 2
MARKED = ("torso", "agent", "ball")  # geoms the top view puts a disc under: the ant's torso, the point, the ball
MARK_RADIUS = 0.02  # of the top view's height


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


def frame_size(model: mujoco.MjModel, camera: str, height: int) -> tuple[int, int]:
    """(height, width) of a frame from `camera` in its own aspect: an orthographic camera's resolution (the
    top view's is the field's aspect), 4:3 for a perspective one. Widths are multiples of 16, which video
    encoders take without rescaling."""
    w, h = model.cam_resolution[model.cam(camera).id]
    aspect = w / h if _view_height(model, camera) is not None else PERSPECTIVE_ASPECT
    return height, max(16, 16 * round(height * aspect / 16))


def render_pose(model: mujoco.MjModel, qpos: np.ndarray | None = None, camera: str = "top",
                height: int = HEIGHT) -> np.ndarray:
    """One RGB frame of the model at `qpos` (default: the `home` keyframe)."""
    data = mujoco.MjData(model)
    data.qpos[:] = model.key("home").qpos if qpos is None else qpos
    mujoco.mj_forward(model, data)
    with renderer(model, frame_size(model, camera, height)) as r:
        r.update_scene(data, camera=camera, scene_option=_scene_option(model, camera))
        _mark(model, data, r.scene, camera)
        return r.render()


def preview(model: mujoco.MjModel) -> np.ndarray:
    """The top-down view and the view from the agent's start, side by side."""
    return np.concatenate([render_pose(model, camera=c) for c in CAMERAS], axis=1)


def render_rollout(model: mujoco.MjModel, qpos: np.ndarray, mocap_pos: np.ndarray, camera: str = "follow",
                   height: int = HEIGHT // 2) -> list[np.ndarray]:
    """Frames of a recorded rollout: qpos [T, nq] and mocap_pos [T, nmocap, 3]."""
    data = mujoco.MjData(model)
    frames = []
    with renderer(model, frame_size(model, camera, height)) as r:
        for q, m in zip(qpos, mocap_pos):
            data.qpos[:], data.mocap_pos[:] = q, m
            mujoco.mj_forward(model, data)
            r.update_scene(data, camera=camera, scene_option=_scene_option(model, camera))
            _mark(model, data, r.scene, camera)
            frames.append(r.render())
    return frames


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


def _scene_option(model: mujoco.MjModel, camera: str) -> mujoco.MjvOption:
    """Bodies and floor markings in every view; the goal's volume and net only in views from the side."""
    option = mujoco.MjvOption()
    option.geomgroup[:] = 0
    option.geomgroup[:SIDE_VIEW + (_view_height(model, camera) is None)] = 1
    return option


def _mark(model: mujoco.MjModel, data: mujoco.MjData, scene: mujoco.MjvScene, camera: str) -> None:
    """In the top view, a translucent disc in its own colour under the agent and under the ball, so both
    show at a glance however large the field; they are drawn, not simulated."""
    height = _view_height(model, camera)
    if height is None:
        return
    radius = MARK_RADIUS * height
    for name in MARKED:
        geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
        if geom < 0 or scene.ngeom == scene.maxgeom:
            continue
        x, y, _ = data.geom_xpos[geom]
        rgba = np.array([*model.geom_rgba[geom][:3], 0.6], dtype=np.float32)
        mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_CYLINDER,
                            np.array([max(radius, 1.5 * model.geom_size[geom][0]), 0.005, 0.0]),
                            np.array([x, y, 0.01]), np.eye(3).ravel(), rgba)
        scene.ngeom += 1


def _view_height(model: mujoco.MjModel, camera: str) -> float | None:
    """The metres a view straight down frames from bottom to top: an orthographic camera's fovy, or what the
    top camera sees of the floor where a field too large for an orthographic one has it in perspective
    (fieldgen.compile.scene); None for a view from the side."""
    i = model.cam(camera).id
    if model.cam_projection[i] == mujoco.mjtProjection.mjPROJ_ORTHOGRAPHIC:
        return float(model.cam_fovy[i])
    if camera == TOP:
        return float(2 * model.cam_pos[i][2] * math.tan(math.radians(model.cam_fovy[i] / 2)))
    return None
