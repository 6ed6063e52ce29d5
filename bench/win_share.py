"""A self-play run's share of matches won against the random policy at each evaluation, one line per seed, with
a dashed line at a target share.

seed_bands.py draws the interquartile mean over seeds, and a self-play run's own ratings.png its win, draw and
loss lines with its ratings; a results page that asks whether every seed reaches a share wants each seed's line
beside the target, drawn from the metrics file kept in bench/results.

    python bench/win_share.py bench/results/selfplay_soccer_1v1/h200_tuning_800to802.metrics.jsonl --target 0.9 \\
        -o bench/results/selfplay_soccer_1v1/win_share.png --title "PPO self-play on soccer_1v1, one H200"

Several settings (LABEL=FILE) are drawn as panels side by side, on one scale of env steps and share.
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


def draw(settings: dict[str, list[dict]], out: Path, title: str, target: float | None) -> None:
    """One panel per setting (label -> a run's rows), its seeds' lines and the target's."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fieldgen.run.plots import save_figure

    fig, axes = plt.subplots(1, len(settings), figsize=(7 * len(settings), 4), sharex=True, sharey=True,
                             squeeze=False)
    for ax, (label, rows) in zip(axes[0], settings.items()):
        for seed, (steps, shares) in win_shares(rows).items():
            ax.plot(steps, shares, marker="o", ms=3, label=f"seed {seed}")
        if target is not None:
            ax.axhline(target, color="grey", ls="--", label=f"target {target:g}")
        ax.set(xlabel="env steps", ylabel="share of matches won", ylim=(-0.02, 1.02),
               title=f"{label}: against a random policy" if label else "against a random policy")
    save_figure(fig, list(axes[0]), title, out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("metrics", nargs="+", metavar="[LABEL=]FILE",
                        help="a self-play run's metrics.jsonl, labelled for a panel of its own")
    parser.add_argument("-o", "--out", type=Path, required=True, help="the plot (PNG)")
    parser.add_argument("--title", default="")
    parser.add_argument("--target", type=float, help="a share to draw as a dashed line")
    args = parser.parse_args()
    settings = {}
    for given in args.metrics:
        label, _, name = given.rpartition("=")
        settings[label] = [json.loads(line) for line in Path(name).read_text().splitlines() if line.strip()]
    draw(settings, args.out, args.title, args.target)
    print(f"plot: {args.out}")


if __name__ == "__main__":
    main()
