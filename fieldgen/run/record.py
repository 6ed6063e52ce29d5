"""A training run's records on disk: runs/<field>-<algo>-<seed>/.

A run folder holds everything needed to resume: `run.json` (the field's build, the
algorithm, its full config and the seeds), `metrics.jsonl` / `metrics.csv` (one row per
evaluation and seed), `checkpoint.msgpack` (the whole training state after the last
evaluation), `learner.msgpack` (what it learned alone, without its episodes and replay buffer: enough
to go on where the whole state is too large to move), `initial.msgpack` (for a run started from another's
networks, `--init-from`, what it starts from), `success.png` and `videos/eval_NNN.mp4` (or .gif); every file
is replaced whole.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections import Counter
from pathlib import Path, PurePosixPath
from typing import Annotated

from pydantic import (AfterValidator, BaseModel, ConfigDict, Field, StrictBool, StrictInt, StrictStr, ValidationError,
                      model_validator)

from fieldgen.curriculum.promotion import Promotion
from fieldgen.files import Output, kind_of_blocker, parsed_json, stands_unlike, write_atomic, written_by
from fieldgen.limits import SEED, SEEDS
from fieldgen.schema.errors import shown_text, shown_value
from fieldgen.suggest import shell

RUN, METRICS, CSV, CHECKPOINT, PLOT = "run.json", "metrics.jsonl", "metrics.csv", "checkpoint.msgpack", "success.png"
LEARNER, INITIAL, VIDEOS = "learner.msgpack", "initial.msgpack", "videos"
RUN_FOLDER = Output("fieldgen train", (), RUN,  # written into file by file, never replaced whole
                    files=(RUN, METRICS, CSV, CHECKPOINT, LEARNER, INITIAL, PLOT, VIDEOS, "field", "stages"),
                    record_keys=("algo", "config"))
# what each of a run's own files holds, in the words of a refusal where something else stands in its place (its
# checkpoint and learner are read before training, and train.py says what stands in their place)
OWN_FILES = {METRICS: "metrics", CSV: "metrics as CSV", PLOT: "plot"}


def in_the_way(run_dir: Path, videos: bool) -> str | None:
    """Where a folder (or a link that leads nowhere) stands where the run writes one of its own files, or a file where
    it keeps its videos: the sentence that says so and how to go on, so that it is refused before training rather
    than at the first write after it; None where nothing is."""
    for name, what in OWN_FILES.items():
        path = run_dir / name
        if stands_unlike(path, Path.is_file):
            return (f"{path} is {kind_of_blocker(path)} where the run writes its {what}; move it aside, then continue "
                    f"with fieldgen train --resume {shell(run_dir)}")
    path = run_dir / VIDEOS
    if videos and stands_unlike(path, Path.is_dir):
        return (f"{path} is {kind_of_blocker(path)} where the run keeps its videos; move it aside, or continue "
                f"without videos: fieldgen train --resume {shell(run_dir)} --no-videos")
    return None


PARSER_COMPLAINT = 120  # characters of what JSON's parser says of a broken record: its whole sentence and place
# the metrics that time the run rather than say what it learned: the only ones in which the same run, trained
# again or over other processes, may differ
TIMINGS = ("wall_seconds", "steps_per_second", "peak_memory_mb", "write_wait_seconds")


def run_name(field: str, algo: str, seeds: list[int]) -> str:
    """The name of a run's folder: <field>-<algo>-<seed>, or <first>to<last> for seeds trained at once."""
    suffix = str(seeds[0]) if len(seeds) == 1 else f"{seeds[0]}to{seeds[-1]}"
    return f"{field}-{algo}-{suffix}"


def has_trained(run_dir: Path) -> bool:
    """Whether the run has a checkpoint to go on from: its whole state, or what it learned alone."""
    return (run_dir / CHECKPOINT).exists() or (run_dir / LEARNER).exists()


def occupied(run_dir: Path) -> str | None:
    """Why a new run cannot be set up in `run_dir`, or None: a run is there to continue, or its checkpoint without
    the run.json that says how it trains (nothing of it is removed here: the folder is the user's to move)."""
    if not has_trained(run_dir):
        return None
    if (run_dir / RUN).is_file():
        return (f"{run_dir} already holds a run; continue it with --resume {shell(run_dir)}, or pick another --seed "
                "or --out")
    return (f"{run_dir} holds a run's checkpoint but not its {RUN}, the record of its settings and seeds, so it can "
            f"neither go on nor be set up again there: restore {RUN} from a copy to continue it, or move the folder "
            f"away (mv {shell(run_dir)} {shell(str(run_dir) + '.old')}) to train it anew")


