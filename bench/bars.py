"""One figure per setting as horizontal bars: the plot of a results page whose answer is a table of numbers
(throughput, seconds, ratios) rather than curves over training.

Each bar is LABEL=VALUE, copied from the page's table, so the plot and the table say the same; a bar drawn
against a reference prints its ratio beside it (--reference LABEL), and a group of bars shares a colour
when LABEL starts with GROUP: (e.g. "1 seed:CRL=56900").

    python bench/bars.py "former preset=36049" "residual preset=147038" --reference "former preset" \\
        --xlabel "env steps/s, five seeds" -o bench/results/crl_ant_residual_network/throughput.png \\
        --title "CRL's ant presets on one H200"
"""

from __future__ import annotations

import argparse
from pathlib import Path


def bar(text: str) -> tuple[str, str, float]:
    """'GROUP:LABEL=VALUE' or 'LABEL=VALUE' -> (group, label, value)."""
    label, sep, value = text.rpartition("=")
    if not sep or not label:
        raise argparse.ArgumentTypeError(f"{text!r}: write a bar as LABEL=VALUE, e.g. 'one seed=56900'")
    try:
        number = float(value.replace(",", "").replace("_", ""))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: {value!r} is not a number") from None
    group, _, name = label.rpartition(":")
    return group, name, number


def draw(bars: list[tuple[str, str, float]], out: Path, title: str, xlabel: str, reference: str | None) -> None:
    """The bars top to bottom in the order given, each with its value (and its ratio to the reference)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fieldgen.run.plots import save_figure, step_count

    groups = list(dict.fromkeys(g for g, _, _ in bars))
    colours = {g: plt.get_cmap("tab10")(i % 10) for i, g in enumerate(groups)}
    base = next((v for _, name, v in bars if name == reference), None)
    if reference is not None and base is None:
        raise SystemExit(f"--reference {reference!r} names no bar; the bars are: {', '.join(n for _, n, _ in bars)}")
    fig, ax = plt.subplots(figsize=(9, 0.5 * len(bars) + 1.6))
    ys = range(len(bars))[::-1]
    ax.barh(list(ys), [v for _, _, v in bars], color=[colours[g] for g, _, _ in bars])
    ax.set_yticks(list(ys), [f"{g}: {n}" if g else n for g, n, _ in bars])
    top = max(v for _, _, v in bars)
    for y, (_, _, value) in zip(ys, bars):
        text = f"{value:,.4g}" if value < 1000 else f"{value:,.0f}"
        if base:
            text += f"  ({value / base:.2f}x)"
        ax.text(value + top * 0.01, y, text, va="center", fontsize=9)
    ax.set_xlim(0, top * 1.25)
    if top >= 1000:  # 50k, not 50000
        from matplotlib.ticker import FuncFormatter

        ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: step_count(x)))
    ax.set_xlabel(xlabel)
    save_figure(fig, [ax], title, out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("bars", nargs="+", type=bar, metavar="[GROUP:]LABEL=VALUE")
    parser.add_argument("-o", "--out", type=Path, required=True, help="the plot (PNG)")
    parser.add_argument("--title", default="")
    parser.add_argument("--xlabel", default="")
    parser.add_argument("--reference", help="a bar's LABEL: every bar also shows its ratio to that one")
    args = parser.parse_args()
    draw(args.bars, args.out, args.title, args.xlabel, args.reference)
    print(f"plot: {args.out}")


if __name__ == "__main__":
    main()
