"""Which recipe (fieldgen.agents.recipes) sets up a new run on a field, what the run trains on where the recipe
trains it on its task's dense reward, another physics or episodes ended by a fall rule (judged on the field as
written all the same), and what
`fieldgen train` and `fieldgen list --recipes` say of it: the recipe, why it was chosen, its measured figure, and
the dense route where a field's reward is its success alone."""

from __future__ import annotations

import dataclasses
import importlib.util
from pathlib import Path

import yaml

from fieldgen import curriculum
from fieldgen.agents import recipes
from fieldgen.agents.recipes import Found, Recipe, RecipeError
from fieldgen.agents.registry import DEFAULT_ALGORITHM
from fieldgen.schema import FieldSpec, SpecError, bundled_fields, load_spec
from fieldgen.schema.backends import BACKENDS
from fieldgen.schema.loader import lineage
from fieldgen.schema.terms import DENSE_REWARDS, MATCH_TERMS, TERMS
from fieldgen.suggest import shell

DENSE_TWIN = "{}_dense"  # the bundled field that gives a field's task a dense reward


def field_lineage(source: Path) -> list[str]:
    """The field a YAML file or build folder holds, then each field it extends, nearest first; [] for a
    curriculum folder: a recipe is a field's."""
    if curriculum.is_curriculum(source):
        return []
    if source.is_dir():
        from fieldgen.compile.artifact import load_artifact

        spec = load_artifact(source).spec
        parent = bundled_fields().get(spec.extends or "")
        return [spec.name, *(n for n in (lineage(parent) if parent else []) if n != spec.name)]
    return lineage(source)


@dataclasses.dataclass(frozen=True)
class Choice:
    """What a new run on a field trains with: the recipe it takes (None: the trainer's defaults) and the
    algorithm; `passed_over` is the field's recipe where --algo names another algorithm."""

    field: str
    found: Found | None
    algo: str
    passed_over: Found | None = None

    @property
    def recipe(self) -> Recipe | None:
        return None if self.found is None else self.found.recipe

    def line(self, overriding: list[str]) -> str | None:
        """One line: which recipe, why, its measured figure, and the flags given that override it."""
        if self.passed_over is not None:
            other = self.passed_over.recipe
            return (f"recipe {other.field} ({other.summary()}) not taken: --algo {self.algo} names another "
                    f"algorithm, which trains with its defaults")
        if self.found is None:
            return None
        recipe = self.recipe
        why = (f"recipe {recipe.field} for {self.field}, which extends {' -> '.join(self.found.lineage[1:])}"
               if self.found.inherited else f"recipe {recipe.field}")
        flags = listed(overriding)
        overrides = f"; {flags} override{'s' * (len(overriding) == 1)} it" if overriding else ""
        return f"{why}: {recipe.summary()}; {figure(self.found)}{overrides}"

    def preset_named(self, given: str | None) -> str | None:
        """The named preset a new run starts from: the one given (--preset), else the recipe's."""
        return given or (self.recipe.preset if self.recipe is not None else None)

    def record(self, overriding: list[str]) -> dict | None:
        """The recipe as run.json keeps it, with the flags that overrode it."""
        if self.recipe is None:
            return None
        return {**self.recipe.record(), **({"overridden_by": overriding} if overriding else {})}


def new_run_config(chosen: Choice, agent: str, config: Path | None, sets: list[str] | None, preset: str | None,
                   **options):
    """The config a new run starts with (RunConfig.layered): its trainer's defaults, the preset of its kind of
    agent, the recipe chosen, the preset named, a config file, --set items, then `options` (total_steps,
    num_envs, seed: None where not given). `fieldgen train` and a sweep's plan both read it here."""
    from fieldgen.agents import registry

    return registry.trainer(chosen.algo).config.layered(config, sets or [], agent=agent,
                                                        preset=chosen.preset_named(preset), recipe=chosen.recipe,
                                                        **options)


def choose(source: Path, algo: str | None, use: bool = True) -> Choice:
    """The recipe a new run on `source` takes, unless `use` is false or `algo` names another algorithm."""
    names = field_lineage(source)
    field = names[0] if names else source.name
    found = recipes.find(names, recipes.read()) if use else None
    if found is not None and algo is not None and algo != found.recipe.algo:
        return Choice(field, None, algo, passed_over=found)
    return Choice(field, found, algo or (found.recipe.algo if found else DEFAULT_ALGORITHM))


