"""Independent contrastive RL (ICRL): the body's actuators split among agents, one per leg
or one per joint, each with its own actor, contrastive critic and entropy coefficient.

Every agent observes the torso, the ball and the goal, plus its own joints' angles and
velocities (picked by name: agents.team), and acts on its own actuators only. The agents
are vmapped over a leading agent axis inside CRL's training step, so they cost one batched
network call rather than a loop; success is the environment's own metric, as for CRL.
"""

from __future__ import annotations

from . import crl
from .config import ICRLConfig
from .loop import Trainer
from .team import split


def make_train(config: ICRLConfig, env) -> Trainer:
    return crl.make_train(config, env, split(env, config.agents), config.share_parameters)
