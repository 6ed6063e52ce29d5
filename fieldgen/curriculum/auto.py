"""The automatic curriculum: levels derived from the spec alone, all trained at once, weighted by what is
being learnt now.

`levels(spec, count)` lays `count` levels on a path from the spec's easy end to the spec itself
(fieldgen.curriculum.levels): first the kick-off moves back from next to the target to the spec's own, then
the obstacles grow back to their width and place and the walls return. A level the schema refuses (its
flood fill finds no way for the ball into the goal, a start inside an obstacle...) is never played. The
levels are built to one structure and batched in one simulation, each environment playing its own level,
as a mixed curriculum is (`Auto` is a `Mixed` schedule with other weights).

`level_weights` is the sampler. A level's learnability is p(1 - p) for its success p (high where some
episodes succeed and some fail, as in Sampling For Learnability); a mixed curriculum's 0.1 + 4p(1-p) gives a
level at p = 0 a share as small as a solved one, so the frontier starves. Here the easiest level not yet
solved (the frontier) always holds `frontier_share` of the episodes, learnable levels share the rest by
p(1 - p), and the spec itself (the last level) keeps `target_share` throughout, so its success is always
learnt from as well as measured.

Each level has up to KICKOFFS kick-off points (`kickoff_tables`): the level's spec with its kick-off moved
back towards the target, over the stretch of the kick-off no level before it covers, each validated up front,
so that a point the schema refuses is never played and no start belongs to two levels. A point differs from
its level only in where the ball and the agent start, so every point of every level plays in the one compiled
simulation. Where the environment has them, `next_levels` keeps a buffer of
about `buffer` levels (a level, one of its points) in the environments' own state, as ACCEL does: it starts
spread from the easy end to the spec, each level's success is estimated from the training episodes that ended
on it, episodes go to the learnable by p(1 - p), and after each evaluation the `replaced` lowest-scoring levels
give way to mutations of the highest-scoring ones (`hardest_share` keeps the level furthest along from leaving).
Those settings are a `Sampler`, recorded in run.json.
"""

from __future__ import annotations

import dataclasses
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from fieldgen import limits
from fieldgen.curriculum.levels import LevelError, LevelSpace
from fieldgen.curriculum.schedule import Mixed
from fieldgen.curriculum.section import SAMPLER
from fieldgen.schema import FieldSpec, SpecError
from fieldgen.schema.errors import shown_text, shown_value
from fieldgen.schema.source import Source
from fieldgen.suggest import allowed, did_you_mean

LEVELS = 8  # levels on the path from the easy end to the spec, the spec included
SOLVED = 0.8  # a level at this success or above is behind the frontier
KICKOFFS = 32  # kick-off points of each level, from the easy end's kick-off to the level's own
HARDER = ((0, 1), (0, 2), (1, 0), (-1, 0))  # the mutations of a level: (level, kick-off point) moved by, in
# reading order over the [level, point] grid, so one point past a level's own is the next level's first


def run_label(field: str) -> str:
    """What a run through a field's automatic curriculum is called (its folder, its plots): <field>-auto."""
    return f"{field}-auto"


@dataclasses.dataclass(frozen=True)
class Level:
    """One level: its coordinates on the space's axes (0 the easy end, 1 the spec) and its spec."""

    coordinates: tuple[float, ...]
    spec: FieldSpec


