"""Where things stand on a field, derived from a spec in one place.

The physics checks and the scene compiler both read these shapes, so a wall the
checks reason about is exactly the wall that gets built.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from fieldgen.schema.models import FieldSpec

# Horizontal reach of each agent from its centre: ant foot spheres sit at
# (0.8, 0.8) from the torso with radius 0.08; the point agent is a disc.
AGENT_REACH = {"ant": math.hypot(0.8, 0.8) + 0.08, "point": 0.25}
POINT_RADIUS = 0.25


@dataclass(frozen=True)
class Part:
    """A named solid or decorative piece of the field."""

    name: str


@dataclass(frozen=True)
class Box(Part):
    center: tuple[float, float, float]
    half: tuple[float, float, float]
    solid: bool

    def xy_bounds(self, inflate: float = 0.0) -> tuple[float, float, float, float]:
        (cx, cy, _), (hx, hy, _) = self.center, self.half
        return (cx - hx - inflate, cx + hx + inflate, cy - hy - inflate, cy + hy + inflate)


@dataclass(frozen=True)
class Capsule(Part):
    start: tuple[float, float, float]
    end: tuple[float, float, float]
    radius: float
    solid: bool


def walls(spec: FieldSpec) -> list[Box]:
    """Wall boxes centred on the field's edges; the front wall opens at the goal mouth, and so does the back
    wall of a team field, which has a goal at each end."""
    w = spec.walls
    if not w.enabled:
        return []
    hx, hy, t, hz = spec.field.width / 2, spec.field.length / 2, w.thickness, w.height / 2
    out = []
    if w.sides:
        for side, x in (("left", -hx), ("right", hx)):
            out.append(Box(f"wall_{side}", (x, 0.0, hz), (t / 2, hy + t / 2, hz), w.solid))
    if w.back:
        out += _goal_line(spec, "back", -hy, has_goal=spec.teams is not None)
    if w.front:
        out += _goal_line(spec, "front", hy, has_goal=True)
    return out


def _goal_line(spec: FieldSpec, end: str, y: float, has_goal: bool) -> list[Box]:
    """The wall along one end of the field (y = +-length/2): open at the goal mouth where a goal stands on it."""
    w, g = spec.walls, spec.goal
    hx, hy, t, hz = spec.field.width / 2, spec.field.length / 2, w.thickness, w.height / 2
    mouth = has_goal and g.enabled and g.distance - g.depth / 2 <= hy <= g.distance + g.depth / 2
    if not mouth:
        return [Box(f"wall_{end}", (0.0, y, hz), (hx + t / 2, t / 2, hz), w.solid)]
    if g.width / 2 >= hx:
        return []
    seg = (hx + t / 2 - g.width / 2) / 2
    return [Box(f"wall_{end}_{side}", (sign * (g.width / 2 + seg), y, hz), (seg, t / 2, hz), w.solid)
            for side, sign in (("left", -1), ("right", 1))]


def goal_behind_wall(spec: FieldSpec) -> str:
    """Why a front wall stands across the whole goal line, where the goal is not on it ('' where not): a spec
    that moved its goal (goal.distance) and kept its walls as they were builds this, which validates, so it is
    said rather than refused (soccer_v2_near means it: a near goal inside a walled field)."""
    w, g, hy = spec.walls, spec.goal, spec.field.length / 2
    if not (w.enabled and w.front and g.enabled) or g.distance - g.depth / 2 <= hy <= g.distance + g.depth / 2:
        return ""
    return (f"the goal stands {g.distance:g} ahead, off the goal line at {hy:g}, so the front wall there runs the "
            "field's whole width with no mouth in it; to play into a goal on the goal line, set goal.distance: "
            f"{hy:g} (or field.length: {2 * g.distance:g}); for no wall there, walls.front: false")


def obstacles(spec: FieldSpec) -> list[Box]:
    out = []
    for name, o in spec.obstacles.items():
        oy = o.y + (spec.goal.distance if o.relative_to == "goal" else 0.0)
        out.append(Box(f"obstacle_{name}", (o.x, oy, o.height / 2), (o.width / 2, o.depth / 2, o.height / 2), o.solid))
    return out


def ball_spawn_centre(spec: FieldSpec) -> tuple[float, float]:
    """The centre of the region the ball spawns in (spawn mode 'region')."""
    spawn = spec.ball.spawn
    return (spawn.x[0] + spawn.x[1]) / 2, (spawn.y[0] + spawn.y[1]) / 2


def in_the_way(spec: FieldSpec) -> list[str]:
    """The solid obstacles on the agent's straight way from its start to where it touches the ball at its
    spawn centre, within the agent's reach of that way: the agent must walk around them before it can
    push the ball. The spec allows it; a curriculum that moves the kick-off past an obstacle says so."""
    if not spec.ball.enabled or spec.ball.spawn.mode != "region":
        return []
    reach, (ax, ay), (bx, by) = AGENT_REACH[spec.agent.kind], spec.agent.start, ball_spawn_centre(spec)
    gap = math.hypot(bx - ax, by - ay)
    stop = max(0.0, 1 - (reach + spec.ball.radius) / gap) if gap else 0.0  # where the agent's reach meets the ball
    touch = (ax + stop * (bx - ax), ay + stop * (by - ay))
    return [box.name.removeprefix("obstacle_") for box in obstacles(spec)
            if box.solid and _segment_meets((ax, ay), touch, box.xy_bounds(inflate=reach))]


def _segment_meets(a, b, rect) -> bool:
    """Whether the segment a-b meets the rectangle (x0, x1, y0, y1): Liang and Barsky's clipping."""
    x0, x1, y0, y1 = rect
    dx, dy = b[0] - a[0], b[1] - a[1]
    enter, leave = 0.0, 1.0
    for p, q in ((-dx, a[0] - x0), (dx, x1 - a[0]), (-dy, a[1] - y0), (dy, y1 - a[1])):
        if p == 0:
            if q < 0:  # parallel to this edge and outside it
                return False
        elif p < 0:
            enter = max(enter, q / p)
        else:
            leave = min(leave, q / p)
    return enter <= leave


