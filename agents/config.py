"""What every trainer's settings share, and the settings several trainers share; each algorithm's own
model is its folder's config.py (agents/<algo>/config.py), built from the types and checks here.

A config is layered (`RunConfig.layered`): defaults < the bundled preset for the field's kind
of agent (presets/<algo>_<agent>.yaml) < the field's recipe (presets/recipes.yaml, agents/recipes.py)
< a named preset (`--preset cpu`: presets/cpu.yaml, a
section per algorithm) < a config file ({algo: {key: value}}) < `--set algo.key=value` < explicit options, each value checked by pydantic as it comes in, so
that a bad one is reported where it was written. `validate_env` holds what only the
environment can tell (its episode length, its actuators, its success), so that a run fails
in a sentence before it compiles rather than in a traceback after. Configs are frozen, hence
hashable: trainers close over them inside jitted code.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Annotated, ClassVar, Literal, Sequence

import yaml
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, StrictBool, ValidationError

from ..env.contract import Environment
from ..counts import count
from ..curriculum.section import SAMPLER
from ..limits import COUNT_MAX, MAX_SEEDS, SEED_MAX, not_boolean
from ..schema.errors import shown_text, shown_value
from ..schema.source import SpecLoader
from ..suggest import allowed, did_you_mean
from .buffer import gradient_steps, iterations
from .choices import ALGORITHMS, EVAL_ACTIONS, PRESETS as NAMED_PRESETS
from .recipes import Recipe
from .sharding import by_seed

PRESETS = Path(__file__).with_name("presets")
COUNTER_MAX = 2**31 - 1  # env steps are counted on the device in int32, up to the last iteration's end


@dataclasses.dataclass(frozen=True)
class Wording:
    """How a budget's message names what the user changes: flags on the command line, keys in a sweep file."""

    steps: str = "--steps"
    envs: str = "--envs {}"
    setting: str = "--set {}={}"


COMMAND_LINE = Wording()
SWEEP_FILE = Wording(steps="steps:", envs="envs: {}", setting="set: {{{}: {}}}")
REWARDS = ("dense", "sparse")


class ConfigError(Exception):
    """Training settings that cannot work: an unknown key or value, or one the environment rules out."""


@dataclasses.dataclass(frozen=True)
class Unknown:
    """How a choice reports a value outside it: `message` with the value in place of {}."""

    message: str


def _listed(value):
    """`hidden: 64` is one layer of 64."""
    return value if isinstance(value, (list, tuple)) else [value]


def _count_text(value):
    """A count written as the command line takes one (50M, 1.5k, 2e6: fieldgen.counts) is that count, so a
    config file, --set and a recipe read counts as --steps does; a number stays as it is. Text with a comma is
    left to be refused: `64,64` is two layer widths written without brackets, not 6,464."""
    return count(value) if isinstance(value, str) and "," not in value else value


# a whole number as large as a count on the command line at most: a larger one is a typo, and past a machine
# integer it would end in an OverflowError where it first sizes an array
Int = Annotated[int, BeforeValidator(not_boolean), Field(ge=-COUNT_MAX, le=COUNT_MAX)]
Count = Annotated[Int, Field(gt=0), BeforeValidator(_count_text)]  # how many of something: at least one
Steps = Annotated[Int, Field(ge=0), BeforeValidator(_count_text)]  # env steps where something changes; 0: from the start
Float = Annotated[float, BeforeValidator(not_boolean), Field(allow_inf_nan=False)]
Rate = Annotated[Float, Field(gt=0)]  # a learning rate, a step size, a scale
Share = Annotated[Float, Field(ge=0, le=1)]
Discount = Annotated[Float, Field(gt=0, lt=1)]
Hidden = Annotated[tuple[Count, ...], BeforeValidator(_listed), Field(min_length=1)]
Reward = Annotated[Literal[REWARDS], Unknown(
    "unknown reward '{}'; choose dense (the field's terms) or sparse (its success)")]
EvalActions = Annotated[Literal[EVAL_ACTIONS], Unknown(
    f"unknown eval_actions '{{}}'; choose one of {', '.join(EVAL_ACTIONS)}")]


