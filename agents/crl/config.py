"""CRL's settings: the replay buffer's, and the contrastive critic's energy, loss and network shape."""

from __future__ import annotations

from typing import Annotated, ClassVar, Literal

from pydantic import Field

from ...env.contract import Environment
from ..config import ConfigError, Count, Float, Int, Rate, ReplayConfig, Share, Steps, Unknown
from ..contrastive import ENERGIES, LOSSES
from ..networks import MATMULS, residual_blocks

Energy = Annotated[Literal[ENERGIES], Unknown(f"unknown energy '{{}}'; choose one of {', '.join(ENERGIES)}")]
Loss = Annotated[Literal[LOSSES], Unknown(f"unknown contrastive_loss '{{}}'; choose one of {', '.join(LOSSES)}")]
Matmul = Annotated[Literal[tuple(MATMULS)], Unknown(f"unknown matmul '{{}}'; choose one of {', '.join(MATMULS)}")]


class CRLConfig(ReplayConfig):
    algo: ClassVar[str] = "crl"

    alpha_lr: Rate = 3e-4
    repr_dim: Count = 64
    skip_every: Annotated[Int, Field(ge=0)] = 0  # residual blocks of this many hidden layers after the first (agents.networks.MLP); 0: none
    matmul: Matmul = "float32"  # bfloat16: the networks' products on bfloat16 operands, summed in float32
    energy: Energy = "norm"
    contrastive_loss: Loss = "fwd_infonce"
    logsumexp_penalty: Annotated[Float, Field(ge=0)] = 0.1
    target_entropy_per_action: Float = -0.5
    # share of the actor's goals that are the episode's commanded goal rather than a later state of it (the
    # critic learns from the later states alone): the actor then practises the goals it is asked for
    actor_commanded_goals: Share = 0.0
    # a minibatch's pairs drawn this many at a time from one episode's window (agents.buffer.minibatch_rows):
    # its negatives then include states of the same episode, told apart by what moved; 1: the reference
    pairs_per_window: Count = 1
    # a share of each iteration's minibatch updates taken until the run's env steps reach early_until, all of
    # them after: while nothing has been learned, the learner's steps cost the clock most and teach least
    early_updates: Annotated[Float, Field(gt=0, le=1)] = 1.0
    early_until: Steps = 0  # env steps (10M as --steps takes it); 0: every update from the start

    def validate_env(self, env: Environment, devices: int = 1, seeds: int = 1) -> None:
        super().validate_env(env, devices, seeds)
        if self.batch_size % self.pairs_per_window or self.pairs_per_window > env.episode_length:
            raise ConfigError(f"{self.algo}.pairs_per_window {self.pairs_per_window} must divide batch_size "
                              f"({self.batch_size}) and be at most an episode's {env.episode_length} steps")
        if self.skip_every:
            try:
                residual_blocks(self.hidden, self.skip_every)
            except ValueError as exc:
                raise ConfigError(f"{self.algo}.skip_every {self.skip_every}: {exc}; {self.algo}.skip_every=0 "
                                  f"builds plain layers") from None
