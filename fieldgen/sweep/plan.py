"""A sweep file, read and checked, and the runs it expands into.

A sweep names fields, algorithms, seeds, fixed config values (`set`) and config axes (`grid`); every
combination of one field, one algorithm, one value of each of that algorithm's axes and one seed is a
run. With `curriculum: auto` each run trains through its field's automatic curriculum, and `sampler.KEY`
in `set` or `grid` sets its level sampler (every algorithm's runs alike). A run is the `fieldgen train` command a user would type, into a folder of the sweep's own. The file is
read as field specs are (fieldgen.schema: YAML with every key's position) and checked by pydantic and
by the trainers' own config classes, so that a wrong key or value is reported at its line before
anything trains.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import os
import shlex
from pathlib import Path
from typing import Annotated, Any, Literal, Union

import yaml
from pydantic import (BaseModel, BeforeValidator, ConfigDict, Field, StrictBool, StrictFloat, StrictInt, StrictStr,
                      ValidationError)

from fieldgen import limits
from fieldgen.agents.registry import ALGORITHMS
from fieldgen.counts import count
from fieldgen.curriculum.section import SAMPLER  # also the prefix of a set or grid key: sampler.replaced
from fieldgen.files import file_in_the_way, kind_of_blocker
from fieldgen.schema import Problem, SpecError, bundled_fields, resolve_spec_path
from fieldgen.schema.messages import problems
from fieldgen.schema.errors import shown_text
from fieldgen.schema.source import Source, read_yaml

BACKENDS = ("local", "slurm")
PLAN = "sweep.json"  # in the sweep's folder: the runs as planned, so that a changed sweep file is noticed


class SweepError(SpecError):
    """A sweep file that cannot be run; one problem reads as one line, with its file, line and key."""

    document = "the sweep file"

    def __str__(self) -> str:
        return str(self.problems[0]) if len(self.problems) == 1 else super().__str__()


def _count(value):
    """A count as `fieldgen train` reads it: 40000, 50M, 1.5k, 2e6."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise ValueError(f"expected a count such as 40000, 50M or 1.5k (got {value!r})")
    return count(value)


Count = Annotated[int, BeforeValidator(_count)]


def within(allowed: limits.Range, strict=StrictInt):
    """A sweep file's number in `allowed`, the same range as the command line's (fieldgen.limits)."""
    return Annotated[strict, Field(ge=allowed.low, le=allowed.high)]


Seed = within(limits.SEED)


class Local(BaseModel):
    """The local backend: which GPUs take a run each ('auto': those CUDA_VISIBLE_DEVICES or nvidia-smi
    lists; an empty list: no GPU, one run at a time)."""

    model_config = ConfigDict(extra="forbid")
    gpus: Union[Literal["auto"], list[within(limits.GPU_INDEX)]] = "auto"


class Slurm(BaseModel):
    """The slurm backend: one array job, each task one run."""

    model_config = ConfigDict(extra="forbid")
    partition: StrictStr | None = None
    time: within(limits.SLURM_MINUTES) = 60  # minutes a task may run before it is stopped and requeued
    gpus_per_task: within(limits.GPUS_PER_TASK) = 1
    cpus_per_task: within(limits.CPUS_PER_TASK) | None = None
    mem_gb: within(limits.MEMORY_GB) | None = None
    # array tasks running at once (default: as the scheduler allows)
    parallel: Annotated[StrictInt, Field(ge=1, le=limits.SWEEP_RUNS)] | None = None
    account: StrictStr | None = None
    qos: StrictStr | None = None
    requeues: within(limits.REQUEUES) = 3  # times a task is requeued after its time limit runs out
    # minutes before `time` at which the run stops at an evaluation, checkpointed, and its task requeues itself
    # (0: the run trains until submitit's signal, and the chunk under way then is lost)
    stop_before: Annotated[Union[StrictInt, StrictFloat], Field(ge=0, le=limits.SLURM_MINUTES.high,
                                                                allow_inf_nan=False)] = 5

    @property
    def run_minutes(self) -> float | None:
        """The `--time-limit` a task gives its run, in minutes (None: none)."""
        return self.time - self.stop_before if self.stop_before else None


