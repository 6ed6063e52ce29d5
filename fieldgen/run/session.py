"""A training run's folder as an object: a new run set up (its fields built and copied in, its config
checked before anything compiles, optionally starting from another run's networks), an existing one opened
with its last checkpoint, or a run's policy put on another field of the same layout."""

from __future__ import annotations

import dataclasses
import functools
import json
from collections.abc import Sequence
from pathlib import Path

import jax
import jax.numpy as jnp
from pydantic import ValidationError

import fieldgen
from fieldgen import curriculum, files
from fieldgen.agents import checkpoint, loop, memory, programs, registry, sharding
from fieldgen.agents.config import ConfigError
from fieldgen.compile.artifact import ArtifactError, load_artifact, write_artifact
from fieldgen.env.team_contract import refuse_team
from fieldgen.curriculum.contract import start_sampling
from fieldgen.run import record
from fieldgen.schema import FieldSpec, load_spec
from fieldgen.schema.errors import shown_text, shown_value
from fieldgen.suggest import shell

FIELD, STAGES = "field", "stages"  # the run's own copies of its built fields: resuming needs no compiler
JUDGED = "judged"  # the field as written, where a recipe trains the run on another (fieldgen.run.recipe.training)


@dataclasses.dataclass
class Run:
    folder: Path
    algo: str
    envs: list  # one per stage; a plain run has one
    config: object
    seeds: list[int]
    rows: list[dict]
    plan: curriculum.Plan = curriculum.Plan()  # how it goes through its stages (a plain run has one), as run.json says
    state: object = None  # the checkpointed training state of a resumed run
    stage: int = 0  # the stage the next chunk trains on
    init_from: dict | None = None  # record.InitFrom of a run started from another run's networks
    judged: Path | None = None  # the run's copy of the field as written where its recipe trained it on another
    # form of it (JUDGED); None: judged on the field it trains on
    sampling: dict | None = None  # how the state's environments draw their episodes (curriculum.contract.
    # start_sampling, as its checkpoint or learner keeps it); None: as the state's own environments draw

    @property
    def finished(self) -> bool:
        return bool(self.rows) and self.rows[-1]["eval"] >= self.config.num_evals

    @property
    def refills(self) -> bool:
        """Whether the run goes on from what it learned alone, with fresh episodes and its buffer filled anew."""
        return self.state is not None and not self.trainers[self.stage].holds_environments(self.state)

    @property
    def label(self) -> str:
        """What the run trains on, as its progress and plot name it: its field, or its curriculum rather than
        the curriculum's last stage."""
        return self.plan.name or self.env.spec.name

    @property
    def env(self):
        """The field a run is judged on: its only one, or a curriculum's last stage."""
        return self.envs[-1]

    @property
    def learned_before(self) -> int:
        """Env steps its networks had trained, from nothing, before this run began (0 for a run from nothing):
        its own env steps plus these count a chain of --init-from runs whole."""
        return record.InitFrom.model_validate(self.init_from).learned if self.init_from else 0

    @functools.cached_property
    def trainers(self) -> list[loop.Trainer]:
        """What trains: the trainers of the environments the plan trains on (a trainer per stage, or for a
        mixed run one on every stage batched together)."""
        make_train = registry.trainer(self.algo).make_train
        return [make_train(self.config, env) for env in self.plan.environments(self.envs)]

    @property
    def judged_trainer(self) -> loop.Trainer:
        """A trainer on the field the run is judged on (its only one, or a curriculum's last stage alone)."""
        if len(self.trainers) == len(self.envs):
            return self.trainers[-1]
        return registry.trainer(self.algo).make_train(self.config, self.env)


