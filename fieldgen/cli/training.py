"""Commands on training runs: train, compare, eval, videos, export."""

from __future__ import annotations

import errno
import os
import sys
import time
from pathlib import Path
from typing import Annotated, NoReturn, Optional

import typer
from rich.table import Column, Table
from rich.text import Text

from fieldgen.agents.registry import ALGORITHMS, DEFAULT_ALGORITHM, EVAL_ACTIONS, PRESETS, judged_on
from fieldgen import limits, stops
from fieldgen.cli.app import app, bounded, choice, count, duration, err, fail, field_source, out, video_format
from fieldgen.command import TIME_LIMIT_STATUS
from fieldgen.cameras import CAMERAS
from fieldgen.policy_onnx import FORMATS as POLICY_FORMATS
from fieldgen.run.loggers import LOGGERS
from fieldgen.schema import FieldSpec, SpecError
from fieldgen.suggest import shell
from fieldgen.video import FORMATS as VIDEO_FORMATS

# --steps' and --envs' defaults, the config's total_steps and num_envs, in words: --help loads no trainer to read
# them (tests/test_cli.py checks them against the configs)
STEPS, ENVS = "[default: 10M, ppo 50M; --preset cpu 200k]", "[default: 1024, ppo 2048; --preset cpu 16]"
Preset = Annotated[Optional[str], typer.Option(
    help="bundled settings sized for a machine: cpu trains any field end to end in minutes on a laptop "
         "(agents/presets/cpu.yaml); a --config file, --set, --steps and --envs override it",
    **choice("preset", PRESETS))]
VideoFormat = Annotated[Optional[str], typer.Option(
    "--video-format", help=f"videos as {' or '.join(VIDEO_FORMATS)}; by default mp4 where imageio-ffmpeg's encoder "
                           "is installed",
    **choice("video format", VIDEO_FORMATS))]


def _set_help(example: str) -> str:
    """--set's help: a later item of a key overrides an earlier one (RunConfig.layered reads them in order)."""
    return f"override a config key: {example} (repeat it for more; a later one wins)"


def _read_config(config: Path | None, unsampled: str | None = None):
    """A --config file as schema.source reads specs (bounded in size, depth and aliases, duplicate keys refused,
    every problem at its line), before its values are checked (ConfigError); None without one. Where the run
    draws no automatic curriculum's levels (`unsampled` says what it trains instead), its `sampler:` section is
    refused at its line: nothing would read it."""
    from fieldgen.agents.config import ConfigError
    from fieldgen.schema.source import read_yaml

    if config is None:
        return None
    try:
        source = read_yaml(config, "a config file", "a config file holds a section per algorithm, such as 'crl:'")
    except SpecError as exc:  # each problem names the file, with its line where it has one
        raise ConfigError("--config " + "; ".join(map(str, exc.problems))) from None
    if unsampled is not None:
        _sampler_unread(source, unsampled)
    return source


def _sampler_unread(config, unsampled: str) -> None:
    """ConfigError at the line of a config file's `sampler:` section (`config` as read) in a run that draws no
    automatic curriculum's levels (`unsampled`: what it trains instead; curriculum.auto.unread)."""
    from fieldgen.agents.config import ConfigError
    from fieldgen.curriculum.auto import unread

    if (said := unread(config, unsampled)) is not None:
        raise ConfigError(said)


def _summary_named(path: Path | None, output) -> None:
    """Refuse, before any work, a --summary that names a folder, a file for JSON named otherwise (summary.png, which
    every reader would take for what it is not), or a file `output`'s command may not write (files.check_file: a
    file of the user's, a folder missing or read-only)."""
    from fieldgen.files import check_file
    from fieldgen.run.summary import SUMMARY

    if path is None:
        return
    if path.is_dir():
        fail(f"--summary {path} is a folder; name the file to write, such as {path / SUMMARY}")
    if path.suffix.lower() != ".json":
        fail(f"--summary {path}: fieldgen writes a summary as JSON; give the file the .json ending, such as "
             f"{path.with_suffix('.json')}")
    check_file(path, output, folder_made=False)


def _exit_interrupted() -> NoReturn:
    """Exit with the status of the signal that stopped the command (130 for Ctrl-C, fieldgen.stops) at once:
    leaving a compile or program under way unfinished (XLA takes no signal mid-compile or mid-program, and
    waiting could take minutes) loses nothing, as every file a command writes is replaced atomically or not yet
    written."""
    from fieldgen.agents import programs

    if programs.under_way():
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(stops.status())  # a normal exit would wait for the compile's thread
    raise typer.Exit(stops.status()) from None


def _train(run, videos: bool, logger: str, fmt: str | None = None, deadline: float | None = None) -> None:
    """Train a run; Ctrl-C exits with 130 at once, leaving a compile or program under way unfinished, and a
    failed write, a diverged run or, in a run over several processes, one that stopped says what to do
    (training.train says how to go on). A run the deadline stopped exits with TIME_LIMIT_STATUS."""
    from fieldgen.run import distributed, record, supervisor
    from fieldgen.files import NO_PERMISSION, NO_SPACE, FolderError
    from fieldgen.run.train import train as train_run

    def and_how_to_go_on(sentence: str) -> str:
        return f"{sentence}. Start every process again with --resume {run.folder} to continue from its last checkpoint"

    def another_stopped(sentence: str) -> None:
        err.print(Text.assemble(("error:", "bold red"), " " + and_how_to_go_on(sentence)), highlight=False)

    import jax

    if (blocked := record.in_the_way(run.folder, videos)) is not None:
        fail(blocked)
    if jax.process_count() > 1:  # what this process's watcher says too, should it notice first
        supervisor.leave_words(and_how_to_go_on(distributed.stopped([0], jax.process_index(), jax.process_count())))
    distributed.watch(another_stopped)
    try:
        complete = train_run(run, out, videos, logger, fmt, deadline)
    except KeyboardInterrupt:
        _exit_interrupted()  # training.train said where the run stands
    except (record.RunError, FolderError) as exc:  # training diverged, or another process trains the run
        fail(str(exc))
    except OSError as exc:  # every file of a run is replaced atomically, so the last good ones remain
        helps = ("move aside what stands there" if exc.errno in (errno.EEXIST, errno.EISDIR, errno.ENOTDIR)
                 else "free some space" if exc.errno in NO_SPACE
                 else "fix the folder's permissions" if exc.errno in NO_PERMISSION
                 else "free some space (or fix the folder's permissions)")
        fail(f"could not write {exc.filename or run.folder}: {exc.strerror or exc}; the files already there are "
              f"intact: {helps} and continue with fieldgen train --resume {shell(run.folder)}")
    except Exception as exc:
        distributed.stop_if_another_stopped(exc, another_stopped)
        raise
    distributed.finished()
    if not complete:
        raise typer.Exit(TIME_LIMIT_STATUS)


