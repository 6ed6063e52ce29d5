"""SAC: its settings (config.py) and its training function (train.py), on agents.offpolicy."""

from .config import SACConfig
from .train import make_train

__all__ = ["SACConfig", "make_train"]
