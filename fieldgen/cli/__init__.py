"""The `fieldgen` command line: each command parses, calls one function of the package that owns the
work, and prints. `app` is the typer application; the modules beside this one register its commands."""

from fieldgen.cli.app import app
from fieldgen.cli import fields, sweep, training, view  # noqa: F401,E402  (their commands join `app`)

__all__ = ["app"]