class SweepFile(BaseModel):
    """What a sweep file holds."""

    model_config = ConfigDict(extra="forbid")
    fields: Annotated[list[StrictStr], Field(min_length=1)]  # bundled names, YAML files or folders
    algorithms: Annotated[list[Literal[ALGORITHMS]], Field(min_length=1)]
    seeds: Union[within(limits.SEEDS), Annotated[list[Seed], Field(min_length=1)]] = 1  # K: seeds 0..K-1
    steps: Count | None = None
    envs: Count | None = None
    config: StrictStr | None = None  # a config file, as `fieldgen train --config` reads it
    curriculum: Literal["auto"] | None = None  # every run through its field's automatic curriculum
    levels: within(limits.LEVELS) | None = None  # with curriculum: auto, as --levels
    set: dict[StrictStr, Any] = {}  # config values every run of that algorithm gets: crl.batch_size: 256
    grid: dict[StrictStr, Annotated[list, Field(min_length=1)]] = {}  # axes: crl.repr_dim: [32, 64]
    videos: StrictBool = False
    out: Annotated[StrictStr, Field(min_length=1)] | None = None  # the sweep's folder (default runs/sweep-<file name>)
    backend: Literal[BACKENDS] = "local"
    local: Local = Local()
    slurm: Slurm = Slurm()

    @property
    def seed_list(self) -> list[int]:
        return list(range(self.seeds)) if isinstance(self.seeds, int) else list(self.seeds)


@dataclasses.dataclass(frozen=True)
class PlannedRun:
    """One run of a sweep: where it trains, and the commands that start it and that continue it."""

    id: str  # its folder inside the sweep's: [<point>/]<field>-<algo>-<seed>
    folder: Path
    field: str  # the field's name, as its run folder and the summary name it
    algo: str
    seed: int
    point: dict  # this run's values of its algorithm's grid axes
    start: tuple[str, ...]  # fieldgen train ... (without the leading "fieldgen")
    videos: bool

    @property
    def resume(self) -> tuple[str, ...]:
        return ("train", "--resume", str(self.folder), "--videos" if self.videos else "--no-videos")

    @property
    def label(self) -> str:
        """The run's settings apart from its field and seed: the algorithm and its axes' values."""
        return " ".join([self.algo, *(f"{k}={_shown(v)}" for k, v in self.point.items())])

    def command(self) -> tuple[str, ...]:
        """What to run now: the run continued where its folder holds one, else started."""
        return self.resume if (self.folder / "run.json").is_file() else self.start


@dataclasses.dataclass(frozen=True)
class Sweep:
    path: Path
    spec: SweepFile
    folder: Path
    runs: list[PlannedRun]


def _shown(value) -> str:
    """A config value as `--set` takes it: text as it is where YAML reads it back the same, else JSON."""
    if isinstance(value, str) and yaml.safe_load(value) == value:
        return value
    return json.dumps(value, separators=(",", ":"))


def shell(words: tuple[str, ...]) -> str:
    return shlex.join(["fieldgen", *words])