def trained_form(trained: FieldSpec, written: FieldSpec, detail: bool = False) -> str:
    """How the field a run trains on differs from the field as written, in words: 'its task's dense reward,
    sim.backend warp and episodes ending once the ant has lain turned over for 50 control steps in a row (2.5 s)';
    with `detail`, the dense reward's terms, what the backend is and the fall rule as a spec writes it."""
    parts = []
    if trained.task.reward != written.task.reward:
        dense = load_spec(written, changes={"task": {"reward": "dense"}}).task.reward == trained.task.reward
        terms = ", ".join(term.term for term in trained.task.reward)
        parts.append(("its task's dense reward" + (f" (task: {{reward: dense}}: {terms})" if detail else ""))
                     if dense else f"other reward terms ({terms})")
    if trained.sim.backend != written.sim.backend:
        backend = trained.sim.backend
        parts.append(f"sim.backend {backend}" + (f" ({BACKENDS[backend].description})" if detail else ""))
    fall = trained.episode.fall
    if fall != written.episode.fall:
        said = fall.ends(trained.episode.control_dt)
        written_as = f"episode: {{fall: {one_line(fall.model_dump(mode='json', exclude_unset=True))}}}"
        if detail:  # beside the seconds, where the words give them
            said = f"{said.removesuffix(')')}; {written_as})" if said.endswith(")") else f"{said} ({written_as})"
        parts.append(f"episodes ending {said}")
    return listed(parts) or "the field as written"


def listed(items: list[str]) -> str:
    """'a', 'a and b', 'a, b and c'."""
    return ", ".join(items[:-1]) + " and " * (len(items) > 1) + "".join(items[-1:])


def one_line(data: dict) -> str:
    """A mapping as a spec writes it on one line: {kind: flipped, grace_steps: 50}."""
    return yaml.safe_dump(data, default_flow_style=True, sort_keys=False, width=10**6).strip()


def training_line(trained: FieldSpec, written: FieldSpec) -> str:
    """One line: what a run trains on in its field's place, and that it is judged on the field as written."""
    return (f"trains {written.name} on {trained_form(trained, written, detail=True)}, as its recipe says; the run "
            "keeps the field as written, and fieldgen eval judges it there (the same success)")


def warp_runs_here() -> bool:
    """Whether MuJoCo Warp's kernels step a field here at the speed a recipe chose them for: warp-lang installed and
    a GPU for JAX (on a CPU Warp runs its CPU kernels, slower than MJX's JAX implementation)."""
    if importlib.util.find_spec("warp") is None:
        return False
    import jax

    return jax.default_backend() == "gpu"


def training(written: FieldSpec, recipe: Recipe | None, trains_here: bool = True,
             batched: bool = False) -> tuple[FieldSpec | None, str | None]:
    """The field a new run on `written` trains on as `recipe` says (None: the field as written; else the same field,
    of the same name, with its task's dense reward, on another of MJX's implementations or with the recipe's fall
    rule), and a line where the recipe's physics or fall rule is left aside. `reward: dense` applies to a field paid
    for its success alone (a field with reward terms of its own trains on them); `backend` replaces one of MJX's
    implementations with another, Warp only where it runs (`warp_runs_here`), or anywhere for a run prepared to train
    elsewhere (not `trains_here`), and never for a run that batches variants of the field in one model (`batched`:
    --curriculum auto's levels); `fall` becomes the episode.fall of an ant's field whose episodes end on time alone
    (`never`: a field with a fall rule of its own keeps it; a point agent never falls, and its field is left as
    written with a note). RecipeError where the field's task has no dense reward, or the field refuses the recipe's
    fall rule."""
    if recipe is None or written.teams is not None:
        return None, None
    changes, note = {}, None
    if recipe.reward == "dense" and is_sparse(written):
        kind = written.task.success.kind
        if kind not in DENSE_REWARDS:
            raise RecipeError(f"{recipe.where}: recipe '{recipe.field}' trains {written.name} on its task's dense "
                              f"reward, and its task (task.success.kind: {kind}) has none; the kinds with one are "
                              f"{', '.join(DENSE_REWARDS)}. List reward terms under task.reward, or train with the "
                              f"defaults: --no-recipe")
        changes["task"] = {"reward": "dense"}
    backend, own = recipe.backend, written.sim.backend
    if backend not in (None, own):
        if BACKENDS[own].mjx_impl is None:
            note = (f"{written.name} trains on its own sim.backend {own}: its recipe's backend {backend} replaces one "
                    f"of MJX's implementations, not brax's pipelines")
        elif backend == "warp" and batched:
            note = (f"{written.name} trains on its own sim.backend {own}: its recipe's backend warp does not batch "
                    f"the levels of --curriculum auto in one model, which MJX's JAX implementation does")
        elif backend == "warp" and trains_here and not warp_runs_here():
            note = (f"{written.name} trains on its own sim.backend {own} here: its recipe's backend warp (the physics "
                    f"its figure was measured on) runs MuJoCo Warp's kernels on a GPU with warp-lang installed "
                    f"(pip install -c requirements.lock -e '.[warp]'), and this machine has not both")
        else:
            changes["sim"] = {"backend": backend}
    if recipe.fall is not None and written.episode.fall.kind == "never" and recipe.fall["kind"] != "never":
        if written.agent.kind == "ant":
            changes["episode"] = {"fall": recipe.fall}
        else:
            aside = (f"{written.name} trains with its own episode.fall never: its recipe's fall rule ends an ant's "
                     f"episodes, and its {written.agent.kind} agent never falls")
            note = aside if note is None else f"{note}; {aside}"
    if not changes:
        return None, note
    try:
        return load_spec(written, changes=changes), note
    except SpecError as exc:
        if "episode" not in changes:
            raise
        said = "; ".join(f"{p.path}: {p.message}" for p in exc.problems)
        raise RecipeError(f"{recipe.where}: recipe '{recipe.field}' trains {written.name} with episode.fall "
                          f"{one_line(recipe.fall)}, which it refuses: {said}; write another fall rule in the "
                          f"recipe, or train with the defaults: --no-recipe") from None


