"""PPO: its settings (config.py) and its training function (train.py)."""

from .config import PPOConfig
from .train import make_train

__all__ = ["PPOConfig", "make_train"]