def load(path: Path, out: Path | None = None, **overrides) -> Sweep:
    """The sweep in `path`, its runs planned; `overrides` (backend, slurm settings) replace the file's.
    Raises SweepError with every problem found."""
    try:
        source = read_yaml(path, "a sweep file", "a sweep needs at least 'fields:' and 'algorithms:'")
    except SweepError:
        raise
    except SpecError as exc:
        raise SweepError(exc.problems) from None
    data = dict(source.data)
    slurm = {k: v for k, v in overrides.items() if k != "backend" and v is not None}
    if slurm:
        data["slurm"] = {**(data.get("slurm") or {}), **slurm}
    if overrides.get("backend") is not None:
        data["backend"] = overrides["backend"]
    try:
        spec = SweepFile.model_validate(data)
    except ValidationError as exc:
        raise SweepError(problems(source, exc.errors(), SweepFile)) from None
    found: list[Problem] = []
    read: list = []  # each field's spec as _field_names read it (None: a curriculum folder)
    names = _field_names(path, spec, source, found, read)
    config = None if spec.config is None else _relative(path, spec.config)
    if config is not None and not config.is_file():
        found.append(source.problem(("config",), f"there is no file {config}"))
    elif config is not None:
        _config_file(config, spec, source, found)
    _assignments(spec, source, found)
    _set_or_grid(spec, source, found)
    _each_once(spec, names, source, found)
    if spec.levels is not None and spec.curriculum is None:
        found.append(source.problem(("levels",), f"{spec.levels} levels of the automatic curriculum: add "
                                                 "curriculum: auto to the sweep"))
    if spec.backend == "slurm" and spec.slurm.stop_before >= spec.slurm.time:
        given = "stop_before" in ((source.data.get("slurm") or {}) if isinstance(source.data, dict) else {})
        before = f"{spec.slurm.stop_before:g} minutes{'' if given else ' (its default)'}"
        task = (f"--time {spec.slurm.time}" if overrides.get("time") is not None else "slurm.time")
        found.append(source.problem(("slurm", "stop_before"), f"{before} before the end of a task of "
                                    f"{spec.slurm.time} minutes ({task}) leaves its run no time to train: give "
                                    f"{task.replace(' ' + str(spec.slurm.time), '')} more minutes than "
                                    f"{spec.slurm.stop_before:g}, or a smaller slurm.stop_before (0 lets the run "
                                    "train until submitit's signal)"))
    if not found:
        _few_enough(spec, source, found)
    if not found:
        _budgets(path, spec, config, names, read, source, found)
    if found:
        raise SweepError(found)
    folder = (Path(spec.out) if out is None and spec.out else out or Path("runs") / f"sweep-{path.stem}").absolute()
    blocker = file_in_the_way(folder)  # said here, once, rather than as a plan in the folder that cannot be read
    if blocker is not None:
        said = (f"is {kind_of_blocker(blocker)}, not a folder, where the sweep's folder {folder} goes; move it "
                "aside or choose another")
        if out is None and spec.out:
            raise SweepError([source.problem(("out",), f"{blocker} {said} out:")])
        raise SweepError([Problem(blocker, None, None, "", f"{said} --out")])
    runs = []
    for ref, name in zip(spec.fields, names):
        field_arg = ref if ref in bundled_fields() and "/" not in ref else str(_relative(path, ref).resolve())
        for algo in spec.algorithms:
            for fixed, point in _points(spec, (algo, SAMPLER)):
                where = folder / _point_folder(point) if point else folder
                for seed in spec.seed_list:
                    run_folder = where / f"{_auto_label(name) if spec.curriculum else name}-{algo}-{seed}"
                    start = ("train", field_arg, "--algo", algo, "--seed", str(seed), "--out", str(where),
                             *(("--curriculum", spec.curriculum) if spec.curriculum else ()),
                             *(("--levels", str(spec.levels)) if spec.levels else ()),
                             *(("--steps", str(spec.steps)) if spec.steps else ()),
                             *(("--envs", str(spec.envs)) if spec.envs else ()),
                             *(("--config", str(config.resolve())) if config else ()),
                             *_options({**fixed, **point}),
                             "--videos" if spec.videos else "--no-videos")
                    runs.append(PlannedRun(str(run_folder.relative_to(folder)), run_folder, name, algo, seed, point,
                                           start, spec.videos))
    if (too_long := _names_too_long(runs, folder, source)) is not None:
        raise SweepError([too_long])
    return Sweep(path, spec, folder, runs)


def _points(spec: SweepFile, sections: tuple[str, ...]):
    """Each grid point over the `grid` keys of `sections` (an algorithm's, the sampler's), with the `set` values of
    those sections that go with every point: ({key: value} fixed, {key: value} point)."""
    axes = {k: v for k, v in spec.grid.items() if k.partition(".")[0] in sections}
    fixed = {k: v for k, v in spec.set.items() if k.partition(".")[0] in sections}
    for values in itertools.product(*axes.values()):
        yield fixed, dict(zip(axes, values))


