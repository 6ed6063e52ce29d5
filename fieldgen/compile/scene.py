"""FieldSpec -> dm_control.mjcf scene: floor, cameras, agent, ball, goal, walls, obstacles.

The scene is built entirely in code; geometry comes from fieldgen.schema.geometry
so the physics checks and the built scene agree. Names are stable and simple
(`ball`, `wall_left`, `obstacle_goalie`, ...) because the environment and the
build report look geoms and joints up by name.
"""

from __future__ import annotations

import math

from dm_control import mjcf

from fieldgen.compile.bodies import BUILDERS, SIDE_RGBA, Placement
from fieldgen.cameras import TOP
from fieldgen.compile.contacts import ball_touches_floor, bits, contact_limit
from fieldgen.compile.pipelines import brax_parameters
from fieldgen.render import MARKINGS, SIDE_VIEW
from fieldgen.schema import geometry
from fieldgen.schema.models import FieldSpec

TOP_HEIGHT_PX = 480  # the top view's frame height; its width follows the field's aspect
TOP_MARGIN = 0.05  # of the framed extent's longer side, on every side of the top view
ORTHOGRAPHIC_MAX_M = 170.0  # the tallest view the top camera frames orthographically (mujoco: fovy below 180)
TOP_FOVY_DEG = 45.0  # the top camera's angle of view where a field is framed in perspective
# Okabe and Ito's colour-blind-safe palette on a neutral floor: the target (vermillion), goal (blue),
# ball (yellow), agent (reddish purple, in fieldgen.compile.bodies), obstacles such as a goalie (sky blue)
# and walls (black) differ in hue and lightness alike, and from the white lines the walls stand on.
RGBA = {
    "wall": (0.0, 0.0, 0.0, 1.0),
    "obstacle": (0.337, 0.706, 0.914, 1.0),
    "post": (0.95, 0.95, 0.95, 1.0),
    "net": (0.95, 0.95, 0.95, 0.25),
    "goal_region": (0.0, 0.447, 0.698, 0.2),
    "goal_area": (0.0, 0.447, 0.698, 1.0),
    "ball": (0.941, 0.894, 0.259, 1.0),
    "target": (0.835, 0.369, 0.0, 1.0),
    "line": (1.0, 1.0, 1.0, 1.0),
}
FLOOR_RGB = ((0.36, 0.36, 0.36), (0.39, 0.39, 0.39))
DECORATIVE_ALPHA = 0.45
GRAVITY = 9.81


def build_scene(spec: FieldSpec, statics: list[dict] | None = None) -> mjcf.RootElement:
    """The scene of `spec`; `statics` (default: `fixtures(spec)`) are its goal, walls and obstacles."""
    root = mjcf.RootElement(model=spec.name)
    _options(root, spec)
    _floor(root, spec)
    _top_camera(root, spec)
    agent_home = _agents(root, spec)
    ball_home = _ball(root, spec) if spec.ball.enabled else ()
    if spec.teams is None:  # a match's targets are the goals
        _target_marker(root, spec)
    for attrs in fixtures(spec) if statics is None else statics:
        root.worldbody.add("geom", **attrs)
    root.keyframe.add("key", name="home", qpos=agent_home + ball_home)
    return root


def _agents(root: mjcf.RootElement, spec: FieldSpec) -> tuple[float, ...]:
    """The single agent, or each team agent (home0_, ..., away0_, ...) at its kick-off in its side's colour, the
    away side facing -y and the follow camera on home0; returns their home qpos, in that order."""
    build = BUILDERS[spec.agent.kind]
    if spec.teams is None:
        return build(root, spec)
    home: tuple[float, ...] = ()
    for name, start in geometry.kickoffs(spec):
        side = name.rstrip("0123456789")
        home += build(root, spec, Placement(prefix=f"{name}_", start=start, turned=side == "away",
                                            rgba=SIDE_RGBA[side], camera=name == "home0"))
    return home


def fixtures(spec: FieldSpec) -> list[dict]:
    """The field's static geoms (goal, walls, obstacles) as MJCF geom attributes, in scene order.

    Variants trained in one batch share one list of fixtures (fieldgen.compile.variants)."""
    goals = _goal(spec) if spec.teams is None else _goal(spec, "away_") + _goal(spec, "home_", turned=True)
    return goals + [_box(b, "wall", spec) for b in geometry.walls(spec)] + [
        _box(b, "obstacle", spec) for b in geometry.obstacles(spec)]


