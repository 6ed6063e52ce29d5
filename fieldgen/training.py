"""Training runs on disk: runs/<field>-<algo>-<seed>/ with config, metrics, checkpoint and plot.

A run directory holds everything needed to resume: `run.json` (the field's
build, the algorithm, its full config and the seeds), `metrics.jsonl` /
`metrics.csv` (one row per evaluation and seed), `checkpoint.msgpack` (the whole
training state after the last evaluation, written atomically), `success.png`
and `videos/eval_NNN.gif` (the policy after each evaluation).
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import jax
import numpy as np

from fieldgen.files import write_atomic

RUN, METRICS, CSV, CHECKPOINT, PLOT = "run.json", "metrics.jsonl", "metrics.csv", "checkpoint.msgpack", "success.png"
VIDEOS = "videos"


class RunError(Exception):
    """A run that cannot start or go on: bad training input, found before anything compiles, or training
    that diverged."""


def write_run(run_dir: Path, field: dict, algo: str, config, layout: dict, seeds: list[int], extra: dict) -> None:
    """run.json: the resolved field spec (a curriculum's last stage), the algorithm, its full config,
    the observation layout, the seeds, and `extra` (where the run keeps its fields, the promotion rule)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    record = {"field": field, "algo": algo, "config": config.model_dump(), "observation": layout,
              "seeds": seeds, **extra}
    write_atomic(run_dir / RUN, (json.dumps(record, indent=1) + "\n").encode())


def read_run(run_dir: Path) -> dict:
    try:
        return json.loads((run_dir / RUN).read_text())
    except FileNotFoundError:
        raise RunError(f"{run_dir} is not a training run: {RUN} is missing") from None
    except ValueError as exc:
        raise RunError(f"{run_dir / RUN} is not valid JSON ({exc})") from None


def read_metrics(run_dir: Path) -> list[dict]:
    path = run_dir / METRICS
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def write_metrics(run_dir: Path, rows: list[dict]) -> None:
    """metrics.jsonl and metrics.csv with every evaluation so far; both replaced atomically."""
    write_atomic(run_dir / METRICS, "".join(json.dumps(r) + "\n" for r in rows).encode())
    flat = [_flat(r) for r in rows]
    names = list(dict.fromkeys(k for r in flat for k in r))
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=names)
    writer.writeheader()
    writer.writerows(flat)
    write_atomic(run_dir / CSV, text.getvalue().encode())


def _flat(row: dict) -> dict:
    """A row as one CSV line: a mixed run's per-variant lists become variants.<metric>.<stage from 1>."""
    out = {k: v for k, v in row.items() if k != "variants"}
    for metric, values in row.get("variants", {}).items():
        out.update({f"variants.{metric}.{k}": v for k, v in enumerate(values, 1)})
    return out


# metric -> (axis label, panel title, y limits or None); a panel is drawn where the rows have the metric
PANELS = {"success_any": ("success_any", "episodes with a success", (-0.02, 1.02)),
          "time_at_goal": ("steps at goal per episode", "time at goal", None),
          "closest_distance": ("distance", "closest approach to the goal", None)}


