"""`python -m fieldgen`: the `fieldgen` command."""

from fieldgen.cli import app

app(prog_name="fieldgen")
