"""Where an automatic curriculum's level buffer settles when the policy's success on each level holds still at what a
run measured: the sampler's own `next_levels`, fed training episodes drawn as its weights say and succeeding at
those rates, evaluation after evaluation, for several settings of the sampler.

It separates the sampler from learning: a run whose evaluations score levels 5-8 at 0.1-0.3 while its buffer plays
levels 2-3 may be slow to learn or slow to move its buffer, and this says which the sampler alone would do.

    python bench/buffer_settles.py RUN --metrics FILE --at 22.0M --ahead 0,1,2,4 -o PNG
    python bench/buffer_settles.py RUN --metrics FILE --at 1.08M --ahead 0,2,2 --ahead-from 0,0,0.1

RUN is a run folder of the automatic curriculum with kick-off points (its run.json's `kickoffs`: `fieldgen train
FIELD --curriculum auto --prepare` writes one); FILE a metrics.jsonl of such a run, whose rows at env steps --at give
each level's in-run success at its own kick-off (the mean over the file's seeds). A kick-off point between two levels'
own kick-offs succeeds at the rate between theirs, by where it lies on its level's stretch; the easy end at the
first level's own rate. Each setting is repeated over --repeats random streams; the table is the mean share of new
episodes by level after --evaluations evaluations of --episodes training episodes each.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from fieldgen import counts
from fieldgen.curriculum.auto import Sampler, kickoff_coordinates, next_levels
from fieldgen.curriculum.levels import LevelError


def env_steps(text: str) -> int:
    """--at as fieldgen's options read a count (22M, 2.2e7); argparse's one-line error where it is none."""
    try:
        return counts.count(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def measured_success(metrics: Path, at: int) -> tuple[int, np.ndarray]:
    """The evaluation nearest env steps `at` and each level's in-run success there at its own kick-off, the mean
    over the file's seeds."""
    rows = [json.loads(line) for line in metrics.read_text().splitlines() if line.strip()]
    rows = [row for row in rows if "variants" in row]
    if not rows:
        raise SystemExit(f"{metrics} holds no per-level success (rows of an automatic curriculum's run)")
    nearest = min({row["env_steps"] for row in rows}, key=lambda steps: abs(steps - at))
    return nearest, np.mean([row["variants"]["success_any"] for row in rows if row["env_steps"] == nearest], axis=0)


