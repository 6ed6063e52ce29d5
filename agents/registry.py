"""The trainers by the names `--algo`, config files and a run's run.json call them, and the other names the
command line offers before JAX loads.

The names are all this module holds until a trainer is looked up: its module, and JAX with it, loads
then, so the command line lists and checks the names (--algo's choices) without importing JAX.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
from typing import TYPE_CHECKING, Callable

from ..suggest import did_you_mean

if TYPE_CHECKING:
    from .config import RunConfig
    from .loop import Trainer

# each algorithm's name -> the name of its config class in agents/config.py; its trainer is the
# make_train of the module agents/<name>.py
CONFIG_CLASSES = {"crl": "CRLConfig", "icrl": "ICRLConfig", "ppo": "PPOConfig", "sac": "SACConfig",
                  "td3": "TD3Config"}
ALGORITHMS: tuple[str, ...] = tuple(CONFIG_CLASSES)
DEFAULT_ALGORITHM = "crl"  # what `fieldgen train` trains a field with when neither --algo nor a recipe names one
# named presets, `--preset NAME`: agents/presets/NAME.yaml, settings of every trainer sized for a kind of machine
PRESETS: tuple[str, ...] = ("cpu",)
# how a policy acts when it is judged (a run's evaluations, `eval_actions`; fieldgen eval --actions): its mean
# action, or actions drawn from it as in training, where the mean alone may do less (or more)
EVAL_ACTIONS: tuple[str, ...] = ("mean", "sampled")


def judged_on(actions: str) -> str:
    """What a figure's title adds about the actions it was judged on: nothing for the mean action."""
    return ", actions sampled from the policy" if actions == "sampled" else ""


@dataclasses.dataclass(frozen=True)
class Entry:
    config: type[RunConfig]  # its settings; config.algo is the name it is listed under
    make_train: Callable[..., Trainer]  # (config, env) -> the run as pure functions


def trainer(name: str) -> Entry:
    from .config import ConfigError

    if name not in CONFIG_CLASSES:
        raise ConfigError(f"unknown algorithm '{name}'{did_you_mean(name, ALGORITHMS)} "
                          f"Available: {', '.join(ALGORITHMS)}.")
    return _load(name)


@functools.cache
def _load(name: str) -> Entry:
    config = getattr(importlib.import_module(".config", __package__), CONFIG_CLASSES[name])
    if config.algo != name:
        raise TypeError(f"{config.__name__}.algo is '{config.algo}', but the registry lists it as '{name}'")
    return Entry(config, importlib.import_module(f".{name}", __package__).make_train)