class Sampler(BaseModel):
    """How the sampler shares new episodes among levels and moves its buffer: a run's own settings, set with
    `--sampler KEY=VALUE` and kept in run.json, so that a resumed run samples as it began (the defaults are
    those of runs that recorded none)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)  # NaN is in no setting's range

    target_share: float = Field(0.2, gt=0, lt=1, description="of new episodes, on the spec itself")
    frontier_share: float = Field(0.3, ge=0, le=1, description="of new episodes, on the easiest level not yet "
                                                               "solved (levels without kick-off points)")
    floor: float = Field(0.05, ge=0, lt=1, description="of new episodes, spread evenly over the levels but the "
                                                       "spec (with kick-off points, over the buffer's entries but "
                                                       "the spec's own): none of them is starved")
    buffer: int = Field(32, ge=2, le=4096, description="entries episodes are drawn from, each a level with one "
                                                       "of its kick-off points")
    replaced: int = Field(4, ge=0, le=4096, description="of the buffer's levels, replaced after each evaluation "
                                                        "by mutations of the most learnable")
    prior: float = Field(2.0, gt=0, le=1000, description="episodes at success 0.5 every estimate starts from: a "
                                                         "level new to the buffer is learnable")
    sharpness: float = Field(1.0, ge=0, le=16, description="the power of p(1 - p) episodes are shared by: above "
                                                           "1 favours the most learnable levels more, 0 shares "
                                                           "evenly")
    kept: float = Field(0.5, ge=0, le=1, description="of a level's episode counts, kept at each evaluation: "
                                                     "older episodes count for less, an unplayed level drifts "
                                                     "back to the prior")
    hardest_share: float = Field(0.0, ge=0, le=1, description="of new episodes, on the buffer's level furthest "
                                                               "along the path but the spec, which is never "
                                                               "replaced: the buffer cannot retreat")
    ahead: float = Field(0.0, ge=0, le=16, description="a level's learnability grows by this much times its place "
                                                       "along the path (0 the easy end, 1 the spec): of levels "
                                                       "alike learnable the harder is kept, mutated from and "
                                                       "played more")
    ahead_from: float = Field(0.0, ge=0, lt=1, description="`ahead` grows only the levels whose counted "
                                                            "training episodes succeeded this often or more "
                                                            "(none counted: not grown): before anything is "
                                                            "learned, levels alike near 0 are not ranked by "
                                                            "place alone")

    _numbers = field_validator("*", mode="before")(limits.not_boolean)  # `--sampler prior=true` is no 1.0

    @model_validator(mode="after")
    def _fits(self):
        if self.floor + self.frontier_share > 1:
            raise ValueError(f"floor {self.floor} and frontier_share {self.frontier_share} together pass 1: "
                             "lower one of them")
        if self.floor + self.hardest_share > 1:
            raise ValueError(f"floor {self.floor} and hardest_share {self.hardest_share} together pass 1: "
                             "lower one of them")
        if self.replaced > self.buffer:
            raise ValueError(f"replaced {self.replaced} is more than the buffer's {self.buffer} levels")
        return self

    @classmethod
    def of(cls, settings: list[str], where: str = "--sampler") -> "Sampler":
        """The sampler of `settings` (KEY=VALUE each, over the defaults); LevelError in one line naming the
        setting, its allowed values and what it means, where one is unknown or out of range."""
        return cls.checked(cls._parsed(settings, where), where)

    @classmethod
    def configured(cls, config: Source | None, settings: Sequence[str] = ()) -> "Sampler | None":
        """The sampler of a --config file's `sampler:` section (`config`, as schema.source reads it) with
        --sampler's `settings` over it, so that a recipe's file holds its sampler as it holds its trainer's
        settings; None where neither sets one. LevelError names the file, line and key of a bad one."""
        section = config.data.get(SAMPLER) if config is not None else None
        if section is None and not settings:
            return None
        values, at, where = {}, {}, "--sampler"
        if section is not None:
            where = f"{_line(config, (SAMPLER,))}: {SAMPLER}"
            if not isinstance(section, dict):
                raise LevelError(f"{where} holds {shown_value(section)} where the sampler's keys go, one a line "
                                 f"and indented below it, e.g. '  replaced: 8'; keys: {', '.join(cls.model_fields)}")
            for key, value in section.items():
                at[key] = f"{_line(config, (SAMPLER, key))}: {SAMPLER}:"
                cls._known(str(key), f"{at[key]} {shown_text(str(key))}")
                values[key] = value
            where += " with --sampler" if settings else ""
        parsed = cls._parsed(settings, "--sampler")
        return cls.checked({**values, **parsed}, where, {**at, **dict.fromkeys(parsed, "--sampler")})

    @classmethod
    def _parsed(cls, settings: Sequence[str], where: str) -> dict:
        """KEY=VALUE settings as values, each key known; LevelError in one line at the first that is not."""
        values = {}
        for setting in settings:
            key, sep, text = setting.partition("=")
            key = key.strip()
            if not sep or not text.strip():
                raise LevelError(f"{where} {setting}: write KEY=VALUE, e.g. {where} replaced=8; keys: "
                                 f"{', '.join(cls.model_fields)}")
            cls._known(key, f"{where} {setting}")
            try:
                values[key] = yaml.safe_load(text) if len(text) <= limits.MAX_DIGITS else text
            except (yaml.YAMLError, ValueError):  # ValueError: an integer of more digits than Python converts
                values[key] = text
        return values

    @classmethod
    def _known(cls, key: str, said: str) -> None:
        """LevelError where `key` is no setting of the sampler, with the nearest one and every key."""
        if key not in cls.model_fields:
            near = did_you_mean(key, list(cls.model_fields)) or "."
            raise LevelError(f"{said}: unknown key '{key}'{near} Keys: {', '.join(cls.model_fields)}")

    @classmethod
    def checked(cls, values: dict, where: str, at: dict[str, str] | None = None) -> "Sampler":
        """`values` as a Sampler, or LevelError in one line naming the first bad key and its allowed values,
        said where it was written (`at`, by key) or else `where`."""
        try:
            return cls.model_validate(values)
        except ValidationError as exc:
            error = exc.errors()[0]
            key = error["loc"][0] if error["loc"] else None
            if key in cls.model_fields:
                info = cls.model_fields[key]
                raise LevelError(f"{(at or {}).get(key, where)} {key}={shown_value(values.get(key))}: {key} "
                                 f"{allowed(error, info)} ({info.description})") from None
            raise LevelError(f"{where}: {error['msg'].removeprefix('Value error, ')}") from None


def unread(config: Source | None, unsampled: str) -> str | None:
    """Where a run draws no automatic curriculum's levels (`unsampled`: what it does instead) and its config file
    (`config`, as schema.source read it) holds a `sampler:` section, the sentence that refuses the section at its
    line: nothing would read it, and a recipe's sampler dropped without a word would be a run unlike its record."""
    if config is None or SAMPLER not in config.data:
        return None
    return (f"{_line(config, (SAMPLER,))}: {SAMPLER}: sets how the automatic curriculum draws its levels, and "
            f"{unsampled}; take the section out, or use a config file without it")


