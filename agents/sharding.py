"""Spreading a training state over the devices with jax.sharding: this process's, or, in a run over
several processes (jax.distributed), every process's, in one global mesh.

Seeds trained at once (vmapped) that fill the devices evenly are split by seed: each
device trains its own seeds and nothing passes between devices. Otherwise the
environments (and anything stored per environment, such as the replay buffer's
columns) are split across devices along one mesh axis; everything else (parameters,
optimizer states, keys) is replicated, and a loss averaged over the sharded batch
becomes a cross-device mean of gradients. Code stays single-device code: the compiler
partitions it from these placements. Every process runs the same program on its own devices' share;
`to_host` brings a result whole to every process, which is a collective: all processes call it alike.
"""

from __future__ import annotations

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

AXIS = "envs"


def device_mesh(count: int | None = None) -> Mesh:
    """A mesh over the first `count` devices of every process (all of them by default)."""
    return Mesh(np.array(jax.devices()[:count]), (AXIS,))


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


def by_seed(seeds: int, devices: int) -> bool:
    """Whether `seeds` vmapped seeds are split by seed over `devices` (else by environment)."""
    return seeds > 1 and seeds % devices == 0


def training_shardings(state, mesh: Mesh, env_axes: dict[str, int]):
    """Shardings for a training state vmapped over seeds (a leading seed axis on every leaf): by seed
    when the seeds are a multiple of the devices, else by environment (`state_shardings`)."""
    if by_seed(jax.tree.leaves(state)[0].shape[0], mesh.size):
        return jax.tree.map(lambda x: NamedSharding(mesh, PartitionSpec(AXIS)), state)
    return state_shardings(state, mesh, env_axes, offset=1)


def device_count() -> int:
    """The devices a run spreads over: every process's."""
    return jax.device_count()


def from_host(tree, placement):
    """`tree`, read alike by every process (a checkpoint), placed as `placement` says. In a run over several
    processes each places its own devices' shares: jax.device_put would first check, by an exchange per
    array, that every process holds the same values."""
    if jax.process_count() == 1:
        return jax.device_put(tree, placement)
    return jax.tree.map(lambda x, s: jax.make_array_from_callback(np.shape(x), s, lambda index: np.asarray(x)[index]),
                        tree, placement)


MEETING_SECONDS = 3600  # how long a process waits for the others at a meeting; one that dies is noticed sooner


def coordination_client():
    """The coordination service's client JAX keeps (None in a run of one process). Its public API has no way
    to it: jax.distributed only starts and stops the runtime, and multihost_utils' barriers are collectives,
    which is what a meeting must come before."""
    from jax._src import distributed

    return distributed.global_state.client


def meet(name: str, seconds: int = MEETING_SECONDS) -> None:
    """Wait until every process of the run has called meet(name), through the coordination service rather
    than a collective: on the CPU, gloo gives the other processes 30 s to join a process's first collective,
    less than one process's compile can lag another's. A no-op in a run of one process."""
    if jax.process_count() > 1:
        coordination_client().wait_at_barrier(name, seconds * 1000)


def to_host(tree):
    """`tree` as NumPy arrays, whole, on this host (jax.device_get), gathering the shares other processes hold
    where a run spans several."""
    if jax.process_count() == 1:
        return jax.device_get(tree)
    from jax.experimental import multihost_utils

    def whole(x):
        if isinstance(x, jax.Array) and not x.is_fully_addressable:
            return np.asarray(multihost_utils.process_allgather(x, tiled=True))
        return jax.device_get(x)

    return jax.tree.map(whole, tree)
