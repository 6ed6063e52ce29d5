"""TD3's settings: the off-policy trainers' (agents.config.OffPolicyConfig), its exploration and target
policy noise, and its delayed actor updates."""

from __future__ import annotations

from typing import Annotated, ClassVar

from pydantic import Field

from ..config import Count, Float, OffPolicyConfig


class TD3Config(OffPolicyConfig):
    algo: ClassVar[str] = "td3"

    exploration_noise: Annotated[Float, Field(ge=0)] = 0.1  # std of the Gaussian added to actions while collecting
    policy_noise: Annotated[Float, Field(ge=0)] = 0.2  # std of the smoothing noise on target actions
    noise_clip: Annotated[Float, Field(ge=0)] = 0.5
    policy_delay: Count = 2  # critic steps per actor step (and target update)