def _line(config: Source, parts: tuple) -> str:
    """FILE:LINE of a key of a YAML file as schema.source read it."""
    file, line, _ = config.position(parts)
    return f"{file}:{line}"


def path(axes: int, count: int) -> np.ndarray:
    """`count` points from every axis at 0 to every axis at 1: the kick-off (axis 0) over the first half,
    the field's geometry (the other axes) over the second; one axis moves over the whole path."""
    t = np.linspace(0.0, 1.0, count)
    if axes == 1:
        return t[:, None]
    kickoff = np.clip(2 * t, 0.0, 1.0)
    geometry = np.clip(2 * t - 1, 0.0, 1.0)
    return np.column_stack([kickoff] + [geometry] * (axes - 1))


def levels(spec: FieldSpec, count: int = LEVELS) -> list[Level]:
    """The playable levels of `spec`'s path, easiest first, the spec itself last (LevelError where the spec
    has no easy end, or too few levels are asked for)."""
    if (said := limits.LEVELS.problem(count)) is not None:
        raise LevelError(f"--levels {count}: {said}")
    space = LevelSpace.of(spec)
    out, seen = [], set()
    for point in path(len(space.axes), count)[:-1]:
        if not space.playable(point):
            continue
        level_spec = space.spec_at(point)
        key = level_spec.model_dump_json()
        if key not in seen:
            seen.add(key)
            out.append(Level(tuple(float(x) for x in point), level_spec))
    return out + [Level(tuple(1.0 for _ in space.axes), spec)]


