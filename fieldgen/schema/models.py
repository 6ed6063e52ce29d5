"""The field spec: pydantic models for every section of a field YAML.

Every key has a default and a one-line description, so `fieldgen schema` gives
editors a complete, documented JSON Schema. Units are MuJoCo's: metres,
kilograms, seconds. The kick-off point is the origin and the goal lies along +y.
"""

from __future__ import annotations

import math
import types
import typing
from typing import Annotated, Literal, Union

from pydantic import (AfterValidator, BaseModel, BeforeValidator, ConfigDict, Discriminator, Field, Tag, WithJsonSchema,
                      field_validator, model_serializer, model_validator)

from fieldgen.schema.backends import BACKENDS, backend_description
from fieldgen.schema.errors import shown_text
from fieldgen.schema.terms import DENSE_REWARDS, MATCH_TERMS, TERMS, dense_reward

MAX_EXTENT = 500.0  # metres; anything larger is a typo, not a field
MAX_OBJECT = 50.0  # metres; the largest single body (ball, goal, obstacle)
MAX_OBSTACLES = 1000  # a spec of this many validates in half a second; a field needs a few
MAX_AGENTS_A_SIDE = 2  # of a team field; its environment's observation names each other agent
DENSE = "dense"  # task.reward: the terms generated for the task (terms.DENSE_REWARDS)


class Section(BaseModel):
    """Base for every spec section: unknown keys and NaN/inf are errors, and a value is taken as written:
    true is no number, "0.5" is text, and 1 is no boolean (pydantic alone would convert all three)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_default=True)

    @model_validator(mode="before")
    @classmethod
    def _as_written(cls, data):
        """A value not taken as written becomes a NotAsWritten, which every type refuses, so the section's
        other keys are still checked and the loader reports the reason the NotAsWritten carries."""
        if not isinstance(data, dict):
            return data
        out = dict(data)
        for key, value in data.items():
            if key in cls.model_fields:
                try:
                    _taken_as_written(value, cls.model_fields[key].annotation)
                except ValueError as exc:
                    out[key] = NotAsWritten(str(exc))
        return out


class NotAsWritten:
    """A value pydantic would convert but the spec's author did not write as its type (true for a number)."""

    def __init__(self, reason: str):
        self.reason = reason

    def __repr__(self) -> str:
        return self.reason


def _kinds(annotation) -> tuple[set, set]:
    """(the plain types a field accepts among bool/int/float/str/tuple, the strings its Literals allow)."""
    types_, words = set(), set()
    stack = [annotation]
    while stack:
        tp = stack.pop()
        origin = typing.get_origin(tp)
        if origin is typing.Annotated:
            stack.append(typing.get_args(tp)[0])
        elif origin in (typing.Union, types.UnionType):
            stack.extend(typing.get_args(tp))
        elif origin is typing.Literal:
            words.update(a for a in typing.get_args(tp) if isinstance(a, str))
        elif origin is tuple or tp is tuple:
            types_.add(tuple)
        elif tp in (bool, int, float, str):
            types_.add(tp)
    return types_, words


def _taken_as_written(value, annotation):
    accepts, words = _kinds(annotation)
    numeric = bool(accepts & {int, float, tuple})
    items = value if isinstance(value, list) and tuple in accepts else [value]
    for item in items:
        if isinstance(item, bool) and bool not in accepts and numeric:
            raise ValueError(f"{str(item).lower()} is not a number")
        if isinstance(item, str) and str not in accepts and item not in words and numeric:
            choices = f" or one of {', '.join(repr(w) for w in sorted(words))}" if words else ""
            read = _as_number(item)
            if read is not None and not math.isfinite(read):  # nan, inf: YAML reads them as text
                raise ValueError(f"expected a finite number{choices} (got {shown_text(item)})")
            raise ValueError(f"'{shown_text(item)}' is text, not a number{choices}"
                             + ("; write it without quotes" if read is not None else ""))
    if accepts == {bool} and not isinstance(value, bool):
        raise ValueError(f"{shown_text(repr(value))} is not true or false")
    return value


def _as_number(text: str) -> float | None:
    """`text` as Python reads a number (quoted "2", or nan and inf, which YAML leaves as text), or None."""
    try:
        return float(text)
    except ValueError:
        return None