def _options(root: mjcf.RootElement, spec: FieldSpec) -> None:
    s, e = spec.sim, spec.episode
    root.compiler.angle = "degree"
    root.compiler.inertiafromgeom = True
    root.option.timestep = e.physics_dt
    root.option.solver = s.solver.upper() if s.solver == "cg" else "Newton"
    root.option.iterations = s.iterations
    root.option.ls_iterations = s.ls_iterations
    root.option.cone = s.cone
    if not s.euler_damping:
        root.option.flag.eulerdamp = "disable"
    limit = contact_limit(spec)
    if limit is not None:
        root.custom.add("numeric", name="max_contact_points", data=(limit,))
    for name, value in brax_parameters(spec).items():
        root.custom.add("numeric", name=name, data=(value,))
    root.default.geom.condim = 3
    root.default.geom.friction = (1.0, 0.5, 0.5)
    root.default.geom.density = 5.0
    # Light that adds up to about 1 on the floor seen from above, so colours show as they are, not washed out.
    root.visual.headlight.ambient = (0.3, 0.3, 0.3)
    root.visual.headlight.diffuse = (0.3, 0.3, 0.3)
    root.visual.headlight.specular = (0.1, 0.1, 0.1)
    root.visual.quality.shadowsize = 2048
    root.visual.map.zfar = 500.0


def _floor(root: mjcf.RootElement, spec: FieldSpec) -> None:
    hx, hy = spec.field.width / 2, spec.field.length / 2
    root.asset.add("texture", name="sky", type="skybox", builtin="gradient", width=256, height=256,
                   rgb1=(0.55, 0.7, 0.9), rgb2=(0.15, 0.2, 0.3))
    tex = root.asset.add("texture", name="grid", type="2d", builtin="checker", width=256, height=256,
                         rgb1=FLOOR_RGB[0], rgb2=FLOOR_RGB[1])
    extent = 1.5 * max(hx, hy) + 4  # the plane collides everywhere; its size only bounds the drawing
    mat = root.asset.add("material", name="floor", texture=tex, texrepeat=(extent, extent), reflectance=0.0)
    ct, ca = bits("floor", spec)
    root.worldbody.add("geom", name="floor", type="plane", size=(extent, extent, 0.1), material=mat,
                       friction=(spec.field.friction, 0.5, 0.5), contype=ct, conaffinity=ca)
    root.worldbody.add("light", name="sun", pos=(0, 0, 40), dir=(0.2, 0.3, -1), directional=True,
                       diffuse=(0.45, 0.45, 0.45), castshadow=False)
    # Painted boundary lines, so a field without walls still shows its extent.
    w = 0.05
    for name, pos, size in (
        ("line_left", (-hx, 0, 0.001), (w, hy, 0.001)),
        ("line_right", (hx, 0, 0.001), (w, hy, 0.001)),
        ("line_back", (0, -hy, 0.001), (hx, w, 0.001)),
        ("line_front", (0, hy, 0.001), (hx, w, 0.001)),
        ("line_kickoff", (0, 0, 0.001), (hx, w, 0.001)),
    ):
        root.worldbody.add("geom", name=name, type="box", pos=pos, size=size, rgba=RGBA["line"],
                           contype=0, conaffinity=0, group=MARKINGS)


def _top_camera(root: mjcf.RootElement, spec: FieldSpec) -> None:
    """An orthographic camera straight down that frames the field, its walls, goal and obstacles with a
    margin. Its resolution keeps their aspect (a portrait field gives a portrait image); orthographic,
    fovy is the view's height in metres."""
    x0, x1, y0, y1 = _framed_extent(spec)
    margin = TOP_MARGIN * max(x1 - x0, y1 - y0)
    span_x, span_y = x1 - x0 + 2 * margin, y1 - y0 + 2 * margin
    width = max(16, 16 * round(TOP_HEIGHT_PX * span_x / span_y / 16))  # what video encoders take
    height_m = max(span_y, span_x * TOP_HEIGHT_PX / width)
    getattr(root.visual, "global").offwidth = max(640, width)
    centre = ((x0 + x1) / 2, (y0 + y1) / 2)
    if height_m < ORTHOGRAPHIC_MAX_M:
        root.worldbody.add("camera", name=TOP, pos=(*centre, 2 * max(span_x, span_y)), xyaxes=(1, 0, 0, 0, 1, 0),
                           projection="orthographic", fovy=height_m, resolution=(width, TOP_HEIGHT_PX))
        return
    # mujoco takes no fovy of 180 or more, even as an orthographic camera's metres: a field this large is framed
    # by a perspective camera as high as frames the same view
    above = height_m / 2 / math.tan(math.radians(TOP_FOVY_DEG / 2))
    root.worldbody.add("camera", name=TOP, pos=(*centre, above), xyaxes=(1, 0, 0, 0, 1, 0), fovy=TOP_FOVY_DEG,
                       resolution=(width, TOP_HEIGHT_PX))


def _framed_extent(spec: FieldSpec) -> tuple[float, float, float, float]:
    """x0, x1, y0, y1 of the field and everything standing on or beside it."""
    hx, hy = spec.field.width / 2, spec.field.length / 2
    boxes = [b.xy_bounds() for b in geometry.walls(spec) + geometry.obstacles(spec)]
    boxes += [goal.xy_bounds(inflate=spec.goal.post_radius) for goal in geometry.goal_regions(spec)]
    x0s, x1s, y0s, y1s = zip((-hx, hx, -hy, hy), *boxes)
    return min(x0s), max(x1s), min(y0s), max(y1s)


