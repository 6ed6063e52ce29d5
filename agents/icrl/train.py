"""Independent contrastive RL (ICRL): the body's actuators split among controllers, one per leg
or one per joint, each with its own actor, contrastive critic and entropy coefficient.

Every controller observes the torso, the ball and the goal, plus its own joints' angles and
velocities (picked by name: agents.team), and acts on its own actuators only. The controllers
are vmapped over a leading controller axis inside CRL's training step, so they cost one batched
network call rather than a loop; success is the environment's own metric, as for CRL.

The grouping is the config key `icrl.agents` (`leg` or `joint`), named as run.json files and
commands already write it; in the code its parts are controllers, so that "agent" keeps meaning
the field's one body.
"""

from __future__ import annotations

from .. import crl
from .config import ICRLConfig
from ..loop import Trainer
from ..team import split


def make_train(config: ICRLConfig, env) -> Trainer:
    return crl.make_train(config, env, split(env, config.agents), config.share_parameters)