# what a run is set up with and --resume goes on with (a resumed run stays in its folder, so --out too):
# parameter -> how a user gives it
FIXED_AT_SETUP = {"spec": "a field named beside it", "algo": "--algo", "steps": "--steps", "envs": "--envs", "seed": "--seed",
                  "seeds": "--seeds", "sets": "--set", "config": "--config", "preset": "--preset",
                  "use_recipe": "--recipe/--no-recipe", "mixed": "--mixed", "curriculum_kind": "--curriculum",
                  "levels": "--levels", "samplers": "--sampler", "runs": "--out"}


@app.command()
def train(
    ctx: typer.Context,
    spec: Annotated[Optional[str], typer.Argument(
        help="a YAML file, bundled field name or build folder (omit with --resume)")] = None,
    algo: Annotated[Optional[str], typer.Option(
        help=f"training algorithm [default: the field's recipe's, else {DEFAULT_ALGORITHM}]",
        **choice("algorithm", ALGORITHMS))] = None,
    steps: Annotated[Optional[int], typer.Option(parser=count, metavar="N", help=f"total env steps: 40000, 50M, 1.5k, "
                                                 f"2e6 {STEPS}; or the field's recipe's")] = None,
    envs: Annotated[Optional[int], typer.Option(parser=count, metavar="N",
                                                help=f"parallel environments {ENVS}; or the field's recipe's")] = None,
    seed: Annotated[int, typer.Option(parser=bounded("--seed", limits.SEED), metavar="SEED",
                                      help="random seed; names the run folder")] = 0,
    seeds: Annotated[int, typer.Option(parser=bounded("--seeds", limits.SEEDS), metavar="K",
                                       help="train this many seeds at once (seed, seed+1, ...), vmapped")] = 1,
    sets: Annotated[Optional[list[str]], typer.Option("--set", metavar="KEY=VALUE",
                                                      help=_set_help("crl.repr_dim=128"))] = None,
    preset: Preset = None,
    config: Annotated[Optional[Path], typer.Option(metavar="FILE", help="YAML file: {crl: {key: value}}")] = None,
    use_recipe: Annotated[bool, typer.Option(
        "--recipe/--no-recipe", help="take the field's recipe (agents/presets/recipes.yaml: its algorithm, env steps, "
                                     "envs, settings, curriculum, and a dense reward or physics to train on, judged "
                                     "on the field as written), or that of the field it extends; its options above "
                                     "and --set override it; --no-recipe trains with the defaults")] = True,
    runs: Annotated[Path, typer.Option("--out", "-o", metavar="DIR", help="folder for run folders")] = Path("runs"),
    resume: Annotated[Optional[Path], typer.Option(metavar="RUN", help="continue the run in this folder")] = None,
    init_from: Annotated[Optional[Path], typer.Option(
        metavar="RUN", help="start from the networks another run learned (its learner.msgpack), e.g. to fine-tune "
                            "a policy on a harder field or a curriculum of the same layout; env steps count from 0")] = None,
    videos: Annotated[bool, typer.Option(help="write videos/eval_NNN.mp4 of the policy at every evaluation")] = True,
    video_fmt: VideoFormat = None,
    mixed: Annotated[bool, typer.Option(help="a curriculum's stages all at once, each env its own stage, "
                                              "re-weighted by progress (default: one stage after another)")] = False,
    curriculum_kind: Annotated[Optional[str], typer.Option(
        "--curriculum", help="auto: make the curriculum from the field itself: levels from an easy end (ball near "
                             "the target, agent behind it, obstacles narrow and aside, walls off) to the field, all "
                             "trained at once, each weighted by how much is being learnt there; the field keeps a "
                             "fixed share", **choice("curriculum", ("auto",)))] = None,
    levels: Annotated[Optional[int], typer.Option(
        parser=bounded("--levels", limits.LEVELS), metavar="N",
        help="with --curriculum auto: levels from the easy end to the field, the field included [default: 8]")] = None,
    samplers: Annotated[Optional[list[str]], typer.Option(
        "--sampler", metavar="KEY=VALUE", help="with --curriculum auto: a setting of its level sampler, kept in "
                                               "run.json: target_share, frontier_share, floor, buffer, replaced, "
                                               "prior, sharpness, kept, hardest_share, ahead, ahead_from (docs: "
                                               "curricula; a --config file's sampler: section holds them too)")] = None,
    prepare: Annotated[bool, typer.Option(help="write the run folder (config, built fields) and stop; start it "
                                                "later with --resume, e.g. on a machine without dm_control")] = False,
    logger: Annotated[str, typer.Option(help="also log every evaluation's numbers and video to TensorBoard "
                                             "(RUN/tensorboard) or Weights & Biases (RUN/wandb)",
                                        **choice("logger", LOGGERS))] = "none",
    coordinator: Annotated[Optional[str], typer.Option(
        metavar="HOST:PORT", envvar="FIELDGEN_COORDINATOR", rich_help_panel="One run over several processes",
        help="process 0's host and a free port: every process started with it joins one run over all their "
             "devices (under srun or mpirun this and the two below come from the launcher)")] = None,
    num_processes: Annotated[Optional[int], typer.Option(
        parser=bounded("--num-processes", limits.PROCESSES, "FIELDGEN_NUM_PROCESSES"), metavar="N", envvar="FIELDGEN_NUM_PROCESSES",
        rich_help_panel="One run over several processes",
        help="how many processes the run has")] = None,
    process_id: Annotated[Optional[int], typer.Option(
        parser=bounded("--process-id", limits.PROCESS_ID, "FIELDGEN_PROCESS_ID"), metavar="I", envvar="FIELDGEN_PROCESS_ID",
        rich_help_panel="One run over several processes",
        help="this process's id, 0 to N-1; process 0 writes the run folder")] = None,
    coordinator_timeout: Annotated[int, typer.Option(
        parser=bounded("--coordinator-timeout", limits.COORDINATOR_TIMEOUT), metavar="SECONDS",
        rich_help_panel="One run over several processes",
        help="how long to wait for the coordinator and the other processes")] = 300,
    time_limit: Annotated[Optional[float], typer.Option(
        parser=duration, metavar="DURATION",
        help="a job's time limit (570, 9m30s, 1.5h), counted from this command's start: training stops at the "
             f"last evaluation whose next chunk and checkpoint would not end in time, exit status "
             f"{TIME_LIMIT_STATUS}; continue with --resume")] = None,
) -> None:
    """Train an agent on a field or through a curriculum folder's stages, or a team field by self-play (docs:
    teams); writes runs/<name>-<algo>-<seed>/.

    Resumes exactly after an interrupt (--resume). A curriculum run moves to the next stage when its
    promotion rule is met and reports which stage it reached, when, and success on the last stage;
    with --mixed it trains on every stage at once, favouring those being learnt (success neither 0 nor 1).

    Example: fieldgen train soccer_v2_dense   (its recipe: ppo, 300M env steps, 8,192 envs, on Warp)
    Example: fieldgen train point_nav --algo crl --steps 40000 --envs 16 --set 'crl.hidden=[64,64]'
    Example: fieldgen train point_nav --logger tensorboard, then: tensorboard --logdir runs
    Example: fieldgen train soccer_v2 --init-from runs/soccer_v1-crl-0 --seed 1
    Example: fieldgen train soccer_v1 --curriculum auto --steps 50M
    Example: fieldgen train soccer_1v1   (a team field: self-play PPO, one network on both sides)
    Example: fieldgen train point_nav --seeds 8 --coordinator node01:12345 --num-processes 2 --process-id 0
    Example: fieldgen train --resume runs/soccer_v2-crl-0 --time-limit 55m
    """
    started = time.monotonic()
    fmt = video_format(video_fmt) if videos else None
    from fieldgen.agents import registry
    from fieldgen.files import FolderError
    from fieldgen.run import distributed, loggers, record, selfplay, session, supervisor
    from fieldgen.run.train import ends_at
    from fieldgen.run import recipe as recipes
    from fieldgen.agents.config import ConfigError
    from fieldgen.agents.recipes import RecipeError

    try:
        where = distributed.layout(coordinator, num_processes, process_id)
        if where is not None and supervisor.needed(where.process_id):
            distributed.reach(where, coordinator_timeout)  # one line here if it never answers
            # the same command trains in a child of this process
            raise typer.Exit(supervisor.supervise(where.process_id, where.num_processes))
        processes = None if where is None else distributed.join(where, coordinator_timeout)
    except record.RunError as exc:
        fail(str(exc))
    run = None
    try:
        loggers.require(logger)
        if resume is not None:
            settings = [flag for name, flag in FIXED_AT_SETUP.items()
                        if getattr(ctx.get_parameter_source(name), "name", "DEFAULT") != "DEFAULT"]
            if settings:
                total = record.read_run(resume).config.get("total_steps")
                # its count where run.json holds one (an edited one may hold anything there)
                recorded = f" (its run.json: {total:,} env steps in all)" if type(total) is int else ""
                fail(f"--resume goes on with the settings {resume} was set up with{recorded}, which "
                     f"{' and '.join(settings)} cannot change; to train "
                     f"on from what it learned, start a new run from it: fieldgen train SPEC --init-from {shell(resume)} "
                     "--steps N --out DIR")
            if init_from is not None:
                fail(f"--init-from sets up a new run; {resume} goes on from its own checkpoint (or from what it "
                     "was set up to start from): drop --init-from, or train into another --out")
            if selfplay.is_team_run(resume):
                _refuse_for_self_play(str(resume), init_from=init_from, logger=logger)
                deadline = None if time_limit is None else started + time_limit
                return _train_team(selfplay.open_run(resume, to_train=True), deadline, fmt)
            run = session.open_run(resume, to_train=True)
            if run.refills and run.rows and not run.finished:
                drawn = "; its episodes drawn as they were (its levels and their counts)" if run.sampling else ""
                refill = run.config.steps_at(0)  # PPO keeps no buffer
                refilled = (f" and a replay buffer filled anew by its policy (its {refill:,} env steps count: the "
                            f"run ends at {ends_at(run):,})" if refill else "")
                out.print(f"{resume} holds no {record.CHECKPOINT}: it goes on from {record.LEARNER} with fresh "
                          f"episodes{refilled}{drawn}")
        else:
            if spec is None:
                fail("name a field to train on, or --resume a run folder")
            source = field_source(spec)
            config_read = _read_config(config)
            field = session.field_spec(source)
            if field.teams is not None:  # a match: one network plays both sides (self-play PPO)
                _sampler_unread(config_read, f"{field.name} trains by self-play on the field itself")
                from fieldgen import curriculum as curricula

                if curricula.is_curriculum(source):
                    last = curricula.load(source).spec_paths()[-1]
                    fail(f"{spec} is a curriculum of team fields: a match trains by self-play on one field from "
                         f"nothing (docs/teams.md), never through stages; train one of its stages itself, e.g. "
                         f"fieldgen train {shell(last)}")
                _refuse_for_self_play(field.name, mixed=mixed, curriculum=curriculum_kind, levels=levels,
                                      sampler=samplers, init_from=init_from, logger=logger)
                team = _team_run(source, field, algo, seeds, config, sets, preset, steps, envs, seed, runs, prepare,
                                 use_recipe)
                if prepare:
                    out.print(f"prepared {team.folder}; start it with: fieldgen train --resume {shell(team.folder)}",
                              soft_wrap=True)
                    try:
                        selfplay.fits_memory(team.config, team.env, len(team.seeds))
                    except ConfigError as exc:
                        out.print(Text(f"note: {exc}; resume it on a machine that holds it", style="yellow"))
                    return
                return _train_team(team, None if time_limit is None else started + time_limit, fmt)
            chosen = recipes.choose(source, algo, use_recipe)
            algo, recipe = chosen.algo, chosen.recipe
            named = chosen.preset_named(preset)
            curriculum_kind = curriculum_kind or (recipe and recipe.curriculum)
            trainer_config, agent = registry.trainer(algo).config, field.agent.kind
            algo_config = recipes.new_run_config(chosen, agent, config, sets, preset, total_steps=steps, num_envs=envs,
                                                 seed=seed)
            overriding = _overriding(steps, envs, sets, config, preset)
            said = chosen.line(overriding)
            if said:
                out.print(said, soft_wrap=True)  # one line, whole
            layers = [f"{p.name}{(' (--preset)' if preset else ' (recipe)') if p.stem == named else ''}" for p in
                      (trainer_config.preset(agent), trainer_config.named_preset(named)) if p]
            if layers:
                out.print(f"{algo} on {agent} fields starts from {' then '.join(layers)} (a --config file or --set "
                          "overrides it)")
            trained_on, left_aside = recipes.training(field, recipe, trains_here=not prepare,
                                                      batched=curriculum_kind == "auto")
            if left_aside:
                out.print(Text(f"note: {left_aside}", style="yellow"), soft_wrap=True)
            if trained_on is not None:
                out.print(recipes.training_line(trained_on, field), soft_wrap=True)
            set_aside = None if use_recipe else recipes.choose(source, algo).recipe  # what --no-recipe left out
            _warn_if_sparse(trained_on or field, algo, getattr(algo_config, "reward", "dense"), set_aside)
            if not prepare:
                _note_if_gpu_sized(algo_config.total_steps)
            if levels is not None and curriculum_kind != "auto":
                fail(f"--levels {levels} sets how many levels --curriculum auto makes; add --curriculum auto")
            sampler = _sampler(samplers, config_read, auto=curriculum_kind == "auto")
            if sampler is not None and curriculum_kind == "auto":  # so that a recipe's file is seen at work
                changed = ", ".join(f"{k}={v}" for k, v in sampler.model_dump(exclude_defaults=True).items())
                out.print(f"the level sampler: {changed or 'its defaults, as given'}; the rest at their defaults "
                          "(docs/curricula.md)", soft_wrap=True)
            stops.check()  # a Ctrl-C dropped while the field built: no run folder for it
            run = session.new_run(source, algo, range(seed, seed + seeds), algo_config, runs, mixed, init_from,
                                  auto=curriculum_kind == "auto", levels=levels, processes=processes,
                                  trains_here=not prepare, sampler=sampler, recipe=chosen.record(overriding),
                                  trained_on=trained_on)
        if run.init_from and not run.rows:
            chain = f", {run.learned_before:,} from nothing learned" if run.init_from.get("before") else ""
            out.print(f"starts from what {run.init_from['run']} learned in {run.init_from['env_steps']:,} env steps "
                      f"(evaluation {run.init_from['eval']}{chain}), with fresh episodes and a replay buffer filled "
                      "anew")
    except (SpecError, ConfigError, RecipeError, record.RunError, FolderError) as exc:
        fail(str(exc))
    except KeyboardInterrupt:
        way_on = "" if run is None else f"; start it with: fieldgen train --resume {shell(run.folder)}"
        out.print(f"{stops.said()} while setting the run up; nothing was trained{way_on}", soft_wrap=True)
        _exit_interrupted()
    if prepare and run.finished:  # set up and trained to its end: nothing to start
        out.print(f"{run.folder} is already complete ({run.rows[-1]['env_steps']:,} env steps)")
        return
    if prepare:
        out.print(f"prepared {run.folder}; start it with: fieldgen train --resume {shell(run.folder)}",
                  soft_wrap=True)  # one line: the command stays whole to copy
        try:
            session.check_memory(run)
        except ConfigError as exc:
            out.print(Text(f"note: {exc}; resume it on a machine that holds it", style="yellow"))
        return
    _train(run, videos, logger, fmt, None if time_limit is None else started + time_limit)