def field_spec(source: Path) -> FieldSpec:
    """The field a field, build folder or curriculum folder (its first stage) trains on, read before anything
    compiles: its kind of agent picks the trainer's preset (agents/presets), its reward what to warn of."""
    if (source / record.RUN).is_file():  # read as a build folder, it would be one whose field.json is missing
        raise record.RunError(f"{source} is a run folder, not a field: continue it with fieldgen train --resume "
                              f"{source}, or train its field anew from the run's own copy, "
                              f"{source / _last_copy(source)}")
    try:
        if curriculum.is_curriculum(source):
            return curriculum.load(source).specs()[0]
        if source.is_dir():
            return load_artifact(source).spec
    except (curriculum.CurriculumError, ArtifactError) as exc:
        raise record.RunError(str(exc)) from None
    return load_spec(source)


def new_run(source: Path, algo: str, seeds: Sequence[int], config, out: Path, mixed: bool = False,
            init_from: Path | None = None, auto: bool = False, levels: int | None = None,
            processes: dict | None = None, trains_here: bool = True, sampler=None, recipe: dict | None = None,
            trained_on: FieldSpec | None = None) -> Run:
    """A run folder for a field (a YAML file or a build folder) or a curriculum folder (staged, or mixed:
    every stage in one batch, built to one structure); with `auto`, a field trained through `levels` levels
    (curriculum.auto.LEVELS by default) between its easy end and itself, drawn as `sampler`
    (curriculum.auto.Sampler, its defaults where None) says; with `init_from`, starting from what that run
    learned; with `recipe`, the recipe it was set up from (run/recipe.py), as run.json keeps it. A run over
    several processes (`processes`: their layout, recorded in run.json) is set up alike in
    each, and written by the first alone. With `trained_on` (a field's spec as its recipe trains on it, recipe.training),
    the run trains on that and keeps the field `source` holds, as written, in its `judged` folder, where `fieldgen
    eval` judges it. Nothing is written before every setting is known good, the memory
    the run needs included where it `trains_here` (a run prepared to train elsewhere is checked where it
    resumes); `seeds` may be a range."""
    if auto and mixed:
        raise record.RunError("--curriculum auto makes its own levels from one field and trains them all at once; "
                              "give it a field (YAML or build folder), without --mixed")
    try:
        plan, envs = curriculum.plan(source if trained_on is None else trained_on, "auto" if auto else
                                     "mixed" if mixed else "staged", levels, sampler)
    except curriculum.PlanError as exc:
        raise record.RunError(str(exc)) from None
    judged = None if trained_on is None else written_field(source)
    if plan.kind == "staged" and not plan.name:
        try:
            refuse_team(envs[0], f"fieldgen train's {algo}")
        except ValueError as exc:
            raise record.RunError(str(exc)) from None
    folder = out / record.run_name(plan.name or envs[0].spec.name, algo, seeds)
    if (taken := record.occupied(folder)) is not None:
        raise record.RunError(taken)
    for env in envs:
        config.validate_env(env, sharding.device_count(), len(seeds))
    dirs = [FIELD] if len(envs) == 1 else [f"{STAGES}/{k + 1:02d}" for k in range(len(envs))]
    run = Run(folder, algo, envs, config, seeds, [], plan, judged=None if judged is None else folder / JUDGED)
    if trains_here:
        check_memory(run)
    run.seeds = seeds = list(seeds)
    if init_from is not None:
        run.state, run.init_from = started_from(run, init_from)
    if jax.process_index() != 0:
        return run
    files.claim(folder, record.RUN_FOLDER)
    try:
        files.take(folder)  # held until the command ends: the run is trained by the process that set it up
        # a folder without a checkpoint holds no training (prepared, or stopped before its first
        # checkpoint): it is set up anew
        folder.mkdir(parents=True, exist_ok=True)
        files.mark(folder, record.RUN_FOLDER)
        files.remove_leftovers(folder)
        for stale in (record.METRICS, record.CSV, record.PLOT, record.INITIAL):
            (folder / stale).unlink(missing_ok=True)
        for env, sub in zip(envs, dirs):
            write_artifact(env.artifact, folder / sub)
        if judged is not None:
            write_artifact(judged, folder / JUDGED)
        if run.state is not None:
            files.write_atomic(folder / record.INITIAL, checkpoint.pieces(jax.device_get(run.state)))
        record.write_run(folder, envs[-1].spec.model_dump(mode="json"), algo, config, envs[0].layout.to_json(),
                         seeds, {"fields": dirs, **plan.record(),
                                 **({"init_from": run.init_from} if run.init_from else {}),
                                 **({"recipe": recipe} if recipe else {}),
                                 **({"judged": JUDGED} if judged is not None else {}),
                                 **({"processes": processes} if processes else {})})
    except OSError as exc:
        raise record.RunError(f"cannot set up the run folder {folder}: "
                              f"{files.way_on(folder.parent, '--out', exc)}") from None
    return run