class RunConfig(BaseModel):
    """What every trainer is told: how long and how wide to train, how often to judge, its seed."""

    model_config = ConfigDict(frozen=True, extra="forbid")
    algo: ClassVar[str]  # the trainer's name: its section of a config file and its --set prefix

    total_steps: Count = 10_000_000
    num_envs: Count = 1024
    unroll_length: Count = 62  # env steps per environment between updates
    num_evals: Count = 10
    eval_envs: Count = 128
    # how the evaluations during training act (success.png, metrics, promotions), and fieldgen eval by default
    eval_actions: EvalActions = "mean"
    # each environment's first episode cut to a length drawn evenly from 1 to a whole one's, so that episodes
    # end spread over time rather than all at once (a curriculum's counts then arrive steadily): first_states
    stagger_starts: bool = False
    seed: Annotated[Int, Field(ge=0, le=SEED_MAX)] = 0

    @classmethod
    def preset(cls, agent: str | None) -> Path | None:
        """The bundled settings of this trainer for fields of this kind of agent (ant, point), if any."""
        path = PRESETS / f"{cls.algo}_{agent}.yaml"
        return path if agent and path.is_file() else None

    @classmethod
    def named_preset(cls, name: str | None) -> Path | None:
        """A bundled preset by its name (choices.PRESETS): settings sized for a kind of machine, for every
        trainer, layered over the agent's preset."""
        if name is not None and name not in NAMED_PRESETS:
            raise ConfigError(f"unknown preset '{name}'{did_you_mean(name, NAMED_PRESETS) or '.'} "
                              f"Presets: {', '.join(NAMED_PRESETS)}.")
        return None if name is None else PRESETS / f"{name}.yaml"

    @classmethod
    def layered(cls, file: Path | None = None, sets: Sequence[str] = (), others: tuple[str, ...] = (),
                agent: str | None = None, preset: str | None = None, recipe: Recipe | None = None,
                **options) -> RunConfig:
        """Defaults < the preset for `agent` < the field's `recipe` < the named `preset` < config file
        ({algo: {key: value}}) < --set algo.key=value < options (None: not given).

        Sections and --set items of the algorithms in `others` (those compared beside this one) are skipped;
        a named preset holds a section for every algorithm."""
        values = {}
        everyone = tuple(a for a in ALGORITHMS if a != cls.algo)
        values.update(cls._section_values(cls.preset(agent), others))
        if recipe is not None:
            values.update(cls._assigned(recipe.assignments(), others, f"{recipe.where}: recipe '{recipe.field}': "))
        for source, skipped in ((cls.named_preset(preset), everyone), (file, others)):
            values.update(cls._section_values(source, skipped))
        values.update(cls._assigned(sets, others, "--set "))
        values.update({key: cls._checked(key, value, key) for key, value in options.items() if value is not None})
        return cls(**values)

    @classmethod
    def _section_values(cls, source: Path | None, skipped: tuple[str, ...]) -> dict:
        """This algorithm's keys in a preset or config file, each checked at its line."""
        section, lines, written = cls._section(source, skipped)
        for key in section:
            cls._not_seed(key, f"{source}:{lines[key]}" if key in lines else f"{source}")
        return {key: cls._checked(key, value, f"{source}:{lines[key]}" if key in lines else f"{source}",
                                  written.get(key)) for key, value in section.items()}  # merged in: no line

    @classmethod
    def _assigned(cls, items: Sequence[str], others: tuple[str, ...], source: str) -> dict:
        """ALGO.KEY=VALUE items (--set's, a recipe's), each checked; `source` says where each was written. A key
        given again overrides the earlier one, as a script's own --set after its defaults does."""
        values = {}
        for item in items:
            name, sep, raw = item.partition("=")
            section, dot, key = name.partition(".")
            if section in others:
                continue
            if sep and dot and section in ALGORITHMS and section != cls.algo:
                raise ConfigError(f"{source}{shown_text(item, quoted=True)}: {section}.* sets {section}'s settings, "
                                  f"and this run trains {cls.algo}; write {cls.algo}.KEY=VALUE (e.g. "
                                  f"{cls.example()}), or train {section} with --algo {section}")
            if not sep or not dot or section != cls.algo:
                raise ConfigError(f"{source}{shown_text(item, quoted=True)}: write {cls.algo}.KEY=VALUE, e.g. "
                                  f"{cls.example()}")
            cls._not_seed(key, f"{source}{shown_text(item)}", raw.strip())
            try:
                value = yaml.load(raw, Loader=SpecLoader)  # as a file's values are read: numbers bounded in digits
            except yaml.YAMLError as exc:
                said = f": {exc.problem}" if isinstance(exc, yaml.constructor.ConstructorError) else ""
                raise ConfigError(f"{source}{shown_text(item)}: {shown_text(repr(raw))} is not a YAML value{said}") \
                    from None
            values[key] = cls._checked(key, value, f"{source}{shown_text(item)}", raw.strip())
        return values

    @classmethod
    def _not_seed(cls, key: str, where: str, written: str = "N") -> None:
        """A run's seed is the command line's (--seed, and --seeds for several), which every command passes: set
        in a config file or by --set it would be overridden without a word, so it is refused where it is written."""
        if key == "seed":
            shown = written if written.isdigit() and len(written) < 11 and int(written) <= SEED_MAX else "N"
            raise ConfigError(f"{where}: {cls.algo}.seed is set on the command line, not here: --seed "
                              f"{shown} (--seeds K trains K seeds from it); a sweep lists its seeds "
                              "under `seeds:`")

    @classmethod
    def example(cls) -> str:
        """A --set assignment this trainer takes: its own first key (not one every trainer shares), at its default."""
        key = next((k for k in cls.model_fields if k not in RunConfig.model_fields), "num_envs")
        default = cls.model_fields[key].default
        value = json.dumps(list(default) if isinstance(default, tuple) else default, separators=(",", ":"))
        return f"{cls.algo}.{key}={value}"

    @classmethod
    def _section(cls, file: Path | None, others: tuple[str, ...]) -> tuple[dict, dict[str, int], dict[str, str]]:
        """This algorithm's keys in a config file, the line of each, and each single value as it is written there;
        a file with any other section is refused but the automatic curriculum's `sampler:`, whose reader is
        `fieldgen train --curriculum auto` (curriculum.auto.Sampler.configured)."""
        if file is None:
            return {}, {}, {}
        try:
            text = file.read_text()
            loaded = yaml.safe_load(text) or {}
        except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
            raise ConfigError(f"cannot read config file {file}: {exc}") from None
        section = (loaded.get(cls.algo) or {}) if isinstance(loaded, dict) else None
        sections = ", ".join(f"'{a}:'" for a in (cls.algo, *others))
        what = f"sections {sections}" if others else f"one section, {sections},"
        if not isinstance(loaded, dict):
            raise ConfigError(f"{file}: a config file is a mapping with {what} of config keys")
        root = yaml.compose(text, Loader=yaml.SafeLoader)
        lines = {key.value: key.start_mark.line + 1 for key, _ in root.value}
        stray = next((key for key in loaded if key not in (cls.algo, *others, SAMPLER)), None)
        if stray is not None:
            near = did_you_mean(str(stray), (cls.algo,))
            hint = (f"; it sets {stray}'s settings and this run trains {cls.algo} (train {stray} with --algo "
                    f"{stray})" if stray in ALGORITHMS else f" ({near[2:]})" if near else "")
            raise ConfigError(f"{file}:{lines.get(stray, '?')}: section '{stray}:' is not read by this run"
                              f"{hint}; a config file is a mapping with {what} of config keys (and '{SAMPLER}:', the "
                              "level sampler's, with --curriculum auto)")
        if not isinstance(section, dict):
            key, value = cls.example().split(".", 1)[1].split("=", 1)
            raise ConfigError(f"{file}:{lines.get(cls.algo, '?')}: '{cls.algo}:' holds {shown_value(section)} where "
                              f"its config keys go, one a line and indented below it, e.g. '  {key}: {value}'")
        body = next(value for key, value in root.value if key.value == cls.algo) if section else None
        pairs = getattr(body, "value", [])
        return (section, {key.value: key.start_mark.line + 1 for key, _ in pairs},
                {key.value: node.value for key, node in pairs if isinstance(node, yaml.ScalarNode)})

    @classmethod
    def read_elsewhere(cls, key: str) -> str | None:
        """Which runs read `key`, a key this config does not have but one that extends it does (the refusal
        then says so rather than that the key is unknown); None otherwise."""
        return None

    @classmethod
    def _checked(cls, key: str, value, where: str, written: str | None = None):
        """`value` as the field `key` holds it; a ConfigError that says `where` it came from if it cannot be,
        quoting a number past a float's range as it was `written` (1e400), not as Python reads it (inf)."""
        fields = cls.model_fields
        if key not in fields:
            reader = cls.read_elsewhere(key)
            if reader is not None:
                raise ConfigError(f"{where}: {cls.algo}.{key} is a setting of {reader}; this run does not read it: "
                                  "leave it out")
            raise ConfigError(f"{where}: unknown config key {shown_text(str(key), quoted=True)}"
                              f"{did_you_mean(key, fields) or '.'} "
                              f"Keys: {', '.join(fields)}.")
        try:
            return getattr(cls.model_validate({key: value}), key)
        except ValidationError as exc:
            if exc.errors()[0]["type"] == "literal_error":
                unknown = next(m for m in fields[key].metadata if isinstance(m, Unknown))
                said = shown_text(value) if isinstance(value, str) else shown_value(value)
                raise ConfigError(f"{where}: {unknown.message.format(said)}") from None
            listed = f"; write it as a list, [{value}]" if isinstance(value, str) and "," in value else ""
            past = isinstance(value, float) and math.isinf(value) and written is not None
            # YAML's null (crl.x=, `x:` with nothing after it, ~) is said as left empty: Python's None was not written
            shown = "left empty" if value is None else shown_text(written) if past else shown_value(value)
            raise ConfigError(f"{where}: {cls.algo}.{key} {allowed(exc.errors()[0], fields[key])}, "
                              f"not {shown}{listed}") from None

    def validate_budget(self, words: Wording = COMMAND_LINE) -> None:
        """Problems of the env steps asked for that the config alone shows, no field needed: a sweep's plan
        checks each run's before any starts (a run queued for hours on a cluster would fail at once). Its
        messages name what to change in `words`: the command line's flags, or a sweep file's keys."""
        if self.total_steps + self.per_iteration > COUNTER_MAX:
            raise ConfigError(f"{words.steps} {self.total_steps:,} with {self.num_envs:,} envs x unroll "
                              f"{self.unroll_length:,} per iteration: a run counts its env steps in 32-bit "
                              f"integers, which reach {COUNTER_MAX:,}; train fewer steps or use fewer envs")

    def validate_env(self, env: Environment, devices: int = 1, seeds: int = 1) -> None:
        """Problems a run would hit after compiling, reported before. `seeds` trained at once on `devices`
        devices (every process's, in a run over several) split by seed when they can, and otherwise split
        each seed's environments."""
        self.validate_budget()
        if seeds > MAX_SEEDS:
            raise ConfigError(f"--seeds {seeds:,}: at most {MAX_SEEDS:,} seeds train at once, each a whole run; "
                              "train them in several runs")
        if self.seed + seeds - 1 > SEED_MAX:
            raise ConfigError(f"--seed {self.seed} with --seeds {seeds:,} runs past seed {SEED_MAX:,}, the largest "
                              "a random key takes; train fewer --seeds or start from a lower --seed")
        if self.num_envs % devices and not by_seed(seeds, devices):
            raise ConfigError(f"num_envs {self.num_envs} does not split evenly over the {devices} devices; "
                              f"use a multiple of {devices}, or train a multiple of {devices} seeds at once")

    def instead(self, envs: int, evals: int, words: Wording = COMMAND_LINE) -> str:
        """What else would fit the steps asked for: `envs` environments, or `evals` evaluations, where either
        is a smaller number that still trains (the steps may be what the user meant to set)."""
        ways = []
        if 1 <= envs < self.num_envs:
            ways.append(words.envs.format(envs))
        if 1 <= evals < self.num_evals:
            ways.append(words.setting.format(f"{self.algo}.num_evals", evals))
        return f"; or keep the steps with {' or '.join(ways)}" if ways else ""

    def too_few(self, words: Wording) -> str:
        """How a message about too few env steps opens, naming where they were asked for."""
        return f"{self.total_steps:,} env steps ({words.steps} or {self.algo}.total_steps) are too few"

    @property
    def per_iteration(self) -> int:
        """Env steps of one training iteration, over all environments."""
        return self.num_envs * self.unroll_length

    def steps_at(self, index: int) -> int:
        """The env steps at evaluation `index` (0: before training) of a run that never refilled its buffer."""
        raise NotImplementedError

    @property
    def trained_steps(self) -> int:
        """The env steps the run ends at: it trains whole iterations, so up to one iteration per evaluation
        short of total_steps (a progress bar counts to this, not to the steps asked for)."""
        return self.steps_at(self.num_evals)

    def ends_at(self, index: int, env_steps: int) -> int:
        """The env steps a run at evaluation `index` and `env_steps` ends at: past trained_steps by the steps of
        each buffer it filled anew on a resume from what it learned alone."""
        return env_steps + self.trained_steps - self.steps_at(index)

    def short_of_asked(self) -> str | None:
        """One line where the run ends short of total_steps, saying why; None where it trains them all."""
        if self.trained_steps >= self.total_steps:
            return None
        return (f"note: trains {self.trained_steps:,} of the {self.total_steps:,} env steps asked: whole iterations "
                f"of {self.per_iteration:,} ({self.num_envs:,} envs x {self.unroll_length} steps), as many before "
                f"each of the {self.num_evals} evaluations")


