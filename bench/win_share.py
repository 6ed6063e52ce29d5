"""A self-play run's share of matches won against the random policy at each evaluation, one line per seed, with
a dashed line at a target share.

seed_bands.py draws the interquartile mean over seeds, and a self-play run's own ratings.png its win, draw and
loss lines with its ratings; a results page that asks whether every seed reaches a share wants each seed's line
beside the target, drawn from the metrics file kept in bench/results.

    python bench/win_share.py bench/results/selfplay_soccer_1v1/h200_tuning_800to802.metrics.jsonl --target 0.9 \\
        -o bench/results/selfplay_soccer_1v1/win_share.png --title "PPO self-play on soccer_1v1, one H200"
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def win_shares(rows: list[dict]) -> dict[int, tuple[list[int], list[float]]]:
    """Each seed's (env steps, win / (win + draw + loss) against the random policy), in env-step order."""
    out: dict[int, tuple[list[int], list[float]]] = {}
    for row in sorted(rows, key=lambda r: (r["seed"], r["env_steps"])):
        played = row["win_vs_random"] + row["draw_vs_random"] + row["loss_vs_random"]
        steps, shares = out.setdefault(row["seed"], ([], []))
        steps.append(row["env_steps"])
        shares.append(row["win_vs_random"] / played)
    return out


def draw(rows: list[dict], out: Path, title: str, target: float | None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fieldgen.run.plots import save_figure

    fig, ax = plt.subplots(figsize=(7, 4))
    for seed, (steps, shares) in win_shares(rows).items():
        ax.plot(steps, shares, marker="o", ms=3, label=f"seed {seed}")
    if target is not None:
        ax.axhline(target, color="grey", ls="--", label=f"target {target:g}")
    ax.set(xlabel="env steps", ylabel="share of matches won", title="against a random policy", ylim=(-0.02, 1.02))
    save_figure(fig, [ax], title, out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("metrics", type=Path, help="a self-play run's metrics.jsonl")
    parser.add_argument("-o", "--out", type=Path, required=True, help="the plot (PNG)")
    parser.add_argument("--title", default="")
    parser.add_argument("--target", type=float, help="a share to draw as a dashed line")
    args = parser.parse_args()
    rows = [json.loads(line) for line in args.metrics.read_text().splitlines() if line.strip()]
    draw(rows, args.out, args.title, args.target)
    print(f"plot: {args.out}")


if __name__ == "__main__":
    main()