def written_field(source: Path):
    """The built field `source` (a YAML file or build folder) holds as written: what a run trained on another form
    of it (fieldgen.run.recipe.training) is judged on."""
    from fieldgen.compile.artifact import compile_spec

    try:
        return load_artifact(source) if source.is_dir() else compile_spec(load_spec(source))
    except ArtifactError as exc:
        raise record.RunError(f"{source}: {exc}") from None


def check_memory(run: Run) -> None:
    """Refuse (ConfigError) a run whose training state and batches need more memory than the machine has."""
    seeds, algo, keys = len(run.seeds), run.algo, type(run.config).model_fields
    more = " or --seeds" if seeds > 1 else ""
    lower = {memory.BUFFER: f"--envs or {algo}.max_replay_rows{more}", memory.EPISODES: f"--envs{more}",
             memory.NETWORKS: f"{algo}.hidden{more}",
             memory.BATCH: (f"{algo}.windows_per_env or --envs" if "windows_per_env" in keys
                            else f"--envs or {algo}.unroll_length") + more}
    for trainer in run.trainers:
        memory.check(memory.training(trainer, seeds),
                     f"training {seeds:,} seed{'s' * (seeds > 1)} of {algo} with {run.config.num_envs:,} envs", lower)
    episodes = run.config.eval_envs  # every evaluation plays them at once for each seed, beside training's state
    for env in run.envs:
        memory.check(memory.episodes(env, episodes * seeds),
                     f"evaluating {episodes:,} episodes of each of {seeds:,} seed{'s' * (seeds > 1)} at once",
                     {memory.EPISODES: f"{algo}.eval_envs{more}"})


def learner_contents(trainer: loop.Trainer, state, sampling: dict) -> tuple:
    """What `learner.msgpack` holds of `state`, in this order: what it learned (Trainer.learned), then how its
    environments draw their episodes (`sampling`, curriculum.contract.start_sampling: a curriculum's weights and
    level counts, carried beside the state)."""
    return trainer.learned(state), sampling


def checkpoint_contents(state, sampling: dict) -> tuple:
    """What `checkpoint.msgpack` holds, in this order: the whole training state, then how its environments draw
    their episodes (`sampling`). A checkpoint written before the sampling was kept beside the state holds the
    state alone; its environments' own weights and counts then say how they draw (`open_run`)."""
    return state, sampling


def _learned_to_the_end(run: Run) -> tuple | None:
    """What the run learned alone (learner.msgpack, megabytes: its state and sampling) where that is of its last
    evaluation: then a run whose rows say it is complete is, and that is its state. None where a kill came
    between the last row and its learner, or the learner is missing or damaged: the whole checkpoint then says
    where the run is."""
    try:
        state, sampling = checkpoint.load(run.folder / record.LEARNER, *learner_template(run))
    except checkpoint.CheckpointError:
        return None
    return (state, sampling) if int(jax.device_get(state.env_steps)[0]) == run.rows[-1]["env_steps"] else None


def learner_template(run: Run) -> tuple:
    """The shapes of what `learner.msgpack` holds for the run's trainer (`learner_contents`)."""
    trainer = run.trainers[run.stage]
    return jax.eval_shape(functools.partial(learner_contents, trainer), *checkpoint_template(run))


def checkpoint_template(run: Run) -> tuple:
    """The shapes of what `checkpoint.msgpack` holds for the run's trainer (`checkpoint_contents`)."""
    _, shapes = programs.started(run.trainers[run.stage], loop.seed_keys(run.seeds))
    return shapes, jax.eval_shape(lambda state: start_sampling(state.env_state), shapes)


