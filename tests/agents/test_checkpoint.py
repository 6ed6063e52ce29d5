"""Checkpoints written piece by piece: a large leaf in row blocks, read back whole."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from flax import serialization

from fieldgen.agents import checkpoint
from fieldgen.files import write_atomic


def test_a_large_leaf_goes_in_row_blocks_and_comes_back_whole(tmp_path, monkeypatch):
    monkeypatch.setattr(checkpoint, "BLOCK_BYTES", 1000)
    state = {"buffer": np.arange(3000, dtype=np.float32).reshape(300, 10), "small": np.ones(3, np.float32), "step": np.int32(7)}
    template = jax.tree.map(lambda x: jax.ShapeDtypeStruct(np.shape(x), np.asarray(x).dtype), state)
    pieces = list(checkpoint.pieces(state))
    assert max(len(p) for p in pieces) < 1100  # no piece holds much more than a block of 25 rows
    path = tmp_path / "checkpoint.msgpack"
    write_atomic(path, iter(pieces))
    saved = serialization.msgpack_restore(path.read_bytes())  # still flax's msgpack
    assert sorted(saved) == ["0", "1", "2", checkpoint.DIGEST] and len(saved["0"]) == 12 and isinstance(saved["1"], np.ndarray)

    restored = checkpoint.load(path, template)
    for got, want in zip(jax.tree.leaves(restored), jax.tree.leaves(state)):
        assert got.dtype == want.dtype
        np.testing.assert_array_equal(np.asarray(got), want)


def test_a_checkpoint_without_its_checksum_is_refused(tmp_path):
    """Written whole by flax without the sha256 entry (as before checksums, or by another program), or with the
    entry cut off: nothing says the arrays are those written, so it is refused rather than trusted."""
    state = {"weights": np.linspace(0, 1, 40, dtype=np.float32), "step": np.int32(7)}
    template = jax.tree.map(lambda x: jax.ShapeDtypeStruct(np.shape(x), np.asarray(x).dtype), state)
    whole = tmp_path / "whole.msgpack"
    whole.write_bytes(serialization.msgpack_serialize({str(i): np.asarray(x) for i, x in enumerate(jax.tree.leaves(state))}))
    with pytest.raises(checkpoint.CheckpointError, match=f"{whole} holds no sha256 entry"):
        checkpoint.load(whole, template)
    saved = serialization.msgpack_restore(checkpoint.to_bytes(state))
    del saved[checkpoint.DIGEST]
    whole.write_bytes(serialization.msgpack_serialize(saved))
    with pytest.raises(checkpoint.CheckpointError, match="holds no sha256 entry"):
        checkpoint.load(whole, template)


def test_flipped_bytes_or_a_folder_are_reported_as_such(tmp_path):
    """A damaged checkpoint fails its checksum at load ("checkpoint corrupt"), wherever the damage lies;
    a folder where the checkpoint should be is named, not a traceback."""
    state = {"weights": np.linspace(0, 1, 4000, dtype=np.float32), "step": np.int32(7)}
    template = jax.tree.map(lambda x: jax.ShapeDtypeStruct(np.shape(x), np.asarray(x).dtype), state)
    path = tmp_path / "checkpoint.msgpack"
    write_atomic(path, checkpoint.pieces(state))
    good = path.read_bytes()
    for where in (len(good) // 2, len(good) - 80):  # inside the weights; inside the small last leaf
        damaged = bytearray(good)
        damaged[where] ^= 0x10
        path.write_bytes(bytes(damaged))
        with pytest.raises(checkpoint.CheckpointError, match="checkpoint corrupt"):
            checkpoint.load(path, template)
    path.write_bytes(good[: len(good) // 3])
    with pytest.raises(checkpoint.CheckpointError, match="checkpoint corrupt: .*truncated"):
        checkpoint.load(path, template)
    folder = tmp_path / "a_folder"
    folder.mkdir()
    with pytest.raises(checkpoint.CheckpointError, match=f"cannot read the checkpoint {folder}"):
        checkpoint.load(folder, template)


def test_a_part_written_after_the_state_comes_back_beside_it_and_an_older_file_gives_none(tmp_path):
    """learner.msgpack holds what was learned, then how the run drew its episodes; a file written before the
    second part was kept still loads, with None for it, and a part of another shape is refused."""
    state, then = {"w": np.ones((2, 3), np.float32)}, {"weights": np.full((2, 4), 0.25, np.float32)}
    shapes = jax.tree.map(lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype), (state, then))
    both, older = tmp_path / "both.msgpack", tmp_path / "older.msgpack"
    write_atomic(both, checkpoint.pieces((state, then)))
    write_atomic(older, checkpoint.pieces(state))
    loaded, part = checkpoint.load(both, *shapes)
    np.testing.assert_array_equal(loaded["w"], state["w"])
    np.testing.assert_array_equal(part["weights"], then["weights"])
    loaded, part = checkpoint.load(older, *shapes)
    assert part is None and loaded["w"].shape == (2, 3)
    with pytest.raises(checkpoint.CheckpointError, match=r"array 1 is float32\[2, 4\] but this run expects"):
        checkpoint.load(both, shapes[0], {"weights": jax.ShapeDtypeStruct((2, 5), np.float32)})


def test_the_last_part_alone_is_read_without_the_template_of_what_comes_before(tmp_path):
    """load_tail reads the part written last (learner.msgpack's sampling) from its own shapes, its checksum
    checked; a file with fewer arrays, or ending with arrays of other shapes (written before that part was
    kept), gives None."""
    state, then = {"w": np.ones((2, 3), np.float32), "b": np.zeros(5, np.float32)}, \
        {"counts": np.arange(8, dtype=np.float32).reshape(2, 4), "weights": np.full((4,), 0.25, np.float32)}
    path = tmp_path / "learner.msgpack"
    write_atomic(path, checkpoint.pieces((state, then)))
    tail = checkpoint.load_tail(path, jax.tree.map(lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype), then))
    np.testing.assert_array_equal(tail["counts"], then["counts"])
    np.testing.assert_array_equal(tail["weights"], then["weights"])
    many = {f"x{i}": jax.ShapeDtypeStruct((1,), np.float32) for i in range(5)}
    assert checkpoint.load_tail(path, many) is None
    assert checkpoint.load_tail(path, {"counts": jax.ShapeDtypeStruct((2, 4), np.float32),
                                       "weights": jax.ShapeDtypeStruct((5,), np.float32)}) is None
    older = tmp_path / "older.msgpack"
    write_atomic(older, checkpoint.pieces(state))
    assert checkpoint.load_tail(older, jax.tree.map(lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype), then)) is None
    damaged = bytearray(path.read_bytes())
    damaged[40] ^= 0xFF
    path.write_bytes(bytes(damaged))
    with pytest.raises(checkpoint.CheckpointError, match="checkpoint corrupt"):
        checkpoint.load_tail(path, jax.tree.map(lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype), then))