def _overriding(steps, envs, sets, config, preset) -> list[str]:
    """The flags given that override a field's recipe, as the recipe's line names them."""
    return [flag for flag, given in (("--steps", steps), ("--envs", envs), ("--set", sets), ("--config", config),
                                     ("--preset", preset)) if given]


def _team_run(source: Path, field, algo: str | None, seeds: int, config: Path | None, sets: list[str] | None,
              preset: str | None, steps: int | None, envs: int | None, seed: int, runs: Path, prepare: bool = False,
              use_recipe: bool = True):
    """A new self-play run on a team field, `seeds` seeds from `seed` trained at once: PPO's settings (`ppo.` keys,
    with self-play's own: docs/teams.md) layered as any run's, the field's recipe among them as for any field."""
    from fieldgen.agents.selfplay import SelfPlayConfig
    from fieldgen.run import recipe as recipes
    from fieldgen.run import selfplay

    if algo not in (None, SelfPlayConfig.algo):
        fail(f"{field.name} is a team field: it trains by self-play, whose learner is {SelfPlayConfig.algo}; "
             f"give --algo {SelfPlayConfig.algo} or leave --algo out")
    chosen = recipes.choose(source, SelfPlayConfig.algo, use_recipe)
    named = [key for key in ("reward", "backend", "fall") if chosen.recipe is not None and getattr(chosen.recipe, key)]
    if named:
        fail(f"{chosen.recipe.where}: recipe '{chosen.recipe.field}' names {recipes.listed(named)}, which a team "
             f"field's recipe cannot: a match trains on its own terms, physics and episode rules (docs/teams.md); "
             f"leave {'it' if len(named) == 1 else 'them'} out, or train with --no-recipe")
    settings = SelfPlayConfig.layered(config, sets or [], agent=field.agent.kind, preset=preset,
                                      recipe=chosen.recipe, total_steps=steps, num_envs=envs, seed=seed)
    overriding = _overriding(steps, envs, sets, config, preset)
    said = chosen.line(overriding)
    if said:
        out.print(said, soft_wrap=True)
    _warn_if_sparse(field, SelfPlayConfig.algo, settings.reward)
    return selfplay.new_run(source, settings, runs, list(range(seed, seed + seeds)), check_memory=not prepare,
                            recipe=chosen.record(overriding))


