"""Training runs on disk: runs/<field>-<algo>-<seed>/ with config, metrics, checkpoint and plot.

A run directory holds everything needed to resume: `run.json` (the field's
build, the algorithm and its full config), `metrics.jsonl` / `metrics.csv` (one
row per evaluation), `checkpoint.npz` (the whole training state after the last
evaluation, written atomically) and `success.png`.
"""

from __future__ import annotations

import csv
import dataclasses
import difflib
import importlib
import io
import json
import typing
from pathlib import Path

import yaml

from fieldgen.compile.artifact import write_atomic

ALGOS = {"crl": "CRLConfig", "ppo": "PPOConfig"}  # agents.<name> module -> its config class
RUN, METRICS, CSV, CHECKPOINT, PLOT = "run.json", "metrics.jsonl", "metrics.csv", "checkpoint.npz", "success.png"


class RunError(Exception):
    """Bad training input, found before anything compiles."""


def algorithm(algo: str):
    """The agents module of an algorithm: make_train(config, env) and train(...)."""
    if algo not in ALGOS:
        near = difflib.get_close_matches(algo, list(ALGOS), n=1)
        hint = f"; did you mean '{near[0]}'?" if near else ""
        raise RunError(f"unknown algorithm '{algo}'{hint} Available: {', '.join(ALGOS)}.")
    return importlib.import_module(f"agents.{algo}")


def config_class(algo: str):
    return getattr(algorithm(algo), ALGOS[algo])


def make_config(algo: str, file: Path | None = None, sets: list[str] = (), **fixed):
    """Defaults < config file ({algo: {key: value}}) < --set algo.key=value < explicit options."""
    cls = config_class(algo)
    values: dict = {}
    if file is not None:
        try:
            loaded = yaml.safe_load(file.read_text()) or {}
        except (OSError, yaml.YAMLError) as exc:
            raise RunError(f"cannot read config file {file}: {exc}") from None
        if not isinstance(loaded, dict) or set(loaded) - {algo}:
            raise RunError(f"{file}: a config file is a mapping with one section, '{algo}:', of config keys")
        for key, value in (loaded.get(algo) or {}).items():
            values[key] = _cast(cls, key, value, f"{file}: {algo}.{key}")
    for item in sets:
        name, sep, raw = item.partition("=")
        section, dot, key = name.partition(".")
        if not sep or not dot or section != algo:
            raise RunError(f"--set {item!r}: write {algo}.KEY=VALUE, e.g. {algo}.repr_dim=128")
        values[key] = _cast(cls, key, yaml.safe_load(raw), f"--set {item}")
    values.update({k: v for k, v in fixed.items() if v is not None})
    return cls(**values)


def _cast(cls, key: str, value, where: str):
    fields = {f.name: f for f in dataclasses.fields(cls)}
    if key not in fields:
        near = difflib.get_close_matches(key, list(fields), n=1)
        hint = f"; did you mean '{near[0]}'?" if near else ""
        raise RunError(f"{where}: unknown config key '{key}'{hint} Keys: {', '.join(fields)}.")
    kind = typing.get_type_hints(cls)[key]
    try:
        if kind is bool:
            if not isinstance(value, bool):
                raise ValueError
            return value
        if typing.get_origin(kind) is tuple:
            return tuple(int(v) for v in (value if isinstance(value, (list, tuple)) else [value]))
        return kind(value)
    except (TypeError, ValueError):
        raise RunError(f"{where}: '{value}' is not a valid {getattr(kind, '__name__', kind)}") from None


def check_config(config, env) -> None:
    """Problems a run would hit after compiling, reported before."""
    per_iter = config.num_envs * config.unroll_length
    if hasattr(config, "num_minibatches"):
        _check_ppo(config, per_iter)
    else:
        _check_crl(config, env, per_iter)


def _check_ppo(config, per_iter: int) -> None:
    if per_iter % config.num_minibatches:
        raise RunError(f"num_envs x unroll_length = {per_iter:,} does not divide into {config.num_minibatches} "
                       "minibatches; change num_envs, unroll_length or num_minibatches")
    need = config.num_evals * per_iter
    if config.total_steps < need:
        raise RunError(f"--steps {config.total_steps:,} is too few: {config.num_evals} evaluations of "
                       f"{per_iter:,}-step iterations need at least {need:,}")
    if config.reward not in ("dense", "sparse"):
        raise RunError(f"unknown reward '{config.reward}'; choose dense (the field's terms) or sparse (its success)")


def _check_crl(config, env, per_iter: int) -> None:
    from agents.contrastive import ENERGIES, LOSSES

    prefill = -(-config.min_replay_rows // config.unroll_length) * per_iter
    need = prefill + config.num_evals * per_iter
    if config.total_steps < need:
        raise RunError(f"--steps {config.total_steps:,} is too few: {config.num_envs} envs x unroll "
                       f"{config.unroll_length} need {prefill:,} steps to prefill the buffer and "
                       f"{config.num_evals} more iterations; use at least {need:,}")
    if config.max_replay_rows < max(config.min_replay_rows, env.episode_length):
        raise RunError(f"max_replay_rows {config.max_replay_rows} must hold min_replay_rows "
                       f"({config.min_replay_rows}) and one episode ({env.episode_length} steps)")
    if config.energy not in ENERGIES:
        raise RunError(f"unknown energy '{config.energy}'; choose one of {', '.join(ENERGIES)}")
    if config.contrastive_loss not in LOSSES:
        raise RunError(f"unknown contrastive_loss '{config.contrastive_loss}'; choose one of {', '.join(LOSSES)}")


def write_run(run_dir: Path, field: dict, algo: str, config, layout: dict) -> None:
    """run.json: the resolved field spec, the algorithm, its full config and the observation layout."""
    run_dir.mkdir(parents=True, exist_ok=True)
    record = {"field": field, "algo": algo, "config": dataclasses.asdict(config), "observation": layout}
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
    names = list(dict.fromkeys(k for r in rows for k in r))
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=names)
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(run_dir / CSV, text.getvalue().encode())


def plot_success(run_dir: Path, rows: list[dict], title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = [r["env_steps"] for r in rows]
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.6))
    left.plot(steps, [r["success_any"] for r in rows], marker="o")
    left.set(xlabel="env steps", ylabel="success_any", ylim=(-0.02, 1.02), title="episodes with a success")
    right.plot(steps, [r["time_at_goal"] for r in rows], marker="o", color="tab:green")
    right.set(xlabel="env steps", ylabel="steps at goal per episode", title="time at goal")
    for ax in (left, right):
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    write_atomic(run_dir / PLOT, buf.getvalue())
