"""observation_scales: each exported policy's normaliser, by observation."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
import observation_scales  # noqa: E402

sys.path.remove(str(ROOT / "bench"))


def policy(folder: Path, seed: int, std: list[float] | None) -> Path:
    folder.mkdir()
    described = {"seed": seed, "field": "f", "env_steps": 100, "observation_names": ["root.x", "root.vx"]}
    if std is not None:
        described["normalizer"] = {"mean": [0.0, 0.0], "std": std}
    (folder / "policy.json").write_text(json.dumps(described))
    return folder


def test_rows_name_each_observations_deviation_and_the_poisoned_seed_stands_out(tmp_path, monkeypatch, capsys):
    sound, blown = policy(tmp_path / "a", 1, [0.5, 1.2]), policy(tmp_path / "b", 2, [0.4, 5.9e5])
    assert observation_scales.scales(blown)["std"] == {"root.x": 0.4, "root.vx": 5.9e5}
    out = tmp_path / "scales.jsonl"
    monkeypatch.setattr(sys, "argv", ["observation_scales.py", str(sound), str(blown), "--top", "1",
                                      "--out", str(out)])
    observation_scales.main()
    printed = capsys.readouterr().out.splitlines()
    assert printed[1].startswith("seed 2 (f, 100 env steps): median") and printed[1].endswith("largest root.vx 5.9e+05")
    assert [json.loads(line)["seed"] for line in out.read_text().splitlines()] == [1, 2]


def test_a_policy_without_a_normaliser_is_one_line(tmp_path):
    with pytest.raises(SystemExit, match="keeps no observation normaliser"):
        observation_scales.scales(policy(tmp_path / "c", 3, None))
