"""The bodies a field's agent can have, built in code with dm_control.mjcf: the ant quadruped and a
planar point.

Each builder adds the agent's body to a scene and returns its home qpos, which the
scene records as the `home` keyframe that every reset starts from.
"""

from __future__ import annotations

from dataclasses import dataclass

from dm_control import mjcf

from fieldgen.cameras import FOLLOW
from fieldgen.compile.contacts import bits
from fieldgen.schema.geometry import POINT_RADIUS
from fieldgen.schema.models import FieldSpec

AGENT_RGBA = (0.8, 0.475, 0.655, 1.0)  # Okabe and Ito's reddish purple (see fieldgen.compile.scene)
# a team field's sides: the home side in the single agent's colour, the away side in Okabe and Ito's bluish green
SIDE_RGBA = {"home": AGENT_RGBA, "away": (0.0, 0.62, 0.451, 1.0)}
# Behind the agent, pitched down 20 degrees: looking along the field, the goal's posts stand upright
# instead of leaning outward as they do under a steeper, wider view.
FOLLOW_CAMERA = dict(name=FOLLOW, mode="trackcom", pos=(0, -8, 3.2), xyaxes=(1, 0, 0, 0, 0.342, 0.94), fovy=40)


# The ant's legs: (name, hip direction in the xy plane, ankle axis, ankle range, home ankle angle).
_LEGS = (
    ("front_left", (1, 1), (-1, 1, 0), (30, 70), 1.0),
    ("front_right", (-1, 1), (1, 1, 0), (-70, -30), -1.0),
    ("back_left", (-1, -1), (-1, 1, 0), (-70, -30), -1.0),
    ("back_right", (1, -1), (1, 1, 0), (30, 70), 1.0),
)
# Actuator order of the study's ant (and brax's): back_right, front_left, front_right, back_left.
_MOTOR_ORDER = (3, 0, 1, 2)


@dataclass(frozen=True)
class Placement:
    """One agent of a scene: what prefixes its names, where it starts, which way it faces, its colour and
    whether the follow camera rides on it. The default is the single agent: unprefixed, at agent.start,
    facing +y; a team field places each of its agents (home0_, away0_...), the away side turned to face -y."""

    prefix: str = ""
    start: tuple[float, float] | None = None  # None: the spec's agent.start
    turned: bool = False  # faces -y, the way the away side attacks
    rgba: tuple[float, float, float, float] = AGENT_RGBA
    camera: bool = True


def build_ant(root: mjcf.RootElement, spec: FieldSpec, at: Placement = Placement()) -> tuple[float, ...]:
    """The standard ant: sphere torso r 0.25, capsule legs r 0.08, 8 motors."""
    gear = spec.agent.gear or 150.0
    p = at.prefix
    sx, sy = spec.agent.start if at.start is None else at.start
    facing = {"quat": TURNED_QUAT} if at.turned else {}
    torso = root.worldbody.add("body", name=f"{p}torso", pos=(sx, sy, 0.75), **facing)
    torso.add("freejoint", name=f"{p}root")
    ct, ca = bits("torso", spec)
    torso.add("geom", name=f"{p}torso", type="sphere", size=(0.25,), contype=ct, conaffinity=ca, rgba=at.rgba)
    if at.camera:
        torso.add("camera", **FOLLOW_CAMERA)
    foot_ct, foot_ca = bits("foot", spec)
    home = [sx, sy, 0.55, *(TURNED_QUAT if at.turned else (1.0, 0.0, 0.0, 0.0))]
    for name, (dx, dy), ankle_axis, ankle_range, ankle_home in _LEGS:
        d1, d2 = (0.2 * dx, 0.2 * dy, 0.0), (0.4 * dx, 0.4 * dy, 0.0)
        leg = torso.add("body", name=f"{p}{name}_leg")
        leg.add("geom", name=f"{p}{name}_aux", type="capsule", fromto=(0, 0, 0) + d1, size=(0.08,), **_inert(at))
        thigh = leg.add("body", name=f"{p}{name}_thigh", pos=d1)
        thigh.add("joint", name=f"{p}{name}_hip", type="hinge", axis=(0, 0, 1), range=(-30, 30), **_joint())
        thigh.add("geom", name=f"{p}{name}_thigh", type="capsule", fromto=(0, 0, 0) + d1, size=(0.08,), **_inert(at))
        shin = thigh.add("body", name=f"{p}{name}_shin", pos=d1)
        shin.add("joint", name=f"{p}{name}_ankle", type="hinge", axis=ankle_axis, range=ankle_range, **_joint())
        shin.add("geom", name=f"{p}{name}_shin", type="capsule", fromto=(0, 0, 0) + d2, size=(0.08,), **_inert(at))
        shin.add("geom", name=f"{p}{name}_foot", type="sphere", size=(0.08,), pos=d2, mass=0,
                 contype=foot_ct, conaffinity=foot_ca, rgba=at.rgba)
        home += [0.0, ankle_home]
    for i in _MOTOR_ORDER:
        leg = _LEGS[i][0]
        for joint in ("hip", "ankle"):
            root.actuator.add("motor", name=f"{p}{leg}_{joint}", joint=f"{p}{leg}_{joint}", gear=(gear,),
                              ctrllimited=True, ctrlrange=(-1, 1))
    return tuple(home)


TURNED_QUAT = (0.0, 0.0, 0.0, 1.0)  # (w, x, y, z): half a turn about z, facing -y


def build_point(root: mjcf.RootElement, spec: FieldSpec, at: Placement = Placement()) -> tuple[float, ...]:
    """A 1 kg sphere on x/y slides with two motors: fast to simulate, easy to learn. Its slides keep the
    field's axes whichever way it faces (a sphere has no front): the away side's environment turns its view."""
    gear = spec.agent.gear or 10.0
    p = at.prefix
    body = root.worldbody.add("body", name=f"{p}agent", pos=(0, 0, POINT_RADIUS))
    for axis, vec in (("x", (1, 0, 0)), ("y", (0, 1, 0))):
        body.add("joint", name=f"{p}agent_{axis}", type="slide", axis=vec, limited=False, damping=5.0, armature=0.0)
    ct, ca = bits("torso", spec)
    body.add("geom", name=f"{p}agent", type="sphere", size=(POINT_RADIUS,), mass=1.0, contype=ct, conaffinity=ca,
             rgba=at.rgba)
    if at.camera:
        body.add("camera", **FOLLOW_CAMERA)
    for axis in ("x", "y"):
        root.actuator.add("motor", name=f"{p}agent_{axis}", joint=f"{p}agent_{axis}", gear=(gear,),
                          ctrllimited=True, ctrlrange=(-1, 1))
    return tuple(spec.agent.start if at.start is None else at.start)


BUILDERS = {"ant": build_ant, "point": build_point}


def _inert(at: Placement) -> dict:
    return {"contype": 0, "conaffinity": 0, "rgba": at.rgba}


def _joint() -> dict:
    return {"armature": 1.0, "damping": 1.0, "limited": True}