class RunError(Exception):
    """A run that cannot start or go on: bad training input, found before anything compiles, or training
    that diverged."""


SET_UP_AGAIN = "set the run up again with the fieldgen train command that made it, or restore the folder from a copy"


def field_copy_error(copy: Path, problem: str) -> RunError:
    """A run's own copy of its field (`copy`, a folder of the run) that cannot be loaded, for `problem`, with the
    way on for a run folder: `fieldgen build` writes build folders, never that copy."""
    return RunError(f"{problem}; {copy} is the run's own copy of its field: {SET_UP_AGAIN}")


def check_field_copy(copy: Path) -> None:
    """Refuse a run whose own copy of its field (`copy`, a folder of the run) is missing or a file: read as a
    field, it would be a spec file that is not there."""
    if not copy.is_dir():
        what = "is a file, not a folder" if copy.exists() else "is missing"
        raise RunError(f"{copy} {what}: the run's own copy of its field (a setup cut short, or a copy of the run "
                       f"that left it out); {SET_UP_AGAIN}")


def write_run(run_dir: Path, field: dict, algo: str, config, layout: dict, seeds: list[int], extra: dict) -> None:
    """run.json: the resolved field spec (a curriculum's last stage), the algorithm, its full config,
    the observation layout, the seeds, and `extra` (where the run keeps its fields, the promotion rule)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    record = {"field": field, "algo": algo, "config": config.model_dump(), "observation": layout,
              "seeds": seeds, **extra}
    write_atomic(run_dir / RUN, (json.dumps(record, indent=1) + "\n").encode())


Index = Annotated[StrictInt, Field(ge=0)]
Rating = Annotated[float, Field(strict=True, allow_inf_nan=False)]  # an Elo rating: any finite number


class Games(BaseModel):
    """A self-play snapshot's games against one opponent, as a league of a metrics row counts them."""

    model_config = ConfigDict(extra="forbid")
    win: Index
    draw: Index
    loss: Index


def _inside(name: str) -> str:
    """A folder of the run's own: a record copied in from elsewhere never reaches outside its run."""
    parts = PurePosixPath(name).parts
    if not parts or name.startswith("/") or ".." in parts:
        raise ValueError("should name a folder inside the run, such as field or stages/01")
    return name


def _each_once(seeds: list[int]) -> list[int]:
    """A run's seeds, each trained once: a seed listed twice would be two runs' worth of arrays where the run
    learned one, and its rows blamed on two seeds of one name."""
    twice = sorted(seed for seed, times in Counter(seeds).items() if times > 1)
    if twice:
        shown = ", ".join(map(str, twice[:3])) + (", ..." if len(twice) > 3 else "")
        raise ValueError(f"should list each seed once (seed{'s' * (len(twice) > 1)} {shown} more than once)")
    return seeds


class InitFrom(BaseModel):
    """Where a run started from another's networks came from: that run's folder as given, and how far it was;
    `before`, the env steps that run's own networks had trained before it (its --init-from, and theirs), so
    that a chain of runs counts from nothing learned (0 in records written before it was kept)."""

    run: StrictStr
    env_steps: Index
    eval: Index
    before: Index = 0

    @property
    def learned(self) -> int:
        """Env steps the networks had trained, from nothing, when this run took them."""
        return self.before + self.env_steps


def _schedule(name: str) -> str:
    from fieldgen.curriculum.kinds import SCHEDULES

    if name not in SCHEDULES:
        raise ValueError(f"should be one of {', '.join(SCHEDULES)}")
    return name


def _algorithm(name: str) -> str:
    """One of this fieldgen's trainers: what reads a run's curves alone (fieldgen compare) checks it as what opens
    the run does."""
    from fieldgen.agents.choices import ALGORITHMS

    if name not in ALGORITHMS:
        raise ValueError(f"should be one of this fieldgen's algorithms, {', '.join(ALGORITHMS)}")
    return name


