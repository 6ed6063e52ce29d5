"""What `--help` shows beside each parameter. typer writes its Python type (`<bool>`, `<str>`,
`<list[str]>`); people read the conventions of command lines instead: a flag alone, a value by its
metavar (`--seed SEED`, `--set KEY=VALUE`, `--algo crl|icrl|ppo`), an argument by its name (`SPEC`).

In a terminal narrower than WIDE columns, `--help` is plain text as click writes it, each option's help
wrapped beside it at word boundaries: typer's panels give an option's help only what four columns of
names, flags and choices leave of 80, and break a choice mid-word."""

from __future__ import annotations

import inspect

import typer
from rich.console import Console
from typer.core import TyperArgument, TyperCommand, TyperGroup, TyperOption

WIDE = 100  # columns from which --help is drawn in typer's panels


class NamedArgument(TyperArgument):
    """An argument shown by its name alone."""

    def display_type_rich(self, ctx) -> None:
        return None

    def _usage_display_name(self) -> str:
        """SPEC, [SPEC] or RUN...: typer's braces around a required one mean nothing on a command line."""
        name = self.display_name_raw if self.required else f"[{self.display_name_raw}]"
        return name if self.nargs == 1 or name.endswith("...") else name + "..."


def readable(params: list) -> list:
    """The parameters with a metavar each, unless one was given."""
    for param in params:
        if isinstance(param, TyperArgument):
            param.__class__ = NamedArgument
            if param.metavar is None:
                param.metavar = param.name.upper()
        elif isinstance(param, TyperOption) and param.metavar is None:
            param.metavar = "" if param.is_flag else param.name.upper()
    return params


def reflowed(text: str, plain: bool) -> str:
    """A docstring's paragraphs each on one line, for the help to wrap to the terminal, and its `Example:` lines
    each whole on a line of its own; for `plain` help the examples are marked as a paragraph click leaves as
    written (\\b)."""
    paragraphs = []
    for paragraph in inspect.cleandoc(text).split("\n\n"):
        lines = paragraph.splitlines()
        prose = " ".join(line for line in lines if not line.startswith("Example:"))
        examples = "\n".join(line for line in lines if line.startswith("Example:"))
        paragraphs += [prose] * bool(prose) + [("\b\n" if plain else "") + examples] * bool(examples)
    return "\n\n".join(paragraphs)


class Readable:
    """What a command and a group of commands share: readable parameters, and help that fits the terminal."""

    def get_params(self, ctx) -> list:
        return readable(super().get_params(ctx))

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.help = self.help and reflowed(self.help, plain=False)  # a group lists its first paragraph too

    def format_help(self, ctx, formatter) -> None:
        if Console().width >= WIDE:
            return super().format_help(ctx, formatter)
        written, mode = self.help, self.rich_markup_mode
        self.help, self.rich_markup_mode = written and reflowed(written, plain=True), None  # click's plain help
        try:
            super().format_help(ctx, formatter)
        finally:
            self.help, self.rich_markup_mode = written, mode


class ReadableCommand(Readable, TyperCommand):
    pass


class ReadableGroup(Readable, TyperGroup):
    pass


class ReadableTyper(typer.Typer):
    """A typer application whose commands all show readable parameters (`command_class`, a ReadableCommand)."""

    def __init__(self, command_class: type = ReadableCommand, **kwargs):
        super().__init__(cls=ReadableGroup, **kwargs)
        self.command_class = command_class

    def command(self, *args, **kwargs):
        return super().command(*args, cls=self.command_class, **kwargs)