def kickoff_tables(spec: FieldSpec, chosen: list[Level], count: int = KICKOFFS) -> list[list[list[float] | None]]:
    """For each level, its `count` kick-off points up to its own (the last), each as [kick-off coordinate, ball
    spawn x0, y0, x1, y1, agent start x, y]; None where the schema refuses the point's spec (a ball start inside
    an obstacle...) or where the level has no point there. No two levels share a point, so that no start is
    counted, weighted and mutated as several levels at once: a level of the geometry of the level before it
    (the path's first half moves the kick-off alone) takes the stretch of the kick-off beyond that level's own,
    up to its own; a level of new geometry the whole stretch from the easy end's kick-off, so its geometry is
    met first with the ball near the target; the easy end is its own point alone."""
    if count < 2:
        raise LevelError(f"{count} kick-off points: a level needs at least 2 (the easy end's and its own)")
    space = LevelSpace.of(spec)
    tables = []
    for i, level in enumerate(chosen):
        own, geometry = level.coordinates[0], level.coordinates[1:]
        before = chosen[i - 1].coordinates if i else None
        banded = before is not None and tuple(before[1:]) == tuple(geometry)
        rows = []
        for j in range(count):
            kickoff = before[0] + (own - before[0]) * (j + 1) / count if banded else own * j / (count - 1)
            if j < count - 1 and kickoff == own:
                rows.append(None)  # the easy end: its own point alone
                continue
            try:
                at = level.spec if j == count - 1 else space.spec_at((kickoff, *geometry))
            except SpecError:
                rows.append(None)
                continue
            spawn = at.ball.spawn
            rows.append([kickoff, spawn.x[0], spawn.y[0], spawn.x[1], spawn.y[1], *at.agent.start])
        tables.append(rows)
    return tables


def kickoff_coordinates(kickoffs: list) -> np.ndarray:
    """[level, point]: each kick-off point's place on the kick-off (0 the easy end's, 1 the spec's) from its
    `kickoff_tables` row, NaN where the point is not played."""
    return np.array([[row[0] if row else np.nan for row in level] for level in kickoffs])