class ReplayConfig(RunConfig):
    """What every trainer with a replay buffer of episode-long windows shares (CRL, SAC, TD3)."""

    batch_size: Count = 256  # transitions per gradient step
    windows: Annotated[Int, Field(ge=0)] = 0  # episode-long trajectory windows sampled per iteration; 0: windows_per_env
    # for each environment, so an iteration makes windows x episode_length / batch_size gradient steps
    windows_per_env: Annotated[Float, Field(gt=0, le=1000)] = 1.0  # 1: the reference; keeps the update ratio at any num_envs
    min_replay_rows: Count = 1000  # time rows collected before updates start
    max_replay_rows: Count = 10000
    discount: Discount = 0.99
    actor_lr: Rate = 3e-4
    critic_lr: Rate = 3e-4
    hidden: Hidden = (256, 256)
    layer_norm: StrictBool = False

    def steps_at(self, index: int) -> int:
        prefill_iters, per_eval = iterations(self)
        return (prefill_iters + index * per_eval) * self.per_iteration

    def validate_budget(self, words: Wording = COMMAND_LINE) -> None:
        """Also: steps to prefill the buffer and train."""
        super().validate_budget(words)
        prefill_iters, per_eval = iterations(self)
        prefill = prefill_iters * self.per_iteration
        need = prefill + self.num_evals * self.per_iteration
        if per_eval < 1:
            envs = self.total_steps // ((prefill_iters + self.num_evals) * self.unroll_length)
            evals = self.total_steps // self.per_iteration - prefill_iters
            raise ConfigError(f"{self.too_few(words)}: {self.num_envs:,} envs x unroll "
                              f"{self.unroll_length} need {prefill:,} steps to prefill the buffer and "
                              f"{self.num_evals} more iterations; use at least {need:,}"
                              + self.instead(envs, evals, words))

    def validate_env(self, env: Environment, devices: int = 1, seeds: int = 1) -> None:
        """Also: room for an episode, a batch's worth of transitions in the windows it samples."""
        super().validate_env(env, devices, seeds)
        if self.max_replay_rows < max(self.min_replay_rows, env.episode_length):
            raise ConfigError(f"max_replay_rows {self.max_replay_rows} must hold min_replay_rows "
                              f"({self.min_replay_rows}) and one episode ({env.episode_length} steps)")
        windows, updates = gradient_steps(self, env.episode_length)
        if updates < 1:
            raise ConfigError(f"{windows} windows of {env.episode_length} steps hold fewer transitions than one "
                              f"batch ({self.batch_size}); raise {self.algo}.windows or lower {self.algo}.batch_size")


class OffPolicyConfig(ReplayConfig):
    """SAC's and TD3's: twin critics with target networks, on the dense reward or the success, with
    hindsight relabelling."""

    tau: Annotated[Float, Field(gt=0, le=1)] = 0.005  # Polyak step of the target networks
    reward: Reward = "dense"  # dense: the field's weighted terms; sparse: its success metric
    reward_scale: Rate = 1.0
    her: Share = 0.0  # share of goals relabelled from the episode's future (needs reward: sparse)

    def validate_env(self, env: Environment, devices: int = 1, seeds: int = 1) -> None:
        super().validate_env(env, devices, seeds)
        algo = self.algo
        if self.her and self.reward != "sparse":
            raise ConfigError(f"{algo}.her relabels goals and rescores them by the field's success; "
                              f"set {algo}.reward=sparse")
        if self.her and not env.success_depends_on_goal:
            raise ConfigError(f"{algo}.her needs a success that depends on the goal; {env.name}'s does not "
                              "(a field's ball_in_goal judges the goal box, wherever the goal is); use "
                              "ball_near_target or agent_near_target")
