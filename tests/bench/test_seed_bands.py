"""seed_bands: each seed's time to a success rate, judged on the field as a curriculum's runs are."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import pytest

from fieldgen.run import compare

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
import seed_bands  # noqa: E402

sys.path.remove(str(ROOT / "bench"))


def row(seed: int, steps: int, field: float, easiest: float) -> dict:
    """A mixed or automatic curriculum's evaluation row: success on every variant, the field last."""
    return {"seed": seed, "eval": steps, "env_steps": steps * 1_000_000, "wall_seconds": steps * 10.0,
            "success_any": (field + easiest) / 2, "variants": {"success_any": [easiest, field]}}


def test_each_seed_reaches_the_threshold_on_the_field_not_on_its_easy_levels():
    rows = [row(0, 1, 0.0, 0.9), row(0, 2, 0.4, 0.9), row(0, 3, 0.2, 0.9),  # the easy level alone is no success
            row(1, 1, 0.1, 0.5), row(1, 2, 0.2, 0.6), row(1, 3, 0.5, 0.6), row(1, 4, 0.6, 0.7),
            row(2, 1, 0.0, 0.8)]
    first = seed_bands.first_reaching(list(reversed(rows)), 0.3)  # in env-step order, whatever the files' order
    assert {seed: r and r["env_steps"] for seed, r in first.items()} == {0: 2_000_000, 1: 3_000_000, 2: None}
    text = seed_bands.reaching_text(rows, 0.3)
    assert text == "first success_any >= 0.3 on the field: 0: 2.0M (20 s), 1: 3.0M (30 s), 2: not by 1.0M"


def test_a_setting_after_earlier_runs_is_counted_from_nothing_learned(tmp_path):
    path = tmp_path / "chain.jsonl"
    path.write_text("\n".join(json.dumps(row(0, k, 0.1 * k, 0.9)) for k in (1, 2)) + "\n")
    moved = seed_bands.setting(str(path), seed_bands.earlier("chain=78.5M,2442")[1])
    assert [(r["env_steps"], r["wall_seconds"]) for r in moved.rows] == [(79_500_000, 2452.0), (80_500_000, 2462.0)]
    assert seed_bands.earlier("chain=3M") == ("chain", (3_000_000, 0.0))
    for bad in ("chain", "chain=lots", "chain=3M,soon"):
        try:
            seed_bands.earlier(bad)
        except argparse.ArgumentTypeError as exc:
            assert "LABEL=STEPS[,SECONDS]" in str(exc)
        else:
            raise AssertionError(f"{bad!r} was taken")


def test_a_label_or_a_run_folder_may_hold_an_equals_sign(tmp_path):
    folder = tmp_path / "sampler.replaced=4"
    folder.mkdir()
    first, second = folder / "a.jsonl", tmp_path / "b.jsonl"
    for path in (first, second):
        path.write_text(json.dumps(row(0, 1, 0.1, 0.9)) + "\n")
    assert seed_bands.labelled(f"share=0.05={first}+{second}") == ("share=0.05", f"{first}+{second}")
    assert seed_bands.labelled(f"preset={second}") == ("preset", str(second))
    for bad, words in ((str(second), "LABEL=FILE"), (f"preset={tmp_path / 'gone.jsonl'}", "no metrics file")):
        try:
            seed_bands.labelled(bad)
        except argparse.ArgumentTypeError as exc:
            assert words in str(exc)
        else:
            raise AssertionError(f"{bad!r} was taken")


def test_seeds_keeps_the_named_seeds_of_every_setting(tmp_path):
    path = tmp_path / "five.jsonl"
    path.write_text("\n".join(json.dumps(row(seed, 1, 0.1, 0.9)) for seed in range(340, 345)) + "\n")
    kept = seed_bands.setting(str(path), only=seed_bands.seed_list("340-341,343"))
    assert kept.seeds == [340, 341, 343]
    with pytest.raises(ValueError, match="none of seeds 350, 351, 352, 353, 354"):
        seed_bands.setting(str(path), only=seed_bands.seed_list("350-354"))
    for bad in ("340-x", "seeds", ""):
        with pytest.raises(argparse.ArgumentTypeError, match="FIRST-LAST"):
            seed_bands.seed_list(bad)


def test_judged_over_the_levels_a_seed_counts_every_level_alike(tmp_path, capsys, monkeypatch):
    rows = [row(0, 1, 0.0, 0.5), row(0, 2, 0.1, 0.7), row(1, 1, 0.0, 0.2), row(1, 2, 0.0, 0.4)]
    first = seed_bands.first_reaching(rows, 0.3, compare.over_levels)  # (0.0 + 0.7) / 2 = 0.35: seed 0's second row
    assert {seed: r and r["env_steps"] for seed, r in first.items()} == {0: 2_000_000, 1: None}
    assert seed_bands.first_reaching(rows, 0.3) == {0: None, 1: None}  # on the field no seed reaches 0.3
    assert seed_bands.reaching_text(rows, 0.3, compare.over_levels) == \
        "first success_any >= 0.3 over the levels: 0: 2.0M (20 s), 1: not by 2.0M"
    path = tmp_path / "two.jsonl"
    path.write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    out = tmp_path / "levels.png"
    monkeypatch.setattr(sys, "argv", ["seed_bands", f"arm={path}", "-o", str(out), "--judge", "levels"])
    seed_bands.main()
    printed = capsys.readouterr().out
    assert "success_any (level mean) 0: 0.400, 1: 0.200; IQM 0.300" in printed
    assert out.stat().st_size > 0