GPU_SIZED = 100_000_000  # env steps from which a run is sized for a GPU: days on a CPU


def _note_if_gpu_sized(total_steps: int) -> None:
    """One line where a run sized for a GPU is about to train on a CPU: its first progress comes after a chunk,
    hours away there."""
    import jax

    if total_steps >= GPU_SIZED and jax.default_backend() == "cpu":
        out.print(Text(f"note: {total_steps:,} env steps is a run sized for a GPU, and JAX finds none here: on this "
                       "CPU it trains for days; --preset cpu sizes a run for a CPU, and --prepare sets this one up "
                       "to train on a GPU machine (fieldgen train --resume RUN there)", style="yellow"), soft_wrap=True)


def _warn_if_sparse(field, algo: str, reward: str, set_aside=None) -> None:
    """One line, once, where PPO would train on a success alone (fieldgen.run.recipe.sparse_warning)."""
    from fieldgen.run import recipe as recipes

    warning = recipes.sparse_warning(field, algo, reward, set_aside)
    if warning:
        out.print(Text(warning, style="yellow"), soft_wrap=True)


def _refuse_for_self_play(what: str, logger: str = "none", **given) -> None:
    """Fail in one line where an option that a self-play run does not take was given (docs/teams.md)."""
    flags = [f"--{name.replace('_', '-')}" for name, value in given.items() if value] + \
        (["--logger"] if logger != "none" else [])
    if flags:
        fail(f"{what} trains by self-play, which takes no {', '.join(flags)}: a self-play run trains one team field "
             "from nothing, to its end, and writes its own metrics and ratings; leave them out")


def _train_team(run, deadline: float | None = None, fmt: str | None = None) -> None:
    """Train a self-play run, with a video of a match at every evaluation in `fmt` (None: no videos); Ctrl-C exits
    with 130 and leaves its last checkpoint; a run the deadline (--time-limit) stopped exits with
    TIME_LIMIT_STATUS."""
    from fieldgen.files import FolderError
    from fieldgen.run import record, selfplay
    from fieldgen.run.videos import EpisodeRecorder

    recorder = None if fmt is None else EpisodeRecorder(run.env, fmt=fmt)
    try:
        complete = selfplay.train(run, lambda line: out.print(line, soft_wrap=True), deadline, recorder)
    except KeyboardInterrupt:
        out.print(f"{stops.said()}; continue with: fieldgen train --resume {shell(run.folder)}", soft_wrap=True)
        _exit_interrupted()
    except (record.RunError, FolderError) as exc:
        fail(str(exc))
    out.print(f"ratings: {run.folder / selfplay.RATINGS_PLOT}; judge it with: fieldgen eval {shell(run.folder)}",
              soft_wrap=True)
    if not complete:
        raise typer.Exit(TIME_LIMIT_STATUS)


