"""`python -m fieldgen.cli`."""

from fieldgen.cli import app

app(prog_name="fieldgen")
