"""TD3: its settings (config.py) and its training function (train.py), on agents.offpolicy."""

from .config import TD3Config
from .train import make_train

__all__ = ["TD3Config", "make_train"]
