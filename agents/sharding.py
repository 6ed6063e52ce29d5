"""Spreading a training state over the local devices with jax.sharding.

The environments (and anything stored per environment, such as the replay buffer's
columns) are split across devices along one mesh axis; everything else (parameters,
optimizer states, keys) is replicated. Code stays single-device code: the compiler
partitions it from these placements, and a loss averaged over a sharded batch becomes a
cross-device mean of gradients.
"""

from __future__ import annotations

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

AXIS = "envs"


def local_mesh(count: int | None = None) -> Mesh:
    """A mesh over the first `count` local devices (all of them by default)."""
    return Mesh(np.array(jax.local_devices()[:count]), (AXIS,))


def state_shardings(state, mesh: Mesh, env_axes: dict[str, int], offset: int = 0):
    """A pytree of NamedShardings for `state` (a flax struct or its shapes).

    Leaves of the fields named in env_axes are split along that axis (+ offset, for
    leading axes such as vmapped seeds); a leaf with too few axes is replicated.
    """

    def place(axis: int | None):
        def leaf(x):
            if axis is None or len(x.shape) <= axis + offset:
                return NamedSharding(mesh, PartitionSpec())
            return NamedSharding(mesh, PartitionSpec(*([None] * (axis + offset)), AXIS))

        return leaf

    return state.replace(**{name: jax.tree.map(place(env_axes.get(name)), getattr(state, name))
                            for name in state.__dataclass_fields__})


def device_count() -> int:
    return len(jax.local_devices())
