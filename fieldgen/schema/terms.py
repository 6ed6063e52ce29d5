"""The reward terms a spec's `task.reward` may name, each with what the field must have for it.

This table is the one place a term is named: the schema's choices for `term`, the checks of what a
term needs and fieldgen/env/task.py's implementations (which refuse to import unless they cover
exactly these names) all read it. It imports nothing, so the schema reads it without JAX.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Term:
    description: str  # one line, as the DSL reference's "Reward terms" table gives it
    ball: bool = False  # needs a ball (ball.enabled)
    goal: bool = False  # needs a goal (goal.enabled)
    torso: bool = False  # needs an agent with a torso (agent.kind: ant)
    sparse: bool = False  # 1 only while a state holds: alone, it gives a learner nothing to follow until it succeeds


TERMS: dict[str, Term] = {
    "success": Term("1 while the success predicate holds (the sparse reward)", sparse=True),
    "ball_progress": Term("decrease of the ball's distance to the target, per second", ball=True),
    "scaled_ball_progress": Term("ball_progress / max(distance, 0.1)", ball=True),
    "ball_path_progress": Term("decrease of the ball's distance to the target along its shortest way around the "
                               "field's solid obstacles, per second (ball_progress where none stands between)",
                               ball=True),
    "scaled_ball_path_progress": Term("ball_path_progress / max(the ball's way to the target, 0.1)", ball=True),
    "agent_approaches_ball": Term("decrease of the agent's distance to the ball, per second", ball=True),
    "agent_behind_ball": Term("decrease of the agent's distance to the point behind the ball from which a push "
                              "sends it along its shortest way to the target (round the solid obstacles), one "
                              "ball radius plus the agent's body radius from the ball's centre, per second",
                              ball=True),
    "agent_progress": Term("decrease of the agent's distance to the target, per second"),
    "upright": Term("1 while the torso height is inside band (default [0.2, 1.0])", torso=True),
    "control_cost": Term("-sum(action^2): give it a positive weight"),
    "ball_in_goal": Term("1 while the ball's centre is inside the goal box", ball=True, goal=True, sparse=True),
}

# `task: {reward: dense}`: the terms generated for a task, by what its success judges (task.success.kind), as the
# bundled _dense fields use them: for the ball, the ball's progress to the target, the agent's approach to the
# point behind the ball from which a push sends it on its way (agent_behind_ball: drawn to the ball itself, seeds
# pinned the ball against an obstacle's face or pushed it from the side), a bonus while the success holds; for the
# agent, its own progress; for both, staying upright (only for an agent with a torso) and a control cost. Where a
# solid obstacle stands, the ball's progress is measured along its way round them (AROUND_OBSTACLES): straight
# progress pays a push into a goalie in the ball's way as well as one past it, and PPO's ant learned to push the
# ball into v2_wide_goalie's goalie and stop there.
DENSE_REWARDS: dict[str, tuple[dict, ...]] = {
    "ball_near_target": ({"term": "ball_progress", "weight": 10.0}, {"term": "agent_behind_ball", "weight": 1.0},
                         {"term": "success", "weight": 10.0}, {"term": "upright", "band": (0.2, 1.0)},
                         {"term": "control_cost", "weight": 0.5}),
    "agent_near_target": ({"term": "agent_progress"}, {"term": "upright", "band": (0.2, 1.0)},
                          {"term": "control_cost", "weight": 0.5}),
}
AROUND_OBSTACLES = {"ball_progress": "ball_path_progress"}  # the generated term -> its stand-in where obstacles stand


@dataclass(frozen=True)
class MatchTerm:
    description: str  # one line, as the DSL reference's "Match reward terms" table gives it
    zero_sum: bool = False  # one side's value is the other's negated: the sides' rewards of it sum to zero
    per_agent: bool = False  # the single-agent term of the same name (TERMS), averaged over the side's agents
    torso: bool = False  # needs agents with a torso (agent.kind: ant)
    sparse: bool = False  # nonzero only when a goal is scored: nothing to follow before the first


# The terms `task.reward` may name on a field with `teams`: each side's reward is sum(weight * term), the term
# read from that side's view. They need a ball and a goal at each end, which every team field has.
MATCH_TERMS: dict[str, MatchTerm] = {
    "goal": MatchTerm("+1 on the step the side scores, -1 on the step it concedes", zero_sum=True, sparse=True),
    "ball_progress": MatchTerm("the ball's speed towards the opponent's goal line, along the field (m/s)",
                               zero_sum=True),
    "ball_goal_progress": MatchTerm("the decrease of the ball's distance to the goal point the side attacks, less "
                                    "that to the goal point it defends, halved (m/s): ball_progress on the centre "
                                    "line, and towards the goal's mouth from beside it", zero_sum=True),
    "agent_approaches_ball": MatchTerm("agent_approaches_ball of each of the side's agents, averaged", per_agent=True),
    "agent_behind_ball": MatchTerm("agent_behind_ball of each of the side's agents towards the goal it attacks, averaged",
                                   per_agent=True),
    "upright": MatchTerm("upright of each of the side's agents, averaged", per_agent=True, torso=True),
    "control_cost": MatchTerm("control_cost of each of the side's agents, averaged", per_agent=True),
}
assert all(name in TERMS for name, t in MATCH_TERMS.items() if t.per_agent)


def dense_reward(success_kind: str, torso: bool, obstacles: bool = False) -> list[dict]:
    """The reward terms `reward: dense` stands for on a task of this success kind, for an agent with or
    without a torso (the terms that need one are left out), on a field with or without solid obstacles."""
    terms = [dict(t) for t in DENSE_REWARDS[success_kind] if torso or not TERMS[t["term"]].torso]
    if obstacles:
        for t in terms:
            t["term"] = AROUND_OBSTACLES.get(t["term"], t["term"])
    return terms