def figure(found: Found, beside: bool = True) -> str:
    """The recipe's measured figure on the field, or that it has none, and then the dense twin's measured route;
    with `beside`, also the measured routes of the fields that extend it (a listing shows those on their rows)."""
    recipe, field = found.recipe, found.lineage[0]
    measured = recipe.measured
    if measured is not None and not found.inherited:
        return f"measured: {measured.stated}, {measured.seeds}" + (routes_beside(field) if beside else "")
    said = f"not measured on {field} yet" if found.inherited else "not measured yet"
    said += f" ({recipe.field}: {measured.stated}, {measured.seeds})" if measured is not None else ""
    return said + dense_route(field) + (routes_beside(field) if beside and not found.inherited else "")


def measured_own(names: list[str], table: dict[str, Recipe]) -> Found | None:
    """The recipe of the first of `names` (a field's lineage) where it is that field's own and has a figure."""
    found = recipes.find(names, table)
    return None if found is None or found.inherited or found.recipe.measured is None else found


def dense_route(field: str) -> str:
    """Where a field's dense twin has a figure of its own recipe: '; the measured route is ...'; else ''."""
    twin = DENSE_TWIN.format(field)
    path = bundled_fields().get(twin)
    found = measured_own(lineage(path), recipes.read()) if path is not None else None
    if found is None:
        beside = routes_beside(twin) if path is not None else ""
        return f"; its dense twin {twin} is not measured itself{beside}" if beside else ""
    measured = found.recipe.measured
    return (f"; the measured route is its dense twin {twin} ({found.recipe.summary()}): {measured.stated}, "
            f"{measured.seeds}" + routes_beside(twin))


def routes_beside(field: str) -> str:
    """'; also measured: ...' for each bundled field that extends `field` with a measured recipe of its own and
    differs from it in its physics alone (the same task another way), but the very runs `field`'s own figure
    states (the same seeds and data: the field its recipe trains on); else ''."""
    table, said = recipes.read(), ""
    fields = bundled_fields()
    own = measured_own(lineage(fields[field]), table)
    runs = None if own is None else (own.recipe.measured.seeds, own.recipe.measured.data)
    for name, path in fields.items():
        names = lineage(path)
        found = measured_own(names, table) if name != field and field in names else None
        if found is None or (found.recipe.measured.seeds, found.recipe.measured.data) == runs:
            continue
        if same_task(fields[field], path):
            said += f"; also measured: {name}, {found.recipe.measured.stated}, {found.recipe.measured.seeds}"
    return said


def same_task(path: Path | FieldSpec, other: Path | FieldSpec) -> bool:
    """Whether two fields set the same scene, task and episode, whatever physics steps them (`sim`)."""
    def task(source: Path | FieldSpec) -> dict:
        return load_spec(source).model_dump(exclude={"name", "description", "extends", "sim"})
    return task(path) == task(other)


