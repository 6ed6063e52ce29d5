"""What `--help` shows beside each parameter. typer writes its Python type (`<bool>`, `<str>`,
`<list[str]>`); people read the conventions of command lines instead: a flag alone, a value by its
metavar (`--seed SEED`, `--set KEY=VALUE`, `--algo crl|icrl|ppo`), an argument by its name (`SPEC`)."""

from __future__ import annotations

import typer
from typer.core import TyperArgument, TyperCommand, TyperGroup, TyperOption


class NamedArgument(TyperArgument):
    """An argument shown by its name alone."""

    def display_type_rich(self, ctx) -> None:
        return None


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


class ReadableCommand(TyperCommand):
    def get_params(self, ctx) -> list:
        return readable(super().get_params(ctx))


class ReadableGroup(TyperGroup):
    def get_params(self, ctx) -> list:
        return readable(super().get_params(ctx))


class ReadableTyper(typer.Typer):
    """A typer application whose commands all show readable parameters."""

    def __init__(self, **kwargs):
        super().__init__(cls=ReadableGroup, **kwargs)

    def command(self, *args, **kwargs):
        return super().command(*args, cls=ReadableCommand, **kwargs)
