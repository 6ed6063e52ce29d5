"""TD3: SAC's off-policy machinery (agents.sac) with a deterministic actor, Gaussian exploration
noise, target policy smoothing and actor updates delayed to every `policy_delay` critic steps."""

from __future__ import annotations

import dataclasses

from . import sac
from .loop import Trainer


@dataclasses.dataclass(frozen=True)
class TD3Config(sac.OffPolicyConfig):
    exploration_noise: float = 0.1  # std of the Gaussian added to actions while collecting
    policy_noise: float = 0.2  # std of the smoothing noise on target actions
    noise_clip: float = 0.5
    policy_delay: int = 2


def make_train(config: TD3Config, env) -> Trainer:
    return sac.make_train(config, env, deterministic=True)
