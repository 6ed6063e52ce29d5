"""Images of a field with mujoco's offscreen renderer (headless through EGL or OSMesa)."""

from __future__ import annotations

import contextlib
import io
import math
import os
import textwrap

import imageio.v3 as iio
import mujoco
import numpy as np

from fieldgen.cameras import CAMERAS, TOP

HEIGHT = 480  # of a still; videos are drawn half as high
PERSPECTIVE_ASPECT = 4 / 3
# Geom groups beside the bodies' 0: floor markings (lines, the goal area, the target) are drawn in every
# view; the goal's volume and net only in perspective ones, since from above they would veil the goal
# area and the target.
MARKINGS, SIDE_VIEW = 1, 2
MARKED = ("torso", "agent", "ball")  # geoms the top view puts a disc under: the ant's torso, the point, the ball
TEAM_AGENTS = tuple(f"{side}{i}_" for side in ("home", "away") for i in range(2))  # prefixes of a team field's agents
MARK_RADIUS = 0.02  # of the top view's height
# what the preview's legend names, and the geoms that show it: a name, or a prefix ending in _ (the first
# geom found gives the colour; an entry with none, or only hidden ones, is left out)
LEGEND = {"agent": ("torso", "agent"), "home": ("home0_torso", "home0_agent"), "away": ("away0_torso", "away0_agent"),
          "ball": ("ball",), "target": ("target",), "goal": ("goal_area", "away_goal_area"),
          "walls": ("wall_",), "obstacles": ("obstacle_",), "field lines": ("line_",)}
LEGEND_HEIGHT = 32  # pixels of the strip under the preview
CAPTION_CHARACTERS = 48  # of a contact sheet's caption line: about its panel's width at 8 points
MAX_FOVY = 180  # mujoco takes no camera fovy of this or more, an orthographic camera's metres included


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
    """The top-down view and the view from the agent's start, side by side, over a legend of their colours."""
    views = np.concatenate([render_pose(model, camera=c) for c in CAMERAS], axis=1)
    return np.concatenate([views, legend(model, views.shape[1])], axis=0)


def legend(model: mujoco.MjModel, width: int) -> np.ndarray:
    """A strip `width` pixels wide naming each colour the model shows (LEGEND), in a swatch of it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, i) or "" for i in range(model.ngeom)]
    entries = []
    for label, shown_by in LEGEND.items():
        geoms = [i for i, name in enumerate(names) if model.geom_rgba[i][3] > 0 and any(
            name.startswith(s) if s.endswith("_") else name == s for s in shown_by)]
        if geoms:
            entries.append(Patch(facecolor=model.geom_rgba[geoms[0]][:3], edgecolor="0.6", label=label))
    # as many entries a row as fit the width: one view alone is narrower than the preview's two
    for columns in range(max(len(entries), 1), 0, -1):
        rows = -(-len(entries) // columns)
        fig = plt.figure(figsize=(width / 100, LEGEND_HEIGHT * (1 + 0.6 * (rows - 1)) / 100), dpi=100,
                         facecolor="0.2")
        shown = fig.legend(handles=entries, loc="center", ncol=columns, frameon=False, labelcolor="white",
                           fontsize=9, handlelength=1.2, columnspacing=1.5)
        fig.canvas.draw()
        if columns == 1 or shown.get_window_extent().width <= width:
            break
        plt.close(fig)
    strip = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    return strip


def same_scale(models: list[mujoco.MjModel], camera: str = "top") -> None:
    """Point each model's orthographic `camera` at the region that all of them frame together, so that a metre
    is as many pixels in each of their images and fields of different sizes look it. Fields framed in
    perspective (too large for an orthographic view: fieldgen.compile.scene), or together too large for one,
    keep their own views."""
    cams = [model.cam(camera).id for model in models]
    if any(model.cam_projection[cam] != mujoco.mjtProjection.mjPROJ_ORTHOGRAPHIC for model, cam in zip(models, cams)):
        return
    views = []
    for model, cam in zip(models, cams):
        (x, y, _), half_height = model.cam_pos[cam], model.cam_fovy[cam] / 2
        w, h = model.cam_resolution[cam]
        views.append((x - half_height * w / h, x + half_height * w / h, y - half_height, y + half_height))
    x0, x1 = min(v[0] for v in views), max(v[1] for v in views)
    y0, y1 = min(v[2] for v in views), max(v[3] for v in views)
    height = models[0].cam_resolution[cams[0]][1]
    width = max(16, 16 * round(height * (x1 - x0) / (y1 - y0) / 16))
    fovy = max(y1 - y0, (x1 - x0) * height / width)
    if fovy >= MAX_FOVY:
        return
    top = max(model.cam_pos[cam][2] for model, cam in zip(models, cams))
    reach = max(abs(x0), abs(x1), abs(y0), abs(y1))
    for model, cam in zip(models, cams):
        model.cam_pos[cam] = ((x0 + x1) / 2, (y0 + y1) / 2, top)
        model.cam_fovy[cam] = fovy
        model.cam_resolution[cam] = (width, height)
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        floor = model.geom("floor")
        if floor.size[0] < reach:  # the floor drawn to the view's edges, its checks still a metre each
            model.mat_texrepeat[floor.matid[0]] *= reach / floor.size[0]
            floor.size[:2] = reach


def render_rollout(model: mujoco.MjModel, qpos: np.ndarray, mocap_pos: np.ndarray, camera: str = "follow",
                   height: int = HEIGHT // 2, width: int | None = None) -> list[np.ndarray]:
    """Frames of a recorded rollout: qpos [T, nq] and mocap_pos [T, nmocap, 3], `width` pixels wide (default: the
    camera's own aspect, frame_size)."""
    data = mujoco.MjData(model)
    frames = []
    size = frame_size(model, camera, height) if width is None else (height, width)
    with renderer(model, size) as r:
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


def contact_sheet(images: list[np.ndarray], titles: list[str], columns: int = 3,
                  captions: list[str] | None = None) -> bytes:
    """PNG bytes of images in a grid, each under its title and over its caption, if any."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = -(-len(images) // columns)
    cols = min(columns, len(images))
    # a caption wider than its panel would run into its neighbours': wrapped at the panel's width, in lines
    # the rows make room for
    wrapped = [textwrap.fill(caption, CAPTION_CHARACTERS) for caption in captions or [""] * len(images)]
    lines = max((text.count("\n") + 1 for text in wrapped if text), default=0)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, (2.7 + 0.14 * max(lines - 1, 0)) * rows), squeeze=False)
    for ax in axes.flat:
        ax.axis("off")
    for ax, image, title, caption in zip(axes.flat, images, titles, wrapped):
        ax.imshow(image)
        ax.set_title(title, fontsize=8)
        ax.text(0.5, -0.03, caption, transform=ax.transAxes, ha="center", va="top", fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
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
    for name in MARKED + tuple(prefix + name for prefix in TEAM_AGENTS for name in MARKED[:2]):
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
