"""The trainers by the names `--algo`, config files and a run's run.json call them.

An algorithm is the folder agents/<name>/: its config.py defines its settings (a RunConfig whose `algo`
is the folder's name) and its train.py its `make_train`. The names (choices.py, handed on here for the
command line) come from the folder list alone; a trainer's modules, and JAX with them, load when it is
looked up.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import inspect
from typing import TYPE_CHECKING, Callable

from ..suggest import did_you_mean
from .choices import ALGORITHMS, DEFAULT_ALGORITHM, EVAL_ACTIONS, PRESETS, judged_on

if TYPE_CHECKING:
    from .config import RunConfig
    from .loop import Trainer

__all__ = ["ALGORITHMS", "DEFAULT_ALGORITHM", "EVAL_ACTIONS", "PRESETS", "Entry", "judged_on", "trainer"]


@dataclasses.dataclass(frozen=True)
class Entry:
    config: type[RunConfig]  # its settings; config.algo is the name it is listed under
    make_train: Callable[..., Trainer]  # (config, env) -> the run as pure functions


def trainer(name: str) -> Entry:
    from .config import ConfigError

    if name not in ALGORITHMS:
        hint, choices = did_you_mean(name, ALGORITHMS), ", ".join(ALGORITHMS)
        raise ConfigError(f"unknown algorithm '{name}'{hint} Available: {choices}." if hint
                          else f"unknown algorithm '{name}'; available: {choices}.")
    return _load(name)


@functools.cache
def _load(name: str) -> Entry:
    return Entry(config_class(importlib.import_module(f".{name}.config", __package__), name),
                 importlib.import_module(f".{name}.train", __package__).make_train)


def config_class(module, name: str) -> type[RunConfig]:
    """The one config class `module` (agents/<name>/config.py) defines, checked to be listed under `name`."""
    from .config import RunConfig

    defined = [value for value in vars(module).values() if inspect.isclass(value) and issubclass(value, RunConfig)
               and value.__module__ == module.__name__]
    if len(defined) != 1:
        raise TypeError(f"{module.__name__} defines {len(defined)} config classes; an algorithm's config.py "
                        "defines one")
    config = defined[0]
    if config.algo != name:
        raise TypeError(f"{config.__name__}.algo is '{config.algo}', but the registry lists it as '{name}'")
    return config
