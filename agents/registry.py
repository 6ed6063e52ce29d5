"""The trainers by the names `--algo`, config files and a run's run.json call them."""

from __future__ import annotations

import dataclasses
from typing import Callable

from ..suggest import did_you_mean
from . import crl, icrl, ppo, sac, td3
from .config import ConfigError, RunConfig
from .loop import Trainer


@dataclasses.dataclass(frozen=True)
class Entry:
    config: type[RunConfig]  # its settings; config.algo is the name it is listed under
    make_train: Callable[..., Trainer]  # (config, env) -> the run as pure functions


TRAINERS: dict[str, Entry] = {entry.config.algo: entry for entry in (
    Entry(crl.CRLConfig, crl.make_train), Entry(icrl.ICRLConfig, icrl.make_train),
    Entry(ppo.PPOConfig, ppo.make_train), Entry(sac.SACConfig, sac.make_train),
    Entry(td3.TD3Config, td3.make_train))}


def trainer(name: str) -> Entry:
    if name not in TRAINERS:
        raise ConfigError(f"unknown algorithm '{name}'{did_you_mean(name, TRAINERS)} "
                          f"Available: {', '.join(TRAINERS)}.")
    return TRAINERS[name]