def _names_too_long(runs: list[PlannedRun], folder: Path, source: Source) -> Problem | None:
    """A problem at `grid` where a run's folder or log would get a name longer than a file system allows: a grid
    point's folder is named after each of its axes and values, so a grid of many axes names folders no run can be
    set up in, found otherwise once the sweep has started."""
    from fieldgen.sweep.launch import log_path

    for run in runs:
        names = [*run.folder.relative_to(folder).parts, log_path(folder, run, ".started").name]  # its longest log
        longest = max(len(os.fsencode(name)) for name in names)
        if longest > limits.NAME_BYTES:
            return source.problem(("grid",), f"names a folder or log of run {shown_text(run.id, 60)} with "
                                             f"{longest:,} bytes, and a file system holds names of at most "
                                             f"{limits.NAME_BYTES}: vary fewer keys in grid (a key of one value goes "
                                             "in set:), or shorter values")
    return None


def _options(values: dict) -> list[str]:
    """`fieldgen train`'s options for a run's config values (--set ALGO.KEY=V) and sampler settings
    (--sampler KEY=V)."""
    words = []
    for key, value in values.items():
        section, _, name = key.partition(".")
        words += ["--sampler", f"{name}={_shown(value)}"] if section == SAMPLER else ["--set", f"{key}={_shown(value)}"]
    return words


def _auto_label(name: str) -> str:
    from fieldgen.curriculum.auto import run_label

    return run_label(name)


def _relative(path: Path, ref: str) -> Path:
    """A path in a sweep file, read relative to the file (a bundled field name stays a name)."""
    return resolve_spec_path(ref, relative_to=path)


def _point_folder(point: dict) -> str:
    """A folder name for one point of the grid: its axes and values, with nothing a path cannot hold."""
    text = ",".join(f"{k}={_shown(v)}" for k, v in point.items())
    return "".join(c if c.isalnum() or c in "._=,+-" else "_" for c in text)


def _field_names(path: Path, spec: SweepFile, source: Source, found: list[Problem], read: list) -> list[str]:
    """Each field's name, which names its runs' folders: a spec's `name`, a build folder's, a curriculum
    folder's own name; each field's spec goes into `read` (None for a curriculum folder)."""
    from fieldgen import curriculum
    from fieldgen.compile.artifact import ArtifactError, load_artifact
    from fieldgen.schema import load_spec

    names = []
    for i, ref in enumerate(spec.fields):
        target = _relative(path, ref)
        try:
            if target.is_dir():
                field = None if curriculum.is_curriculum(target) else load_artifact(target).spec
                names.append(target.name if field is None else field.name)
                read.append(field)
            elif target.is_file():
                field = load_spec(target)
                names.append(field.name)
                read.append(field)
            else:
                field = None
                found.append(source.problem(("fields", i), f"'{ref}' is neither a file nor a folder nor a bundled "
                                                           f"field ({', '.join(bundled_fields())})"))
            if field is not None and field.teams is not None:
                _self_play_algorithms(ref, spec, source, ("fields", i), found)
        except (SpecError, ArtifactError) as exc:
            found.append(source.problem(("fields", i), f"'{ref}' cannot be read: {exc}".replace("\n", " ")))
    return names


def _self_play_algorithms(ref: str, spec: SweepFile, source: Source, where: tuple, found: list[Problem]) -> None:
    """A team field trains by self-play alone, whose learner is one algorithm: a sweep listing another would plan
    runs that each refuse at their start."""
    from fieldgen.agents.selfplay import SelfPlayConfig

    others = [algo for algo in spec.algorithms if algo != SelfPlayConfig.algo]
    if others:
        found.append(source.problem(where, f"'{ref}' is a team field: it trains by self-play, whose learner is "
                                           f"{SelfPlayConfig.algo}, and the sweep's algorithms list "
                                           f"{', '.join(others)}; sweep team fields in a file of their own with "
                                           f"algorithms: [{SelfPlayConfig.algo}]"))