def _as_span(value):
    """A span is `x` (a single value) or `[lo, hi]` (uniform between them)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return (value, value)
    return value


def _ordered(span: tuple[float, float]) -> tuple[float, float]:
    if span[0] > span[1]:
        raise ValueError(f"the low end {span[0]} is above the high end {span[1]}")
    return span


Span = Annotated[
    tuple[float, float],
    BeforeValidator(_as_span),
    AfterValidator(_ordered),
    WithJsonSchema({"anyOf": [{"type": "number"},
                              {"type": "array", "prefixItems": [{"type": "number"}, {"type": "number"}],
                               "minItems": 2, "maxItems": 2}],
                    "description": "a number, or [low, high] for a uniform draw"}),
]


Length = Annotated[float, Field(gt=0, le=MAX_EXTENT)]
Size = Annotated[float, Field(gt=0, le=MAX_OBJECT)]


class FieldSection(Section):
    length: Length = Field(40.0, description="extent along y (towards the goal), centred on the kick-off point")
    width: Length = Field(32.0, description="extent along x, centred on the kick-off point")
    friction: float = Field(1.0, gt=0, le=10, description="sliding friction of the floor")


class WallsSection(Section):
    enabled: bool = Field(False, description="build walls around the field")
    height: Size = Field(0.6, description="wall height")
    thickness: Size = Field(0.2, description="wall thickness; walls are centred on the field's edge")
    sides: bool = Field(True, description="walls along both sides (x = +-width/2)")
    back: bool = Field(False, description="wall behind the kick-off point (y = -length/2)")
    front: bool = Field(
        True,
        description="wall on the goal line (y = +length/2), open at the goal mouth; "
        "false leaves it out so the ball can pass beside the goal",
    )
    solid: bool = Field(True, description="walls collide with the ball and the agent; false makes them decorative")


class GoalSection(Section):
    enabled: bool = Field(True, description="build a goal")
    distance: Length = Field(10.0, description="distance from the kick-off point to the goal point, along +y")
    width: Size = Field(4.0, description="goal box width (x)")
    depth: Size = Field(1.0, description="goal box depth (y), centred on the goal point")
    height: Size = Field(2.0, description="goal box height and post height")
    post_radius: Size = Field(0.2, description="radius of the capsule posts and crossbar")
    post_setback: float | None = Field(
        None, ge=0, le=MAX_OBJECT, description="post axis distance behind the box's front face; default post_radius"
    )
    crossbar: bool = Field(True, description="a crossbar joins the post tops")
    net: bool = Field(True, description="translucent net panels (never collide)")
    solid: bool = Field(True, description="posts and crossbar collide with the ball and the agent")

    @property
    def posts_y(self) -> float:
        setback = self.post_radius if self.post_setback is None else self.post_setback
        return self.distance - self.depth / 2 + setback


class SpawnRegion(Section):
    mode: Literal["region"] = Field("region", description="uniform in an axis-aligned box around a point")
    x: Span = Field((0.0, 0.0), description="x of the ball centre: a number or [low, high]")
    y: Span = Field((3.0, 3.0), description="y of the ball centre: a number or [low, high]")


class SpawnTowardTarget(Section):
    mode: Literal["toward_target"] = Field(description="on the line from the agent to the target, plus jitter")
    fraction: float = Field(0.5, gt=0, lt=1, description="how far along the agent-to-target line")
    jitter: float = Field(0.5, ge=0, le=MAX_OBJECT, description="uniform offset in [-jitter, jitter] on x and y")


def _spawn_mode(value) -> str:
    """`mode` may be left out and then means 'region'."""
    if isinstance(value, dict):
        return value.get("mode", "region")
    return getattr(value, "mode", "region")


Spawn = Annotated[
    Union[Annotated[SpawnRegion, Tag("region")], Annotated[SpawnTowardTarget, Tag("toward_target")]],
    Discriminator(_spawn_mode),
]


class BallSection(Section):
    enabled: bool = Field(True, description="put a ball on the field")
    radius: Size = Field(0.5, description="ball radius")
    mass: float = Field(0.58, gt=0, le=1000, description="ball mass in kilograms")
    friction: float = Field(1.0, gt=0, le=10, description="sliding friction of the ball")
    joint: Literal["planar", "free"] = Field(
        "planar", description="planar: a puck on x/y slides (cannot roll or lift); free: a rolling ball"
    )
    spawn: Spawn = Field(default_factory=SpawnRegion, description="where the ball starts each episode")


class ResetNoise(Section):
    qpos: float = Field(0.1, ge=0, le=10, description="uniform noise [-qpos, qpos] added to the agent's joint positions")
    qvel: float = Field(0.1, ge=0, le=10, description="standard deviation of the agent's initial joint velocities")


class AgentSection(Section):
    kind: Literal["ant", "point"] = Field("ant", description="ant: the 8-motor quadruped; point: a fast planar disc")
    start: tuple[float, float] = Field((0.0, 0.0), description="start position (x, y) of the agent")
    reset_noise: ResetNoise = Field(default_factory=ResetNoise, description="randomness added at every reset")
    gear: float | None = Field(None, gt=0, le=10000, description="motor gear; default 150 for ant, 10 for point")


class TeamSide(Section):
    agents: int = Field(1, ge=1, le=MAX_AGENTS_A_SIDE, description="agents on this side; both sides field as many")
    start: list[tuple[float, float]] | None = Field(
        None, min_length=1, max_length=MAX_AGENTS_A_SIDE,
        description="each agent's kick-off (x, y) in this side's own frame, where it attacks along +y (the away "
                    "side's is the field's turned half a turn); default: side by side, halfway between the centre "
                    "and the side's own goal")


class LackOfProgress(Section):
    seconds: float = Field(3.0, gt=0, le=3600, description="how long the ball may stay within `distance` of a spot")
    distance: float = Field(0.5, ge=0, le=MAX_EXTENT, description="how far (m) the ball must move from where it "
                            "was to count as progress: a ball pinned between two agents creeps, it does not stop")


class TeamsSection(Section):
    home: TeamSide = Field(default_factory=TeamSide,
                           description="the side that attacks the goal at +y and defends the one at -y")
    away: TeamSide = Field(default_factory=TeamSide,
                           description="the side that attacks the goal at -y and defends the one at +y")
    lack_of_progress: LackOfProgress | None = Field(
        None, description="a ball that stays this long near one spot is moved, at rest, to the neutral spot "
                          "farthest from every agent (the centre spot, or a quarter of the width out and half the "
                          "goal distance up or down), as robot-soccer referees restart a stalled game; the episode "
                          "goes on. Default: none")


SIDES = ("home", "away")  # a team field's sides, in the order its agents and rewards come


class Obstacle(Section):
    x: float = Field(0.0, ge=-MAX_EXTENT, le=MAX_EXTENT, description="x of the box centre")
    y: float = Field(0.0, ge=-MAX_EXTENT, le=MAX_EXTENT, description="y of the box centre")
    relative_to: Literal["kickoff", "goal"] = Field("kickoff", description="origin of x and y: the kick-off or goal point")
    width: Size = Field(1.0, description="extent along x")
    depth: Size = Field(1.0, description="extent along y")
    height: Size = Field(1.0, description="extent along z")
    solid: bool = Field(True, description="collides with the ball and the agent; false makes it decorative")


class TargetGoal(Section):
    kind: Literal["goal"] = Field(description="the goal point, (0, goal.distance)")


class TargetRing(Section):
    kind: Literal["ring"] = Field(description="a random point on a ring around the agent's start")
    radius: Span = Field((10.0, 10.0), description="ring radius: a number or [low, high]")
    angle_deg: Span = Field((-180.0, 180.0), description="angle range in degrees, 0 along +x")

    @model_validator(mode="after")
    def _positive(self):
        if self.radius[0] <= 0:
            raise ValueError("radius must be positive")
        return self


class TargetPoint(Section):
    kind: Literal["point"] = Field(description="a fixed point")
    x: float = Field(0.0, ge=-MAX_EXTENT, le=MAX_EXTENT, description="x of the target")
    y: float = Field(0.0, ge=-MAX_EXTENT, le=MAX_EXTENT, description="y of the target")


Target = Annotated[Union[TargetGoal, TargetRing, TargetPoint], Field(discriminator="kind")]


class Success(Section):
    kind: Literal["ball_near_target", "ball_in_goal", "agent_near_target"] = Field(
        "ball_near_target", description="what counts as success at a step"
    )
    radius: Size = Field(0.5, description="distance to the target that counts (the *_near_target kinds)")


class RewardTerm(Section):
    term: Literal[tuple(dict.fromkeys([*TERMS, *MATCH_TERMS]))] = Field(
        description="a term from the reward-term registry (fieldgen/schema/terms.py): TERMS for one agent, "
                    "MATCH_TERMS for a field with teams")
    weight: float = Field(1.0, ge=-1e4, le=1e4, description="the term's factor in the reward sum")
    band: Span | None = Field(None, description="upright only: torso height band that earns the bonus")

    @model_validator(mode="after")
    def _band(self):
        if self.term == "upright":
            self.band = self.band or (0.2, 1.0)
        elif self.band is not None:
            raise ValueError(f"'band' applies to the upright term only, not to {self.term!r}")
        return self


def _reward_form(value) -> str:
    """Which form task.reward is written in: text (`dense`) or a list of terms; each form's own errors alone."""
    return "generated" if isinstance(value, str) else "listed"


