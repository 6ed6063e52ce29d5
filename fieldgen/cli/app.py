"""The `fieldgen` application and what its commands share: the consoles, counts as people write them,
resolving a field named on the command line, and failing with one paragraph."""

from __future__ import annotations

import errno
import os
import re
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.text import Text

from fieldgen import counts, files, limits, stops, xla_cache, xla_flags
from fieldgen.cli.helptext import ReadableCommand, ReadableTyper
from fieldgen.schema import bundled_fields, resolve_spec_path
from fieldgen.schema.errors import shown_text
from fieldgen.suggest import did_you_mean
from fieldgen.version import VERSION

try:
    from typer._click.exceptions import UsageError  # the click that typer carries inside it
except ImportError:  # a typer that uses the click package
    from click import UsageError


class Command(ReadableCommand):
    """A command that fails on a path the system refuses (a name too long for it, a loop of links, no
    permission, a full disk) says so in one line naming the path, as any other bad input, not in a traceback."""

    def parse_args(self, ctx, args):
        """Words left over that read KEY=VALUE were meant as settings: say that each takes its own --set."""
        try:
            return super().parse_args(ctx, args)
        except UsageError as exc:
            left = re.fullmatch(r"Got unexpected extra argument(?:s|\(s\))? \((.*)\)", exc.message)
            takes_sets = any("--set" in getattr(param, "opts", ()) for param in self.params)
            settings = [word for word in left.group(1).split() if "=" in word] if left and takes_sets else []
            if settings:
                exc.message += ("; give each setting its own --set: "
                                + " ".join(f"--set {word}" for word in settings))
            raise

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except OSError as exc:
            if exc.filename is None:
                raise
            fail(os_problem(exc))
        except files.FolderError as exc:  # a file or folder of the user's where fieldgen would write
            fail(str(exc))
        except (RuntimeError, AssertionError):
            from fieldgen.doctor import platform_problem

            said = platform_problem()
            if said is None:
                raise
            fail(said)


PATH_CHARACTERS = 300  # of a path echoed in a message: any real one, not one the system refuses as too long


def os_problem(exc: OSError) -> str:
    """What the system refused, about which path, in a few words."""
    if isinstance(exc, files.WriteError):
        return str(exc)  # its own words: "cannot write PATH: why"
    said = exc.strerror or str(exc)
    if exc.errno == errno.ENAMETOOLONG:  # the system's words name no limit and no way on
        said += (f"; a folder's or file's name holds at most {limits.NAME_BYTES} bytes and a path "
                 f"{limits.PATH_BYTES:,}: choose a shorter one")
    return said if exc.filename is None else f"{shown_text(str(exc.filename), PATH_CHARACTERS)}: {said}"