def _sampler(settings: list[str] | None, config, auto: bool):
    """The automatic curriculum's sampler of a --config file's `sampler:` section (`config`, as read) and
    --sampler's settings over it, None where neither sets one; one line where one is bad, or where the run
    draws no automatic curriculum's levels (`auto`)."""
    from fieldgen.curriculum.auto import Sampler
    from fieldgen.curriculum.levels import LevelError

    if not auto:  # --sampler alone is refused with the run's plan (curriculum.plans.plan)
        _sampler_unread(config, "this run makes none (add --curriculum auto)")
    try:
        return Sampler.configured(config if auto else None, settings or [])
    except LevelError as exc:
        fail(str(exc))


@app.command()
def compare(
    ctx: typer.Context,
    sources: Annotated[list[str], typer.Argument(
        metavar="FIELD | RUN...", help="a field to train on (YAML file, bundled field name or build folder), or run "
                                       "folders already trained (each holding run.json) to compare as they are")],
    algos: Annotated[str, typer.Option(metavar="A,B,...",
                                       help=f"comma-separated algorithms: {', '.join(ALGORITHMS)}")] = "crl,ppo",
    steps: Annotated[Optional[int], typer.Option(parser=count, metavar="N",
                                                 help=f"total env steps of each run: 40000, 50M, 1.5k {STEPS}")] = None,
    envs: Annotated[Optional[int], typer.Option(parser=count, metavar="N",
                                                help=f"parallel environments of each run {ENVS}")] = None,
    seeds: Annotated[int, typer.Option(parser=bounded("--seeds", limits.SEEDS), metavar="K",
                                       help="seeds per algorithm (0, 1, ...), vmapped in one run")] = 1,
    sets: Annotated[Optional[list[str]], typer.Option("--set", metavar="KEY=VALUE",
                                                      help=_set_help("sac.her=0.8"))] = None,
    preset: Preset = None,
    config: Annotated[Optional[Path], typer.Option(metavar="FILE", help="YAML file: {crl: {...}, sac: {...}}")] = None,
    runs: Annotated[Optional[Path], typer.Option("--out", "-o", metavar="PATH", help=(
        "training: the folder of the runs and the plot (default runs/compare-<field>); run folders: the plot "
        "(default compare.png)"))] = None,
    videos: Annotated[bool, typer.Option(help="write each run's videos")] = False,
    prepare: Annotated[bool, typer.Option(help="write the run folders and stop (train them with "
                                                "fieldgen train --resume, then compare again to plot)")] = False,
    logger: Annotated[str, typer.Option(help="also log each run to TensorBoard or Weights & Biases",
                                        **choice("logger", LOGGERS))] = "none",
) -> None:
    """Train several algorithms on one field, or compare runs already trained; plot success against env steps
    and wall-clock time.

    Runs train one after another (the seeds of each at once); rerunning the same comparison
    resumes unfinished runs and redraws compare.png and compare.json. Over several seeds, the plot and
    table give the interquartile mean with its 95% bootstrap interval. Given run folders instead (a sweep's,
    each possibly of several seeds), it tables each run's last evaluation and draws their curves, training nothing,
    and measures each run against the first named: env steps a second, and success at equal env steps and at equal
    wall clock, as ratios.

    Example: fieldgen compare point_nav --algos crl,icrl,sac --steps 40000 --envs 16 --seeds 2
    Example: fieldgen compare runs/point_nav-crl-0to4 runs/point_nav-sac-0to4 -o compare.png
    """
    from fieldgen.agents.config import ConfigError
    from fieldgen.files import FolderError
    from fieldgen.run import compare as comparing
    from fieldgen.run import record

    try:
        trained = comparing.run_folders(sources)
    except record.RunError as exc:
        fail(str(exc))
    if trained is not None:
        _compare_trained(ctx, trained, runs)
        return
    source = field_source(sources[0], "a build folder, or run folders to compare")
    names = [a.strip() for a in algos.split(",") if a.strip()]
    try:
        _read_config(config, "fieldgen compare trains each algorithm on the field itself")
        folder, todo = comparing.runs(source, names, list(range(seeds)), runs, config, sets or [],
                                      preset=preset, total_steps=steps, num_envs=envs)
    except (SpecError, ConfigError, record.RunError, FolderError) as exc:
        fail(str(exc))
    if prepare:
        out.print(f"prepared {len(todo)} runs in {folder}; train each with fieldgen train --resume RUN, "
                  "then run this comparison again to plot")
        return
    for run in todo:
        if run.finished:
            out.print(f"{run.folder} is already complete ({run.rows[-1]['env_steps']:,} env steps)")
            continue
        out.print(Text.assemble((run.algo, "bold"), f" -> {run.folder}"))
        _train(run, videos, logger)
    comparing.report(todo, folder, out, _command_line(ctx))


def _compare_trained(ctx: typer.Context, folders: list[Path], plot: Path | None) -> None:
    """`fieldgen compare RUN...`: the runs' table and plot from their records; the options that set up training
    are refused, as nothing trains."""
    from fieldgen.files import WriteError
    from fieldgen.run import compare as comparing
    from fieldgen.run import record

    given = [p for p in ctx.command.params if p.param_type_name == "option" and p.name != "runs"
             and ctx.get_parameter_source(p.name) is not None and ctx.get_parameter_source(p.name).name != "DEFAULT"]
    if given:  # each as it was spelt: --no-videos, not --videos
        training = [p.secondary_opts[0] if p.secondary_opts and not ctx.params[p.name] else p.opts[0] for p in given]
        fail(f"{' and '.join(training)} set{'s' * (len(training) == 1)} up new runs on a field; comparing run "
             f"folders already trained takes only -o PLOT: drop {'it' if len(training) == 1 else 'them'}, or give a "
             "field to train on instead of the run folders")
    plot = Path(comparing.PLOT) if plot is None else plot / comparing.PLOT if plot.is_dir() else plot
    if plot.suffix.lower() != ".png":
        fail(f"-o {plot}: the plot is a PNG; name a file ending in .png, such as {plot.with_suffix('.png')}")
    from fieldgen.files import COMPARE, check_file

    check_file(plot, COMPARE, folder_made=False)
    try:
        comparing.report_recorded([comparing.recorded(f) for f in folders], plot, out)
    except record.RunError as exc:
        fail(str(exc))
    except WriteError as exc:
        fail(f"{exc}; choose another -o")