Reward = Annotated[Union[Annotated[Annotated[list[RewardTerm], Field(min_length=1)], Tag("listed")],
                         Annotated[Literal[DENSE], Tag("generated")]], Discriminator(_reward_form)]


class TaskSection(Section):
    target: Target = Field(default_factory=lambda: TargetGoal(kind="goal"), description="where the goal point lies")
    success: Success = Field(default_factory=Success, description="the success predicate")
    goal_positions: list[Literal["agent", "ball"]] | None = Field(
        None, min_length=1, max_length=2,
        description="whose x, y the goal names, in this order, each commanded to the target; default: what the "
                    "success judges. [agent, ball] gives hindsight the agent's own moves to learn from before the "
                    "ball ever moves")
    reward: Reward = Field(
        default_factory=lambda: [RewardTerm(term="success")],
        description="weighted reward terms, summed; the default is the sparse success reward; dense: the terms "
                    "generated for the task's success kind (see Dense rewards below)",
    )

    @field_validator("reward")
    @classmethod
    def _dense_known(cls, reward, info):
        """`dense` left as written: the task's success kind has no generated terms (FieldSpec expands the rest)."""
        if reward == DENSE:
            if "success" not in info.data:
                return reward  # the success is wrong itself, and says so: which terms it has is not known
            kind = info.data["success"].kind
            if kind in DENSE_REWARDS:  # left as written by FieldSpec only on a field with teams
                raise ValueError(f"dense names the terms generated for one agent's task; a field with teams lists "
                                 f"its match terms instead: {', '.join(MATCH_TERMS)}")
            kinds = ", ".join(DENSE_REWARDS)
            raise ValueError(f"dense names the terms generated for a task, and success kind '{kind}' has none; "
                             f"the kinds with them: {kinds}; list this task's terms instead")
        return reward

    @model_validator(mode="after")
    def _goal_of_success(self):
        """By default the goal names only what the success judges: the ball, or the agent."""
        if self.goal_positions is None:
            self.goal_positions = [self.success_subject]
            self.model_fields_set.discard("goal_positions")
        return self

    @property
    def success_subject(self) -> str:
        """What the success predicate judges: "ball" or "agent"."""
        return "ball" if self.success.kind.startswith("ball") else "agent"


