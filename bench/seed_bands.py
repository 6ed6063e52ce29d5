"""Runs of several seeds, kept as metrics files, drawn and summarised as `fieldgen compare` does for run
folders: the interquartile mean over seeds with its 95% stratified bootstrap interval (fieldgen.run.summary),
success against env steps and wall clock, and each seed's last evaluation with the IQM line; a curriculum's runs are judged on its field (compare.on_field).

Each LABEL names one setting, its rows from one or more metrics.jsonl files (seeds trained in separate
programs, e.g. two GPUs, joined with '+'); rows of one evaluation index are one point, drawn up to the last evaluation every seed reached.

    python bench/seed_bands.py preset=bench/results/ant_nav_fresh_seeds/preset_200to202.metrics.jsonl+... \\
        -o bench/results/ant_nav_fresh_seeds/preset.png --title "ant_nav, CRL preset, fresh seeds 200-204"

--threshold T also prints, for each seed, the first evaluation whose success on the field reached T (its env
steps and wall clock, from every row the seed has, also those past the last evaluation all seeds reached).

--after LABEL=STEPS[,SECONDS] counts a setting from nothing learned: a run started from another's networks
(`fieldgen train --init-from`, a chain of hand-made curricula) has its env steps and wall clock moved on by
what the runs before it took (e.g. --after "staged chain=78.5M,2442"), so that it stands beside runs from
nothing at its true cost.

--seeds 340-342 keeps only those seeds of every setting: a five-seed run's tuning seeds beside a three-seed arm
trained on them alone.

--judge levels measures a curriculum's runs on the mean of all its levels (compare.over_levels) instead of on
the field alone: how far along the path a run has come while the field is still out of reach.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from types import SimpleNamespace

from typer import BadParameter

from fieldgen.cli.app import count
from fieldgen.run import compare, summary


def setting(files: str, after: tuple[int, float] = (0, 0.0), only: set[int] | None = None) -> SimpleNamespace:
    """One setting's rows from '+'-joined metrics files, as compare.plot reads a run (rows, seeds, algo), their
    env steps and wall clock moved on by `after` (what the runs before them took); `only` keeps those seeds."""
    rows = [json.loads(line) for f in files.split("+") for line in Path(f).read_text().splitlines() if line.strip()]
    if only is not None:
        rows = [r for r in rows if r["seed"] in only]
        if not rows:
            raise ValueError(f"{files} holds none of seeds {', '.join(map(str, sorted(only)))}")
    steps, seconds = after
    for r in rows:
        r["env_steps"] += steps
        if "wall_seconds" in r:
            r["wall_seconds"] += seconds
    seeds = sorted({r["seed"] for r in rows})
    return SimpleNamespace(rows=compare.reached_by_every_seed(rows, seeds), seeds=seeds, every_row=rows)


def first_reaching(rows: list[dict], threshold: float, judge=compare.on_field) -> dict[int, dict | None]:
    """Each seed's first evaluation row whose success (on the field, or as another of compare.JUDGES measures
    it) reached `threshold`, in env-step order; None for a seed none of whose rows did."""
    out: dict[int, dict | None] = {}
    for row in sorted(rows, key=lambda r: r["env_steps"]):
        seed = row["seed"]
        out.setdefault(seed, None)
        if out[seed] is None and judge(row, "success_any") >= threshold:
            out[seed] = row
    return out


def reaching_text(rows: list[dict], threshold: float, judge=compare.on_field) -> str:
    """One line: each seed's env steps and wall clock to `threshold`, or the env steps it got to without."""
    parts = []
    for seed, row in first_reaching(rows, threshold, judge).items():
        if row is None:
            last = max(r["env_steps"] for r in rows if r["seed"] == seed)
            parts.append(f"{seed}: not by {last / 1e6:.1f}M")
        else:
            wall = row.get("wall_seconds")
            parts.append(f"{seed}: {row['env_steps'] / 1e6:.1f}M" + (f" ({wall:,.0f} s)" if wall is not None else ""))
    where = "on the field" if judge is compare.on_field else "over the levels"
    return f"first success_any >= {threshold:g} {where}: " + ", ".join(parts)


def last_evaluation(run: SimpleNamespace) -> dict:
    """Each seed's row at the last evaluation every seed reached (`setting` keeps no later rows)."""
    return compare.last_evaluation(run.rows)