def plot_success(run_dir: Path, rows: list[dict], title: str) -> None:
    """success_any, time_at_goal and closest_distance against env steps: one line per seed; for a
    staged curriculum one colour per stage and a line for the last stage; for a mixed one a line per stage."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metrics = [m for m in PANELS if any(m in r for r in rows)]
    fig, axes = plt.subplots(1, len(metrics), figsize=(5 * len(metrics), 3.6))
    panels = dict(zip(metrics, axes))
    (_plot_variants if "variants" in rows[0] else _plot_groups)(panels, rows)
    for metric, ax in panels.items():
        label, name, limits = PANELS[metric]
        ax.set(xlabel="env steps", ylabel=label, title=name, ylim=limits)
    save_figure(fig, axes, title, run_dir / PLOT)


def save_figure(fig, axes, title: str, path: Path) -> None:
    """Grids, legends where there are labels, the title; then the PNG, written atomically."""
    import matplotlib.pyplot as plt

    for ax in axes:
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    write_atomic(path, buf.getvalue())


def _series(rows: list[dict], metric: str) -> tuple[list, list]:
    """(env steps, values) of the rows that have the metric (a run resumed from older code may lack it)."""
    have = [r for r in rows if metric in r]
    return [r["env_steps"] for r in have], [r[metric] for r in have]


def _plot_groups(panels: dict, rows: list[dict]) -> None:
    """A line per seed, or the points of each stage of a staged run and its last stage's line."""
    staged = "stage" in rows[0]
    groups = list(dict.fromkeys(r["stage"] if staged else r.get("seed", 0) for r in rows))
    for group in groups:
        mine = [r for r in rows if (r["stage"] if staged else r.get("seed", 0)) == group]
        label = f"stage {group + 1}" if staged else (f"seed {group}" if len(groups) > 1 else None)
        for metric, ax in panels.items():
            ax.plot(*_series(mine, metric), marker="o", ls="" if staged else "-", label=label)
    if staged:
        panels["success_any"].plot(*_series(rows, "last_stage_success_any"), color="black", label="last stage")


def _plot_variants(panels: dict, rows: list[dict]) -> None:
    """A mixed run: one line per stage (mean over seeds), the last stage in black."""
    count = len(rows[0]["variants"]["success_any"])
    steps = sorted({r["env_steps"] for r in rows})
    for k in range(count):
        last = k == count - 1
        style = {"color": "black", "lw": 2} if last else {}
        for metric, ax in panels.items():
            values = [np.mean([r["variants"][metric][k] for r in rows if r["env_steps"] == s]) for s in steps]
            ax.plot(steps, values, marker="o", label=f"stage {k + 1}" + (" (last)" if last else ""), **style)


def peak_memory_mb() -> float | None:
    """The largest peak of bytes in use over the local devices, where the backend reports it (GPUs do)."""
    peaks = [(d.memory_stats() or {}).get("peak_bytes_in_use") for d in jax.local_devices()]
    peaks = [p for p in peaks if p is not None]
    return max(peaks) / 2**20 if peaks else None


def video_name(run_dir: Path, index: int) -> Path:
    """Where the video of evaluation `index` goes, without its suffix: videos/eval_NNN."""
    (run_dir / VIDEOS).mkdir(exist_ok=True)
    return run_dir / VIDEOS / f"eval_{index:03d}"


class EpisodeRecorder:
    """Videos of a policy's deterministic episode, filmed by its evaluation (`film`, passed to
    agents.loop's evaluation) and drawn by mujoco's renderer."""

    def __init__(self, env, camera: str = "follow"):
        self.env, self.camera, self.broken = env, camera, False

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

    def save(self, run_dir: Path, name: Path, episode: dict, console) -> int | None:
        """name.gif, and its frame count. A machine that cannot render keeps the episode instead (name.npz,
        drawn later by `fieldgen videos` where a renderer works), with one warning, and returns None."""
        if not self.broken:
            try:
                data, frames = draw_episode(self.env.mj_model, episode, self.camera)
                write_atomic(name.with_suffix(".gif"), data)
                return frames
            except Exception as exc:  # noqa: BLE001 - renderer back ends fail in many ways
                self.broken = True
                console.print(f"[yellow]warning:[/] cannot render here ({exc}); keeping episodes as .npz files "
                              f"where their videos would be: draw them with `fieldgen videos {run_dir}` "
                              "on a machine that renders")
        buf = io.BytesIO()
        np.savez(buf, field=self.env.spec.name, camera=self.camera, **episode)
        write_atomic(name.with_suffix(".npz"), buf.getvalue())
        return None


def draw_episode(model, episode, camera: str) -> tuple[bytes, int]:
    """GIF bytes of a recorded episode ({qpos, mocap_pos, fps}) and its frame count."""
    from fieldgen.render import gif_bytes, render_rollout

    frames = render_rollout(model, episode["qpos"], episode["mocap_pos"], camera)
    return gif_bytes(frames, fps=float(episode["fps"])), len(frames)