class FallFlipped(Section):
    kind: Literal["flipped"] = Field(description="the ant has fallen once its torso turns over (MuJoCo Playground's quadrupeds)")
    tilt_deg: float = Field(90.0, gt=0, le=180, description="turned over once the torso's up axis tilts more than "
                            "this from vertical; 90: it points below the horizon")
    grace_steps: int = Field(0, ge=0, le=100_000, description="control steps the ant may stay turned over, "
                             "free to right itself, before it counts as fallen")

    def ends(self, control_dt: float | None = None) -> str:
        """When the rule ends an episode, in words: 'once the ant has lain turned over for 50 control steps in a
        row'; `control_dt` (seconds a control step) adds how long that is: ' (2.5 s)'."""
        lying = "turned over" if self.tilt_deg == 90 else f"tilted more than {self.tilt_deg:g} degrees from vertical"
        if not self.grace_steps:
            return f"once the ant lies {lying}"
        seconds = f" ({self.grace_steps * control_dt:g} s)" if control_dt else ""
        return (f"once the ant has lain {lying} for {self.grace_steps:,} control step{'s' * (self.grace_steps != 1)} "
                f"in a row{seconds}")


class FallHeightBand(Section):
    kind: Literal["height_band"] = Field(description="the ant has fallen once its torso leaves a height band "
                                         "(the soccer study's and the CRL reference's ant, tuned on brax's spring physics)")
    band: Span = Field((0.2, 1.0), description="torso heights (z of its centre) that count as standing")

    def ends(self, control_dt: float | None = None) -> str:
        """When the rule ends an episode, in words (as FallFlipped.ends)."""
        return f"once the ant's torso leaves heights {self.band[0]:g} to {self.band[1]:g} m"