def kickoffs(spec: FieldSpec) -> list[tuple[str, tuple[float, float]]]:
    """Each agent's name and kick-off (x, y) in the field's frame: the single agent's start, or each team
    agent's (home0, home1, away0, ...), the away side's turned half a turn from its own frame."""
    if spec.teams is None:
        return [("agent", tuple(spec.agent.start))]
    out = []
    for side in ("home", "away"):
        for i, (x, y) in enumerate(side_starts(spec, side)):
            out.append((f"{side}{i}", (x, y) if side == "home" else turn((x, y))))
    return out


def side_starts(spec: FieldSpec, side: str) -> list[tuple[float, float]]:
    """A side's kick-offs in its own frame (attacking along +y): as written, or by default side by side a
    third of the field's width apart, halfway between the centre and the side's own goal."""
    team = getattr(spec.teams, side)
    if team.start is not None:
        return [tuple(p) for p in team.start]
    n, spacing = team.agents, spec.field.width / 3
    return [((i - (n - 1) / 2) * spacing, -spec.goal.distance / 2) for i in range(n)]


def turned(spec: FieldSpec) -> FieldSpec:
    """A team field turned half a turn about the kick-off point: the home side's view of it is the away side's
    of the original. The checks judge the home side's goal as the away side's goal of the turned field."""
    data = spec.model_dump(mode="json")
    for name, o in spec.obstacles.items():
        y = o.y + (spec.goal.distance if o.relative_to == "goal" else 0.0)
        data["obstacles"][name].update(x=-o.x, y=-y, relative_to="kickoff")
    if spec.ball.spawn.mode == "region":
        data["ball"]["spawn"].update(x=[-spec.ball.spawn.x[1], -spec.ball.spawn.x[0]],
                                     y=[-spec.ball.spawn.y[1], -spec.ball.spawn.y[0]])
    data["walls"].update(front=spec.walls.back, back=spec.walls.front)
    data["teams"] = {"home": data["teams"]["away"], "away": data["teams"]["home"]}
    return FieldSpec.model_validate(data)


