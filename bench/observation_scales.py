"""The observation normaliser of exported policies, observation by observation: a seed whose normaliser counted
the steps of a blown-up simulation holds standard deviations thousands of times its siblings', and its policy
then reads every ordinary observation as nearly zero for the rest of its run.

    fieldgen export RUN --seed 700 -o policies/700      # once per seed
    python bench/observation_scales.py policies/700 policies/701 policies/702 --out scales.jsonl

Prints each policy's largest standard deviations and their median; --out keeps one row per policy (its seed,
field, env steps and the standard deviation of every observation, by name).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def scales(folder: Path) -> dict:
    """One policy's row: seed, field, env steps and {observation name: the normaliser's standard deviation}."""
    described = json.loads((folder / "policy.json").read_text())
    normalizer = described.get("normalizer")
    if normalizer is None:
        raise SystemExit(f"{folder}: its policy keeps no observation normaliser (trained without one)")
    return {"policy": str(folder), "seed": described["seed"], "field": described["field"],
            "env_steps": described["env_steps"],
            "std": dict(zip(described["observation_names"], normalizer["std"]))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("policies", nargs="+", type=Path, help="folders written by `fieldgen export`")
    parser.add_argument("--top", type=int, default=5, help="largest deviations to print per policy")
    parser.add_argument("--out", type=Path, help="a .jsonl of the rows")
    args = parser.parse_args()
    rows = [scales(folder) for folder in args.policies]
    for row in rows:
        std = row["std"]
        largest = sorted(std, key=std.get, reverse=True)[:args.top]
        print(f"seed {row['seed']} ({row['field']}, {row['env_steps']:,} env steps): median "
              f"{np.median(list(std.values())):.3g}; largest " + ", ".join(f"{n} {std[n]:.3g}" for n in largest))
    if args.out:
        args.out.write_text("".join(json.dumps(row) + "\n" for row in rows))


if __name__ == "__main__":
    main()