def _few_enough(spec: SweepFile, source: Source, found: list[Problem]) -> None:
    """Refuse a sweep of more than SWEEP_RUNS runs, counted from its lists before a run is planned (a plan of a
    million runs would take gigabytes before its first line)."""
    planned = 0
    for algo in spec.algorithms:
        points = 1
        for key, values in spec.grid.items():
            points *= len(values) if key.partition(".")[0] in (algo, SAMPLER) else 1
        planned += points
    planned *= len(spec.fields) * (spec.seeds if isinstance(spec.seeds, int) else len(spec.seeds))
    if planned > limits.SWEEP_RUNS:
        found.append(source.problem((), f"plans {planned:,} runs (fields x algorithms x grid points x seeds); a sweep "
                                         f"runs at most {limits.SWEEP_RUNS:,}: split it into several sweep files, "
                                         "or list fewer values"))


def _budgets(path: Path, spec: SweepFile, config: Path | None, names: list[str], read: list, source: Source,
             found: list[Problem]) -> None:
    """Each run's env steps checked as its config will hold them (the field's recipe, the config file, `set` and
    its grid point, `steps` and `envs`), before any run starts: too few for its evaluations fails every run at its
    start, on a cluster after its wait in the queue. A team field's runs are self-play's to check."""
    from fieldgen.agents.config import SWEEP_FILE, ConfigError
    from fieldgen.run import recipe as recipes
    from fieldgen.run.session import field_spec

    for i, (ref, name, field) in enumerate(zip(spec.fields, names, read)):
        target = _relative(path, ref)
        field = field or field_spec(target)  # a curriculum folder: its first stage
        if field.teams is not None:
            continue
        for algo in spec.algorithms:
            chosen = recipes.choose(target, algo)
            for fixed, point in _points(spec, (algo,)):
                sets = [f"{k}={_shown(v)}" for k, v in {**fixed, **point}.items()]
                try:
                    recipes.new_run_config(chosen, field.agent.kind, config, sets, None, total_steps=spec.steps,
                                           num_envs=spec.envs).validate_budget(SWEEP_FILE)
                except ConfigError as exc:
                    at = "".join(f", {k}={_shown(v)}" for k, v in point.items())
                    where = ("steps",) if spec.steps is not None else ("fields", i)
                    found.append(source.problem(where, f"the {algo} runs on {name}{at} would stop at their start: "
                                                       f"{exc}"))
                    break


def _each_once(spec: SweepFile, names: list[str], source: Source, found: list[Problem]) -> None:
    """Refuse a sweep that would plan one run twice (a seed, an algorithm or a grid value listed twice, or two
    fields of one name, whose runs share folders): trained twice, or counted twice in a summary, it would weigh
    as two seeds; and one that lists a GPU twice, which would put two runs on it at a time."""
    twice = "the same run is planned twice"
    lists = [(("seeds",), spec.seed_list if isinstance(spec.seeds, list) else [], "seed", twice),
             (("algorithms",), spec.algorithms, "algorithm", twice),
             (("local", "gpus"), spec.local.gpus if isinstance(spec.local.gpus, list) else [], "GPU",
              "two runs at a time share that GPU"),
             *((("grid", key), [_shown(v) for v in values], "value", twice) for key, values in spec.grid.items())]
    for where, values, what, otherwise in lists:
        seen: dict = {}
        for i, value in enumerate(values):
            if value in seen:
                found.append(source.problem((*where, i), f"{what} {value} is listed twice (items {seen[value]} and "
                                                         f"{i}); list each once, or {otherwise}"))
                break
            seen[value] = i
    first: dict[str, int] = {}
    for i, name in enumerate(names if len(names) == len(spec.fields) else []):  # else a field is refused already
        if name in first:
            found.append(source.problem(("fields", i), f"'{spec.fields[i]}' is the field {name}, as "
                                                       f"'{spec.fields[first[name]]}' (fields[{first[name]}]) is: "
                                                       "their runs would share folders and a summary; give one "
                                                       "another name, or list it once"))
        first.setdefault(name, i)


