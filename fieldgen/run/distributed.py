"""One run over several processes, one per host or per GPU: JAX's multi-controller runtime
(jax.distributed), which every `fieldgen train` process joins before anything touches a device. The
processes then see one global set of devices, over which agents.sharding lays one mesh; each trains its
share, and the first writes the run folder.

Where the processes come from: `--coordinator HOST:PORT --num-processes N --process-id I` (or the
FIELDGEN_COORDINATOR, FIELDGEN_NUM_PROCESSES and FIELDGEN_PROCESS_ID variables), or, with none of them,
a launcher JAX recognises by itself when it started more than one task (srun, mpirun). Failures come as
one line: settings that do not fit, a coordinator that never answers, and, mid-run, a process that died
(`stopped_process`).
"""

from __future__ import annotations

import dataclasses
import os
import socket
import time

from fieldgen.run.record import RunError

HEARTBEAT_SECONDS = 30  # a process silent this long is taken for dead, and the others are stopped
LAUNCHERS = {"SLURM_STEP_NUM_TASKS": "srun", "OMPI_COMM_WORLD_SIZE": "mpirun"}  # variable -> launcher


@dataclasses.dataclass(frozen=True)
class Layout:
    """How to join: all three given, or none (the launcher's own settings, read by JAX)."""

    coordinator: str | None
    num_processes: int | None
    process_id: int | None


def layout(coordinator: str | None, num_processes: int | None, process_id: int | None) -> Layout | None:
    """The processes to join as the options (or their variables) give them; a launcher's when none are given
    and it started several tasks; None for a run in this process alone."""
    given = {"--coordinator": coordinator, "--num-processes": num_processes, "--process-id": process_id}
    if all(v is None for v in given.values()):
        launched = [name for variable, name in LAUNCHERS.items() if int(os.environ.get(variable) or 1) > 1]
        return Layout(None, None, None) if launched else None
    if num_processes is not None and num_processes < 1:
        raise RunError(f"--num-processes {num_processes}: a run needs at least one process")
    missing = [name for name, value in given.items() if value is None]
    if missing:
        raise RunError(f"{', '.join(missing)} missing: a run over several processes needs --coordinator HOST:PORT, "
                       "--num-processes N and --process-id I, each process its own id")
    if not 0 <= process_id < num_processes:
        raise RunError(f"--process-id {process_id} is out of range: with --num-processes {num_processes} the ids "
                       f"are 0 to {num_processes - 1}")
    host, _, port = coordinator.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise RunError(f"--coordinator {coordinator}: write it as HOST:PORT, the address of process 0's host and a "
                       "free port, such as node01:12345")
    return Layout(coordinator, num_processes, process_id)


def join(where: Layout, timeout: int) -> dict:
    """Join the run's processes (waiting up to `timeout` seconds for the coordinator and the others); returns
    the layout as run.json records it."""
    import jax

    if where.coordinator is not None and where.process_id != 0:
        _wait_for(where.coordinator, timeout)
    jax.config.update("jax_cpu_collectives_implementation", "gloo")  # CPU processes reach one another too
    jax.distributed.initialize(where.coordinator, where.num_processes, where.process_id,
                               initialization_timeout=timeout, heartbeat_timeout_seconds=HEARTBEAT_SECONDS)
    counts = [sum(d.process_index == p for d in jax.devices()) for p in range(jax.process_count())]
    return {"count": jax.process_count(), "devices_per_process": counts,
            "coordinator": where.coordinator or "from the launcher"}


def _wait_for(coordinator: str, timeout: int) -> None:
    """Wait until process 0's coordinator accepts connections: JAX itself would end the process with a
    stack trace when it never does."""
    host, _, port = coordinator.rpartition(":")
    deadline = time.monotonic() + timeout
    while True:
        try:
            socket.create_connection((host, int(port)), timeout=5).close()
            return
        except OSError as exc:
            if time.monotonic() > deadline:
                raise RunError(f"no coordinator answered at {coordinator} within {timeout} s ({exc.strerror or exc}): "
                               "start process 0 (--process-id 0 runs it) on that host, and check the address "
                               "and that the port is open between the hosts") from None
            time.sleep(0.5)


def stopped_process(error: BaseException) -> str | None:
    """Where a run over several processes failed because one of them stopped, a sentence naming the ones gone;
    None otherwise (a single process, or another error)."""
    import jax

    if jax.process_count() == 1 or "Gloo" not in str(error) and "NCCL" not in str(error) \
            and "heartbeat" not in str(error) and "coordination" not in str(error).lower():
        return None
    gone = _gone()
    who = (f"process{'es' if len(gone) > 1 else ''} {', '.join(map(str, gone))} of {jax.process_count()}" if gone
           else f"another of the {jax.process_count()} processes")
    return f"{who} stopped, so this one (process {jax.process_index()}) stops too: {str(error).splitlines()[0]}"


def _gone(wait: float = HEARTBEAT_SECONDS + 5) -> list[int]:
    """The processes the coordination service no longer hears from (as soon as it notices, up to `wait`)."""
    import jax
    from jax._src import distributed  # the client JAX keeps: the live processes are not asked of it otherwise

    client = distributed.global_state.client
    everyone = list(range(jax.process_count()))
    deadline = time.monotonic() + wait
    while client is not None and time.monotonic() < deadline:
        try:
            live = client.get_live_nodes(everyone)
        except Exception:  # the coordinator itself is gone
            return [0] if jax.process_index() != 0 else []
        gone = [p for p in everyone if p not in live]
        if gone:
            return gone
        time.sleep(1)
    return []