def started_from(run: Run, source: Path) -> tuple[object, dict]:
    """What `source`, another run, learned, as the start of `run`: its networks, optimizers and normalizer,
    with the env steps counted from 0 and the randomness of `run`'s own seeds, so that fine-tuning one
    policy with two seeds gives two runs. Refused, before anything is written, where `source` has not
    learned yet or trained another algorithm, observation layout, action size, seed count or network."""
    from fieldgen.run import selfplay

    try:
        record.read_run(source)  # a missing path, a file, a folder of no run: each said as itself
    except record.RunError as exc:
        raise record.RunError(f"--init-from {source}: {exc}") from None
    if selfplay.is_team_run(source):
        raise record.RunError(f"--init-from {source}: it is a self-play run on a team field; start from a run of one "
                              "agent on a field of the same layout")
    learner = source / record.LEARNER
    if learner.is_dir() or learner.is_symlink() and not learner.exists():
        raise record.RunError(f"--init-from {source}: its {record.LEARNER} is "
                              f"{'a folder' if learner.is_dir() else 'a link that leads nowhere'}; make it the file "
                              f"fieldgen train wrote: fieldgen train --resume {shell(source)} writes it again from "
                              "the run's checkpoint")
    if not learner.is_file():
        trained = (source / record.METRICS).exists()  # its evaluations are there, what they judged is not
        raise record.RunError(f"--init-from {source}: " + (
            f"its {record.LEARNER} is missing; fieldgen train --resume {shell(source)} writes it again from the "
            "run's checkpoint" if (source / record.CHECKPOINT).exists() else
            f"it has evaluations in {record.METRICS} but neither {record.LEARNER} nor {record.CHECKPOINT} (moved or "
            "deleted): put them back, or name another run" if trained else
            f"it holds no {record.LEARNER} (written at each evaluation) nor checkpoint: it has not trained yet; "
            f"train it first (fieldgen train --resume {shell(source)}), or name a run that has"))
    other = open_run(source, load_state=False)
    here = f"this run ({run.algo} on {run.env.spec.name})"
    if other.algo != run.algo:
        raise record.RunError(f"--init-from {source}: it trained {other.algo}, {here} trains {run.algo}; "
                              f"start from a run of the same --algo")
    if differ := interface_difference(other.env, run.env):
        raise record.RunError(f"--init-from {source}: {other.env.spec.name} observes or acts differently from "
                              f"{run.env.spec.name} ({differ}); start from a run on a field of the same agent, "
                              "objects and goal")
    if len(other.seeds) != len(run.seeds):
        raise record.RunError(f"--init-from {source}: it trained {len(other.seeds)} seeds at once, {here} "
                              f"{len(run.seeds)}; give --seeds {len(other.seeds)}")
    try:  # its networks alone: how its episodes were drawn belongs to its own levels
        state, _ = checkpoint.load(learner, learner_template(run)[0], learner_template(other)[1])
    except checkpoint.CheckpointDamaged as exc:  # no question of networks: the file itself cannot be read
        raise record.RunError(f"--init-from {source}: {exc}") from None
    except checkpoint.CheckpointError as exc:
        theirs, mine = other.config.model_dump(), run.config.model_dump()
        differ = [f"{run.algo}.{k} ({json.dumps(theirs[k])} there, {json.dumps(mine[k])} here)"
                  for k in mine if theirs.get(k) != mine[k]]
        raise record.RunError(f"--init-from {source}: its networks do not fit {here}'s ({exc}); the configs "
                              f"differ in {', '.join(differ) or 'nothing'}: give this run its network keys "
                              "with --set or --config") from None
    last = other.rows[-1] if other.rows else {"eval": 0, "env_steps": int(jax.device_get(state.env_steps)[0])}
    state = state.replace(key=loop.seed_keys(run.seeds), env_steps=jnp.zeros_like(state.env_steps))
    return state, {"run": str(source), "env_steps": int(last["env_steps"]), "eval": int(last["eval"]),
                   "before": other.learned_before}


