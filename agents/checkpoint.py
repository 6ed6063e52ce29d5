"""Checkpoints of a whole training state: every leaf of the pytree as one .npz blob.

The state's structure comes from a template built the same way as the saved
run (same config, same environment), so loading checks that every leaf's shape
and dtype match and says which one does not. Writing the bytes to disk (and
doing it atomically) is the caller's business.
"""

from __future__ import annotations

import io
from pathlib import Path

import jax
import numpy as np


class CheckpointError(Exception):
    """A checkpoint that is missing, corrupt, or from a different run shape."""


def to_bytes(state) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, *[np.asarray(x) for x in jax.tree.leaves(jax.device_get(state))])
    return buf.getvalue()


def load(path: Path, template):
    """The saved state, in the structure of `template`."""
    try:
        with np.load(path) as saved:
            leaves = [saved[f"arr_{i}"] for i in range(len(saved.files))]
    except FileNotFoundError:
        raise CheckpointError(f"no checkpoint at {path}") from None
    except (OSError, ValueError, KeyError, EOFError) as exc:
        raise CheckpointError(f"{path} is not a readable checkpoint ({exc}); it may be truncated or corrupt") from None
    expected, treedef = jax.tree.flatten(template)
    if len(leaves) != len(expected):
        raise CheckpointError(f"{path} holds {len(leaves)} arrays but this run has {len(expected)}: "
                              "it was written by a different algorithm, network or field")
    for i, (got, want) in enumerate(zip(leaves, expected)):
        if got.shape != np.shape(want) or got.dtype != np.asarray(want).dtype:
            raise CheckpointError(f"{path}: array {i} is {got.dtype}{list(got.shape)} but this run expects "
                                  f"{np.asarray(want).dtype}{list(np.shape(want))}: the config or the field's "
                                  "observation layout differs from the run that wrote it")
    return jax.tree.unflatten(treedef, [jax.numpy.asarray(x) for x in leaves])
