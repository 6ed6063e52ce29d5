"""SAC's settings: the off-policy trainers' (agents.config.OffPolicyConfig) and its entropy coefficient's."""

from __future__ import annotations

from typing import ClassVar

from ..config import Float, OffPolicyConfig, Rate


class SACConfig(OffPolicyConfig):
    algo: ClassVar[str] = "sac"

    alpha_lr: Rate = 3e-4
    target_entropy_per_action: Float = -1.0