app = ReadableTyper(
    command_class=Command,
    help="Robot-soccer fields from YAML specs, compiled to GPU-batched MJX environments.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)
# Nothing is read as rich markup: messages quote spec text, names and paths ("[/x]", "[link=...]",
# the name pattern "^[a-z0-9]...$", fieldgen[wandb]), which print as written; styles come as Text.
out = Console(markup=False)
err = Console(stderr=True, soft_wrap=True, markup=False)  # messages wrap in the terminal, not mid-phrase here

SpecArg = Annotated[str, typer.Argument(help="a YAML file, a bundled field name, or (render, bench) a build directory")]


def choice(what: str, choices: tuple[str, ...]) -> dict:
    """typer.Option settings for one of `choices`: listed in --help, completed by the shell, and checked as
    the command line is read, before anything loads."""

    def check(value: str | None) -> str | None:
        if value is not None and value not in choices:
            fail(f"unknown {what} '{value}'{did_you_mean(value, choices) or '.'} Choose one of: {', '.join(choices)}.")
        return value

    def complete(incomplete: str) -> list[str]:
        return [c for c in choices if c.startswith(incomplete)]

    return {"metavar": "|".join(choices), "callback": check, "autocompletion": complete}


def bounded(option: str, allowed: limits.Range, envvar: str | None = None):
    """A typer parser for a number in `allowed` (fieldgen.limits): read as people write it (2e6 too), and one
    line stating the range where it is out of it or no number, before anything loads; naming the environment
    variable `envvar` where the value is the one it holds (a launcher's, not one typed)."""

    def parse(text: str | int | float) -> int | float:
        value = limits.number(text, allowed.whole)
        said = allowed.problem(value)  # None, for no number, is out of every range
        if said is not None:
            shown = shown_text(str(text))
            given = (f"{envvar}={shown} ({option})" if envvar and os.environ.get(envvar) == str(text)
                     else f"{option} {shown}")
            fail(f"{given}: {said}; give one in that range")
        return value

    return parse


def numeric(option: str, what: str, whole: bool = False):
    """A typer parser for a number whose range is checked where its meaning is known (a curriculum's stages, its
    field's distances): read as people write it (2e6 too), and one line saying what the option takes where the
    value is no number (or no whole number), before anything loads."""

    def parse(text: str | int | float) -> int | float:
        value = limits.number(text, whole)
        if value is None or (whole and not isinstance(value, int)):
            fail(f"{option} {shown_text(str(text))}: {what} is {'a whole number' if whole else 'a number'}, "
                 f"such as {'2' if whole else '0.5'}")
        return value

    return parse


def count(text: str | int) -> int:
    """A whole count as people write them (fieldgen.counts), read as an option's value."""
    try:
        return counts.count(text)
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from None


DURATION = re.compile(r"(?:(\d+(?:\.\d*)?)h)?(?:(\d+(?:\.\d*)?)m)?(?:(\d+(?:\.\d*)?)s?)?")


def duration(text: str | float) -> float:
    """Seconds as people write a time limit: 570, 570s, 9m30s, 45m, 1.5h or 2h30m; a time read but out of range
    (0s, a century) is told the range, not that it is no time."""
    match = DURATION.fullmatch(str(text).strip().lower().replace(" ", ""))
    how = "write it in hours, minutes and seconds (h, m, s), as 570 (seconds), 9m30s, 45m or 1.5h"
    if not (match and any(match.groups())):
        days = re.fullmatch(r"(\d+(?:\.\d*)?)d", str(text).strip().lower())
        hint = f" ({float(days[1]) * 24:g}h for {days[0]})" if days else ""
        raise typer.BadParameter(f"'{text}' is not a length of time; {how}{hint}")
    hours, minutes, seconds = (float(part or 0) for part in match.groups())
    total = hours * 3600 + minutes * 60 + seconds
    if not 0 < total < limits.TIME_LIMIT_SECONDS:
        raise typer.BadParameter(f"'{text}' is out of range: a time limit is above 0 and under "
                                 f"{limits.TIME_LIMIT_SECONDS:,} seconds (some thirty years); {how}")
    return total


def fail(message: str) -> None:
    """The message as written, and exit 1."""
    err.print(Text.assemble(("error:", "bold red"), f" {message}"), highlight=False)
    raise typer.Exit(1)


def empty_argument(argv: list[str]) -> str | None:
    """Why a command line with an empty word cannot mean what it says, or None: a shell variable unset or empty
    (`fieldgen train "$FIELD"`) gives '', which a path reads as '.', the folder the command runs in."""
    command = next((word for word in argv if word and not word.startswith("-")), "")
    for i, word in enumerate(argv):
        option = word[:-1] if word.startswith("--") and word.endswith("=") else None
        if word and option is None:
            continue
        takes = _takes_value(command, argv[i - 1]) if option is None and i > 0 else False
        if takes is None:
            return None
        if takes:
            option = argv[i - 1]
        if option is not None:
            return (f"{option} is given an empty value (''), as a shell variable unset or empty gives it "
                    f"({option} \"$VAR\"); give it the value it stands for")
        return (f"word {i + 1} of the command line after fieldgen is empty (''), as a shell variable unset or empty "
                f"gives it (fieldgen {command or 'COMMAND'} \"$VAR\"); give the name or path it stands for")
    return None


def _takes_value(command: str, word: str) -> bool | None:
    """Whether `word` is an option of `fieldgen command` that takes a value (not a flag such as --no-videos)."""
    if not word.startswith("-") or "=" in word:
        return False
    found = getattr(typer.main.get_command(app), "commands", {}).get(command)
    for param in getattr(found, "params", []):
        if word in (*param.opts, *param.secondary_opts):
            # an argument has no is_flag; a flag (--no-videos) takes no value
            return getattr(param, "is_flag", None) is False and not getattr(param, "count", False)
    return None  # an option this command lacks: click's own error names it


def spec_path(ref: str, folders: str | None = None) -> Path:
    """The YAML file a field named on the command line is in; a name or path that is not one, refused with
    the nearest that is, and with what else the command takes (`folders`, e.g. "a run folder") where it
    takes folders too."""
    from fieldgen.curriculum import INDEX, is_curriculum

    path = resolve_spec_path(ref)
    try:
        path.stat()
    except (FileNotFoundError, NotADirectoryError):
        pass  # said below, with the nearest names
    except OSError as exc:  # a name too long, a loop of links, no permission
        fail(os_problem(exc))
    if path.name == INDEX and is_curriculum(path.parent):
        fail(f"{ref} lists the stages of a curriculum, not a field: give the curriculum's folder, {path.parent}, "
             "to validate, build, render or train")
    if path.is_dir():
        _refuse_run_folder(path)
    elif path.suffix == ".json" and path.is_file():
        _refuse_record(ref, path)
    if path.exists():
        return path
    if path == Path(ref) and ("/" in ref or path.suffix):  # a path, not a bundled name
        folder, what = path.parent, "a file" if folders is None else "a file or folder"
        if not folder.is_dir():
            fail(f"'{ref}' is not {what}: there is no folder {folder}")
        files = {p.stem: p for p in folder.iterdir() if p.suffix in (".yaml", ".yml")}
        takes = "." if folders is None else f": name a field's YAML file, a bundled field or {folders}"
        fail(f"'{ref}' is not {what}{did_you_mean(path.stem, files, files) or takes}")
    fail(f"'{ref}' is neither a file{'' if folders is None else ', a folder'} nor a bundled field"
         f"{did_you_mean(ref, bundled_fields()) or '.'} `fieldgen list` shows the bundled fields.")


def _refuse_run_folder(folder: Path, named: str | None = None) -> None:
    """A run's folder (or its record, `named`) given where a field spec is asked for: what it is, and the run's own
    copy of its field (session.refuse_folder_of_fields)."""
    from fieldgen.run.record import RUN, RunError

    if not (folder / RUN).is_file():
        return
    from fieldgen.run import session  # loads the trainers: only for a run's folder

    try:
        session.refuse_folder_of_fields(folder, None)
    except RunError as exc:
        fail(f"{named} is the record of a run, not a field spec; {exc}" if named else str(exc))


def _refuse_record(ref: str, path: Path) -> None:
    """The records fieldgen writes beside a run or a build, which read as a spec of some 25 unknown keys."""
    from fieldgen.compile.artifact import META  # loads mujoco: only for a JSON file
    from fieldgen.run.record import RUN

    if path.name == RUN:
        _refuse_run_folder(path.parent, ref)
    elif path.name == META:
        fail(f"{ref} is the record of a built field, not a field spec: give its folder, {path.parent}")


def field_source(ref: str, folders: str = "a build folder") -> Path:
    """A build folder as it is; else a YAML file or bundled field name (`folders`: what else the command takes,
    for the message where `ref` is none of them)."""
    return Path(ref) if Path(ref).is_dir() else spec_path(ref, folders)  # a path the system refuses: `Command` says so


def _print_version(given: bool) -> None:
    if given:
        out.print(f"fieldgen {VERSION}")
        raise typer.Exit()


@app.callback()
def main(ctx: typer.Context,
         version: Annotated[bool, typer.Option("--version", callback=_print_version, is_eager=True,
                                               help="print fieldgen's version and exit")] = False) -> None:
    """Robot-soccer fields from YAML specs, compiled to GPU-batched MJX environments."""
    from fieldgen import gl_problem

    problem = gl_problem()
    if problem:  # before anything imports mujoco, which would fail with PyOpenGL's traceback
        fail(problem)
    problem = xla_flags.problem()
    if problem:  # else XLA aborts the process once JAX starts, in its own log's words
        fail(problem)
    ctx.call_on_close(files.release_all)  # the folders a command locked are free once it ends
    ctx.call_on_close(stops.catch())  # kill and a closed terminal stop it as Ctrl-C does
    xla_cache.enable()
    xla_flags.apply()
    _float32()


def _float32() -> None:
    """fieldgen's fields and trainers compute in float32: a JAX_ENABLE_X64 set for other work made a run's programs
    fail to trace (a scan's carry turned float64), so a command runs with JAX's 64-bit numbers off."""
    os.environ.pop("JAX_ENABLE_X64", None)  # read as JAX loads, in this process and the ones a command starts
    if "jax" in sys.modules:
        import jax

        jax.config.update("jax_enable_x64", False)


def video_format(fmt: str | None) -> str:
    """The video format to write (fieldgen.video.choose: mp4 where its encoder is installed), checked before
    anything loads."""
    from fieldgen.video import VideoError, choose

    try:
        return choose(fmt)
    except VideoError as exc:
        fail(str(exc))
