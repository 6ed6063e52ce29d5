"""Success on a curriculum's last field against env steps and wall clock, for runs trained directly
on it and through it.

Each run is a metrics.jsonl (a run folder's, or one kept in bench/results): a direct run's own
success, a staged or mixed run's `last_stage_success_any` (the policy judged on the last field
at every evaluation, whichever stage it trained on). Time at goal is drawn where the run was
judged on the last field (a direct run, a mixed run's last variant, a staged run once there).
With --own-field every run is judged on the field it trained on at each evaluation instead (a
staged run's stage), to compare runs on one stage of a curriculum. A run started from another's
networks (`fieldgen train --init-from`) is drawn as LABEL=SOURCE_METRICS+METRICS: its curve begins
where its source's ended, in env steps and wall clock, so both count from nothing learned (the
source's own evaluations, of its own field, are drawn only under a label of their own).

    python bench/curriculum_curves.py direct=bench/results/ppo_dense_reward/h200_soccer_v2_direct_global_spread_s0.jsonl \\
        staged=bench/results/ppo_dense_reward/h200_soccer_v2_staged_global_spread.jsonl mixed=... -o curves.png
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path

from fieldgen.run.plots import save_figure


def last_field(rows: list[dict]) -> tuple[list, list, list, list]:
    """(steps, success on the last field, steps judged there for time at goal, time at goal)."""
    last = max((r.get("stage", 0) for r in rows), default=0)
    # results recorded before a mixed run's per-variant results became one record name them variant_KK_...
    legacy = sorted(k for k in rows[0] if k.startswith("variant_") and k.endswith("_time_at_goal"))
    steps = [r["env_steps"] for r in rows]
    success = [r.get("last_stage_success_any", r["success_any"]) for r in rows]
    if "variants" in rows[0]:
        judged = [(r["env_steps"], r["variants"]["time_at_goal"][-1]) for r in rows]
    elif legacy:
        judged = [(r["env_steps"], r[legacy[-1]]) for r in rows]
    else:
        # a stage whose own success differs from the last field's at some evaluation is not the last field
        before = {r["stage"] for r in rows if r.get("last_stage_success_any", r["success_any"]) != r["success_any"]}
        judged = [(r["env_steps"], r["time_at_goal"]) for r in rows
                  if r.get("stage", 0) == last and last not in before]
    return steps, success, [s for s, _ in judged], [t for _, t in judged]


def own_field(rows: list[dict]) -> tuple[list, list, list, list]:
    """(steps, success on the field trained on, the same steps, time at goal there)."""
    steps = [r["env_steps"] for r in rows]
    return steps, [r["success_any"] for r in rows], steps, [r["time_at_goal"] for r in rows]


def load(paths: str) -> list[dict]:
    """A run's evaluations; after a '+', shifted to start where the run before it (its source) ended."""
    *sources, path = paths.split("+")
    steps = seconds = 0
    for source in sources:
        last = read(source)[-1]
        steps, seconds = steps + last["env_steps"], seconds + last["wall_seconds"]
    return [{**r, "env_steps": r["env_steps"] + steps, "wall_seconds": r["wall_seconds"] + seconds} for r in read(path)]


def read(path: str) -> list[dict]:
    return [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", metavar="LABEL=[SOURCE_METRICS+]METRICS")
    parser.add_argument("-o", "--out", type=Path, required=True)
    parser.add_argument("--title", default="success on the last field")
    parser.add_argument("--own-field", action="store_true", help="judge each evaluation on the field it trained on")
    parser.add_argument("--log", action="store_true", help="env steps and wall clock on log scales, for runs of "
                        "very different lengths")
    args = parser.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, clock, right) = plt.subplots(1, 3, figsize=(15, 3.6 + 0.25 * -(-len(args.runs) // 3)))
    colors = plt.get_cmap("tab10" if len(args.runs) <= 10 else "tab20").colors  # a colour of its own for each run
    for item, color in zip(args.runs, itertools.cycle(colors)):
        label, _, path = item.partition("=")
        rows = load(path)
        steps, success, judged, at_goal = (own_field if args.own_field else last_field)(rows)
        left.plot(steps, success, marker="o", color=color)
        clock.plot([r["wall_seconds"] / 60 for r in rows], success, marker="o", color=color)
        right.plot(judged, at_goal, marker="o", color=color)
        at_goal_text = f"time at goal {at_goal[-1]:.0f}" if at_goal else "not yet on the last field"
        print(f"{label:>10s}: last evaluation {success[-1]:.2f} success_any, best {max(success):.2f}; {at_goal_text}")
    left.set(xlabel="env steps", ylabel="success_any", ylim=(-0.02, 1.02), title="episodes with a success")
    clock.set(xlabel="minutes from the start (resumes included)", ylabel="success_any", ylim=(-0.02, 1.02),
              title="against wall clock")
    right.set(xlabel="env steps", ylabel="steps at goal per episode", title="time at goal")
    if args.log:
        for axes in (left, clock, right):
            axes.set_xscale("log")
    fig.legend(left.get_lines(), [item.partition("=")[0] for item in args.runs], loc="lower center", ncol=3,
               fontsize=8, frameon=False)  # one legend under the panels, three labels a row
    save_figure(fig, (left, clock, right), args.title, args.out)


if __name__ == "__main__":
    main()