def _check_observation(folder: Path, saved: dict, given: dict, sub: str) -> None:
    """The observation layout run.json records is the one the run's copy of its field `sub` gives: else the policy
    would read its inputs from the wrong entries. Refused naming the first key that differs, both values, and the
    way on."""
    if saved == given:
        return
    key = next(k for k in sorted(saved.keys() | given.keys(), key=str) if saved.get(k) != given.get(k))
    held, gives = (shown_value(layout[key]) if key in layout else "nothing" for layout in (saved, given))
    raise record.RunError(f"{folder / record.RUN} records observation.{shown_text(str(key))} as {held}, where the "
                          f"run's own copy of its field, {folder / sub}, gives {gives}: the run "
                          "was trained on another observation layout than its field gives (an edit, or a copy put "
                          "together from two runs); restore the run from a copy, or start it again in a new folder")


def _team_field_said(folder: Path, sub: str) -> str:
    """Why a run on a team field is not read here: a self-play run is read by the commands that know matches; a
    record that does not say self-play while its field has sides was edited."""
    from fieldgen.run import selfplay

    if selfplay.is_team_run(folder):
        return (f"{folder} is a self-play run on a team field: fieldgen eval, export and view read it (fieldgen eval "
                f"{shell(folder)} judges it in matches and films one); this command reads runs of one agent")
    return (f"{folder / record.RUN} does not say selfplay: true, yet the run's field ({folder / sub}) has two sides: "
            "a self-play run's record was edited or damaged; restore it from a copy, or start the run again in a "
            "new folder")