class RunRecord(BaseModel):
    """What run.json must hold to reopen a run, each value of the type fieldgen wrote."""

    algo: Annotated[StrictStr, AfterValidator(_algorithm)]
    config: dict
    observation: dict
    field: Annotated[dict, Field(strict=True)] | None = None  # the resolved spec of the field the run is judged on
    # (reading metrics needs no field; opening the run does: session.open_run refuses a record without it)
    seeds: Annotated[list[Annotated[StrictInt, Field(ge=SEED.low, le=SEED.high)]],
                     Field(min_length=1, max_length=SEEDS.high), AfterValidator(_each_once)] = []  # []: config's seed
    fields: Annotated[list[Annotated[StrictStr, AfterValidator(_inside)]], Field(min_length=1)] = []  # []: field/
    promotion: Promotion = Promotion()
    mixed: StrictBool = False
    schedule: Annotated[StrictStr, AfterValidator(_schedule)] | None = None  # None (older runs): staged, or mixed
    # an automatic curriculum's levels: each stage's coordinates on the named axes, from 0 (the easy end) to 1 (the spec)
    levels: list[dict[StrictStr, Annotated[float, Field(strict=True, ge=0, le=1)]]] = []
    # and each level's kick-off points (curriculum.auto.kickoff_tables): [coordinate, ball spawn x0, y0, x1, y1,
    # agent start x, y], null where the point is not played
    kickoffs: list[list[Annotated[list[Annotated[float, Field(allow_inf_nan=False)]], Field(min_length=7, max_length=7)]
                        | None]] = []  # finite: an edited NaN would be trained on
    sampler: dict = {}  # an automatic curriculum's sampler settings (curriculum.auto.Sampler); {}: its defaults
    curriculum: StrictStr = ""  # the name of the curriculum the run trains through; "" (left out): a field
    init_from: InitFrom | None = None
    recipe: dict = {}  # the recipe the run was set up from (fieldgen/run/recipe.py); {} (left out): none
    judged: Annotated[StrictStr, AfterValidator(_inside)] | None = None  # the run's copy of the field as written,
    # where its recipe trained it on another form of it (session.JUDGED); None (left out): judged where it trained
    selfplay: StrictBool = False  # a team field's self-play run (fieldgen/run/selfplay.py): judged by matches won

    @model_validator(mode="after")
    def _config_seed(self):
        """A record that lists no seeds has its config's one: that must be a seed too, or each metrics row would be
        blamed for a seed the record lacks."""
        seed = self.config.get("seed", 0)
        if not self.seeds and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
            raise ValueError(f"config.seed, the run's seed where it lists no seeds, should be a whole number from 0 "
                             f"up, not {shown_value(seed)}")
        return self

    @model_validator(mode="after")
    def _config_counts(self):
        """The counts a sweep reads from the config as they are, without the trainer's config class: whether a run
        is finished (the evaluation its last row must reach) and the episodes each of its figures is over."""
        for key, least in (("num_evals", 0), ("eval_envs", 1)):
            value = self.config.get(key, least)
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise ValueError(f"config.{key} should be a whole number from {least} up, not {shown_value(value)}")
        from fieldgen.agents.choices import EVAL_ACTIONS

        actions = self.config.get("eval_actions", EVAL_ACTIONS[0])  # how every figure of the run was judged
        if actions not in EVAL_ACTIONS:
            raise ValueError(f"config.eval_actions should be one of {', '.join(EVAL_ACTIONS)}, not "
                             f"{shown_value(actions)}")
        return self

    @property
    def every_seed(self) -> list[int]:
        """The run's seeds: the list it records, else its config's one seed (0 where it names none)."""
        return self.seeds or [self.config.get("seed", 0)]


# what the metrics that figures are computed over can hold: success is a share of episodes, time at the goal a
# count of steps, a variant's weight its share of new episodes; the timings are drawn, tabled and counted on
# when a run resumes
METRIC_RANGES = {"success_any": (0.0, 1.0), "last_stage_success_any": (0.0, 1.0), "time_at_goal": (0.0, math.inf),
                 "weight": (0.0, 1.0), **dict.fromkeys(TIMINGS, (0.0, math.inf))}


def metric_problem(metric: str, value) -> str | None:
    """What is wrong with `value` as `metric` (None where it can be what it claims, or the metric has no
    range): a figure is computed only over values that pass, and a file holding another is refused."""
    if metric not in METRIC_RANGES:
        return None
    low, high = METRIC_RANGES[metric]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f"{metric} is {shown_text(repr(value))}, not a number"
    if math.isnan(value):
        return f"{metric} is NaN: it was not measured"
    if not (math.isfinite(value) and low <= value <= high):
        span = f"from {low:g} to {high:g}" if math.isfinite(high) else f"a finite number from {low:g} up"
        return f"{metric} is {value!r}, outside its range ({span})"
    return None


