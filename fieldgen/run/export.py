"""A run's policy taken out of its run folder: one seed's actor, at the last checkpoint, written as an
exported policy folder (fieldgen.policy_folder) that `fieldgen.load_policy` calls without fieldgen's trainers."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import jax

from fieldgen.agents import loop
from fieldgen.agents.actor import Policy
from fieldgen.files import WriteError, way_on
from fieldgen.policy_folder import Description, describe, save_policy
from fieldgen.run import record, selfplay, session
from fieldgen.suggest import shell


@dataclasses.dataclass(frozen=True)
class Exported:
    folder: Path
    description: Description


def export(run_dir: Path, out: Path, seed: int | None = None, fmt: str = "flax") -> Exported:
    """Write the policy of `seed` (the run's first by default) to `out`, replacing what was there; with `fmt`
    "onnx" also as policy.onnx (fieldgen.policy_folder.save_policy). A self-play run's policy is one agent's:
    it reads that agent's observation in its own side's frame and drives that agent, on either side."""
    if selfplay.is_team_run(run_dir):
        run = selfplay.open_run(run_dir)
        seed, policy, state = team_policy(run, seed)
        algo = run.config.algo
    else:
        run = session.open_run(run_dir, learned=True)
        seed, policy, state = learned_policy(run, seed)
        algo = run.algo
    env = run.env
    description = describe(policy, env.observation_names, env.action_names, algorithm=algo, field=env.spec.name,
                           seed=seed, env_steps=int(jax.device_get(state.env_steps)))
    try:
        save_policy(policy, description, out, fmt)
    except WriteError as exc:
        raise record.RunError(f"{exc}; {way_on(out.parent, '-o', exc, said=True)}") from None
    return Exported(out, description)


def _seed_state(run, seed: int | None) -> tuple[int, object]:
    """(seed, its training state) of a run with a checkpoint, `seed` the run's first by default."""
    if run.state is None:
        raise record.RunError(f"{run.folder} has not trained yet, so it has no policy; start it with: "
                              f"fieldgen train --resume {shell(run.folder)}")
    seed = run.seeds[0] if seed is None else seed
    if seed not in run.seeds:
        raise record.RunError(f"{run.folder} trained seeds {', '.join(map(str, run.seeds))}, not {seed}; "
                              "pick one of them with --seed")
    return seed, loop.seed_slice(run.state, run.seeds.index(seed))


def team_policy(run: selfplay.TeamRun, seed: int | None = None) -> tuple[int, Policy, object]:
    """(seed, the learner as one agent's policy, its training state) of a self-play run: the one network every
    agent of both sides acts with, on the observation of the agent it drives."""
    seed, state = _seed_state(run, seed)
    return seed, run.algorithm.export(state), state


def learned_policy(run: session.Run, seed: int | None = None) -> tuple[int, Policy, object]:
    """(seed, its policy, its training state) of a run opened with what it learned (session.open_run(...,
    learned=True)), `seed` the run's first by default: what an export writes and `fieldgen view` plays."""
    seed, state = _seed_state(run, seed)
    return seed, run.judged_trainer.export(state), state