@app.command("eval")
def evaluate(
    ctx: typer.Context,
    run_dirs: Annotated[list[Path], typer.Argument(
        metavar="RUN...", help="run folders written by fieldgen train: one (all its seeds), or several of one "
                               "field and algorithm, e.g. one per seed")],
    episodes: Annotated[Optional[int], typer.Option(
        parser=count, metavar="N", help="evaluation episodes per seed, one per parallel env [default: as many as "
                                        "each evaluation of the (first) run played, its eval_envs]")] = None,
    video: Annotated[bool, typer.Option(help="write eval.mp4 of one episode of the first run's first seed")] = True,
    video_fmt: VideoFormat = None,
    camera: Annotated[str, typer.Option(help="video camera", **choice("camera", CAMERAS))] = "follow",
    film_seed: Annotated[Optional[int], typer.Option(
        parser=bounded("--film-seed", limits.SEED), metavar="SEED",
        help="film an episode of this training seed instead, as eval_seed<SEED>.mp4")] = None,
    seed: Annotated[int, typer.Option(parser=bounded("--seed", limits.SEED), metavar="SEED",
                                      help="evaluation seed")] = 0,
    actions: Annotated[Optional[str], typer.Option(
        help="mean: the policy's mean action at every step; sampled: actions drawn from the policy as in training "
             "[default: as the (first) run's evaluations acted, its eval_actions]",
        **choice("actions", EVAL_ACTIONS))] = None,
    field: Annotated[Optional[str], typer.Option(metavar="SPEC",
        help="judge the policy on this field instead (YAML file, bundled name or build folder) with the "
             "run's observations and actions; the video is eval_<field>.mp4, the summary summary_<field>.json")] = None,
    summary_file: Annotated[Optional[Path], typer.Option(
        "--summary", metavar="PATH", help="where to write the summary over seeds (default: RUN/summary.json; "
                                          "for several runs, summary.json in the first one's parent folder)")] = None,
) -> None:
    """Evaluate runs' policies as of their last evaluation (on a curriculum's last stage, or --field): each seed's
    success rate, time at goal, return, and over the seeds the interquartile mean with a 95% bootstrap interval
    (summary.json); video.

    Example: fieldgen eval runs/point_nav-crl-0to4 --episodes 256
    Example: fieldgen eval runs/point_nav-crl-0 runs/point_nav-crl-1 runs/point_nav-crl-2 --summary runs/crl.json
    """
    if film_seed is not None and not video:
        fail(f"--film-seed {film_seed} names the seed to film, and --no-video films none; drop one of them")
    fmt = video_format(video_fmt) if video else None
    from fieldgen import files
    from fieldgen.agents.config import ConfigError
    from fieldgen.files import WriteError
    from fieldgen.run import evaluate as judging
    from fieldgen.run import recipe as recipes
    from fieldgen.run import record, summary
    from fieldgen.run.videos import EpisodeRecorder

    _summary_named(summary_file, files.EVAL)
    from fieldgen.run import selfplay

    if any(selfplay.is_team_run(folder) for folder in run_dirs):
        return _evaluate_team(run_dirs, episodes, seed, actions, field, summary_file, fmt, camera, film_seed)
    evaluating = (str(run_dirs[0]) if len(run_dirs) == 1 else f"{len(run_dirs)} runs") + \
        (f" on {field}" if field is not None else "")
    summary_written = False  # what Ctrl-C leaves: the summary and the video are each written whole or not at all
    try:
        try:
            runs = judging.open_runs(run_dirs, None if field is None else field_source(field))
            judged = runs[0].judged if field is None else None  # by default, the field as written a run keeps
            episodes = episodes or runs[0].config.eval_envs  # sized with training: a CPU-sized run evaluates quickly
            actions = actions or runs[0].config.eval_actions  # the figures training drew are the ones judged again
            for run in runs:
                judging.check_memory(run, episodes)
            filmed_run, filmed_place = judging.filmed(runs, film_seed)
        except (SpecError, ConfigError, record.RunError) as exc:
            fail(str(exc))
        path, kept = (summary_file, None) if summary_file else judging.summary_path(run_dirs, runs[0], field is not None,
                                                                                      episodes)
        video_name = judging.video_path(run_dirs[filmed_run], None if field is None else runs[0].env.spec.name,
                                        film_seed)
        files.check_file(path, files.EVAL)  # before evaluating: a file it may not replace is one line now
        if video:
            files.check_file(video_name.with_suffix(f".{fmt}"), files.EVAL, "pass --no-video")
        elsewhere = recipes.judged_elsewhere(runs[0].env.spec, run_dirs) if field is None else None
        if elsewhere is not None:  # a figure on the training physics is not the one a recipe's figure is judged on
            out.print(f"note: {elsewhere}", soft_wrap=True)
        if judged is not None:
            trained = FieldSpec.model_validate(record.read_run(run_dirs[0]).field)
            out.print(f"judged on {runs[0].env.spec.name} as written ({judged}), where its recipe trained it on "
                      f"{recipes.trained_form(trained, runs[0].env.spec)}; --field {run_dirs[0] / 'field'} judges it "
                      "on the field it trained on", soft_wrap=True)
        try:
            evaluations = [judging.evaluate(run, episodes, seed, filmed_place if video and k == filmed_run else None,
                                            actions) for k, run in enumerate(runs)]
        except record.RunError as exc:  # the physics outgrew its capacities
            fail(str(exc))
        try:
            result = judging.summarize(runs, evaluations, episodes, _command_line(ctx), actions)
        except summary.SummaryError as exc:  # a seed measured nothing that can be a figure
            fail(str(exc))
        length = runs[0].env.episode_length
        steps = sorted({e.env_steps for e in evaluations})
        several = len(runs) > 1
        judged = f"{len(runs)} runs of {result.algo}" if several else str(run_dirs[0])
        at = f"{steps[0]:,}" if len(steps) == 1 else f"{steps[0]:,} to {steps[-1]:,}"
        at += " env steps"
        if result.env_steps_before:  # runs started from others' networks: count the chain from nothing too
            whole = sorted({result.env_steps[s] + result.env_steps_before.get(s, 0) for s in result.seeds})
            at += f" ({whole[0]:,}" + (f" to {whole[-1]:,}" if len(whole) > 1 else "") + " from nothing learned)"
        turned = all("turned_over" in e.metrics for e in evaluations)  # an agent with a torso: how long upside down
        table = Table(*["run"] * several, "seed", "success_any", "time at goal", "closest",
                      *(["turned over"] if turned else []), "length", "return",
                      title=f"{judged} at {at} on {runs[0].env.spec.name}, {episodes} episodes per seed"
                            + judged_on(actions))
        for run, evaluation in zip(runs, evaluations):
            metrics = evaluation.metrics
            for i, s in enumerate(run.seeds):
                table.add_row(*[run.folder.name] * several, str(s), f"{metrics['success_any'][i]:.3f}",
                              f"{metrics['time_at_goal'][i]:.1f} of {length} steps",
                              f"{metrics['closest_distance'][i]:.2f}",
                              *([f"{metrics['turned_over'][i]:.2f}"] if turned else []),
                              f"{metrics['episode_length'][i]:.0f}", f"{metrics['episode_return'][i]:.2f}")
        table.add_section()
        table.add_row(*[""] * several, result.label, result.success_any.text(3),
                      f"{result.time_at_goal.text(1)} of {length} steps", "", *([""] if turned else []), "", "")
        out.print(table)
        # the headline again as a line of its own, which a terminal too narrow for the table still shows whole
        out.print(f"{result.label}: success_any {result.success_any.text(3)}, time at goal "
                  f"{result.time_at_goal.text(1)} of {length} steps; " +
                  ("one seed: its value, and its interval the value alone" if len(result.seeds) == 1 else
                   f"the interquartile mean of the {len(result.seeds)} seeds [its 95% bootstrap interval]"))
        try:
            summary.write(result, path, files.EVAL)
            summary_written = True
        except WriteError as exc:
            fail(str(exc))
        out.print(f"summary: {path}" + (f" ({kept}, of more episodes, kept)" if kept else ""), soft_wrap=True)
        if video:  # the filmed seed's first evaluation episode
            drawn = EpisodeRecorder(runs[filmed_run].env, camera, fmt).save(
                run_dirs[filmed_run], video_name, evaluations[filmed_run].episode, err, files.EVAL)
            if drawn is not None:
                out.print(f"video: {video_name.with_suffix('.' + fmt)} ({drawn} frames, {camera} camera)")
    except KeyboardInterrupt:
        out.print(f"{stops.said()} evaluating {evaluating}; " +
                  (f"{path} was written, the video was not" if summary_written else "nothing was written"),
                  soft_wrap=True)  # one line, its paths whole
        _exit_interrupted()