class MetricsRow(BaseModel):
    """What a metrics row must hold for a run to go on from it; its other values are only reported, except that
    the metrics of METRIC_RANGES, where present, must lie in their range (in `variants`, NaN where an
    evaluation played no episode of that variant)."""

    model_config = ConfigDict(extra="allow")
    eval: Index
    env_steps: Index
    seed: Index | None = None  # None: left out, which a reader given the run's seeds refuses
    stage: Index = 0
    promoted_to: Index = 0
    # a self-play row's league (games by opponent) and ratings, where present: read as numbers by eval and compare
    league: dict[StrictStr, Games] | None = None
    elo: Rating | None = None
    ratings: dict[StrictStr, Rating] | None = None

    @model_validator(mode="after")
    def _in_range(self):
        extra = self.model_extra or {}
        for metric in METRIC_RANGES.keys() & extra.keys():
            if (said := metric_problem(metric, extra[metric])) is not None:
                raise ValueError(said)
        variants = extra.get("variants")
        for metric in METRIC_RANGES.keys() & (variants.keys() if isinstance(variants, dict) else set()):
            values = variants[metric] if isinstance(variants[metric], list) else [variants[metric]]
            for value in values:
                unmeasured = metric != "weight" and isinstance(value, float) and math.isnan(value)
                if not unmeasured and (said := metric_problem(metric, value)) is not None:
                    raise ValueError(f"variants.{said}")
        return self


def _problems(exc: ValidationError) -> str:
    """pydantic's complaints in the record's words: the key, what it should be and what it holds."""
    errors = exc.errors()
    missing = [".".join(map(str, e["loc"])) for e in errors if e["type"] == "missing"]
    said = [f"it lacks {', '.join(missing)}"] if missing else []
    for e in errors:
        if e["type"] != "missing":
            what = _should(e)
            where = ".".join(shown_text(str(part)) for part in e["loc"])
            said.append(f"{where} {what}, not {shown_value(e['input'])}" if where else what)  # a whole row's check says its key
    return "; ".join(said)


def _should(error: dict) -> str:
    """What a value should be, by one pydantic complaint (not pydantic's "List should have at least 1 item after
    validation, not 0", which reads wrongly after the key and before the value)."""
    if error["type"] in ("too_short", "too_long"):
        short = error["type"] == "too_short"
        bound = error["ctx"]["min_length" if short else "max_length"]
        return f"should hold {'at least' if short else 'at most'} {bound:,} item{'s' * (bound != 1)}"
    return str(error["ctx"]["error"]) if error["type"] == "value_error" else error["msg"].removeprefix("Input ")


def _json_kind(value) -> str:
    """What a parsed JSON value is, in words (a run record must be an object)."""
    if isinstance(value, list):
        return f"a list of {len(value):,} item{'s' * (len(value) != 1)}"
    return {str: "a string", bool: "true or false", type(None): "null"}.get(type(value), "a number")


def read_run(run_dir: Path) -> RunRecord:
    if not run_dir.is_dir():
        what = kind_of_blocker(run_dir) if run_dir.is_symlink() or run_dir.exists() else "missing"
        raise RunError(f"{run_dir} is {what}, not a run folder; name the folder fieldgen train wrote "
                       "(runs/<field>-<algo>-<seed>)")
    try:
        text = (run_dir / RUN).read_bytes()
    except FileNotFoundError:
        other = written_by(run_dir)
        if other is not None and other != RUN_FOLDER.command:  # a policy or a build named where a run goes
            raise RunError(f"{run_dir} was written by {shown_text(other)}, not fieldgen train: it is no training "
                           "run; name the folder fieldgen train wrote (runs/<field>-<algo>-<seed>)") from None
        raise RunError(f"{run_dir} is not a training run: {RUN} is missing; name the folder fieldgen train "
                       "wrote (runs/<field>-<algo>-<seed>); one whose setup was cut short is set up again by the "
                       "same fieldgen train command") from None
    except OSError as exc:  # no permission, a folder in its place
        raise RunError(f"{run_dir / RUN} cannot be read ({exc.strerror}); make it the readable file fieldgen train "
                       "wrote, or name another run folder") from None
    try:
        saved = parsed_json(text)
    except ValueError as exc:
        said = "it is empty" if not text.strip() else f"it is not JSON: {shown_text(str(exc), PARSER_COMPLAINT)}"
        raise RunError(f"{run_dir / RUN} cannot be read as a run record ({said}); it was edited or damaged: "
                       "restore it from a copy, or start the run again in a new folder") from None
    if not isinstance(saved, dict):
        raise RunError(f"{run_dir / RUN} is not a run record: it holds {_json_kind(saved)}, where fieldgen train "
                       "writes one JSON object (algo, config, observation, ...); it was edited or damaged: restore "
                       "it from a copy, or start the run again in a new folder")
    try:
        return RunRecord.model_validate(saved)
    except ValidationError as exc:
        raise RunError(f"{run_dir / RUN} is not a run record: {_problems(exc)} (edited or damaged); "
                       "start the run again in a new folder") from None


