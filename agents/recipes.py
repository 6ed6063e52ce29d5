"""Recipes: what learns a field (an algorithm, env steps, environments, config overrides, a named preset, a
curriculum, and what the run trains on in the field's place: its task's dense reward, another physics, a fall
rule that ends its episodes), keyed by the field's name in presets/recipes.yaml, beside the presets they layer over.

A recipe writes a trainer's settings only as `--set` writes them (`steps` and `envs` are total_steps and
num_envs), so the configs and the presets stay the one owner of what a setting means and allows:
`RunConfig.layered` checks a recipe's settings as it checks --set's, each at its line of the recipes file.
`measured` is what README.md and bench/results report of the recipe on its field, and nothing else; it is
never inherited, so a field that takes another's recipe says it is not measured yet. `fall` is read and said as a
spec's episode.fall is (fieldgen.schema), so a spec and a recipe allow the same fall rules in the same words.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Sequence

import yaml

from ..suggest import did_you_mean
from .choices import ALGORITHMS, PRESETS

RECIPES = Path(__file__).with_name("presets") / "recipes.yaml"
CURRICULA = ("auto",)  # the curricula a recipe may name, as `fieldgen train --curriculum` does
KEYS = ("extends", "algo", "steps", "envs", "set", "preset", "curriculum", "reward", "backend", "fall", "measured")
INHERITED = ("algo", "steps", "envs", "preset", "curriculum", "reward", "backend", "fall")  # and `set`, item by item
REWARDS = ("dense",)  # `reward: dense`: a field paid for its success alone trains on its task's dense reward
BACKENDS = ("mjx", "warp")  # `backend`: the MJX implementation a run trains on where it runs (fieldgen/run/recipe.py)
MEASURED_KEYS = ("figure", "seeds", "data")  # and `detail`, which may be left out


class RecipeError(Exception):
    """A recipes file that cannot be read as one: the file, line, recipe and key, and what is allowed."""


@dataclasses.dataclass(frozen=True)
class Measured:
    """A figure the recipe reached on its field (its headline, which a listing shows, and the detail that a
    figure's full statement adds), its seeds, and the folder that holds its data and commands."""

    figure: str
    seeds: str
    data: str
    detail: str = ""

    @property
    def stated(self) -> str:
        """The figure in full: its headline, then its detail."""
        return f"{self.figure}, {self.detail}" if self.detail else self.figure

    def text(self) -> str:
        return f"{self.stated}, {self.seeds} ({self.data})"


@dataclasses.dataclass(frozen=True)
class Recipe:
    field: str  # the field the recipe is written for
    algo: str
    steps: int | None = None
    envs: int | None = None
    sets: tuple[str, ...] = ()  # ALGO.KEY=VALUE, as --set writes them
    preset: str | None = None  # a named preset (choices.PRESETS), as --preset names it
    curriculum: str | None = None
    reward: str | None = None  # dense: where the field's reward is its success alone, its task's dense reward
    backend: str | None = None  # the physics (sim.backend) the run trains on in the field's own place
    # the fall rule (as a spec's episode.fall writes it) that ends the run's episodes where the field has none; a
    # mapping, left out of the hash that a frozen dataclass gives
    fall: dict | None = dataclasses.field(default=None, hash=False)
    measured: Measured | None = None
    where: str = ""  # file:line of the recipe, for messages about its settings

    def assignments(self) -> list[str]:
        """The recipe's settings as --set items: its env steps and environments, then its overrides."""
        counts = [f"{self.algo}.{key}={value}" for key, value in (("total_steps", self.steps),
                                                                  ("num_envs", self.envs)) if value is not None]
        return counts + list(self.sets)

    def summary(self) -> str:
        """What the recipe trains with, as the command line would say it: ppo, 560M env steps, 8,192 envs, ..."""
        parts = [self.algo]
        parts += [f"{short_count(self.steps)} env steps"] if self.steps else []
        parts += [f"{self.envs:,} envs"] if self.envs else []
        parts += [" ".join(f"--set {item}" for item in self.sets)] if self.sets else []
        parts += [f"--preset {self.preset}"] if self.preset else []
        parts += [f"--curriculum {self.curriculum}"] if self.curriculum else []
        parts += [f"on its task's {self.reward} reward"] if self.reward else []
        parts += [f"on sim.backend {self.backend}"] if self.backend else []
        parts += [f"on episodes ending {fall_rule(self.fall).ends()}"] if self.fall else []
        return ", ".join(parts) if len(parts) > 1 else f"{self.algo} with its defaults"

    def record(self) -> dict:
        """The recipe as run.json keeps it."""
        kept = {"field": self.field, "algo": self.algo, "steps": self.steps, "envs": self.envs,
                "set": list(self.sets), "preset": self.preset, "curriculum": self.curriculum,
                "reward": self.reward, "backend": self.backend, "fall": self.fall}
        return {key: value for key, value in kept.items() if value not in (None, [])}


def fall_rule(fall: dict):
    """A recipe's `fall` as the spec's model of a fall rule (fieldgen.schema.models.Fall), which says it in words."""
    from fieldgen.schema.models import EpisodeSection

    return EpisodeSection.model_validate({"fall": fall}).fall


def short_count(value: int) -> str:
    """250M, 10M, 200k: a count as the command line takes it, exact; otherwise with thousands separators."""
    for suffix, scale in (("G", 10**9), ("M", 10**6), ("k", 10**3)):
        if value >= scale and value % scale == 0:
            return f"{value // scale}{suffix}"
    return f"{value:,}"


@dataclasses.dataclass(frozen=True)
class Found:
    """The recipe a field trains with: its own, or that of the nearest field it extends that has one."""

    recipe: Recipe
    lineage: tuple[str, ...]  # the field, then each field it extends, up to the one whose recipe this is

    @property
    def inherited(self) -> bool:
        return len(self.lineage) > 1


def find(lineage: Sequence[str], recipes: dict[str, Recipe]) -> Found | None:
    """The recipe of the first of `lineage` (a field, then the fields it extends, nearest first) that has one."""
    for n, name in enumerate(lineage):
        if name in recipes:
            return Found(recipes[name], tuple(lineage[:n + 1]))
    return None


def read(path: Path = RECIPES) -> dict[str, Recipe]:
    """Every recipe of a recipes file by its field, `extends` resolved; a RecipeError names what is wrong."""
    try:
        text = path.read_text()
        data, root = yaml.safe_load(text), yaml.compose(text, Loader=yaml.SafeLoader)
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise RecipeError(f"cannot read the recipes file {path}: {exc}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise RecipeError(f"{path}:1: a recipes file maps field names to recipes")
    lines = {key.value: (key.start_mark.line + 1, {k.value: k.start_mark.line + 1 for k, _ in
                                                   getattr(node, "value", []) if isinstance(k, yaml.Node)})
             for key, node in root.value}
    entries = {str(name): _entry(path, str(name), *lines[str(name)], recipe) for name, recipe in data.items()}
    return {name: _resolved(path, name, entries, ()) for name in entries}


def _entry(path: Path, name: str, line: int, key_lines: dict[str, int], recipe) -> dict:
    """One recipe as written: its keys' values checked, and the line of each."""
    if not isinstance(recipe, dict):
        raise RecipeError(f"{path}:{line}: recipe '{name}' must be a mapping of {', '.join(KEYS)}")
    entry = {"where": f"{path}:{line}", "lines": key_lines}
    for key, value in recipe.items():
        where = f"{path}:{key_lines.get(key, line)}: recipe '{name}'"
        if key not in KEYS:
            raise RecipeError(f"{where}: unknown key '{key}'{did_you_mean(str(key), KEYS) or '.'} "
                              f"Keys: {', '.join(KEYS)}.")
        entry[key] = _checked(where, key, value)
    return entry


def _checked(where: str, key: str, value):
    """A recipe key's value as the recipe keeps it; a RecipeError saying what the key allows where it is not."""
    def refuse(allowed: str):
        raise RecipeError(f"{where}: {key} {allowed}, not {value!r}")

    if key in ("extends", "algo", "preset", "curriculum", "reward", "backend"):
        choices = {"algo": ALGORITHMS, "preset": PRESETS, "curriculum": CURRICULA, "reward": REWARDS,
                   "backend": BACKENDS}.get(key)
        if not isinstance(value, str) or (choices is not None and value not in choices):
            near = did_you_mean(value, choices) if isinstance(value, str) and choices else ""
            refuse(f"must be {'one of ' + ', '.join(choices) if choices else 'the name of a field with a recipe'}"
                   + (f" ({near.removeprefix('; ')})" if near else ""))
        return value
    if key == "fall":
        if not isinstance(value, dict):
            refuse("must be a mapping, as a spec's episode.fall writes it ({kind: flipped, grace_steps: 50})")
        return _fall_checked(where, value)
    if key in ("steps", "envs"):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            refuse("must be a whole count above 0")
        return value
    if key == "set":
        if not isinstance(value, list) or not all(isinstance(item, str) and "=" in item for item in value):
            refuse("must be a list of ALGO.KEY=VALUE items, as --set writes them")
        return tuple(value)
    if not isinstance(value, dict) or not set(MEASURED_KEYS) <= set(value) <= {*MEASURED_KEYS, "detail"} or \
            not all(isinstance(v, str) and v for v in value.values()):
        refuse(f"must be a mapping of {', '.join(MEASURED_KEYS)} (and a detail, if any), each a text")
    return Measured(**value)


def _fall_checked(where: str, value: dict) -> dict:
    """A recipe's `fall` mapping as written, where a spec's episode.fall would take it; else a RecipeError in the
    words of a spec's problem (the kinds, or a kind's keys, that are allowed)."""
    from pydantic import ValidationError

    from fieldgen.schema.messages import problems
    from fieldgen.schema.models import EpisodeSection
    from fieldgen.schema.source import Source

    try:
        fall_rule(value)
    except ValidationError as exc:
        found = problems(Source({"fall": value}), exc.errors(), EpisodeSection)
        raise RecipeError(f"{where}: " + "; ".join(f"{p.path}: {p.message}" for p in found)) from None
    return dict(value)


def _resolved(path: Path, name: str, entries: dict, chain: tuple[str, ...]) -> Recipe:
    """A recipe with what it extends filled in: its own keys over its parent's, a `set` item of a key the recipe
    sets itself replaced, `measured` its own alone."""
    entry = entries[name]
    values = {key: value for key, value in entry.items() if key in KEYS}
    parent = values.pop("extends", None)
    if parent is not None:
        where = f"{path}:{entry['lines']['extends']}: recipe '{name}'"
        if parent not in entries:
            raise RecipeError(f"{where}: extends '{parent}', which has no recipe"
                              f"{did_you_mean(parent, entries) or '.'} Recipes: {', '.join(entries)}.")
        if parent in chain + (name,):
            raise RecipeError(f"{where}: extends forms a cycle: {' -> '.join(chain + (name, parent))}")
        base = dataclasses.asdict(_resolved(path, parent, entries, chain + (name,)))
        own = {item.partition("=")[0] for item in values.get("set", ())}
        sets = tuple(item for item in base["sets"] if item.partition("=")[0] not in own) + values.pop("set", ())
        inherited = {key: base[key] for key in INHERITED}
        values = {**inherited, **values, "set": sets}
    if values.get("algo") is None:
        raise RecipeError(f"{entry['where']}: recipe '{name}' names no algo; choose one of {', '.join(ALGORITHMS)}")
    algo, sets = values["algo"], values.pop("set", ())
    for item in sets:
        if not item.startswith(f"{algo}."):
            line = entry["lines"].get("set", entry["where"].rpartition(":")[2])
            raise RecipeError(f"{path}:{line}: recipe '{name}': set item '{item}' is not {algo}'s; write "
                              f"{algo}.KEY=VALUE")
    return Recipe(field=name, sets=tuple(sets), where=entry["where"], **values)