def physics_twin(spec: FieldSpec) -> str | None:
    """The bundled field `spec` extends where the two differ in their physics alone (a `_warp` field's own field):
    the field whose physics a recipe's figure is judged on; else None."""
    path = bundled_fields().get(spec.extends or "")
    parent = None if path is None else load_spec(path)
    if parent is None or parent.sim.backend == spec.sim.backend or not same_task(spec, parent):
        return None
    return spec.extends


def judged_elsewhere(spec: FieldSpec, runs: list[Path]) -> str | None:
    """For runs (their folders) on a physics twin (`physics_twin`): that their evaluations play the training
    physics, and the command that judges them as the recipe's figure is judged; else None."""
    twin = physics_twin(spec)
    if twin is None:
        return None
    folders = " ".join(map(shell, runs))
    return (f"{spec.name} is {twin} with sim.backend {spec.sim.backend}: its evaluations play that physics, and its "
            f"recipe's figure is judged on {twin} itself: fieldgen eval {folders} --episodes 1024 --field {shell(twin)}")


def is_sparse(spec: FieldSpec) -> bool:
    """Whether a field's reward is a success signal alone (a match's: its goals): nothing to follow until the
    first success."""
    terms = MATCH_TERMS if spec.teams is not None else TERMS
    return all(terms[term.term].sparse for term in spec.task.reward)


def sparse_warning(spec: FieldSpec, algo: str, reward: str = "dense", set_aside: Recipe | None = None) -> str | None:
    """The warning for PPO trained on a success alone, naming the dense alternative: a field whose reward is its
    success, or a field with reward terms that `ppo.reward=sparse` sets aside (`reward`, PPO's setting).
    `set_aside`: the field's recipe that --no-recipe left out, named where it trains on the dense reward."""
    if algo != "ppo":
        return None
    if not is_sparse(spec):
        if reward != "sparse":
            return None
        return (f"warning: PPO learns nothing from a success signal alone until its first success, and "
                f"ppo.reward=sparse trains it on {spec.name}'s success; leave ppo.reward at dense to train on the "
                f"field's reward terms")
    twin = DENSE_TWIN.format(spec.name)
    if spec.teams is not None:
        instead = "list match terms that pay the way to a goal under task.reward (docs/teams.md)"
    elif set_aside is not None and set_aside.reward == "dense":
        instead = f"its recipe ({set_aside.field}) trains it on its task's dense reward: leave out --no-recipe"
    elif twin in bundled_fields():
        instead = f"train its dense twin instead: fieldgen train {shell(twin)}"
    elif spec.task.success.kind in DENSE_REWARDS:
        instead = "give the field the dense reward of its task: task: {reward: dense}"
    else:
        instead = "list reward terms that shape the way there under task.reward"
    return f"warning: PPO learns nothing from a success signal alone, and {spec.name}'s reward is its success; {instead}"


def listing() -> list[tuple[str, str, str]]:
    """(field, its recipe, the headline of its measured figure and its seeds) for each bundled field, as
    `fieldgen list --recipes` shows them; `statement` gives a field's figure in full."""
    table = recipes.read()
    rows = []
    for name, path in bundled_fields().items():
        found = recipes.find(lineage(path), table)
        if found is None:
            trainer = "ppo self-play" if load_spec(path).teams is not None else DEFAULT_ALGORITHM  # as train picks
            twin = DENSE_TWIN.format(name)
            route = measured_own(lineage(bundled_fields()[twin]), table) if twin in bundled_fields() else None
            if route is not None:
                said = f"its dense twin {twin}: {route.recipe.measured.figure}"
            else:  # measured on other physics alone, or not at all
                said = f"its dense twin {twin}: measured on other physics" if dense_route(name) else "-"
            rows.append((name, f"none: {trainer} with its defaults", said))
            continue
        inherited = f" (the recipe of {found.recipe.field})" if found.inherited else ""
        measured = found.recipe.measured
        said = "not measured yet" if measured is None or found.inherited else f"{measured.figure}; {measured.seeds}"
        rows.append((name, found.recipe.summary() + inherited, said))
    return rows


def statement(name: str) -> str:
    """A bundled field's recipe and its measured figure in full, with the page of its data and commands (the
    dense twin's route where the field has no recipe)."""
    found = recipes.find(lineage(bundled_fields()[name]), recipes.read())
    if found is None:
        return f"{name}: no recipe (its trainer's defaults){dense_route(name) or '; no measured route'}"
    measured = found.recipe.measured
    page = f"; data and commands: {measured.data}" if measured is not None and not found.inherited else ""
    inherited = f" (the recipe of {found.recipe.field})" if found.inherited else ""
    return f"{name}: {found.recipe.summary()}{inherited}; {figure(found)}{page}"