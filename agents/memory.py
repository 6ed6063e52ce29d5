"""How much memory a run or a batch of episodes needs, found before anything is allocated, and a refusal
in words where the machine cannot hold it.

A trainer's state is measured exactly from its shapes (jax.eval_shape of `init`, nothing allocated): the
replay buffer, the episodes under way, the networks and their optimizers. To it comes what one update
holds besides: the windows of trajectory sampled from the buffer with their hindsight goals, or an
on-policy rollout. That second part is an estimate, so the total is "about"; it is compared with the
memory of the devices where JAX reports it (GPUs), and with the machine's memory otherwise (CPU).
"""

from __future__ import annotations

import dataclasses
import os

import jax
import jax.numpy as jnp
import numpy as np

from ..env.contract import agents_per_env
from .buffer import gradient_steps
from .config import ConfigError

BUFFER, EPISODES, NETWORKS, BATCH = "replay buffer", "episodes", "networks and optimizers", "update batch"
_PARTS = {"buffer": BUFFER, "env_state": EPISODES}  # trainer state fields by name; the rest: NETWORKS


@dataclasses.dataclass(frozen=True)
class Estimate:
    parts: dict[str, int]  # what holds memory -> bytes

    @property
    def total(self) -> int:
        return sum(self.parts.values())

    def text(self) -> str:
        parts = sorted(((b, name) for name, b in self.parts.items() if b), reverse=True)
        return f"about {size(self.total)} ({', '.join(f'{name} {size(b)}' for b, name in parts)})"


def training(trainer, seeds: int) -> Estimate:
    """What training `seeds` seeds at once with `trainer` (agents.loop.Trainer) holds in device memory."""
    keys = jax.ShapeDtypeStruct((seeds, 2), jnp.uint32)
    state = jax.eval_shape(jax.vmap(trainer.init), keys)
    parts = {name: 0 for name in (*_PARTS.values(), NETWORKS)}
    for field in dataclasses.fields(state):
        parts[_PARTS.get(field.name, NETWORKS)] += _bytes(getattr(state, field.name))
    parts[BATCH] = seeds * _batch_bytes(trainer, state)
    return Estimate(parts)


def episodes(env, count: int) -> Estimate:
    """What `count` episodes played at once on `env` hold (an evaluation, a benchmark)."""
    one = jax.eval_shape(env.reset, jax.ShapeDtypeStruct((2,), jnp.uint32))
    return Estimate({EPISODES: count * _bytes(one)})


def check(estimate: Estimate, what: str, lower: dict[str, str]) -> None:
    """Refuse (ConfigError) what the machine cannot hold, saying how much it would take and what to lower:
    `lower` names the settings that size each part, and the largest part's are named."""
    have, where = available()
    if estimate.total > have:
        largest = max(estimate.parts, key=estimate.parts.get)
        raise ConfigError(f"{what} needs {estimate.text()} of memory, more than the {size(have)} of {where}; "
                          f"lower {lower[largest]}")


def available() -> tuple[int, str]:
    """(bytes, in words where): the devices' memory where JAX reports it, else the machine's; in a run over
    several processes, as much again for each of the others (each reports only its own devices)."""
    devices, processes = jax.local_devices(), jax.process_count()
    limits = [(d.memory_stats() or {}).get("bytes_limit") for d in devices]
    over = f" of each of {processes} processes" if processes > 1 else ""
    if all(limits):
        kind = devices[0].device_kind
        return sum(limits) * processes, f"the {len(devices)} {kind} device{'s' * (len(devices) > 1)}{over}"
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") * processes, f"this machine{over}"


def size(count: int) -> str:
    for unit, scale in (("EB", 1e18), ("PB", 1e15), ("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if count >= scale:
            return f"{count / scale:,.3g} {unit}" if count < 1000 * scale else f"{count / scale:,.0f} {unit}"
    return f"{count} bytes"


def _bytes(tree) -> int:
    return sum(int(np.prod(x.shape, dtype=object)) * x.dtype.itemsize for x in jax.tree.leaves(tree))


def _batch_bytes(trainer, state) -> int:
    """One seed's update besides its state: windows sampled from a replay buffer, each step with its stored row
    and as much again for its hindsight goal and next state; without a buffer, a rollout of every environment
    (observation, action and the few numbers kept per step, for every agent of a match)."""
    config, env = trainer.config, trainer.env
    buffer = getattr(state, "buffer", None)
    if buffer is not None:
        data = jax.tree.leaves(buffer.data)
        row = sum(_bytes(x) // (x.shape[0] * x.shape[1] * x.shape[2]) for x in data)  # [seeds, rows, envs, ...]
        windows, _ = gradient_steps(config, env.episode_length)
        return 2 * windows * env.episode_length * row
    agents = agents_per_env(env)  # a match's every agent steps and is learned from
    return config.num_envs * config.unroll_length * agents * 4 * (env.observation_size + 2 * env.action_size + 6)