def turn(point: tuple) -> tuple:
    """A point (x, y[, z...]) turned half a turn about the vertical through the kick-off point (0.0, never -0.0,
    where it lies on an axis)."""
    return (0.0 - point[0], 0.0 - point[1], *point[2:])


def goal_region(spec: FieldSpec) -> Box | None:
    """The goal box: the region that counts as 'in the goal'; it never collides."""
    g = spec.goal
    if not g.enabled:
        return None
    return Box("goal_region", (0.0, g.distance, g.height / 2), (g.width / 2, g.depth / 2, g.height / 2), False)


def goal_regions(spec: FieldSpec) -> list[Box]:
    """Every goal's box: the goal at +y, and on a team field the home side's goal at -y (the away side's turned)."""
    region = goal_region(spec)
    if region is None:
        return []
    if spec.teams is None:
        return [region]
    return [Box("away_goal_region", region.center, region.half, False),
            Box("home_goal_region", turn(region.center), region.half, False)]


def goal_frame(spec: FieldSpec) -> list[Capsule]:
    """Posts at the mouth's edges and an optional crossbar on top."""
    g = spec.goal
    if not g.enabled:
        return []
    y, r, h, x = g.posts_y, g.post_radius, g.height, g.width / 2
    out = [Capsule(f"post_{side}", (s * x, y, 0.0), (s * x, y, h), r, g.solid) for side, s in (("left", -1), ("right", 1))]
    if g.crossbar:
        out.append(Capsule("crossbar", (-x, y, h), (x, y, h), r, g.solid))
    return out


def sample_target(spec: FieldSpec) -> tuple[float, float]:
    """The target of a typical episode, for the scene's home pose and previews."""
    fixed = spec.target_fixed()
    if fixed is not None:
        return fixed
    t = spec.task.target
    lo, hi = t.angle_deg
    angle = 90.0 if lo <= 90.0 <= hi else (lo + hi) / 2
    radius = sum(t.radius) / 2
    sx, sy = spec.agent.start
    return (sx + radius * math.cos(math.radians(angle)), sy + radius * math.sin(math.radians(angle)))


def reach_height(spec: FieldSpec) -> float:
    """The highest point a moving body can reach; static geoms above it are pruned.

    A free ball can be kicked upwards, so it reaches everything.
    """
    if spec.ball.enabled and spec.ball.joint == "free":
        return math.inf
    ball_top = 2 * spec.ball.radius if spec.ball.enabled else 0.0
    agent_top = ant_reach(spec) if spec.agent.kind == "ant" else 2 * POINT_RADIUS
    return max(ball_top, agent_top)


ANT_TORSO_RADIUS = 0.25
ANT_HOP_HEIGHT = 1.5  # torso centre; a hop under MJX rises past 1.0 where no height band ends it


def ant_reach(spec: FieldSpec) -> float:
    """The top of the ant's torso at the highest it can be while its episode goes on."""
    fall = spec.episode.fall
    return (fall.band[1] if fall.kind == "height_band" else ANT_HOP_HEIGHT) + ANT_TORSO_RADIUS


def inner_bounds(spec: FieldSpec) -> tuple[float, float, float, float]:
    """x/y extent a body centre may reach, inside any walls present."""
    hx, hy = spec.field.width / 2, spec.field.length / 2
    w = spec.walls
    t = w.thickness / 2 if w.enabled else 0.0
    side, back = (t if w.sides else 0.0), (t if w.back else 0.0)
    return (-hx + side, hx - side, -hy + back, hy)
