"""ICRL's settings: CRL's, and how the body's actuators are split among controllers."""

from __future__ import annotations

from typing import Annotated, ClassVar, Literal

from pydantic import StrictBool

from ...env.contract import Environment
from ..config import ConfigError, Unknown
from ..crl.config import CRLConfig
from ..team import GROUPINGS, split

Grouping = Annotated[Literal[GROUPINGS], Unknown(
    f"icrl.agents: unknown grouping '{{}}'; choose one of {', '.join(GROUPINGS)}")]


class ICRLConfig(CRLConfig):
    algo: ClassVar[str] = "icrl"

    # leg: one agent per leg (the study's code); joint: one per actuated joint (its text)
    agents: Grouping = "leg"
    share_parameters: StrictBool = False  # one actor and one critic applied by every agent

    def validate_env(self, env: Environment, devices: int = 1, seeds: int = 1) -> None:
        super().validate_env(env, devices, seeds)
        try:
            split(env, self.agents)
        except ValueError as exc:
            raise ConfigError(f"icrl.agents: {exc}") from None