def _ball(root: mjcf.RootElement, spec: FieldSpec) -> tuple[float, ...]:
    """The ball; returns its home qpos (spawn centre)."""
    b = spec.ball
    if b.spawn.mode == "region":
        cx, cy = sum(b.spawn.x) / 2, sum(b.spawn.y) / 2
    else:
        (sx, sy), (tx, ty) = spec.agent.start, geometry.sample_target(spec)
        cx, cy = sx + b.spawn.fraction * (tx - sx), sy + b.spawn.fraction * (ty - sy)
    ct, ca = bits("ball", spec)
    if b.joint == "free":
        body = root.worldbody.add("body", name="ball", pos=(cx, cy, b.radius))
        body.add("freejoint", name="ball")
        home = (cx, cy, b.radius, 1.0, 0.0, 0.0, 0.0)
    else:
        # Slide joints measure from the body's position: keep it at the origin so qpos is world x, y.
        # A puck presses on the floor with its weight alone, so Coulomb floor friction is exactly a
        # frictionloss of mu*m*g on each slide: no floor contact needed (the study's bits keep one, and
        # brax, which ignores frictionloss, gets one).
        touches = spec.sim.contacts == "study" or ball_touches_floor(spec)
        frictionloss = 0.0 if touches else max(b.friction, spec.field.friction) * b.mass * GRAVITY
        body = root.worldbody.add("body", name="ball", pos=(0, 0, b.radius))
        for axis, vec in (("x", (1, 0, 0)), ("y", (0, 1, 0))):
            body.add("joint", name=f"ball_{axis}", type="slide", axis=vec, limited=False, armature=0, damping=0,
                     frictionloss=frictionloss)
        home = (cx, cy)
    body.add("geom", name="ball", type="sphere", size=(b.radius,), mass=b.mass, rgba=RGBA["ball"],
             friction=(b.friction, 0.5, 0.5), contype=ct, conaffinity=ca)
    return home


def _target_marker(root: mjcf.RootElement, spec: FieldSpec) -> None:
    """A mocap disc at the target, moved per episode; it never collides."""
    x, y = geometry.sample_target(spec)
    success = spec.task.success
    radius = 0.1 if success.kind == "ball_in_goal" else success.radius
    body = root.worldbody.add("body", name="target", mocap=True, pos=(x, y, 0.0))
    body.add("geom", name="target", type="cylinder", size=(radius, 0.005), rgba=RGBA["target"],
             contype=0, conaffinity=0, group=MARKINGS)


def _goal(spec: FieldSpec, prefix: str = "", turned: bool = False) -> list[dict]:
    """The goal at +y, its geoms' names prefixed; `turned`: half a turn about the kick-off point, at -y (a team
    field's home goal)."""
    region = geometry.goal_region(spec)
    if region is None:
        return []
    g = spec.goal
    (cx, cy, cz), (hx, hy, hz) = region.center, region.half
    out = [dict(name="goal_region", type="box", pos=region.center, size=region.half, rgba=RGBA["goal_region"],
                contype=0, conaffinity=0, group=SIDE_VIEW),
           dict(name="goal_area", type="box", pos=(cx, cy, 0.002), size=(hx, hy, 0.001), rgba=RGBA["goal_area"],
                contype=0, conaffinity=0, group=MARKINGS)]
    alpha = 1.0 if g.solid else DECORATIVE_ALPHA
    for cap in geometry.goal_frame(spec):
        reachable = min(cap.start[2], cap.end[2]) - cap.radius < geometry.reach_height(spec)
        ct, ca = bits("post", spec) if (g.solid and reachable) else (0, 0)
        out.append(dict(name=cap.name, type="capsule", fromto=cap.start + cap.end, size=(cap.radius,),
                        rgba=RGBA["post"][:3] + (alpha,), contype=ct, conaffinity=ca))
    if g.net:
        t = 0.01
        for name, pos, size in (
            ("net_back", (cx, cy + hy, cz), (hx, t, hz)),
            ("net_left", (cx - hx, cy, cz), (t, hy, hz)),
            ("net_right", (cx + hx, cy, cz), (t, hy, hz)),
            ("net_top", (cx, cy, cz + hz), (hx, hy, t)),
        ):
            out.append(dict(name=name, type="box", pos=pos, size=size, rgba=RGBA["net"], contype=0, conaffinity=0,
                            group=SIDE_VIEW))
    for geom in out:
        geom["name"] = prefix + geom["name"]
        if turned and "pos" in geom:
            geom["pos"] = geometry.turn(geom["pos"])
        if turned and "fromto" in geom:
            geom["fromto"] = geometry.turn(geom["fromto"][:3]) + geometry.turn(geom["fromto"][3:])
    return out


def _box(box: geometry.Box, role: str, spec: FieldSpec) -> dict:
    ct, ca = bits(role, spec) if box.solid else (0, 0)
    rgba = RGBA[role][:3] + ((1.0,) if box.solid else (DECORATIVE_ALPHA,))
    return dict(name=box.name, type="box", pos=box.center, size=box.half, rgba=rgba, contype=ct, conaffinity=ca)