class FallNever(Section):
    kind: Literal["never"] = Field(description="episodes end only when time runs out (OGBench's ant soccer)")

    def ends(self, control_dt: float | None = None) -> str:
        """When the rule ends an episode, in words (as FallFlipped.ends)."""
        return "on time alone"


Fall = Annotated[Union[FallFlipped, FallHeightBand, FallNever], Field(discriminator="kind")]


class EpisodeSection(Section):
    length: int = Field(1001, ge=1, le=1_000_000, description="control steps per episode")
    control_dt: float = Field(0.05, ge=1e-4, le=10, description="seconds per control step")
    physics_dt: float = Field(0.01, ge=1e-4, le=1, description="seconds per physics step")
    fall: Fall = Field(default_factory=lambda: FallNever(kind="never"),
                       description="when the ant has fallen, which ends its episode early; by default never: "
                       "with episodes ended at a fall, CRL did not learn the MJX ant; a point agent never falls")

    @property
    def substeps(self) -> int:
        return round(self.control_dt / self.physics_dt)


# sim.agent_contacts: each choice, and the agent's parts (contact roles, fieldgen/compile/contacts.py) it lets
# collide with walls, obstacles and posts
AGENT_CONTACTS = {"none": (), "torso": ("torso",), "torso_and_feet": ("torso", "foot")}


class SimSection(Section):
    backend: Literal[tuple(BACKENDS)] = Field("mjx", description=backend_description())
    solver: Literal["newton", "cg"] = Field("newton", description="constraint solver")
    iterations: int = Field(1, ge=1, le=100, description="solver iterations")
    ls_iterations: int = Field(4, ge=1, le=100, description="line-search iterations")
    euler_damping: bool = Field(False, description="implicit joint damping in the Euler integrator (slow in MJX)")
    cone: Literal["pyramidal", "elliptic"] = Field("pyramidal", description="friction cone")
    agent_contacts: Literal[tuple(AGENT_CONTACTS)] = Field(
        "torso", description="which agent geoms collide with walls, obstacles and posts"
    )
    max_contacts: Annotated[int, Field(ge=1, le=10_000)] | Literal["auto", "all"] = Field(
        "auto",
        description="contacts passed to the solver each step, nearest first (MJX max_contact_points); "
        "auto: the agent's resting contacts + 8; all: no limit",
    )
    contacts: Literal["pruned", "torso_floor", "study"] = Field(
        "pruned",
        description="pruned: only pairs that can matter are checked, the ant's torso not against the floor (as in "
        "the soccer study), so a turned-over ant sinks its torso through it; torso_floor: pruned, and the ant's "
        "torso touches the floor too, so a turned-over ant lies on its back; study: the soccer study's contact "
        "bits (feet touch each other and the torso; walls, goalie and posts touch nothing)",
    )
    precision: Literal["highest", "default"] = Field(
        "highest",
        description="matrix-multiply precision of the physics: highest (float32, the same on every device), or "
        "default, which on recent NVIDIA GPUs is TF32: a little faster, but no longer the same on every device",
    )


class ObservationSection(Section):
    ball_velocity: bool = Field(False, description="append the ball's velocity to the observation")


NAME_PATTERN = r"^[a-z0-9][a-z0-9_\-]*$"  # a field's name: it names build folders and runs
OBSTACLE_NAME_PATTERN = r"^[a-z0-9][a-z0-9_]*$"  # an obstacle's: it names its geom, obstacle_<name>
# each pattern in the words a problem says instead of the regular expression
PATTERN_WORDS = {NAME_PATTERN: "lower-case letters, digits, _ and -, beginning with a letter or digit",
                 OBSTACLE_NAME_PATTERN: "lower-case letters, digits and _, beginning with a letter or digit"}