def _evaluate_team(run_dirs: list[Path], episodes: int | None, seed: int, actions: str | None, field: str | None,
                   summary_file: Path | None, fmt: str | None = None, camera: str = "follow",
                   film_seed: int | None = None) -> None:
    """`fieldgen eval` of a self-play run: each seed's last snapshot's wins, draws and losses against a random
    policy and against its snapshot from a third of the way through, and its snapshots' Elo ratings; over several
    seeds, the interquartile mean of the shares won with its 95% bootstrap interval; written to
    RUN/selfplay_eval.json (or --summary); with `fmt`, RUN/eval.mp4 (or .gif) of one match of the first seed's
    two (of `film_seed`'s: eval_seed<S>)."""
    import json

    from fieldgen import files
    from fieldgen.agents.config import ConfigError
    from fieldgen.files import WriteError
    from fieldgen.run import record, selfplay, summary

    team = next(d for d in run_dirs if selfplay.is_team_run(d))
    if len(run_dirs) != 1:
        fail(f"{team} is a self-play run: it is evaluated alone, in matches on its own field; name it alone "
             f"(fieldgen eval {shell(team)}) and evaluate the other runs without it")
    if field is not None:
        fail(f"{team} is a self-play run: it is evaluated on its own team field alone; leave out --field")
    from fieldgen.run import evaluate as judging

    path = summary_file or run_dirs[0] / selfplay.EVALUATION
    video_name = judging.video_path(run_dirs[0], None, film_seed)
    try:
        files.check_file(path, files.EVAL)  # before evaluating: a file it may not replace is one line now
        if fmt is not None:
            files.check_file(video_name.with_suffix(f".{fmt}"), files.EVAL, "pass --no-video")
        run = selfplay.open_run(run_dirs[0])
        if run.state is None:
            fail(f"{run_dirs[0]} has no checkpoint: it has not trained yet; train it with "
                 f"fieldgen train --resume {shell(run_dirs[0])}, then evaluate it")
        _, place = judging.filmed([run], film_seed)
        result, filmed = selfplay.evaluate(run, episodes, seed, actions, film=place if fmt is not None else None)
    except (ConfigError, record.RunError, files.FolderError) as exc:
        fail(str(exc))
    except KeyboardInterrupt:
        out.print(f"{stops.said()} evaluating {run_dirs[0]}; nothing was written")
        _exit_interrupted()
    several = len(run.seeds) > 1
    earlier = result["per_seed"][run.seeds[0]]["vs_snapshot"]
    against = {"vs_random": "random policy",
               "vs_snapshot": f"snapshot {earlier['snapshot']} ({earlier['env_steps']:,} env steps)"}
    table = Table(*["seed"] * several, "opponent", "win", "draw", "loss",
                  title=f"{run_dirs[0]} (snapshot {result['eval']}, {result['env_steps']:,} env steps), "
                        f"{result['episodes']} episodes each, half on either side" + judged_on(result["actions"]))
    for s, judged in result["per_seed"].items():
        for opponent, name in against.items():
            table.add_row(*[str(s)] * several, name, *(str(judged[opponent][r]) for r in selfplay.RESULTS))
    out.print(table)
    for opponent, name in against.items():
        if f"win_{opponent}" in result:
            won = summary.MetricSummary.model_validate(result[f"win_{opponent}"])
            out.print(f"won against the {name}: {won.text(3)}, the interquartile mean of the {len(run.seeds)} "
                      "seeds' shares [its 95% bootstrap interval]", soft_wrap=True)
    for s, judged in result["per_seed"].items():
        ranked = sorted(judged["ratings"].items(), key=lambda item: -item[1])
        out.print(f"Elo ratings{f' of seed {s}' if several else ''} (snapshot by evaluation): "
                  + ", ".join(f"{name} {value:.0f}" for name, value in ranked), soft_wrap=True)
    path, kept = (path, None) if summary_file else judging.kept_beside(path, result["episodes"])
    try:
        files.write_file(path, (json.dumps(result, indent=1) + "\n").encode(), files.EVAL)
    except WriteError as exc:
        fail(str(exc))
    out.print(f"summary: {path}" + (f" ({kept}, of more episodes, kept)" if kept else ""), soft_wrap=True)
    if filmed is not None:  # the last snapshot at home, the earlier one away
        from fieldgen.run.videos import EpisodeRecorder

        recorder = EpisodeRecorder(run.env, camera, fmt)
        try:
            drawn = recorder.save(run_dirs[0], video_name, recorder.episode(filmed), err, files.EVAL)
        except WriteError as exc:
            fail(str(exc))
        if drawn is not None:
            out.print(f"video: {video_name.with_suffix('.' + fmt)} ({drawn} frames, {camera} camera): snapshot "
                      f"{result['eval']}{f' of seed {run.seeds[place]}' if several else ''} at home against snapshot "
                      f"{earlier['snapshot']}")


