"""A training run's records on disk: runs/<field>-<algo>-<seed>/.

A run folder holds everything needed to resume: `run.json` (the field's build, the
algorithm, its full config and the seeds), `metrics.jsonl` / `metrics.csv` (one row per
evaluation and seed), `checkpoint.msgpack` (the whole training state after the last
evaluation), `success.png` and `videos/eval_NNN.mp4` (or .gif); every file is replaced whole.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

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


