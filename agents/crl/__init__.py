"""Contrastive RL (CRL): its settings (config.py) and its training function (train.py)."""

from .config import CRLConfig
from .train import make_train

__all__ = ["CRLConfig", "make_train"]
