"""Videos of a run's evaluation episodes: filmed inside the evaluation, drawn by mujoco's renderer,
or kept as joint positions (.npz) where nothing renders and drawn later."""

from __future__ import annotations

import io
import math
import zipfile
from pathlib import Path

import jax
import numpy as np
from rich.text import Text

from fieldgen.files import (VIDEOS as DRAWN, FolderError, Output, kind_of_blocker, stands_unlike, write_atomic,
                            write_file)
from fieldgen.run.record import VIDEOS
from fieldgen.suggest import shell


def video_name(run_dir: Path, index: int) -> Path:
    """Where the video of evaluation `index` goes, without its suffix: videos/eval_NNN."""
    (run_dir / VIDEOS).mkdir(exist_ok=True)
    return run_dir / VIDEOS / f"eval_{index:03d}"


class EpisodeRecorder:
    """Videos of a policy's deterministic episode, filmed by its evaluation (`film`, passed to
    agents.loop's evaluation) and drawn by mujoco's renderer."""

    def __init__(self, env, camera: str = "follow", fmt: str | None = None):
        """`fmt`: mp4 or gif, by default mp4 where its encoder is installed (fieldgen.video.choose)."""
        from fieldgen.video import choose

        self.env, self.camera, self.fmt, self.broken = env, camera, choose(fmt), False

    @staticmethod
    def film(env_state) -> tuple:
        """What a frame needs of a batch of environment states: joint positions and mocap bodies (targets)."""
        return env_state.pipeline_state.qpos, env_state.pipeline_state.mocap_pos

    def episode(self, filmed) -> dict:
        """An evaluation's filmed episode ((qpos, mocap_pos), done), cut at its end to at most ~300
        frames: {qpos [T, nq], mocap_pos [T, nmocap, 3], fps}."""
        (qpos, mocap), done = (jax.tree.map(np.asarray, x) for x in filmed)
        end = int(np.argmax(done)) + 1 if done.any() else self.env.episode_length
        stride = max(1, end // 300)
        return {"qpos": qpos[:end:stride], "mocap_pos": mocap[:end:stride], "fps": 1 / (self.env.dt * stride)}

    def save(self, run_dir: Path, name: Path, episode: dict, console, output: Output | None = None) -> int | None:
        """name.mp4 or name.gif, and its frame count. A machine that cannot render keeps the episode instead
        (name.npz, drawn later by `fieldgen videos` where a renderer works), with one warning, and returns None.
        `output`: the command writing it where files of the user's may be (eval's, beside a run's files; write_file),
        None for a run's own videos/."""
        def write(path: Path, data: bytes) -> None:
            write_atomic(path, data) if output is None else write_file(path, data, output, "pass --no-video")

        if not self.broken:
            try:
                data, frames = draw_episode(self.env.mj_model, episode, self.camera, self.fmt)
                write(name.with_suffix(f".{self.fmt}"), data)
                return frames
            except FolderError:  # a file of the user's where the video goes: no renderer's failure
                raise
            except Exception as exc:  # noqa: BLE001 - renderer back ends fail in many ways
                self.broken = True
                console.print(Text.assemble(("warning:", "yellow"), f" cannot render here ({exc}); keeping episodes as "
                              f".npz files where their videos would be: draw them with `fieldgen videos {shell(run_dir)}` "
                              "on a machine that renders"))
        buf = io.BytesIO()
        np.savez(buf, field=self.env.spec.name, camera=self.camera, **episode)
        write(name.with_suffix(".npz"), buf.getvalue())
        return None


def _check_episode(path: Path, episode: dict, model, camera: str) -> None:
    """A kept episode is of the field it names: a frame of that model's joint positions and targets per step,
    finite, at a frame rate above zero, for one of fieldgen's cameras (EpisodeRecorder.episode writes it so)."""
    from fieldgen.cameras import CAMERAS
    from fieldgen.run.record import RunError

    qpos, mocap, fps = (np.asarray(episode.get(k)) for k in ("qpos", "mocap_pos", "fps"))
    problem = None
    if qpos.ndim != 2 or qpos.shape[1] != model.nq or not 1 <= len(qpos) <= MAX_FRAMES:
        problem = f"qpos should be [frames, {model.nq}] with 1 to {MAX_FRAMES} frames, not {list(qpos.shape)}"
    elif mocap.shape != (len(qpos), model.nmocap, 3):
        problem = f"mocap_pos should be {[len(qpos), model.nmocap, 3]}, not {list(mocap.shape)}"
    elif not (all(np.issubdtype(a.dtype, np.floating) for a in (qpos, mocap)) and np.isfinite(qpos).all()
              and np.isfinite(mocap).all()):
        problem = "its positions are not all finite numbers"
    elif fps.shape != () or not np.issubdtype(fps.dtype, np.number) or not 0 < float(fps) <= MAX_FPS:
        problem = f"fps should be one number above 0 and at most {MAX_FPS:,}, not {fps.tolist()!r}"
    elif camera not in CAMERAS:
        problem = f"camera should be one of {', '.join(CAMERAS)}, not {camera!r}"
    if problem:
        raise RunError(f"{path} is not an episode kept by fieldgen train: {problem} (edited or damaged); delete it "
                       "or train again")


MAX_FRAMES = 1_000  # EpisodeRecorder.episode cuts an episode to fewer than 600 frames; each is drawn in memory
MAX_FPS = 10_000  # a control step of 1e-4 s, the shortest a spec allows, filmed at every step
MAX_KEPT_BYTES = 256 * 2**20  # unpacked: ~300 frames of joint positions take kilobytes to a few megabytes


def _check_sizes(path: Path, kept) -> None:
    """What the arrays of a kept episode unpack to, from their headers, before any is read: a file of megabytes
    packed from gigabytes of zeros is refused, not unpacked into memory."""
    from fieldgen.run.record import RunError

    total = 0
    for member in kept.zip.namelist():
        with kept.zip.open(member) as stream:
            version = np.lib.format.read_magic(stream)
            if version not in ((1, 0), (2, 0)):
                raise ValueError(f"{member} is an array of format {version}, which numpy.savez does not write")
            read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else \
                np.lib.format.read_array_header_2_0
            shape, _, dtype = read_header(stream)
        total += math.prod(shape) * dtype.itemsize
    if total > MAX_KEPT_BYTES:
        raise RunError(f"{path} unpacks to {total:,} bytes, more than an episode fieldgen keeps ever holds "
                       f"({MAX_KEPT_BYTES:,}); it is not one fieldgen train kept (edited or damaged): delete it or "
                       "train again")


def draw_episode(model, episode, camera: str, fmt: str) -> tuple[bytes, int]:
    """The video (`fmt`: mp4 or gif) of a recorded episode ({qpos, mocap_pos, fps}) and its frame count."""
    from fieldgen.render import render_rollout
    from fieldgen.video import encode

    frames = render_rollout(model, episode["qpos"], episode["mocap_pos"], camera)
    return encode(frames, float(episode["fps"]), fmt)


def kept_episodes(run_dir: Path) -> list[Path]:
    """The episodes a run kept where nothing could render: videos/eval_NNN.npz, and eval*.npz of `fieldgen eval`."""
    return sorted((run_dir / VIDEOS).glob("eval_*.npz")) + sorted(run_dir.glob("eval*.npz"))


def draw_kept(path: Path, models: dict, fmt: str) -> tuple[str, int | None]:
    """Draw a kept episode as the video (`fmt`: mp4 or gif) beside it, with the model of the field it records
    (`models`: field name -> MjModel). Returns (the field, frames drawn), frames None where that video was
    already there."""
    from fieldgen.run.record import RunError

    try:
        if not zipfile.is_zipfile(path):  # else numpy reads it as a pickle, and its refusal speaks of unpickling
            raise ValueError("not an .npz archive")
        with np.load(path) as kept:
            _check_sizes(path, kept)
            played, camera, episode = str(kept["field"]), str(kept["camera"]), dict(kept)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        raise RunError(f"{path} is not an episode kept by fieldgen train ({exc}); delete it or train again") from None
    if played not in models:
        raise RunError(f"{path} records field '{played}', which is not one of this run's fields "
                       f"({', '.join(models)}); pass its YAML file, bundled name or build folder: "
                       f"fieldgen videos {path.parent if path.parent.name != VIDEOS else path.parent.parent} "
                       "--field SPEC")
    _check_episode(path, episode, models[played], camera)
    video = path.with_suffix(f".{fmt}")
    if stands_unlike(video, Path.is_file):
        raise RunError(f"{video} is {kind_of_blocker(video)} where the video of "
                       f"{path.name} goes; move it aside, or draw the episodes as {'gif' if fmt == 'mp4' else 'mp4'} "
                       "(--video-format)")
    if video.exists():
        return played, None
    data, frames = draw_episode(models[played], episode, camera, fmt)
    write_file(video, data, DRAWN)
    return played, frames