def seed_list(text: str) -> set[int]:
    """`--seeds 340-342` or `--seeds 340,342`: the seeds kept of every setting."""
    try:
        seeds = set()
        for part in text.split(","):
            first, _, last = part.partition("-")
            seeds.update(range(int(first), int(last or first) + 1))
    except ValueError:
        raise argparse.ArgumentTypeError(f"seeds as FIRST-LAST or A,B,C, not {text!r}") from None
    return seeds


def earlier(text: str) -> tuple[str, tuple[int, float]]:
    """--after's LABEL=STEPS[,SECONDS]: the label and what the runs before that setting took."""
    label, _, cost = text.partition("=")
    steps, _, seconds = cost.partition(",")
    try:
        return label, (count(steps), float(seconds or 0))
    except (ValueError, BadParameter):
        raise argparse.ArgumentTypeError(f"'{text}' is not LABEL=STEPS[,SECONDS] (e.g. \"staged chain=78.5M,2442\")")


def labelled(text: str) -> tuple[str, str]:
    """A setting's LABEL=FILE[+FILE...]: split at the first '=' after which every file exists, so that a label
    or a run folder (a sweep's `sampler.replaced=4/...`) may hold '=' too."""
    cuts = [i for i, ch in enumerate(text) if ch == "="]
    for i in cuts:
        files = text[i + 1:].split("+")
        if all(Path(f).is_file() for f in files):
            return text[:i], text[i + 1:]
    if not cuts:
        raise argparse.ArgumentTypeError(f"'{text}' is not LABEL=FILE[+FILE...] (e.g. \"preset=run/metrics.jsonl\")")
    missing = [f for f in text[cuts[0] + 1:].split("+") if not Path(f).is_file()]
    raise argparse.ArgumentTypeError(f"'{text}': no metrics file {', '.join(missing)} (LABEL=FILE[+FILE...], "
                                     "each FILE a run's metrics.jsonl)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("settings", nargs="+", type=labelled, metavar="LABEL=FILE[+FILE...]")
    parser.add_argument("-o", "--out", type=Path, required=True, help="the plot (PNG)")
    parser.add_argument("--title", default="")
    parser.add_argument("--threshold", type=float, help="also print each seed's first evaluation reaching it")
    parser.add_argument("--after", type=earlier, action="append", default=[], metavar="LABEL=STEPS[,SECONDS]",
                        help="count a setting from nothing learned: what the runs before it took")
    parser.add_argument("--seeds", type=seed_list, metavar="FIRST-LAST",
                        help="keep only these seeds of every setting (e.g. the tuning seeds of a five-seed run)")
    parser.add_argument("--judge", choices=sorted(compare.JUDGES), default="field",
                        help="a curriculum's runs measured on the field (default) or on the mean of its levels")
    args = parser.parse_args()
    judge = compare.JUDGES[args.judge]
    before = dict(args.after)
    labels, runs = [], []
    for label, files in args.settings:
        labels.append(label)
        try:
            runs.append(setting(files, before.pop(label, (0, 0.0)), args.seeds))
        except ValueError as exc:
            parser.error(f"{label}: {exc}")
    if before:
        parser.error(f"--after names no setting: {', '.join(before)} (settings: {', '.join(labels)})")
    for label, run in zip(labels, runs):
        rows = last_evaluation(run)
        values = [judge(rows[s], "success_any") for s in run.seeds]
        low, high = summary.interval(values)
        steps = {r["env_steps"] for r in rows.values()}
        where = "" if judge is compare.on_field else " (level mean)"
        print(f"{label}: env steps {', '.join(f'{s:,}' for s in sorted(steps))}; success_any{where} "
              + ", ".join(f"{s}: {v:.3f}" for s, v in zip(run.seeds, values))
              + f"; IQM {summary.iqm(values):.3f} [{low:.3f}, {high:.3f}] over {len(values)} seeds")
        if args.threshold is not None:
            print(f"{label}: {reaching_text(run.every_row, args.threshold, judge)}")
    compare.plot(runs, args.out, args.title, labels=labels, judge=judge, output=None)  # a results folder's own plot
    print(f"plot: {args.out}")


if __name__ == "__main__":
    main()