def open_run(folder: Path, load_state: bool = True, to_train: bool = False, learned: bool = False) -> Run:
    """A run folder with its fields loaded from the run's own copies and (with load_state) its last
    checkpoint; without, the run's record and metrics alone, enough to report on a finished run. To train it
    further, it is refused first where this machine's memory cannot hold its training (set up elsewhere).
    With `learned`, the state is what the run learned alone (learner.msgpack, megabytes, written at every
    evaluation) where that file is there: all an evaluation or an export reads, and never older than the
    whole checkpoint (gigabytes, left out of an evaluation while the one before is still being written)."""
    saved = record.read_run(folder)
    envs = []
    for sub in saved.fields or [FIELD]:
        record.check_field_copy(folder / sub)
        try:
            artifact = load_artifact(folder / sub)
            if artifact.spec.teams is not None:
                raise record.RunError(_team_field_said(folder, sub))
            envs.append(fieldgen.FieldEnv(artifact))
        except ArtifactError as exc:
            raise record.field_copy_error(folder / sub, exc.problem) from None
    if saved.judged and not (folder / saved.judged).is_dir():
        raise record.RunError(f"{folder / saved.judged} is missing: the run's own copy of the field as written, which "
                              f"its figures are judged on (a copy of the run that left it out); restore it from the "
                              f"run's copy, or judge it on that field by name: fieldgen eval {shell(folder)} --field FIELD")
    for env, sub in zip(envs, saved.fields or [FIELD]):
        _check_observation(folder, saved.observation, env.layout.to_json(), sub)
    try:
        described = FieldSpec.model_validate(saved.field).model_dump(mode="json")
    except ValidationError:
        described = None
    if described != envs[-1].spec.model_dump(mode="json"):
        raise record.RunError(f"{folder / record.RUN} describes another field than the run's own copy of it, "
                              f"{folder / (saved.fields or [FIELD])[-1]} ({envs[-1].spec.name}): the two disagree, "
                              "as after an edit or a copy put together from two runs; restore the run from a copy, "
                              "or start it again in a new folder")
    try:
        config = registry.trainer(saved.algo).config.layered(**saved.config)
        seeds = saved.seeds or [config.seed]
        for env in envs:  # values each fine alone that together build no trainer: refused as new runs' are
            config.validate_env(env, seeds=len(seeds))
    except (KeyError, ConfigError) as exc:
        raise record.RunError(f"{folder / record.RUN} holds no usable config ({exc}); it was edited or damaged, "
                              "or written by another version of fieldgen") from None
    rows = record.read_metrics(folder, seeds)
    try:
        plan = curriculum.Plan.recorded(saved, len(envs), folder / record.RUN)
    except curriculum.PlanError as exc:
        raise record.RunError(str(exc)) from None
    _check_levels_results(folder, rows, plan.kind, len(envs))
    run = Run(folder, saved.algo, envs, config, seeds, rows, plan,
              init_from=saved.init_from.model_dump() if saved.init_from else None,
              judged=folder / saved.judged if saved.judged else None)
    if not load_state:
        return run  # only reported on
    damaged = "the file was edited or damaged: restore it from a copy, or start the run again in a new folder"
    trained = record.has_trained(folder)
    if trained:
        if not rows:  # the checkpoint's own evaluation is always written before it
            raise record.RunError(f"{folder / record.METRICS} holds no evaluation, yet the run has a checkpoint; "
                                  f"{damaged}")
        if not plan.mixed:
            run.stage = rows[-1].get("promoted_to", rows[-1].get("stage", 0))
            if run.stage >= len(envs):
                raise record.RunError(f"{folder / record.METRICS}'s last row puts the run at stage {run.stage + 1}, "
                                      f"past its last ({len(envs)}); {damaged}")
        if to_train and run.finished and (at_end := _learned_to_the_end(run)) is not None:
            run.state, run.sampling = at_end
            return run  # trains no further: neither its whole checkpoint (gigabytes) nor this machine's memory matter
    if to_train and not trained and any(row["eval"] > 0 for row in rows):  # past the first: its checkpoint is gone
        raise record.RunError(f"{folder / record.METRICS} holds evaluations to {rows[-1]['env_steps']:,} env steps, "
                              f"but the run has neither {record.CHECKPOINT} nor {record.LEARNER} to go on from (moved "
                              "or deleted): put them back to continue it; training it again from the start would "
                              "replace those evaluations, so start it in a new folder (another --out) instead")
    if to_train:
        try:
            check_memory(run)
        except ConfigError as exc:
            raise record.RunError(str(exc)) from None
    if not trained:
        run.rows = []  # prepared, or stopped before its first checkpoint: it starts from the beginning
        if run.init_from:
            try:
                run.state = checkpoint.load(folder / record.INITIAL, learner_template(run)[0])
            except checkpoint.CheckpointError as exc:
                raise record.RunError(f"{exc}; it holds what the run was set up to start from "
                                      f"({run.init_from['run']}): set the run up again with --init-from") from None
        return run
    path = folder / record.CHECKPOINT
    alone = not path.exists() or (learned and (folder / record.LEARNER).exists())
    try:
        if alone:  # what it learned alone: asked for, or the run was copied without its checkpoint (it goes on
            # from there, its buffer filled anew, its episodes drawn as they were)
            path = folder / record.LEARNER
            run.state, run.sampling = checkpoint.load(path, *learner_template(run))
        else:  # one written before its sampling was kept holds none: its environments' own counts say it
            run.state, run.sampling = checkpoint.load(path, *checkpoint_template(run))
    except checkpoint.CheckpointError as exc:
        said = str(exc)
        if isinstance(exc, checkpoint.CheckpointDamaged) and not alone and (folder / record.LEARNER).is_file():
            said += (f"; or move {path.name} aside: fieldgen train --resume {shell(folder)} then goes on from "
                     f"{record.LEARNER} (what the run learned, its replay buffer filled anew)")
        elif isinstance(exc, checkpoint.CheckpointDamaged) and alone and (folder / record.CHECKPOINT).is_file():
            said += (f"; or move {path.name} aside: what the run learned is then read from {record.CHECKPOINT}, "
                     "which holds its whole state")
        raise record.RunError(said) from None
    done = int(jax.device_get(run.state.env_steps)[0])
    # a kill between an evaluation's metrics and its checkpoint leaves rows after it; the checkpoint's own is there
    run.rows = [r for r in run.rows if r["env_steps"] <= done]
    if not run.rows or run.rows[-1]["env_steps"] != done:
        last = (f"its last evaluation at or before them is at {run.rows[-1]['env_steps']:,}" if run.rows
                else "none is at or before them")
        raise record.RunError(f"{path} holds the run at {done:,} env steps, but {folder / record.METRICS} has no "
                              f"evaluation there ({last}): the two disagree; {damaged}")
    return run


