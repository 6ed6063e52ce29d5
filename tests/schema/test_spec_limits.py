"""Hostile and heavy specs: each is refused (or accepted) within a few hundred MB, with one line naming the
file, line and key; measured here, not assumed. Memory, not the clock, bounds the work: a spec that expands
without end (an alias bomb, a nesting without end) shows as memory long before it shows as minutes, and a
machine's load changes no count of bytes."""

from __future__ import annotations

import os
import tracemalloc

import pytest

from fieldgen.schema import SpecError, load_spec

MEGABYTES = 300


def measured(path):
    """Problems or None, once the load's peak memory under tracemalloc is checked."""
    def run():
        try:
            load_spec(path)
        except SpecError as exc:
            return exc.problems
        return None

    tracemalloc.start()
    try:
        found = run()
        peak = tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()
    assert peak < MEGABYTES, f"{peak:.0f} MB"
    return found


def one_problem(path):
    found = measured(path)
    assert found is not None and len(found) == 1, found
    return found[0]


LAUGHS = "".join(f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 9)}]\n" for i in range(1, 10))


def test_an_alias_bomb_is_refused_before_it_is_built(write_spec):
    p = one_problem(write_spec("l0: &l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n" + LAUGHS + "name: x\n"))
    assert (p.line, p.path) == (10, "l9")
    assert "a field spec holds 4,412,961,518 values" in p.message and "at most 30,000" in p.message


def test_an_alias_inside_itself_is_refused(write_spec):
    p = one_problem(write_spec("name: x\ngoal: &g\n  width: *g\n"))
    assert p.line == 2 and "would nest without end" in p.message


@pytest.mark.parametrize("opening,closing", [("[", "]"), ("{a: ", "}")])
def test_twenty_thousand_nested_brackets(write_spec, opening, closing):
    spec = write_spec("name: x\ndescription: " + opening * 20_000 + "1" + closing * 20_000 + "\n")
    p = one_problem(spec)
    assert p.file == spec and p.line == 2 and "nests deeper than 32 levels" in p.message


@pytest.mark.parametrize("text,path", [
    ("name: x\ndescription: " + "[" * 40 + "]" * 40 + "\n", "description[0][0][0][0][0][0][0][0][0][0][0][0][0][0][0]"
     "[0][0][0][0][0][0][0][0][0][0][0][0][0][0][0][0]"),
    ("name: x\nobstacles:\n  rock:\n    x: " + "{a: " * 40 + "1" + "}" * 40 + "\n", "obstacles.rock.x.a.a.a.a.a.a.a"),
    ("name: x\ntask:\n  reward:\n  - term: success\n  - " + "[" * 40 + "]" * 40 + "\n", "task.reward[1]"),
])
def test_nesting_too_deep_names_the_key_path_it_got_to(write_spec, text, path):
    """Before: the refusal named no key, so the author of a large spec had to find the place by line alone."""
    p = one_problem(write_spec(text))
    assert p.path.startswith(path) and "nests deeper than 32 levels" in p.message


def test_an_extends_chain_hundreds_deep(tmp_path):
    for i in range(300):
        (tmp_path / f"c{i}.yaml").write_text(f"extends: c{i + 1}.yaml\nname: c{i}\n" if i < 299 else "name: c299\n")
    p = one_problem(tmp_path / "c0.yaml")
    assert p.file == tmp_path / "c15.yaml" and (p.line, p.path) == (1, "extends")
    assert "longer than 16 files" in p.message


def test_devices_pipes_and_huge_files_are_not_read(write_spec, tmp_path):
    p = one_problem(write_spec("extends: /dev/zero\nname: x\n"))
    assert (p.line, p.path) == (1, "extends") and "'/dev/zero' is an absolute path" in p.message
    os.symlink("/dev/zero", tmp_path / "zero.yaml")
    p = one_problem(write_spec("name: x\nextends: zero.yaml\n", "via_link.yaml"))
    assert (p.line, p.path) == (2, "extends") and "'zero.yaml' is not a regular file" in p.message
    os.mkfifo(tmp_path / "pipe.yaml")
    p = one_problem(tmp_path / "pipe.yaml")
    assert "not a regular file" in p.message
    p = one_problem(write_spec("name: x\ndescription: " + "a" * 1_100_000 + "\n", "huge.yaml"))
    assert "has 1,100,022 bytes; a field spec may have at most 1,000,000" in p.message


def obstacles(n: int, size: float = 1.0) -> str:
    """n obstacles on a grid over a 500 x 500 field, clear of the column from the start to the goal."""
    step = 12 if n <= 1400 else 6
    spots = [(x, y) for y in range(-230, 231, step) for x in range(-230, 231, step) if abs(x) >= 10]
    return "".join(f"  o{i}: {{x: {x}, y: {y}, width: {size}, depth: {size}}}\n" for i, (x, y) in enumerate(spots[:n]))


HEAVY = "extends: soccer_v2\nname: heavy\nfield: {length: 500, width: 500}\ngoal: {distance: 240}\n"


def test_the_largest_field_with_a_thousand_obstacles_validates_quickly(write_spec):
    assert measured(write_spec(HEAVY)) is None
    spec = write_spec(HEAVY + "obstacles:\n  goalie: null\n" + obstacles(1000, size=3.0), "many.yaml")
    found = measured(spec)
    assert found is None, found
    assert len(load_spec(spec).obstacles) == 1000


def test_more_obstacles_than_the_limit_are_one_problem(write_spec):
    p = one_problem(write_spec(HEAVY + "obstacles:\n" + obstacles(1000)))  # and soccer_v2's goalie
    assert (p.line, p.path) == (5, "obstacles") and "at most 1,000 items here (got 1,001)" in p.message
