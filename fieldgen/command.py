"""The `fieldgen` command as a child process of this interpreter: a sweep's runs, a benchmark's, and the
supervised child of a run's process other than process 0 all start it this way, and read its exit status."""

from __future__ import annotations

import sys

TIME_LIMIT_STATUS = 75  # sysexits' EX_TEMPFAIL, "try again later": a run stopped by --time-limit, to be continued


def fieldgen_command(*arguments: str) -> list[str]:
    """`fieldgen ARGUMENTS...` run by this Python with -P: started from a checkout of fieldgen (its top folder
    the working directory, as on a cluster node), the checkout's own fieldgen/ would otherwise shadow the
    installed package, which alone holds fieldgen.agents, and the child would die importing it."""
    return [sys.executable, "-P", "-m", "fieldgen", *arguments]
