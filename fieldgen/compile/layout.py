"""The observation layout: named slices of the observation vector, found by joint name.

obs = [agent qpos, agent qvel, ball position, (ball velocity), goal]. The first
part is the state (state_dim); the goal names an x, y for each of the spec's
`task.goal_positions` (the ball's for ball tasks, the agent's otherwise, or both),
each the target, and `goal_indices` says which state entries it is compared with.
`success_goal_entries` are the goal's entries that the success predicate reads.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from fieldgen.schema.models import FieldSpec

AGENT_JOINTS = {
    "ant": ("root",) + tuple(f"{leg}_{j}" for leg in ("front_left", "front_right", "back_left", "back_right")
                             for j in ("hip", "ankle")),
    "point": ("agent_x", "agent_y"),
}


@dataclass(frozen=True)
class Layout:
    slices: dict[str, tuple[int, int]]  # name -> [start, stop) in the observation
    agent_qpos: np.ndarray  # qpos addresses read into the observation
    agent_qvel: np.ndarray
    ball_qpos: np.ndarray  # x, y (planar) or x, y, z (free); empty without a ball
    ball_qvel: np.ndarray  # empty unless observation.ball_velocity
    state_dim: int
    goal_indices: tuple[int, ...]
    success_goal_entries: tuple[int, int]  # the goal's x, y of what the success judges
    names: tuple[str, ...]  # one per observation entry: "<joint>.<coordinate>", "ball.x", "goal.y"...

    @property
    def size(self) -> int:
        return self.state_dim + len(self.goal_indices)

    def to_json(self) -> dict:
        return {
            "slices": {k: list(v) for k, v in self.slices.items()},
            "state_dim": self.state_dim,
            "goal_indices": list(self.goal_indices),
            "size": self.size,
        }


COORDINATES = {  # joint type -> names of its qpos and qvel entries
    mujoco.mjtJoint.mjJNT_FREE: (("x", "y", "z", "qw", "qx", "qy", "qz"), ("vx", "vy", "vz", "wx", "wy", "wz")),
    mujoco.mjtJoint.mjJNT_BALL: (("qw", "qx", "qy", "qz"), ("wx", "wy", "wz")),
}


def _addresses(model: mujoco.MjModel, joints: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, list, list]:
    """qpos and qvel addresses of the joints, and a name for each ("front_left_hip.pos", "root.vx")."""
    qpos, qvel, qpos_names, qvel_names = [], [], [], []
    for name in joints:
        j = model.joint(name)
        pos, vel = COORDINATES.get(int(j.type[0]), (("pos",), ("vel",)))
        qpos += range(int(j.qposadr[0]), int(j.qposadr[0]) + len(pos))
        qvel += range(int(j.dofadr[0]), int(j.dofadr[0]) + len(vel))
        qpos_names += [f"{name}.{c}" for c in pos]
        qvel_names += [f"{name}.{c}" for c in vel]
    return np.array(qpos, dtype=np.int32), np.array(qvel, dtype=np.int32), qpos_names, qvel_names


def observation_layout(spec: FieldSpec, model: mujoco.MjModel) -> Layout:
    agent_qpos, agent_qvel, qpos_names, qvel_names = _addresses(model, AGENT_JOINTS[spec.agent.kind])
    names = qpos_names + qvel_names
    empty = np.zeros(0, dtype=np.int32)
    ball_qpos = ball_qvel = empty
    if spec.ball.enabled:
        joints = ("ball",) if spec.ball.joint == "free" else ("ball_x", "ball_y")
        qpos, qvel, _, _ = _addresses(model, joints)
        ball_qpos = qpos[:3] if spec.ball.joint == "free" else qpos
        names += ["ball.x", "ball.y", "ball.z"][:len(ball_qpos)]
        if spec.observation.ball_velocity:
            ball_qvel = qvel[:3] if spec.ball.joint == "free" else qvel
            names += ["ball.vx", "ball.vy", "ball.vz"][:len(ball_qvel)]
    parts = [("agent_qpos", len(agent_qpos)), ("agent_qvel", len(agent_qvel))]
    if spec.ball.enabled:
        parts.append(("ball_pos", len(ball_qpos)))
        if len(ball_qvel):
            parts.append(("ball_vel", len(ball_qvel)))
    slices, at = {}, 0
    for name, n in parts:
        slices[name] = (at, at + n)
        at += n
    state_dim = at
    positions = spec.task.goal_positions
    slices["goal"] = (at, at + 2 * len(positions))
    starts = {"agent": slices["agent_qpos"][0]}  # torso or point x, y come first in the agent's qpos
    if spec.ball.enabled:
        starts["ball"] = slices["ball_pos"][0]
    goal_indices = tuple(i for p in positions for i in (starts[p], starts[p] + 1))
    judged = 2 * positions.index(spec.task.success_subject)
    goal_names = ["goal.x", "goal.y"] if len(positions) == 1 else [f"goal.{p}.{c}" for p in positions for c in "xy"]
    return Layout(slices, agent_qpos, agent_qvel, ball_qpos, ball_qvel, state_dim, goal_indices,
                  (judged, judged + 1), (*names, *goal_names))


OTHER_ENTRIES = ("x", "y", "vx", "vy")  # what an agent observes of each other agent: its planar position and velocity


@dataclass(frozen=True)
class TeamLayout:
    """A team field's agents and what each observes, the same for every agent, in its side's own frame:
    its own joints, the ball, then each teammate's and each opponent's OTHER_ENTRIES."""

    agents: tuple[str, ...]  # home0, home1, away0, away1: the order of observations and actions
    sides: tuple[int, ...]  # each agent's side: 0 home, 1 away
    agent_qpos: np.ndarray  # [agent, entry] qpos addresses of each agent's own joints
    agent_qvel: np.ndarray
    ball_qpos: np.ndarray
    ball_qvel: np.ndarray  # empty unless observation.ball_velocity
    actuators: np.ndarray  # [agent, entry] each agent's actuators, in the same order for every agent
    slices: dict[str, tuple[int, int]]
    names: tuple[str, ...]  # one per entry of an agent's observation
    action_names: tuple[str, ...]  # one per entry of an agent's action: its joints' names without the prefix

    @property
    def size(self) -> int:
        return len(self.names)

    def to_json(self) -> dict:
        return {"agents": list(self.agents), "slices": {k: list(v) for k, v in self.slices.items()},
                "size": self.size, "names": list(self.names)}


def team_layout(spec: FieldSpec, model: mujoco.MjModel) -> TeamLayout:
    from fieldgen.schema.geometry import kickoffs

    agents = tuple(name for name, _ in kickoffs(spec))
    per_agent = [_addresses(model, tuple(f"{a}_{j}" for j in AGENT_JOINTS[spec.agent.kind])) for a in agents]
    _, _, qpos_names, qvel_names = per_agent[0]
    own = [n.removeprefix(f"{agents[0]}_") for n in qpos_names + qvel_names]
    joints = ("ball",) if spec.ball.joint == "free" else ("ball_x", "ball_y")
    ball_qpos, ball_qvel, _, _ = _addresses(model, joints)
    ball_qpos = ball_qpos[:3] if spec.ball.joint == "free" else ball_qpos
    ball_qvel = (ball_qvel[:3] if spec.ball.joint == "free" else ball_qvel) if spec.observation.ball_velocity else \
        np.zeros(0, dtype=np.int32)
    n = len(agents) // 2
    parts = [("agent_qpos", len(per_agent[0][0])), ("agent_qvel", len(per_agent[0][1])), ("ball_pos", len(ball_qpos))]
    names = own + ["ball.x", "ball.y", "ball.z"][:len(ball_qpos)]
    if len(ball_qvel):
        parts.append(("ball_vel", len(ball_qvel)))
        names += ["ball.vx", "ball.vy", "ball.vz"][:len(ball_qvel)]
    parts += [("teammates", len(OTHER_ENTRIES) * (n - 1)), ("opponents", len(OTHER_ENTRIES) * n)]
    names += [f"{who}{i}.{c}" for who, count in (("teammate", n - 1), ("opponent", n)) for i in range(count)
              for c in OTHER_ENTRIES]
    slices, at = {}, 0
    for name, size in parts:
        slices[name] = (at, at + size)
        at += size
    actuator_names = [model.actuator(i).name for i in range(model.nu)]
    actuators = np.array([[i for i, a in enumerate(actuator_names) if a.startswith(f"{agent}_")] for agent in agents],
                         dtype=np.int32)
    return TeamLayout(agents, tuple(0 if a.startswith("home") else 1 for a in agents),
                      np.stack([p[0] for p in per_agent]), np.stack([p[1] for p in per_agent]), ball_qpos, ball_qvel,
                      actuators, slices, tuple(names),
                      tuple(actuator_names[i].removeprefix(f"{agents[0]}_") for i in actuators[0]))