@app.command()
def aggregate(
    ctx: typer.Context,
    files: Annotated[list[Path], typer.Argument(
        metavar="SUMMARY...", help="summary.json files that fieldgen eval wrote, of one field and algorithm")],
    summary_file: Annotated[Optional[Path], typer.Option(
        "--summary", metavar="PATH", help="write the pooled summary here (default: print it only)")] = None,
) -> None:
    """Pool the seeds of several evaluations into one: each seed's success rate and time at goal, and over
    all of them the interquartile mean with its 95% bootstrap interval, as fieldgen eval gives over the seeds
    of one run (seeds trained and judged on different machines, or in runs of their own).

    Example: fieldgen aggregate runs/s340/summary.json runs/s341/summary.json --summary runs/all.json
    """
    from fieldgen.files import AGGREGATE, WriteError
    from fieldgen.run import summary

    _summary_named(summary_file, AGGREGATE)
    try:
        summaries = [(f, summary.read(f)) for f in files]
        result = summary.pooled(summaries, _command_line(ctx))
    except summary.SummaryError as exc:
        fail(str(exc))
    table = Table("seed", "success_any", "time at goal", "env steps", Column("from", overflow="fold"),
                  title=f"{result.algo} on {', '.join(result.fields)}, {result.episodes} episodes per seed"
                        + judged_on(result.actions))
    owner = {s: f for f, one in summaries for s in one.seeds}
    for s in result.seeds:
        table.add_row(str(s), f"{result.success_any.per_seed[s]:.3f}", f"{result.time_at_goal.per_seed[s]:.1f}",
                      f"{result.env_steps[s]:,}", f"{owner[s].parent.name}/{owner[s].name}")
    table.add_section()
    table.add_row(result.label, result.success_any.text(3), result.time_at_goal.text(1), "", "")
    out.print(table)
    out.print(f"{result.label}: success_any {result.success_any.text(3)}, time at goal "
              f"{result.time_at_goal.text(1)} steps")
    if summary_file is not None:
        try:
            summary.write(result, summary_file, AGGREGATE)
        except WriteError as exc:
            fail(str(exc))
        out.print(f"summary: {summary_file}")


def _command_line(ctx: typer.Context) -> str:
    """The command being run, as a summary records it: each argument and option given (typer keeps no raw
    command line), options in their first spelling, values as read."""
    import shlex

    arguments, options = [], []
    for param in ctx.command.params:
        value = ctx.params.get(param.name)
        source = ctx.get_parameter_source(param.name)
        if source is None or source.name == "DEFAULT" or value is None:
            continue
        values = list(value) if isinstance(value, (list, tuple)) else [value]
        if param.param_type_name == "argument":
            arguments += map(str, values)
        elif getattr(param, "is_flag", False) and param.secondary_opts:
            options.append(param.opts[0] if value else param.secondary_opts[0])
        else:
            options += [word for v in values for word in (param.opts[0], str(v))]
    return shlex.join(["fieldgen", ctx.info_name, *arguments, *options])


@app.command()
def videos(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN", help="a run folder written by fieldgen train")],
    field: Annotated[Optional[str], typer.Option(metavar="SPEC",
        help="the field that `fieldgen eval --field` played eval_<field>.npz on")] = None,
    video_fmt: VideoFormat = None,
) -> None:
    """Draw the episodes a run kept where nothing could render (videos/eval_NNN.npz, eval.npz) as videos beside them.

    A training machine without OpenGL keeps each evaluation's episode as joint positions; run this
    wherever mujoco's renderer works (MUJOCO_GL=egl or osmesa). Videos already drawn are left alone.

    Example: fieldgen videos runs/soccer_v1-crl-0
    """
    fmt = video_format(video_fmt)
    from fieldgen.agents.config import ConfigError
    from fieldgen.render import RenderError
    from fieldgen.run import record, session
    from fieldgen.run.videos import draw_kept, kept_episodes

    try:
        run = session.open_run(run_dir, load_state=False)
        if field is not None:
            run.envs.append(session.on_field(run, field_source(field)).env)
    except (SpecError, ConfigError, record.RunError) as exc:
        fail(str(exc))
    kept = kept_episodes(run_dir)
    if not kept:
        fail(f"nothing to draw: {run_dir / record.VIDEOS} holds no eval_NNN.npz and {run_dir} no eval.npz "
              "(training and fieldgen eval keep them only where they could not render)")
    models = {env.spec.name: env.mj_model for env in run.envs}
    table = Table("episode", "field", "frames", "video", title=f"{run_dir}: kept episodes")
    for path in kept:
        try:
            played, frames = draw_kept(path, models, fmt)
        except (RenderError, record.RunError) as exc:
            fail(str(exc))
        drawn_name = path.with_suffix(f".{fmt}").name
        table.add_row(path.name, played, "" if frames is None else str(frames),
                      f"{drawn_name} (already drawn)" if frames is None else drawn_name)
    out.print(table)


@app.command()
def export(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN", help="a run folder written by fieldgen train")],
    folder: Annotated[Path, typer.Option("--out", "-o", metavar="DIR", help="the folder to write the policy to")],
    seed: Annotated[Optional[int], typer.Option(parser=bounded("--seed", limits.SEED), metavar="SEED",
                                                help="which of the run's seeds (default: its first)")] = None,
    fmt: Annotated[str, typer.Option(
        "--format", help="flax: policy.json and params.msgpack; onnx: also policy.onnx, the policy as an ONNX graph "
                         "(observation -> action) for onnxruntime without JAX (pip install 'fieldgen[onnx]')",
        **choice("format", POLICY_FORMATS))] = "flax",
) -> None:
    """Write a run's policy (policy.json and params.msgpack) for fieldgen.load_policy, which needs no trainer or run.

    Example: fieldgen export runs/point_nav-crl-0 -o policies/point_nav
    Example: fieldgen export runs/point_nav-crl-0 -o policies/point_nav --format onnx
    """
    from fieldgen.agents.config import ConfigError
    from fieldgen.files import FolderError
    from fieldgen.policy_onnx import OnnxMissing, require
    from fieldgen.run import record
    from fieldgen.run.export import export as write_policy

    try:
        if fmt == "onnx":
            require()  # before the run is read
        d = write_policy(run_dir, folder, seed, fmt).description
    except (SpecError, ConfigError, record.RunError, FolderError, OnnxMissing) as exc:
        fail(str(exc))
    onnx = f", or run {folder}/policy.onnx in onnxruntime" if fmt == "onnx" else ""
    from fieldgen.run import selfplay

    whose = (", one agent's, on either side: its observation in its own side's frame"
             if selfplay.is_team_run(run_dir) else "")
    out.print(f"exported {d.algorithm} seed {d.seed} at {d.env_steps:,} env steps ({d.field}: "
              f"{len(d.observation_names)} observations -> {len(d.action_names)} actions{whose}) to {folder}; "
              f"load it with fieldgen.load_policy('{folder}'){onnx}", highlight=False)