def read_metrics(run_dir: Path, seeds: list[int] | None = None) -> list[dict]:
    """The evaluation rows; a torn last line (a write cut short by a kill) is dropped, since the run
    resumes from its checkpoint, which never comes after the last whole row. Given the run's `seeds`, a row of
    another seed is refused as damage: every reader of a run (train, eval, export, compare, a sweep's status)
    passes them, so none judges, resumes or plots rows that are not the run's."""
    path = run_dir / METRICS
    try:
        lines = [(n, line) for n, line in enumerate(path.read_bytes().splitlines(), 1) if line.strip()]
    except FileNotFoundError:
        return []
    except OSError as exc:
        raise RunError(f"{path} cannot be read ({exc.strerror})") from None
    rows, at = [], {}  # (eval, seed) -> its line: a row twice (files joined, a line pasted) would count twice
    for k, (n, line) in enumerate(lines, 1):  # n: the line in the file, blank lines counted, as an editor shows it
        damaged = (f"{path}:{n} is not a metrics row ({{}}); the file was edited or damaged: restore it from a "
                   "copy, or start the run again in a new folder")
        try:
            row = parsed_json(line)
        except ValueError:  # undecodable bytes as well as broken JSON
            if k == len(lines):
                break
            raise RunError(damaged.format("not JSON")) from None
        try:
            MetricsRow.model_validate(row if isinstance(row, dict) else {})
        except ValidationError as exc:
            raise RunError(damaged.format(_problems(exc))) from None
        if seeds is not None and "seed" not in row:
            raise RunError(damaged.format("it lacks seed"))
        if seeds is not None and row["seed"] not in seeds:
            raise RunError(damaged.format(f"its seed {shown_value(row['seed'])} is not one of the run's seeds, "
                                          f"{', '.join(map(str, seeds))}"))
        if (earlier := at.setdefault((row["eval"], row.get("seed")), n)) != n:
            raise RunError(damaged.format(f"evaluation {row['eval']} of seed {row.get('seed')} is at line {earlier} "
                                          "already"))
        rows.append(row)
    _refuse_steps_back(path, rows, at)
    return rows


def _refuse_steps_back(path: Path, rows: list[dict], at: dict) -> None:
    """Refuse a seed whose env steps fall from one evaluation to the next (rows of two runs joined, a number edited):
    a run only ever adds env steps, and its curves and ratios read them as a clock."""
    last: dict = {}  # seed -> (eval, env_steps) of its evaluation before
    for row in sorted(rows, key=lambda r: r["eval"]):
        seed = row.get("seed")
        before = last.get(seed)
        if before is not None and row["env_steps"] < before[1]:
            raise RunError(f"{path}:{at[(row['eval'], seed)]} is not a metrics row (evaluation {row['eval']} of seed "
                           f"{seed} is at {row['env_steps']:,} env steps, fewer than evaluation {before[0]}'s "
                           f"{before[1]:,}); the file was edited or damaged: restore it from a copy, or start the run "
                           "again in a new folder")
        last[seed] = (row["eval"], row["env_steps"])


def write_metrics(run_dir: Path, rows: list[dict]) -> None:
    """metrics.jsonl and metrics.csv with every evaluation so far; both replaced atomically."""
    write_atomic(run_dir / METRICS, "".join(json.dumps(r) + "\n" for r in rows).encode())
    flat = [flat_row(r) for r in rows]
    names = list(dict.fromkeys(k for r in flat for k in r))
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=names)
    writer.writeheader()
    writer.writerows(flat)
    write_atomic(run_dir / CSV, text.getvalue().encode())


def _flat_map(name: str, value) -> dict:
    if not isinstance(value, dict):
        return {name: value}
    return {k: v for key, inner in value.items() for k, v in _flat_map(f"{name}.{key}", inner).items()}


def flat_row(row: dict) -> dict:
    """A row as one CSV line (and as loggers name its numbers): a mixed run's per-variant lists become
    variants.<metric>.<stage from 1>; another map's entries (a self-play run's league and ratings)
    <name>.<key>[.<key>...]."""
    out = {}
    for k, v in row.items():
        if k != "variants":
            out.update(_flat_map(k, v))
    for metric, values in row.get("variants", {}).items():
        out.update({f"variants.{metric}.{k}": v for k, v in enumerate(values, 1)})
    return out