def _check_levels_results(folder: Path, rows: list[dict], kind: str, levels: int) -> None:
    """Every metrics row of a run that draws its episodes over several levels at once (mixed, auto) holds each
    level's weight and success (`variants`), one per level, and no other run's rows hold them: a schedule edited
    in run.json, or rows of another run, are refused here, not found by a plot or the level buffer's table."""
    weighs = kind != "staged" and levels > 1
    for row in rows:
        variants = row.get("variants")
        sized = isinstance(variants, dict) and all(isinstance(variants.get(k), list) and len(variants[k]) == levels
                                                   for k in ("weight", "success_any"))
        if sized != weighs or (variants is not None and not weighs):
            what = (f"lack the {levels} levels' weights and success (variants)" if weighs else
                    "hold levels' results (variants)")
            raise record.RunError(f"{folder / record.METRICS}: the rows of evaluation {row['eval']} {what}, where "
                                  f"{folder / record.RUN} records a {kind} run of {levels} field"
                                  f"{'s' if levels != 1 else ''}; one of the two was edited or damaged: restore the "
                                  "run from a copy, or start it again in a new folder")


def on_field(run: Run, source: Path) -> Run:
    """The run with its policy judged on another field (a YAML file or build folder) that observes and
    acts alike: whether what it learnt carries over, e.g. from an easier variant to the field it stands for."""
    refuse_folder_of_fields(source)
    try:
        env = fieldgen.make(source)
    except ArtifactError as exc:
        raise record.RunError(f"{source}: {exc}") from None
    if differ := interface_difference(env, run.env):
        raise record.RunError(f"{source} observes or acts differently from {run.env.spec.name}, which {run.folder} "
                              f"was trained on ({differ}); a policy moves only between fields of one layout")
    return dataclasses.replace(run, envs=[env], plan=run.plan.on_one_field(), stage=0)


def refuse_folder_of_fields(source: Path, taker: str | None = "--field") -> None:
    """Refuse a run folder or a curriculum folder named where one field is asked for (by `taker`, an option or a
    command; None: where a field spec is), saying what it is and the field to name instead: read as a build
    folder, either would be called one whose field.json is missing."""
    if (source / record.RUN).is_file():
        takes = f": {taker} takes one field (" if taker else " ("
        raise record.RunError(f"{source} is a run folder, not a field{takes}a YAML file, bundled name or build "
                              f"folder); the field that run trained on is its copy {source / _last_copy(source)}")
    if curriculum.is_curriculum(source):
        try:
            last = f", e.g. its last stage, {curriculum.load(source).spec_paths()[-1]}"
        except curriculum.CurriculumError:
            last = ""
        takes = f"{taker} takes" if taker else "a field spec is"
        raise record.RunError(f"{source} is a curriculum folder: {takes} one field, such as one of its stages (a "
                              f"stage's spec or its build folder){last}")


def _last_copy(run_dir: Path) -> str:
    """The run's own copy of the field it is judged on (a curriculum's last stage), within its folder."""
    try:
        return (record.read_run(run_dir).fields or [FIELD])[-1]
    except record.RunError:  # a damaged record: the copy a plain run keeps
        return FIELD


def interface_difference(env, other) -> str:
    """How two fields' observations or actions differ ('' where a policy of one acts on the other)."""
    if env.layout.to_json() == other.layout.to_json() and env.action_size == other.action_size:
        return ""
    return (f"observation {env.observation_size} against {other.observation_size} values, actions "
            f"{env.action_size} against {other.action_size}")