def point_success(coordinates: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """[level, point] success: between the level before's own rate and this level's, by place on its stretch."""
    playable = np.isfinite(coordinates)
    success = np.zeros(coordinates.shape)
    for level, row in enumerate(coordinates):
        points = np.flatnonzero(playable[level])
        stretch = row[points]
        low = levels[level - 1] if level else levels[0]
        span = stretch.max() - stretch.min()
        t = (stretch - stretch.min()) / span if span > 0 else np.ones(len(points))
        success[level, points] = low + (levels[level] - low) * t
    return success


def settle(coordinates: np.ndarray, success: np.ndarray, sampler: Sampler, evaluations: int, episodes: int,
           repeat: int) -> np.ndarray:
    """The share of new episodes on each level after `evaluations` re-weighings, from each level's own kick-off."""
    playable = np.isfinite(coordinates)
    rng, key = np.random.default_rng(repeat), jax.random.PRNGKey(repeat)
    weights = jnp.zeros(playable.shape).at[:, -1].set(1.0 / playable.shape[0])
    counts = jnp.zeros((2, *playable.shape))
    for _ in range(evaluations):
        drawn = np.asarray(weights).ravel()
        played = rng.multinomial(episodes, drawn / drawn.sum()).reshape(playable.shape)
        won = rng.binomial(played, success)
        counts = counts + jnp.asarray(np.stack([played, won]), jnp.float32)
        key, step = jax.random.split(key)
        weights, kept = next_levels(counts, weights, playable, step, sampler)
        counts = counts * kept
    shares = np.asarray(weights)
    return shares.sum(axis=1) / shares.sum()


def samplers(ahead: str, ahead_from: str, replaced: int, parser: argparse.ArgumentParser) -> dict[str, Sampler]:
    """The sampler of each row by its label: --ahead-from pairs with --ahead value by value, or one value for
    all; argparse's one line, in the sampler's own words (Sampler.checked), where a value is not one."""
    try:
        aheads, froms = [float(a) for a in ahead.split(",")], [float(f) for f in ahead_from.split(",")]
    except ValueError as exc:
        parser.error(f"--ahead and --ahead-from take comma-separated numbers: {exc}")
    if len(froms) == 1:
        froms *= len(aheads)
    if len(froms) != len(aheads):
        parser.error(f"--ahead-from has {len(froms)} values for --ahead's {len(aheads)}: give one for each, or one")
    try:
        return {label(a, f): Sampler.checked({"replaced": replaced, "ahead": a, "ahead_from": f},
                                             "a row's sampler:") for a, f in zip(aheads, froms)}
    except LevelError as exc:
        parser.error(str(exc))


def label(ahead: float, ahead_from: float) -> str:
    """A row's name: the ahead value, and where it is grown from when that is not 0."""
    return f"{ahead:g}" + (f" from {ahead_from:g}" if ahead_from else "")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path, help="a run folder of the automatic curriculum (its run.json's kickoffs)")
    parser.add_argument("--metrics", type=Path, required=True, help="a metrics.jsonl with per-level success")
    parser.add_argument("--at", type=env_steps, required=True,
                        help="env steps: the evaluation nearest them is read (22M)")
    parser.add_argument("--ahead", default="0,1,2,4", help="comma-separated values of the sampler's `ahead`")
    parser.add_argument("--ahead-from", default="0", help="comma-separated values of the sampler's `ahead_from`, "
                                                          "one for each --ahead value or one for all")
    parser.add_argument("--replaced", type=int, default=8, help="the sampler's `replaced`")
    parser.add_argument("--evaluations", type=int, default=15)
    parser.add_argument("--episodes", type=int, default=1900, help="training episodes between evaluations")
    parser.add_argument("--repeats", type=int, default=4)
    parser.add_argument("-o", "--out", type=Path, help="a PNG of the shares by level")
    args = parser.parse_args()

    settings = samplers(args.ahead, args.ahead_from, args.replaced, parser)
    for path in (args.run / "run.json", args.metrics):
        if not path.is_file():
            parser.error(f"{path} is not a file")
    coordinates = kickoff_coordinates(json.loads((args.run / "run.json").read_text())["kickoffs"])
    at, levels = measured_success(args.metrics, args.at)
    success = point_success(coordinates, levels)
    table = {name: np.mean([settle(coordinates, success, sampler, args.evaluations, args.episodes, r)
                            for r in range(args.repeats)], axis=0) for name, sampler in settings.items()}
    names = [f"level {k + 1}" for k in range(len(levels))]
    print(f"measured success at each level's own kick-off ({at:,} env steps): "
          + ", ".join(f"{v:.2f}" for v in levels))
    print("| ahead | " + " | ".join(names) + " |")
    print("|---" * (len(names) + 1) + "|")
    for name, shares in table.items():
        print(f"| {name} | " + " | ".join(f"{s:.2f}" for s in shares) + " |")
    if args.out:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(9, 4.2))
        width = 0.8 / len(table)
        for k, (name, shares) in enumerate(table.items()):
            ax.bar(np.arange(len(names)) + (k - (len(table) - 1) / 2) * width, shares, width, label=f"ahead {name}")
        ax.plot(np.arange(len(names)), levels, "k.--", label="measured success at the level's own kick-off")
        ax.set_xticks(np.arange(len(names)), names)
        ax.set_ylabel("share of new episodes (bars); success (dots)")
        ax.set_ylim(0, 1)
        ax.set_title(f"where the level buffer settles, success held at {at / 1e6:.1f}M env steps' "
                     f"(replaced {args.replaced}, {args.evaluations} evaluations)")
        ax.legend(fontsize=8)
        ax.grid(axis="y", alpha=0.3)
        fig.tight_layout()
        fig.savefig(args.out, dpi=110)
        print(f"plot: {args.out}")


if __name__ == "__main__":
    main()
