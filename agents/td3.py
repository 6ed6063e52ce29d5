"""TD3: SAC's off-policy machinery (agents.sac) with a deterministic actor, Gaussian exploration
noise, target policy smoothing and actor updates delayed to every `policy_delay` critic steps."""

from __future__ import annotations

from . import sac
from .config import TD3Config
from .loop import Trainer


def make_train(config: TD3Config, env) -> Trainer:
    return sac.make_train(config, env, deterministic=True)