def _set_or_grid(spec: SweepFile, source: Source, found: list[Problem]) -> None:
    """Refuse a `set` key that `grid` varies too: every run takes the grid's value, so the fixed one would be
    planned into no run, silently."""
    for key in (k for k in spec.set if k in spec.grid):
        found.append(source.problem(("set", key), f"grid varies {key} too, so every run would take the grid's value, "
                                                  "never this one: keep the key in set or in grid, not both"))


def _config_file(config: Path, spec: SweepFile, source: Source, found: list[Problem]) -> None:
    """Read the config file as each algorithm's runs will (`fieldgen train --config`), so that a file every run
    would refuse is refused before any starts."""
    from fieldgen.agents import registry
    from fieldgen.agents.config import ConfigError
    from fieldgen.curriculum.auto import Sampler, unread
    from fieldgen.curriculum.levels import LevelError

    for algo in spec.algorithms:
        try:
            registry.trainer(algo).config.layered(config)
        except ConfigError as exc:
            found.append(source.problem(("config",), f"the {algo} runs read it with --config and would stop: {exc}"))
            return
    try:
        read = read_yaml(config, "a config file", "a config file holds a section per algorithm, such as 'crl:'")
        if spec.curriculum is None and (said := unread(read, "this sweep makes none (add curriculum: auto)")):
            found.append(source.problem(("config",), said))
        else:
            Sampler.configured(read)
    except (SpecError, LevelError) as exc:
        found.append(source.problem(("config",), f"the runs read it with --config and would stop: {exc}"))


def _assignments(spec: SweepFile, source: Source, found: list[Problem]) -> None:
    """Check every `set` and `grid` value with its algorithm's config class, as `--set` would be, and every
    `sampler.KEY` with the automatic curriculum's sampler, as `--sampler` would be."""
    from fieldgen.agents import registry
    from fieldgen.agents.config import ConfigError
    from fieldgen.curriculum.auto import Sampler
    from fieldgen.curriculum.levels import LevelError

    listed = ", ".join(spec.algorithms)
    for section, values in (("set", {k: [v] for k, v in spec.set.items()}), ("grid", spec.grid)):
        for key, choices in values.items():
            algo, dot, name = key.partition(".")
            if not dot or not name:
                found.append(source.problem((section, key), f"write the key as ALGO.KEY, such as crl.repr_dim, "
                                                            f"or sampler.KEY (got {key!r})"))
                continue
            if algo == SAMPLER:
                if spec.curriculum != "auto":
                    found.append(source.problem((section, key), "sets the automatic curriculum's level sampler; "
                                                                "add curriculum: auto to the sweep"))
                    continue
                for value in choices:
                    try:
                        Sampler.of([f"{name}={_shown(value)}"], where="sampler:")
                    except LevelError as exc:
                        found.append(source.problem((section, key), str(exc).removeprefix("sampler: ")))
                        break
                continue
            if algo not in spec.algorithms:
                found.append(source.problem((section, key), f"'{algo}' is not among the sweep's algorithms "
                                                            f"({listed}); its keys apply to those runs alone"))
                continue
            config = registry.trainer(algo).config
            read: list = []  # each value as the trainer reads it: 4 and "4" plan one run twice in two folders
            for i, value in enumerate(choices):
                item = f"{key}={_shown(value)}"
                try:
                    setting = getattr(config.layered(sets=[item]), key.partition(".")[2])
                except ConfigError as exc:
                    found.append(source.problem((section, key), str(exc).removeprefix(f"--set {item}: ")))
                    break
                # the same as written is _each_once's to say; the same as read, written otherwise, is said here
                if section == "grid" and setting in read and _shown(value) not in map(_shown, choices[:i]):
                    found.append(source.problem((section, key, i), f"{_shown(value)} sets what item "
                                                                  f"{read.index(setting)} sets ({setting!r}): the same "
                                                                  "run is planned twice; list each value once"))
                    break
                read.append(setting)


