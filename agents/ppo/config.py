"""PPO's settings: its rollouts' minibatches and epochs, GAE, the clipped surrogate and the policy's spread."""

from __future__ import annotations

import math
from typing import Annotated, ClassVar, Literal

from pydantic import Field, StrictBool

from ..config import (COMMAND_LINE, ConfigError, Count, Discount, Float, Hidden, Rate, Reward, RunConfig, Share,
                      Unknown, Wording)

SPREADS = ("global", "state")
Spread = Annotated[Literal[SPREADS], Unknown(
    "unknown ppo.spread '{}'; choose global (one learned log-std per action) "
    "or state (the policy network's own spread for each state)")]

LEARNING_RATE_SCHEDULES = ("constant", "linear")
LearningRateSchedule = Annotated[Literal[LEARNING_RATE_SCHEDULES], Unknown(
    "unknown ppo.learning_rate_schedule '{}'; choose constant (every update at learning_rate) "
    "or linear (from learning_rate down to zero at the run's last update)")]

GRAD_CLIPS = ("together", "apart")
GradClip = Annotated[Literal[GRAD_CLIPS], Unknown(
    "unknown ppo.grad_clip '{}'; choose together (one norm over the policy's and the value's gradients) "
    "or apart (each network's own)")]


class PPOConfig(RunConfig):
    algo: ClassVar[str] = "ppo"

    total_steps: Count = 50_000_000
    num_envs: Count = 2048
    unroll_length: Count = 20
    num_minibatches: Count = 32
    update_epochs: Count = 4
    learning_rate: Rate = 3e-4
    # linear: each update's rate falls from learning_rate to zero at the run's last one, so that late updates
    # refine what the policy does rather than move it on as far as early ones (total_steps fixes the end)
    learning_rate_schedule: LearningRateSchedule = "constant"
    discount: Discount = 0.97
    gae_lambda: Share = 0.95
    clip: Rate = 0.3
    entropy_coef: Annotated[Float, Field(ge=0)] = 1e-2
    value_coef: Rate = 0.5
    max_grad_norm: Rate = 1.0
    # together: one norm over the policy's and the value's gradients, whose value part (a regression on returns
    # of hundreds) sets how far both move; apart: each network's gradients clipped to max_grad_norm on its own
    grad_clip: GradClip = "together"
    hidden: Hidden = (256, 256)
    # the variance scale of the policy's output layer's first weights (its hidden layers': 1): small, so that
    # the first actions sit mid-range rather than on the bounds tanh squashes them to
    policy_out_scale: Annotated[Float, Field(gt=0)] = 1e-2
    # state: the policy network's softplus head (brax's); global: one learned log-std per action
    spread: Spread = "state"
    reward: Reward = "dense"  # dense: the field's weighted terms; sparse: its success metric
    normalize_observations: StrictBool = True

    @classmethod
    def read_elsewhere(cls, key: str) -> str | None:
        from ..selfplay import SelfPlayConfig

        if key in SelfPlayConfig.model_fields:
            return "self-play, which trains team fields (soccer_1v1, soccer_2v2)"
        return None

    @property
    def iterations_per_eval(self) -> int:
        """The whole iterations between two evaluations, which the trainer scans; a remainder is not run."""
        return self.total_steps // self.per_iteration // self.num_evals

    def steps_at(self, index: int) -> int:
        return self.iterations_per_eval * index * self.per_iteration

    @property
    def updates(self) -> int:
        """Gradient steps over the whole run: its iterations, each of update_epochs passes over num_minibatches
        minibatches."""
        return self.iterations_per_eval * self.num_evals * self.update_epochs * self.num_minibatches

    def validate_budget(self, words: Wording = COMMAND_LINE) -> None:
        """Also: iterations that split into whole minibatches, one at least before each evaluation."""
        super().validate_budget(words)
        per_iter = self.per_iteration
        if per_iter % self.num_minibatches:
            fits = max(d for d in range(1, self.num_minibatches) if per_iter % d == 0)
            step = self.num_minibatches // math.gcd(self.unroll_length, self.num_minibatches)
            raise ConfigError(f"num_envs x unroll_length = {per_iter:,} does not divide into {self.num_minibatches} "
                              f"minibatches; change num_envs, unroll_length or num_minibatches: "
                              f"{words.setting.format('ppo.num_minibatches', fits)}, or "
                              f"{words.envs.format(f'a multiple of {step}')}")
        need = self.num_evals * per_iter
        if self.total_steps < need:
            step = self.num_minibatches  # envs that keep a minibatch whole at any unroll
            envs = self.total_steps // (self.num_evals * self.unroll_length) // step * step
            raise ConfigError(f"{self.too_few(words)}: {self.num_evals} evaluations of "
                              f"{per_iter:,}-step iterations need at least {need:,}"
                              + self.instead(envs, self.total_steps // per_iter, words))
