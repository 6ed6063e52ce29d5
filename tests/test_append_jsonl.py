"""Benchmark rows appended to a JSON-lines file (fieldgen.files.append_jsonl): each a line any JSON reader takes,
the rows before kept whole."""

from __future__ import annotations

import json
import math

from fieldgen.files import append_jsonl


def test_rows_append_as_strict_json_with_no_number_written_null(tmp_path):
    path = tmp_path / "rows.jsonl"
    append_jsonl(path, {"envs": 8192, "ratio_to_jax": math.nan, "nested": {"x": [1.0, math.inf]}})
    append_jsonl(path, {"envs": 24576, "ratio_to_jax": 0.97})
    append_jsonl(None, {"envs": 1})  # no file named: nothing written
    rows = [json.loads(line, parse_constant=lambda name: (_ for _ in ()).throw(ValueError(name)))
            for line in path.read_text().splitlines()]
    assert rows == [{"envs": 8192, "ratio_to_jax": None, "nested": {"x": [1.0, None]}},
                    {"envs": 24576, "ratio_to_jax": 0.97}]


def test_a_torn_last_line_is_left_as_it_was_and_the_new_row_starts_its_own(tmp_path):
    path = tmp_path / "rows.jsonl"
    path.write_text('{"envs": 8192}\n{"envs": 24')  # a line cut by a kill mid-write in code before
    append_jsonl(path, {"envs": 64})
    assert path.read_text().splitlines() == ['{"envs": 8192}', '{"envs": 24', '{"envs": 64}']
    assert not list(tmp_path.glob(".rows.jsonl.*"))  # no temporary file left beside it
