"""Physical sense beyond types: things fit on the field, the ball can reach the goal.

Each check returns (key path, message) pairs so the loader can point at the
line that set the offending value. The goal-mouth check floods a grid of ball
centre positions, with every solid thing inflated by the ball radius.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from fieldgen.schema import geometry
from fieldgen.schema.backends import backend_problems
from fieldgen.schema.backends import BACKENDS
from fieldgen.schema.models import SIDES, FieldSpec
from fieldgen.schema.terms import MATCH_TERMS, TERMS

GRID = 0.05  # metres per cell of the reachability grid
MAX_CELLS = 2000  # cells a side at most: a 500 x 500 field is judged on 0.25 m cells


class Among(tuple):
    """Key paths whose values conflict (a goal beyond the field's end: goal.distance, field.length): the
    problem is shown at the one set in the spec a person edits rather than in a file it extends."""

    def __new__(cls, *paths: tuple):
        return super().__new__(cls, paths)


Found = list[tuple[tuple, str]]  # (key path or Among, message)
FIELD_SIZE = (("field", "length"), ("field", "width"))  # length first: most conflicts lie along it


def physics_problems(spec: FieldSpec) -> Found:
    out: Found = []
    out += _timing(spec)
    out += backend_problems(spec)
    out += _task_needs(spec) if spec.teams is None else _match(spec)
    out += _fits_on_field(spec)
    if spec.sim.contacts == "torso_floor" and spec.agent.kind != "ant":
        out.append((("sim", "contacts"), f"'torso_floor' gives an ant's torso a floor contact; a {spec.agent.kind} "
                    "agent slides at a fixed height and has no torso to give one: use pruned or study"))
    if spec.ball.enabled and not out:
        out += _ball_spawn(spec)
    if not out:
        out += _goal_reachable(spec)
    if not out and spec.teams is not None:  # the home side's goal, at -y: the away side's goal of the field turned
        out += _goal_reachable(geometry.turned(spec))
    return out


MAX_SUBSTEPS = 1000  # physics steps per control step


def _timing(spec: FieldSpec) -> Found:
    e = spec.episode
    ratio = e.control_dt / e.physics_dt
    if ratio > MAX_SUBSTEPS:
        return [(("episode", "physics_dt"), f"{ratio:,.0f} physics steps per control step (control_dt "
                 f"{e.control_dt:g} / physics_dt {e.physics_dt:g}); at most {MAX_SUBSTEPS}: raise physics_dt "
                 f"to at least {e.control_dt / MAX_SUBSTEPS:g}")]
    if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
        return [
            (
                ("episode", "control_dt"),
                f"control_dt ({e.control_dt}) must be a whole multiple of physics_dt ({e.physics_dt}); "
                f"for example {max(1, round(ratio)) * e.physics_dt:g}",
            )
        ]
    return []


def _task_needs(spec: FieldSpec) -> Found:
    out: Found = []
    kind = spec.task.success.kind
    if kind.startswith("ball") and not spec.ball.enabled:
        out.append((("task", "success", "kind"), f"'{kind}' needs a ball, but ball.enabled is false"))
    if kind == "ball_in_goal" and not spec.goal.enabled:
        out.append((("task", "success", "kind"), "'ball_in_goal' needs a goal, but goal.enabled is false"))
    if spec.task.target.kind == "goal" and not spec.goal.enabled:
        out.append((("task", "target", "kind"), "target 'goal' needs a goal, but goal.enabled is false"))
    positions, subject = spec.task.goal_positions, spec.task.success_subject
    if len(set(positions)) < len(positions):
        out.append((("task", "goal_positions"), f"names {positions[0]!r} twice; each of agent, ball at most once"))
    elif subject not in positions:
        out.append((("task", "goal_positions"), f"the success ('{kind}') judges the {subject}, so the goal must "
                    f"name it: add {subject!r}"))
    if "ball" in positions and not spec.ball.enabled:
        out.append((("task", "goal_positions"), "'ball' needs a ball, but ball.enabled is false"))
    for i, term in enumerate(spec.task.reward):
        needs, where = TERMS.get(term.term), ("task", "reward", i, "term")
        if needs is None:
            out.append((where, f"'{term.term}' is a term of a match (a field with teams); with one agent, one of "
                        f"{', '.join(TERMS)}"))
            continue
        if needs.ball and not spec.ball.enabled:
            out.append((where, f"the '{term.term}' term needs a ball, but ball.enabled is false"))
        if needs.goal and not spec.goal.enabled:
            out.append((where, f"the '{term.term}' term needs a goal, but goal.enabled is false"))
        if needs.torso and spec.agent.kind != "ant":
            out.append((where, f"the '{term.term}' term needs an agent with a torso (kind: ant)"))
    if spec.ball.spawn.mode == "toward_target" and spec.task.target.kind == "goal":
        out.append((("ball", "spawn", "mode"), "'toward_target' needs a ring or point target; use 'region' with a goal"))
    return out


def _match(spec: FieldSpec) -> Found:
    """What a field with teams needs and refuses: a match is played with a ball between two goals, won by
    goals, and ends at a goal or on time; both sides field as many agents, so that one policy plays either."""
    out: Found = []
    teams, task = spec.teams, spec.task
    why = "a match is won by goals"
    if "start" in spec.agent.model_fields_set:
        out.append((("agent", "start"), "places the single agent; a team field places its agents with "
                    "teams.home.start and teams.away.start"))
    if teams.home.agents != teams.away.agents:
        out.append((Among(("teams", "home", "agents"), ("teams", "away", "agents")),
                    f"home fields {teams.home.agents} agents and away {teams.away.agents}; both sides field as many, "
                    "so that one policy plays either side"))
    for side in SIDES:
        team = getattr(spec.teams, side)
        if team.start is not None and len(team.start) != team.agents:
            out.append((Among(("teams", side, "start"), ("teams", side, "agents")),
                        f"{len(team.start)} kick-offs for {team.agents} agent{'s' * (team.agents != 1)}; give one "
                        "(x, y) per agent, or leave start out for the default"))
    if not spec.goal.enabled:
        out.append((("goal", "enabled"), "a team field needs a goal at each end, one for each side to defend; "
                    "set goal.enabled: true"))
    if not spec.ball.enabled:
        out.append((("ball", "enabled"), "a match needs a ball; set ball.enabled: true"))
    if task.success.kind != "ball_in_goal":
        out.append((("task", "success", "kind"), f"'{task.success.kind}' judges one agent's task; {why}: a side "
                    "succeeds when the ball enters the opponent's goal (ball_in_goal, the default with teams)"))
    if task.target.kind != "goal":
        out.append((("task", "target", "kind"), f"a '{task.target.kind}' target is one agent's; each side's target "
                    "is the opponent's goal (kind: goal, the default)"))
    if "goal_positions" in task.model_fields_set:
        out.append((("task", "goal_positions"), "a match observation names no goal; leave goal_positions out"))
    if spec.episode.fall.kind != "never":
        out.append((("episode", "fall", "kind"), f"'{spec.episode.fall.kind}' ends one agent's episode; a match "
                    "ends at a goal or on time (kind: never)"))
    if BACKENDS[spec.sim.backend].brax:
        mjx = ", ".join(name for name, b in BACKENDS.items() if not b.brax)
        out.append((("sim", "backend"), f"a team field runs on MJX ({mjx}), not on brax's {spec.sim.backend} pipeline"))
    if spec.ball.spawn.mode == "toward_target":
        out.append((("ball", "spawn", "mode"), "'toward_target' follows one agent's target; a match spawns the ball "
                    "in a region (mode: region)"))
    if spec.sim.contacts == "study":
        out.append((("sim", "contacts"), "'study' is the soccer study's contact set for one ant, in which agents "
                    "never touch each other; use pruned or torso_floor"))
    for i, term in enumerate(task.reward):
        needs, where = MATCH_TERMS.get(term.term), ("task", "reward", i, "term")
        if needs is None:
            out.append((where, f"'{term.term}' is a term of one agent's task; a match's terms: "
                        f"{', '.join(MATCH_TERMS)}"))
        elif needs.torso and spec.agent.kind != "ant":
            out.append((where, f"the '{term.term}' term needs agents with a torso (kind: ant)"))
    return out


def _start_key(spec: FieldSpec, name: str) -> tuple:
    """The key that placed an agent: agent.start, or its side's start (or agents, where the start is default)."""
    if spec.teams is None:
        return ("agent", "start")
    side = name.rstrip("0123456789")
    return ("teams", side, "start" if getattr(spec.teams, side).start is not None else "agents")


def _fits_on_field(spec: FieldSpec) -> Found:
    out: Found = []
    x0, x1, y0, y1 = geometry.inner_bounds(spec)
    hx, hy = spec.field.width / 2, spec.field.length / 2
    g = spec.goal
    if g.enabled:
        if g.distance > hy:
            out.append((Among(("goal", "distance"), ("field", "length")),
                        f"the goal point (y = {g.distance:g}) lies beyond the field's end (y = {hy:g}); "
                        f"make field.length at least {2 * g.distance:g}"))
        if g.width / 2 > hx:
            out.append((Among(("goal", "width"), ("field", "width")),
                        f"the goal ({g.width:g} wide) is wider than the field ({spec.field.width:g})"))
    reach = geometry.AGENT_REACH[spec.agent.kind]
    starts = geometry.kickoffs(spec)
    for agent, (sx, sy) in starts:
        if not (x0 + reach <= sx <= x1 - reach and y0 + reach <= sy <= y1 - reach):
            out.append((Among(_start_key(spec, agent), *FIELD_SIZE),
                        f"the {agent} at ({sx:g}, {sy:g}) with reach {reach:.2f} does not fit inside the field"))
    for i, (agent, (sx, sy)) in enumerate(starts):
        for other, (ox, oy) in starts[:i]:
            if math.hypot(sx - ox, sy - oy) < 2 * reach:
                out.append((_start_key(spec, agent), f"the kick-offs of {other} at ({ox:g}, {oy:g}) and {agent} at "
                            f"({sx:g}, {sy:g}) overlap: agents of reach {reach:.2f} start at least {2 * reach:.2f} "
                            "apart (the away side's kick-offs are its own frame's turned half a turn)"))
    for box in geometry.obstacles(spec):
        name = box.name.removeprefix("obstacle_")
        bx0, bx1, by0, by1 = box.xy_bounds()
        if bx1 < -hx or bx0 > hx or by1 < -hy or by0 > hy:
            out.append((Among(("obstacles", name), *FIELD_SIZE), f"obstacle '{name}' lies entirely off the field"))
        for agent, (sx, sy) in starts:
            if _disc_hits_rect(sx, sy, reach, box.xy_bounds()):
                out.append((("obstacles", name), f"obstacle '{name}' overlaps the {agent}'s start at ({sx:g}, {sy:g})"))
    sx, sy = spec.agent.start
    t = spec.task.target
    if t.kind == "ring":
        far = t.radius[1]
        if not (x0 <= sx - far and sx + far <= x1 and y0 <= sy - far and sy + far <= y1):
            out.append((Among(("task", "target", "radius"), *FIELD_SIZE),
                        f"targets up to {far:g} from the agent's start can fall off the field"))
    if t.kind == "point" and not (x0 <= t.x <= x1 and y0 <= t.y <= y1):
        out.append((Among(("task", "target"), *FIELD_SIZE), f"the target ({t.x:g}, {t.y:g}) lies off the field"))
    return out


def _ball_spawn(spec: FieldSpec) -> Found:
    """The spawn region lies inside the field, clear of walls, obstacles, goal and agent."""
    b = spec.ball
    r, reach = b.radius, geometry.AGENT_REACH[spec.agent.kind]
    sx, sy = spec.agent.start
    where = ("ball", "spawn")
    if b.spawn.mode == "toward_target":
        s = b.spawn
        t = spec.task.target
        if t.kind == "ring":
            near = s.fraction * t.radius[0] - s.jitter * math.sqrt(2)
            if near < r + reach:
                return [(where, f"the ball can spawn {max(near, 0):.2f} from the agent's start; it needs "
                         f"{r + reach:.2f} (ball radius + agent reach): raise fraction or lower jitter")]
            return []
        cx, cy = sx + s.fraction * (t.x - sx), sy + s.fraction * (t.y - sy)
        rect = (cx - s.jitter, cx + s.jitter, cy - s.jitter, cy + s.jitter)
    else:
        rect = (b.spawn.x[0], b.spawn.x[1], b.spawn.y[0], b.spawn.y[1])
    out: Found = []
    x0, x1, y0, y1 = geometry.inner_bounds(spec)
    if rect[0] - r < x0 or rect[1] + r > x1 or rect[2] - r < y0 or rect[3] + r > y1:
        out.append((Among(where, *FIELD_SIZE), f"the ball (radius {r:g}) can spawn outside the field or inside a wall; "
                    f"centres must stay within x [{x0 + r:g}, {x1 - r:g}], y [{y0 + r:g}, {y1 - r:g}]"))
    for box in geometry.obstacles(spec):
        if _rects_overlap(rect, box.xy_bounds(inflate=r)):
            name = box.name.removeprefix("obstacle_")
            out.append((("obstacles", name), f"the ball can spawn touching obstacle '{name}'"))
    goal = geometry.goal_region(spec)
    if goal is not None and _rects_overlap(rect, goal.xy_bounds(inflate=r)):
        out.append((where, "the ball can spawn inside or touching the goal"))
    for agent, (ax, ay) in geometry.kickoffs(spec):
        gap = _rect_distance(rect, ax, ay)
        if gap < r + reach:
            out.append((where, f"the ball can spawn {gap:.2f} from the {agent}'s start; it needs {r + reach:.2f} "
                        "(ball radius + agent reach)"))
    return out


def _goal_reachable(spec: FieldSpec) -> Found:
    """Flood-fill on-field ball centres from the spawn; some centre inside the goal box must be reached.

    The grid has cells of GRID metres, coarser on a field so large that it would need more than
    MAX_CELLS a side (a gap narrower than a cell may then be judged either way); each solid thing marks
    only the cells within its reach, so the cost grows with the field's area and the things on it."""
    if not (spec.goal.enabled and spec.ball.enabled and spec.ball.spawn.mode == "region"):
        return []
    r = spec.ball.radius
    hx, hy = spec.field.width / 2, spec.field.length / 2
    goal = geometry.goal_region(spec)
    gx0, gx1, gy0, gy1 = goal.xy_bounds()
    top = max(hy, gy1)
    step = max(GRID, 2 * hx / MAX_CELLS, (top + hy) / MAX_CELLS)
    xs = np.arange(-hx, hx + step, step)
    ys = np.arange(-hy, top + step, step)

    def window(x0, x1, y0, y1):
        """Index slices of the cells whose centres lie in [x0, x1] x [y0, y1], and their coordinates."""
        i0, i1 = np.searchsorted(ys, y0), np.searchsorted(ys, y1, side="right")
        j0, j1 = np.searchsorted(xs, x0), np.searchsorted(xs, x1, side="right")
        return (slice(i0, i1), slice(j0, j1)), np.meshgrid(xs[j0:j1], ys[i0:i1], indexing="xy")

    in_goal = np.zeros((len(ys), len(xs)), bool)
    cells, _ = window(gx0, gx1, gy0, gy1)
    in_goal[cells] = True
    blocked = (ys > hy)[:, None] & ~in_goal  # the ball stays on the field, or in the goal box behind its end
    for box in geometry.walls(spec) + geometry.obstacles(spec):
        if box.solid:
            bx0, bx1, by0, by1 = box.xy_bounds()
            cells, (X, Y) = window(bx0 - r, bx1 + r, by0 - r, by1 + r)
            dx = np.maximum(np.maximum(bx0 - X, X - bx1), 0)
            dy = np.maximum(np.maximum(by0 - Y, Y - by1), 0)
            blocked[cells] |= dx * dx + dy * dy < r * r
    for cap in geometry.goal_frame(spec):
        if cap.solid and cap.start[2] == 0.0:  # posts stand on the floor; the crossbar is above the ball
            reach = r + cap.radius
            cx, cy = cap.start[0], cap.start[1]
            cells, (X, Y) = window(cx - reach, cx + reach, cy - reach, cy + reach)
            blocked[cells] |= (X - cx) ** 2 + (Y - cy) ** 2 < reach ** 2
    labels, _ = ndimage.label(~blocked)
    sx = (spec.ball.spawn.x[0] + spec.ball.spawn.x[1]) / 2
    sy = (spec.ball.spawn.y[0] + spec.ball.spawn.y[1]) / 2
    start = labels[np.argmin(np.abs(ys - sy)), np.argmin(np.abs(xs - sx))]
    if start == 0 or not np.any(labels[in_goal] == start):
        return [(("obstacles",) if spec.obstacles else ("goal",),
                 "the ball cannot reach the goal from its spawn: walls, obstacles or posts seal the goal mouth "
                 f"for a ball of radius {r:g}")]
    return []


def _rects_overlap(a, b) -> bool:
    return a[0] < b[1] and b[0] < a[1] and a[2] < b[3] and b[2] < a[3]


def _rect_distance(rect, x, y) -> float:
    dx = max(rect[0] - x, 0.0, x - rect[1])
    dy = max(rect[2] - y, 0.0, y - rect[3])
    return math.hypot(dx, dy)


def _disc_hits_rect(x, y, radius, rect) -> bool:
    return _rect_distance(rect, x, y) < radius
