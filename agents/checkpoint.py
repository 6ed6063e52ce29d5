"""Checkpoints of a whole training state: every leaf of the pytree, msgpack-serialized by flax.

The state's structure comes from a template built the same way as the saved
run (same config, same environment), so loading checks that every leaf's shape
and dtype match and says which one does not. Writing the bytes to disk (and
doing it atomically) is the caller's business.
"""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np
from flax import serialization


class CheckpointError(Exception):
    """A checkpoint that is missing, corrupt, or from a different run shape."""


def to_bytes(state) -> bytes:
    leaves = jax.tree.leaves(jax.device_get(state))
    return serialization.msgpack_serialize({str(i): np.asarray(x) for i, x in enumerate(leaves)})


def load(path: Path, template):
    """The saved state, in the structure of `template` (arrays or jax.ShapeDtypeStructs)."""
    try:
        blob = path.read_bytes()
    except FileNotFoundError:
        raise CheckpointError(f"no checkpoint at {path}") from None
    try:
        saved = serialization.msgpack_restore(blob)
        leaves = [np.asarray(saved[str(i)]) for i in range(len(saved))]
    except Exception as exc:  # msgpack raises many types on damaged input
        raise CheckpointError(f"{path} is not a readable checkpoint ({type(exc).__name__}); "
                              "it may be truncated or corrupt") from None
    expected, treedef = jax.tree.flatten(template)
    if len(leaves) != len(expected):
        raise CheckpointError(f"{path} holds {len(leaves)} arrays but this run has {len(expected)}: "
                              "it was written by a different algorithm, network or field, or by an earlier "
                              "version of the trainer whose training state was laid out differently")
    for i, (got, want) in enumerate(zip(leaves, expected)):
        if got.shape != tuple(want.shape) or got.dtype != want.dtype:
            raise CheckpointError(f"{path}: array {i} is {got.dtype}{list(got.shape)} but this run expects "
                                  f"{want.dtype}{list(want.shape)}: the config or the field's "
                                  "observation layout differs from the run that wrote it")
    return jax.tree.unflatten(treedef, [jax.numpy.asarray(x) for x in leaves])
