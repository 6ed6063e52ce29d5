"""`python -m fieldgen` and the installed `fieldgen` script: the command line, which takes seconds to load."""

import sys

from fieldgen import stops


def main() -> None:
    """Run the `fieldgen` command. A command says where it stands when Ctrl-C stops it; one stopped before it
    says anything (while its modules load, or before its work begins, where typer turns the KeyboardInterrupt
    into status 130 without a word) says that it was, rather than an import's traceback or nothing."""
    try:
        from fieldgen.cli import app
    except KeyboardInterrupt:
        print(f"{stops.said()} while fieldgen loaded; nothing was done", file=sys.stderr)
        sys.exit(stops.status())
    from fieldgen.cli.app import empty_argument

    problem = empty_argument(sys.argv[1:])
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        sys.exit(1)
    try:
        app(prog_name="fieldgen")
    except SystemExit as done:
        if isinstance(getattr(done.__context__, "__cause__", None), KeyboardInterrupt):  # typer's Exit(130)
            print(stops.said(), file=sys.stderr)
            sys.exit(stops.status())
        raise


if __name__ == "__main__":
    main()
