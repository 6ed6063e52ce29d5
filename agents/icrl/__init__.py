"""Independent contrastive RL (ICRL): its settings (config.py) and its training function (train.py), CRL's
with the body split among controllers."""

from .config import ICRLConfig
from .train import make_train

__all__ = ["ICRLConfig", "make_train"]