class FieldSpec(Section):
    """A complete robot-soccer field: geometry, agent, task and simulation."""

    extends: str | None = Field(None, description="a bundled field name or a path relative to this file")
    name: str = Field(pattern=NAME_PATTERN, max_length=64, description="lower-case identifier")
    description: str = Field("", description="what the field models and where its numbers come from")
    field: FieldSection = Field(default_factory=FieldSection, description="floor size and friction")
    walls: WallsSection = Field(default_factory=WallsSection, description="walls around the field")
    goal: GoalSection = Field(default_factory=GoalSection, description="the goal box, posts and crossbar")
    ball: BallSection = Field(default_factory=BallSection, description="the ball")
    agent: AgentSection = Field(default_factory=AgentSection, description="the controlled agent; with teams, "
                                "every agent's kind, gear and reset noise")
    teams: TeamsSection | None = Field(None, description="two sides playing a match, each attacking the other's goal "
                                       "(a goal at each end from the goal keys); null: one agent")
    obstacles: dict[Annotated[str, Field(pattern=OBSTACLE_NAME_PATTERN, max_length=32)], Obstacle] = Field(
        default_factory=dict, max_length=MAX_OBSTACLES, description="named boxes, e.g. a goalie")
    task: TaskSection = Field(default_factory=TaskSection, description="target, success predicate, reward")
    episode: EpisodeSection = Field(default_factory=EpisodeSection, description="timing and termination")
    sim: SimSection = Field(default_factory=SimSection, description="physics pipeline and its options")
    observation: ObservationSection = Field(default_factory=ObservationSection, description="observation extras")

    @model_validator(mode="before")
    @classmethod
    def _dense_reward(cls, data):
        """`task: {reward: dense}` as the terms generated for the task's success kind and the agent (terms.py)."""
        task = data.get("task") if isinstance(data, dict) else None
        if not isinstance(task, dict) or task.get("reward") != DENSE:
            return data
        success, agent = task.get("success", {}), data.get("agent")
        kind = success.get("kind", Success.model_fields["kind"].default) if isinstance(success, dict) else None
        agent_kind = agent.get("kind", AgentSection.model_fields["kind"].default) if isinstance(agent, dict) else \
            AgentSection.model_fields["kind"].default
        if kind not in DENSE_REWARDS or data.get("teams") is not None:
            return data  # TaskSection says which kinds have terms, and that a match has none
        obstacles = data.get("obstacles")
        solid = isinstance(obstacles, dict) and any(not (isinstance(o, dict) and o.get("solid") is False)
                                                    for o in obstacles.values())
        return {**data, "task": {**task, "reward": dense_reward(kind, torso=agent_kind == "ant", obstacles=solid)}}

    @model_validator(mode="after")
    def _backend_defaults(self):
        """The physics step each pipeline was tuned for, where the spec leaves it out."""
        for (section, key), value in BACKENDS[self.sim.backend].defaults.items():
            part = getattr(self, section)
            if key not in part.model_fields_set:
                setattr(part, key, value)
                part.model_fields_set.discard(key)  # still a default: another backend brings its own
        return self

    @model_validator(mode="after")
    def _match_defaults(self):
        """A match is won by goals: a team field's success is the ball in a goal and its reward the goal term,
        where the spec leaves them out (checks.py refuses other settings that make no sense for a match)."""
        if self.teams is None:
            return self
        task = self.task
        if "success" not in task.model_fields_set:
            task.success = Success(kind="ball_in_goal")
            task.model_fields_set.discard("success")
        if "reward" not in task.model_fields_set:
            task.reward = [RewardTerm(term="goal")]
            task.model_fields_set.discard("reward")
        return self

    @model_serializer(mode="wrap")
    def _without_teams_unless_set(self, handler):
        """A single-agent field dumps as it did before teams existed, so its field.json, build hash and run
        records' field digest stay what they were."""
        data = handler(self)
        if self.teams is None and isinstance(data, dict):
            data.pop("teams", None)
        return data

    def target_fixed(self) -> tuple[float, float] | None:
        """The target point when it does not vary between episodes."""
        t = self.task.target
        if t.kind == "goal":
            return (0.0, self.goal.distance)
        if t.kind == "point":
            return (t.x, t.y)
        return None
