"""buffer_settles: where the level buffer settles under per-level success held still, for a results page."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from fieldgen.curriculum.auto import Sampler

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
import buffer_settles  # noqa: E402

sys.path.remove(str(ROOT / "bench"))


def test_a_point_succeeds_between_its_level_and_the_one_before_by_its_place():
    coordinates = np.array([[np.nan, np.nan, 0.0], [0.1, 0.3, 0.5]])
    success = buffer_settles.point_success(coordinates, np.array([0.8, 0.2]))
    np.testing.assert_allclose(success[1], [0.8, 0.5, 0.2])
    assert success[0, 2] == 0.8 and success[0, 0] == 0.0  # a point not played has no success


def test_the_evaluation_nearest_the_steps_asked_is_read_over_seeds(tmp_path):
    metrics = tmp_path / "metrics.jsonl"
    rows = [{"env_steps": s, "seed": seed, "variants": {"success_any": [seed * 0.2 + s / 1e3, 0.0]}}
            for s in (100, 200) for seed in (0, 1)]
    metrics.write_text("".join(json.dumps(r) + "\n" for r in rows))
    at, levels = buffer_settles.measured_success(metrics, 190)
    assert at == 200 and np.allclose(levels, [0.3, 0.0])


def test_ahead_moves_the_settled_buffer_towards_the_field():
    """Success falling along the path: at ahead 0 the episodes stay on the early levels, at 4 they move on; the
    field keeps its share either way, and the shares sum to one."""
    coordinates = np.where(np.arange(8)[None, :] >= 4, np.linspace(0, 1, 32).reshape(4, 8), np.nan)
    coordinates[0, :-1] = np.nan
    success = buffer_settles.point_success(coordinates, np.array([0.6, 0.4, 0.2, 0.1]))
    shares = {a: buffer_settles.settle(coordinates, success, Sampler(buffer=8, replaced=2, ahead=a), 10, 400, 0)
              for a in (0.0, 4.0)}
    for settled in shares.values():
        assert np.isclose(settled.sum(), 1.0) and settled[-1] >= 0.2 - 1e-6
    assert shares[4.0][2:].sum() > shares[0.0][2:].sum()


def test_env_steps_read_as_fieldgen_reads_counts_and_refused_in_argparse_s_words():
    assert buffer_settles.env_steps("22M") == 22_000_000 and buffer_settles.env_steps("1.08M") == 1_080_000
    with pytest.raises(argparse.ArgumentTypeError, match="'abc' is not a positive whole count"):
        buffer_settles.env_steps("abc")


def test_ahead_from_pairs_with_ahead_value_by_value_or_one_for_all():
    parser = argparse.ArgumentParser(prog="buffer_settles.py")
    paired = buffer_settles.samplers("0,2,2", "0,0,0.1", 8, parser)
    assert list(paired) == ["0", "2", "2 from 0.1"]
    assert [(s.ahead, s.ahead_from, s.replaced) for s in paired.values()] == [(0, 0, 8), (2, 0, 8), (2, 0.1, 8)]
    assert [(s.ahead, s.ahead_from) for s in buffer_settles.samplers("0,2", "0.1", 4, parser).values()] == \
        [(0, 0.1), (2, 0.1)]
    for ahead, ahead_from in (("0,2,4", "0,0.1"), ("2", "half"), ("2", "1.5")):  # argparse's one line each
        with pytest.raises(SystemExit):
            buffer_settles.samplers(ahead, ahead_from, 8, parser)