def initial_buffer(playable: np.ndarray, buffer: int = Sampler().buffer) -> np.ndarray:
    """The buffer's first levels [level, kick-off point]: `buffer` // levels playable points of each level (at
    least one), evenly spread from its easiest to its own kick-off, so that it starts from the easy end to the
    spec and moves from there."""
    out = np.zeros_like(playable, bool)
    for level, row in enumerate(playable):
        points = np.flatnonzero(row)
        spread = np.round(np.linspace(0, len(points) - 1, max(1, buffer // len(playable)))).astype(int)
        out[level, points[spread]] = True
    return out


def estimated_success(counts, prior: float):
    """Each level's success as the sampler estimates it from `counts` [2 (episodes ended, succeeded), ...]:
    `prior` episodes at one success in two added, so a level not yet played is at 0.5."""
    episodes, successes = counts[0], counts[1]
    return (successes + prior / 2) / (episodes + prior)


def counted_success(counts):
    """Each level's share of counted episodes that succeeded, without the prior: 0 where none is counted, so
    that `ahead_from` grows no level on the prior's 0.5 alone (a kick-off new to the buffer, or every kick-off
    while the first episodes, drawn before the buffer, are still running)."""
    episodes, successes = counts[0], counts[1]
    return successes / jnp.maximum(episodes, jnp.finfo(jnp.float32).tiny)


def next_levels(counts: jax.Array, weights: jax.Array, playable: np.ndarray, key: jax.Array,
                sampler: Sampler = Sampler()) -> tuple[jax.Array, jax.Array]:
    """The level buffer after an evaluation: (the weights [level, kick-off point] new episodes are drawn with,
    the share of each level's episode counts kept). The buffer is every level of positive weight, first
    `initial_buffer` (where the environment's own weights hold fewer levels); each level's success p is
    estimated from `counts` (training episodes ended, succeeded) and its prior. After that `replaced`
    lowest-scoring levels give way to mutations (HARDER) of the highest-scoring ones, each a playable level
    not yet in the buffer; the spec (the last level's own kick-off) never leaves. The spec keeps `target_share`,
    every other level `floor` spread evenly, the rest goes by `learnability` (p (1 - p), grown by `ahead`) to the power
    `sharpness`. With `hardest_share`, the buffer's level furthest along the path (in reading order) but the
    spec takes that share and is never replaced, so the hardest start the buffer holds moves only forward:
    without it a level at success 0 scores as low as a solved one and leaves first."""
    levels, points = playable.shape
    p = estimated_success(counts, sampler.prior).ravel()
    along = np.cumsum(playable.ravel()) - 1  # reading order is the path's: a level's points, then the next level's
    score = learnability(p, jnp.asarray(along / max(int(playable.sum()) - 1, 1), p.dtype), sampler,
                         counted_success(counts).ravel())
    target = jnp.arange(levels * points) == levels * points - 1
    start = initial_buffer(playable, sampler.buffer).ravel()
    member = weights.ravel() > 0
    first = jnp.sum(member) < start.sum()  # the environment's own weights: the buffer starts here
    member = jnp.where(first, jnp.asarray(start), member)
    playable_cells, moves = jnp.asarray(playable.ravel()), jnp.asarray(HARDER)
    cells = jnp.arange(levels * points)

    def hardest(member):
        """The buffer's level furthest along the path but the spec (one-hot; none where it holds only the spec)."""
        furthest = jnp.max(jnp.where(member & ~target, cells, -1))
        return (cells == furthest) & (sampler.hardest_share > 0)

    def mutate(tried, carry):
        member, added, replaced, key = carry
        key, k_move = jax.random.split(key)
        parent = jnp.argsort(jnp.where(member, -score, jnp.inf))[tried]  # the buffer's levels, best first
        child = parent + moves[:, 0] * points + moves[:, 1]  # in reading order: past a level's own, the next's first
        inside = (child >= 0) & (child < levels * points)
        child = jnp.where(inside, child, 0)
        fresh = inside & playable_cells[child] & ~member[child]
        chosen = child[jax.random.categorical(k_move, jnp.where(fresh, 0.0, -jnp.inf))]
        removable = member & ~target & ~added & ~hardest(member)
        victim = jnp.argmin(jnp.where(removable, score, jnp.inf))  # the lowest-scoring level not just added
        swap = ~first & member[parent] & jnp.any(fresh) & jnp.any(removable) & (replaced < sampler.replaced)
        member = jnp.where(swap, member.at[victim].set(False).at[chosen].set(True), member)
        added = jnp.where(swap, added.at[chosen].set(True), added)
        return member, added, replaced + swap, key

    member, *_ = jax.lax.fori_loop(0, int(start.sum()), mutate,
                                   (member, jnp.zeros_like(member), jnp.zeros((), jnp.int32), key))
    member = member | target
    others = member & ~target
    count = jnp.maximum(jnp.sum(others), 1)
    learnable = jnp.where(others, score ** sampler.sharpness, 0.0)
    total = jnp.sum(learnable)
    rest = jnp.where(total > 0, learnable / jnp.where(total > 0, total, 1.0), others / count)
    floor, target_share, furthest = sampler.floor, sampler.target_share, hardest(member)
    share = jnp.where(others, floor / count + sampler.hardest_share * furthest
                      + (1 - floor - sampler.hardest_share) * rest, 0.0)
    out = jnp.where(target, target_share, (1 - target_share) * share)
    out = jnp.where(jnp.any(others), out, target.astype(out.dtype))
    return out.reshape(levels, points).astype(weights.dtype), \
        jnp.where(member, sampler.kept, 0.0).reshape(levels, points).astype(weights.dtype)


def learnability(p, place, sampler: Sampler, measured=None):
    """p (1 - p) of a level at success p, grown by `ahead` times its `place` along the path (0 the easy end, 1 the
    spec): p (1 - p) alone rates a level at 0.5 near the easy end above one at 0.2 near the spec, so a policy
    that succeeds a little everywhere keeps its episodes, and the buffer, near the easy end. A level whose
    `measured` success (p where not given) is below `ahead_from` is not grown: where every level is near 0,
    place alone would rank them."""
    grown = jnp.where((p if measured is None else measured) >= sampler.ahead_from, sampler.ahead * place, 0.0)
    return p * (1 - p) * (1 + grown)


def level_weights(success: jnp.ndarray, sampler: Sampler = Sampler()) -> jnp.ndarray:
    """How often each level starts an episode next, from each level's success (the spec's last)."""
    n = success.shape[-1] - 1
    if n == 0:
        return jnp.ones_like(success)
    p = success[:-1]
    learnable = learnability(p, jnp.arange(n) / n, sampler) ** sampler.sharpness
    unsolved = p < SOLVED
    frontier = jnp.where(jnp.any(unsolved), jnp.argmax(unsolved), n - 1)
    at_frontier = (jnp.arange(n) == frontier).astype(success.dtype)
    total = jnp.sum(learnable)
    # learnable levels share what the frontier and the floor leave; with none learnable, the frontier takes it
    rest = jnp.where(total > 0, learnable / jnp.where(total > 0, total, 1.0), at_frontier)
    floor, frontier = sampler.floor, sampler.frontier_share
    levels_ = floor / n + frontier * at_frontier + (1.0 - floor - frontier) * rest
    target = sampler.target_share
    return jnp.concatenate([(1.0 - target) * levels_, jnp.full((1,), target, success.dtype)])


@dataclasses.dataclass(frozen=True)
class Auto(Mixed):
    """Every level at once, in one batched simulation: with kick-off points, drawn from the level buffer
    (`next_levels`); a run set up without them (before the buffer), each level weighted by `level_weights`;
    both as `sampler` says."""

    sampler: Sampler = Sampler()

    def variant_weights(self, success):
        return level_weights(success, self.sampler)

    def next_levels(self, counts, weights, playable, key):
        return next_levels(counts, weights, playable, key, self.sampler)

    def environments(self, envs, kickoffs=()) -> list:
        """What the trainer trains on: one environment batching every level, with each level's kick-off points
        (`kickoff_tables`, as run.json keeps them) where given."""
        if not kickoffs:
            return super().environments(envs)
        from fieldgen.env.make import environment

        starts = np.array([[row[1:] if row else [np.nan] * 6 for row in level] for level in kickoffs], np.float32)
        return [environment([e.artifact for e in envs], kickoffs=starts,
                            kickoff_coordinates=kickoff_coordinates(kickoffs))]


@dataclasses.dataclass(frozen=True)
class HeldLevel:
    """What a level buffer holds of one level: its points, where they start the ball, their share of new
    episodes, the episodes counted on them (older ones count for less) and the success the sampler estimates."""

    level: int  # from 0; the last is the field itself
    points: int
    kickoff: tuple[float, float]  # the lowest and highest of its points, 0 the easy end's, 1 the field's
    share: float
    episodes: float
    success: tuple[float, float]  # the lowest and highest estimate over its points


def buffer_shapes(seeds: int, kickoffs: list) -> dict:
    """The shapes of `seeds` seeds' level sampling (weights and counts) of a run with these kick-off points
    (`kickoff_tables`, as run.json keeps them): how the sampling a run keeps is read back."""
    from fieldgen.curriculum.contract import level_sampling_shapes

    return level_sampling_shapes(seeds, *kickoff_coordinates(kickoffs).shape)


def held_levels(kickoffs: list, sampling: dict, sampler: Sampler | None = None) -> list[HeldLevel]:
    """Level by level, what one seed's level buffer holds (`HeldLevel`), from its `sampling` (the level weights
    and counts of curriculum.contract.start_sampling, one seed's) and its run's `sampler` (None: the
    defaults), for a run with these kick-off points (`kickoff_tables`)."""
    coordinates = kickoff_coordinates(kickoffs)
    weights, counts = np.asarray(sampling["level_weights"]), np.asarray(sampling["level_counts"])
    success = np.asarray(estimated_success(counts, (sampler or Sampler()).prior))
    out = []
    for level in range(coordinates.shape[0]):
        held = weights[level] > 0
        if not held.any():
            continue
        where, p = coordinates[level][held], success[level][held]
        out.append(HeldLevel(level, int(held.sum()), (float(where.min()), float(where.max())),
                             float(weights[level].sum()), float(counts[0, level][held].sum()),
                             (float(p.min()), float(p.max()))))
    return out
