"""Checkpoints of a whole training state: every leaf of the pytree, msgpack-serialized by flax.

The state's structure comes from a template built the same way as the saved
run (same config, same environment), so loading checks that every leaf's shape
and dtype match and says which one does not. The last entry is the SHA-256 of
every byte before it, so damage on disk or in a copy is found at load, not
mistaken later for training that diverged; a checkpoint without it is refused too. Writing the bytes to disk (and doing
it atomically) is the caller's business.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Iterator

import jax
import msgpack
import numpy as np
from flax import serialization

BLOCK_BYTES = 16 * 2**20  # a larger leaf (a replay buffer) is stored as a map of row blocks of about this size
DIGEST = "sha256"  # the key of the checksum entry, last in the map
_TRAILER = len(msgpack.packb(DIGEST)) + len(msgpack.packb("0" * 64))  # its bytes at the end of the file


class CheckpointError(Exception):
    """A checkpoint that is missing, corrupt, or from a different run shape."""


class CheckpointDamaged(CheckpointError):
    """A checkpoint that cannot be read whole (missing, cut short, edited): no question of its run's shape."""


def pieces(state) -> Iterator[bytes]:
    """The checkpoint of `state`, a msgpack map from leaf index to leaf, as consecutive pieces of bytes,
    closed by the checksum of all of them.

    Each leaf, and each row block of a leaf over BLOCK_BYTES, is serialized by flax on its own. Python's
    lock is then held for one block at a time rather than for the whole state: serializing a gigabyte
    in one call would stall the training thread beside it for seconds. Written one after another,
    the pieces also never hold a second copy of the whole state in memory."""
    digest = hashlib.sha256()
    for piece in _leaf_pieces(state):
        digest.update(piece)
        yield piece
    yield msgpack.packb(DIGEST) + msgpack.packb(digest.hexdigest())


def _leaf_pieces(state) -> Iterator[bytes]:
    leaves = [np.asarray(x) for x in jax.tree.leaves(jax.device_get(state))]
    packer = msgpack.Packer()
    yield packer.pack_map_header(len(leaves) + 1)
    for i, leaf in enumerate(leaves):
        yield packer.pack(str(i))
        if leaf.nbytes <= BLOCK_BYTES or leaf.ndim == 0:
            yield serialization.msgpack_serialize(leaf)
            continue
        rows = max(1, BLOCK_BYTES * leaf.shape[0] // leaf.nbytes)
        starts = range(0, leaf.shape[0], rows)
        yield packer.pack_map_header(len(starts))
        for k, start in enumerate(starts):
            yield packer.pack(str(k))
            yield serialization.msgpack_serialize(leaf[start:start + rows])


def to_bytes(state) -> bytes:
    return b"".join(pieces(state))


def load(path: Path, template, then=None):
    """The saved state, in the structure of `template` (arrays or jax.ShapeDtypeStructs). With `then`, the
    file may go on after `template`'s arrays with `then`'s, which later versions write there (a file written
    before holds none): the result is (the state, `then`'s part or None)."""
    leaves = _read_leaves(path)
    older = then is not None and len(leaves) == len(jax.tree.leaves(template))  # written before `then` was kept
    expected, treedef = jax.tree.flatten(template if then is None or older else (template, then))
    if len(leaves) != len(expected):
        raise CheckpointError(f"{path} holds {len(leaves)} arrays but this run has {len(expected)}: "
                              "it was written by a different algorithm, network or field, or by an earlier "
                              "version of the trainer whose training state was laid out differently")
    for i, (got, want) in enumerate(zip(leaves, expected)):
        if got.shape != tuple(want.shape) or got.dtype != want.dtype:
            raise CheckpointError(f"{path}: array {i} is {got.dtype}{list(got.shape)} but this run expects "
                                  f"{want.dtype}{list(want.shape)}: the config or the field's "
                                  "observation layout differs from the run that wrote it")
    loaded = jax.tree.unflatten(treedef, [jax.numpy.asarray(x) for x in leaves])
    return (loaded, None) if older else loaded


def load_tail(path: Path, template):
    """The last arrays of the file at `path`, in the structure of `template`: a part written last (what
    `load`'s `then` reads) read without the template of everything before it. None where the file does not
    end with arrays of those shapes and dtypes (a file written before that part was kept)."""
    leaves = _read_leaves(path)
    expected, treedef = jax.tree.flatten(template)
    tail = leaves[-len(expected):]  # fewer where the file holds fewer
    if len(tail) != len(expected) or any(got.shape != tuple(want.shape) or got.dtype != want.dtype
                                         for got, want in zip(tail, expected)):
        return None
    return jax.tree.unflatten(treedef, tail)


def _read_leaves(path: Path) -> list[np.ndarray]:
    """Every array of the checkpoint at `path`, in order, its checksum verified; CheckpointError in a sentence."""
    try:
        blob = path.read_bytes()
    except FileNotFoundError:
        raise CheckpointDamaged(f"no checkpoint at {path}") from None
    except OSError as exc:
        raise CheckpointDamaged(f"cannot read the checkpoint {path}: {exc.strerror}; put the run's checkpoint file "
                              "there, or move what is there aside to train the run again from its start") from None
    corrupt = (f"checkpoint corrupt: {path} was damaged after it was written (on disk or in a copy); "
               "restore it from a copy, or start the run again in a new folder")
    try:
        saved = serialization.msgpack_restore(blob)
        if not isinstance(saved, dict) or DIGEST not in saved:
            raise CheckpointDamaged(f"{path} holds no {DIGEST} entry, so it cannot be told from a damaged one (cut "
                                  "short, edited, or written by another program): restore it from a copy, or start "
                                  "the run again in a new folder")
        if saved[DIGEST] != hashlib.sha256(blob[:-_TRAILER]).hexdigest():
            raise CheckpointDamaged(corrupt)
        return [_joined(saved[str(i)]) for i in range(len(saved) - 1)]
    except CheckpointError:
        raise
    except Exception:  # msgpack raises many types on damaged input
        raise CheckpointDamaged(f"{corrupt}; it may also be truncated") from None


def _joined(leaf) -> np.ndarray:
    """A leaf as saved: an array, or the row blocks of one (`pieces`)."""
    if isinstance(leaf, dict):
        return np.concatenate([np.asarray(leaf[str(k)]) for k in range(len(leaf))])
    return np.asarray(leaf)