class PlanRecord(BaseModel):
    """What sweep.json holds (launch.record_plan writes it): the sweep file, each run's command as it was first
    started, and (slurm) each run's job id."""

    model_config = ConfigDict(extra="forbid")
    file: StrictStr
    backend: StrictStr
    runs: dict[StrictStr, Annotated[list[StrictStr], Field(min_length=1)]] = {}
    jobs: dict[StrictStr, StrictStr] = {}


MAX_PLAN_BYTES = 64 * 2**20  # a command line per run, at most limits' run count: megabytes at most


def read_plan(folder: Path) -> PlanRecord | None:
    """The sweep's record of its runs, None where there is none yet; SweepError naming the file and what is wrong
    where it was edited or damaged, as nothing in it can then be trusted to say how its runs were started."""
    path = folder / PLAN
    aside = "move it aside to plan the sweep anew (runs already started keep their own settings)"
    try:
        if path.stat().st_size > MAX_PLAN_BYTES:
            raise SweepError([Problem(path, None, None, "", f"has {path.stat().st_size:,} bytes, more than a sweep's "
                                                            f"plan ever holds ({MAX_PLAN_BYTES:,}); {aside}")])
        return PlanRecord.model_validate_json(path.read_bytes())
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise SweepError([Problem(path, None, None, "", f"cannot be read ({exc.strerror}); {aside}")]) from None
    except ValidationError as exc:
        error = exc.errors()[0]
        where = ".".join(shown_text(str(part)) for part in error["loc"])
        said = f"{where}: {error['msg']}" if where else error["msg"]
        raise SweepError([Problem(path, None, None, "", f"is not a plan fieldgen sweep wrote ({said}; edited or "
                                                        f"damaged); {aside}")]) from None


def _another_file(recorded: str, path: Path) -> bool:
    """Whether the sweep file a plan records is another one that is still there (a file moved since is this one)."""
    try:
        other = Path(recorded)
        return other.is_file() and not other.samefile(path)
    except (OSError, ValueError):  # a name the system refuses: no file of the user's
        return False


def _same_start(recorded: list[str], planned: tuple[str, ...], folder: Path) -> bool:
    """Whether a run was started as the plan would start it now, the sweep's folder moved since allowed for: its
    `--out` then names the old folder, the same grid point's folder under it."""
    if len(recorded) != len(planned):
        return False
    for i, (was, now) in enumerate(zip(recorded, planned)):
        if was == now or _same_file(was, now):
            continue
        if i == 0 or planned[i - 1] != "--out" or recorded[i - 1] != "--out":
            return False
        try:
            inside = Path(now).relative_to(folder).parts
        except ValueError:
            return False
        if inside and Path(was).parts[-len(inside):] != inside:
            return False
    return True


def _same_file(was: str, now: str) -> bool:
    """Whether two words of a command name one file: plans before paths were resolved kept `sweeps/../fields`."""
    if "/" not in was or "/" not in now:
        return False
    try:
        return Path(was).resolve() == Path(now).resolve()
    except (OSError, RuntimeError, ValueError):
        return False


def check_plan(sweep: Sweep) -> None:
    """Refuse to go on in a folder whose runs were planned otherwise (the sweep file edited since): a run
    would resume with the settings it started with, not those the file now gives."""
    recorded = read_plan(sweep.folder)
    if recorded is None:
        return
    if _another_file(recorded.file, sweep.path):
        raise SweepError([Problem(sweep.path, None, None, "", f"{sweep.folder} holds the sweep of {recorded.file}, "
                                  "another sweep file (two files of one name take the same default folder): the two "
                                  "would share its logs and replace each other's summary; give this sweep a folder "
                                  "of its own (out: in the file, or --out)")])
    before = recorded.runs
    for run in sweep.runs:
        if run.id in before and not _same_start(before[run.id], run.start, sweep.folder) and \
                (run.folder / "run.json").is_file():
            raise SweepError([Problem(sweep.path, None, None, "", f"{run.folder} was started as `{shell(before[run.id])}`, "
                                      f"the sweep file now plans `{shell(run.start)}`; give the sweep another "
                                      "out: folder, or move that run aside")])
