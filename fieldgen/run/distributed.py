"""One run over several processes, one per host or per GPU: JAX's multi-controller runtime
(jax.distributed), which every `fieldgen train` process joins before anything touches a device. The
processes then see one global set of devices, over which agents.sharding lays one mesh; each trains its
share, and the first writes the run folder.

Where the processes come from: `--coordinator HOST:PORT --num-processes N --process-id I` (or the
FIELDGEN_COORDINATOR, FIELDGEN_NUM_PROCESSES and FIELDGEN_PROCESS_ID variables), or, with none of them,
a launcher JAX recognises by itself when it started more than one task (srun, mpirun). Failures come as
one line naming the process, the address and what to check, each within the timeout: settings that do not fit,
a launcher's task count without the launcher's other variables, a coordinator port another program holds, a
coordinator that never answers, processes that never come to it (process 0 first meets the others on its port,
`gather`, before JAX's runtime, which would end it with a fatal error, is started), and, mid-run, a process that
died (`watch`, `stop_if_another_stopped`).
"""

from __future__ import annotations

import atexit
import dataclasses
import errno
import os
import socket
import sys
import threading
import time
from typing import Callable, Sequence

from fieldgen.run.record import RunError

HEARTBEAT_SECONDS = 30  # a process silent this long is taken for dead, and the others are stopped
FINISHED_KEY = "fieldgen/finished"  # + "/<process>": set by each process that trained to the end
LAUNCHERS = {"SLURM_STEP_NUM_TASKS": "srun", "OMPI_COMM_WORLD_SIZE": "mpirun"}  # variable -> launcher
# the variables JAX reads a launcher's processes from (jax._src.clusters): all set in a process it started
LAUNCHED = {"srun": ("SLURM_JOB_ID", "SLURM_STEP_NODELIST", "SLURM_NTASKS", "SLURM_PROCID", "SLURM_LOCALID"),
            "mpirun": ("OMPI_MCA_orte_hnp_uri", "OMPI_COMM_WORLD_RANK", "OMPI_COMM_WORLD_LOCAL_RANK")}
HELLO = b"fieldgen process "  # + "<id>\n": what a process other than 0 says on process 0's port before joining
_stopping = threading.Lock()  # one thread says why the process stops, and ends it
_finished = threading.Event()  # this process trained to the end: no other's leaving stops it


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
        launched = [(variable, name) for variable, name in LAUNCHERS.items() if _count(variable) > 1]
        for variable, name in launched:
            missing = [v for v in LAUNCHED[name] if v not in os.environ]
            if missing:
                raise RunError(f"{variable}={os.environ[variable]} says {name} started {_count(variable)} processes, "
                               f"but {', '.join(missing)} {'is' if len(missing) == 1 else 'are'} not set, so {name} did "
                               f"not start this one: start it with {name}, give --coordinator HOST:PORT "
                               f"--num-processes N --process-id I, or unset {variable} (left from another shell) to "
                               "train in this process alone")
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
    if host and port.isdigit() and not 0 < int(port) < 65536:
        raise RunError(f"--coordinator {coordinator}: port {int(port):,} is out of range; a port is 1 to 65535, a "
                       "free one on process 0's host, such as node01:12345")
    if not host or not port.isdigit():
        raise RunError(f"--coordinator {coordinator}: write it as HOST:PORT, the address of process 0's host and a "
                       "free port, such as node01:12345")
    return Layout(coordinator, num_processes, process_id)


def _count(variable: str) -> int:
    try:
        return int(os.environ.get(variable) or 1)
    except ValueError:
        return 1


def join(where: Layout, timeout: int) -> dict:
    """Join the run's processes (waiting up to `timeout` seconds for the coordinator and the others); returns
    the layout as run.json records it."""
    import jax

    gather(where, timeout)
    reach(where, timeout)
    jax.config.update("jax_cpu_collectives_implementation", "gloo")  # CPU processes reach one another too
    # a process that stops is then noticed by asking the coordination service (`watch`), instead of JAX
    # aborting every other process with a stack trace
    jax.config.update("jax_enable_recoverability", True)
    try:
        jax.distributed.initialize(where.coordinator, where.num_processes, where.process_id,
                                   initialization_timeout=timeout, heartbeat_timeout_seconds=HEARTBEAT_SECONDS)
    except Exception as exc:  # noqa: BLE001 - JAX's runtime fails in its own words
        me = "this process" if where.process_id is None else f"process {where.process_id}"
        at = where.coordinator or "the address its launcher gives"
        said = " ".join(str(exc).split())[:300] or type(exc).__name__
        raise RunError(f"{me} could not join the run's processes at {at} within {timeout} s ({said}): check that "
                       "every process was started with the same --coordinator and --num-processes and its own "
                       "--process-id, and that the port is open between the hosts") from None
    if jax.process_index() == 0:
        atexit.register(_leave_last, jax.process_count())  # before JAX's exit handler, which stops the service
    counts = [sum(d.process_index == p for d in jax.devices()) for p in range(jax.process_count())]
    return {"count": jax.process_count(), "devices_per_process": counts,
            "coordinator": where.coordinator or "from the launcher"}


def reach(where: Layout, timeout: int) -> None:
    """Wait until process 0's coordinator answers, for a process other than 0 given its address, and say this
    process's id to it (`gather`)."""
    if where.coordinator is not None and where.process_id != 0:
        _wait_for(where.coordinator, timeout, where.process_id)


def _wait_for(coordinator: str, timeout: int, process_id: int | None = None) -> None:
    """Wait until process 0's coordinator accepts connections (saying `process_id` to it): JAX itself would
    end the process with a stack trace when it never does."""
    host, _, port = coordinator.rpartition(":")
    deadline = time.monotonic() + timeout
    while True:
        try:
            with socket.create_connection((host, int(port)), timeout=5) as connection:
                if process_id is not None:
                    connection.sendall(HELLO + f"{process_id}\n".encode())
            return
        except OSError as exc:
            if time.monotonic() > deadline:
                raise RunError(f"no coordinator answered at {coordinator} within {timeout} s ({exc.strerror or exc}): "
                               "start process 0 (--process-id 0 runs it) on that host, and check the address "
                               "and that the port is open between the hosts") from None
            time.sleep(0.5)


def gather(where: Layout, timeout: int) -> None:
    """In process 0 given its address: listen on the coordinator's port until every other process has said its
    id there (`reach`), then free the port for JAX's coordination service. A port another program holds, and
    processes that never come within `timeout` seconds, are one line each: JAX's runtime, started without them,
    would end this process with a fatal error (or a crash) that no Python code can catch."""
    if where.coordinator is None or where.process_id != 0:
        return
    _, _, port = where.coordinator.rpartition(":")
    listener = _listen(int(port), where.coordinator)
    waiting = set(range(1, where.num_processes))
    deadline = time.monotonic() + timeout
    with listener:
        while waiting:
            left = deadline - time.monotonic()
            if left <= 0:
                them = ", ".join(map(str, sorted(waiting)))
                plural = len(waiting) > 1
                raise RunError(f"process 0 of {where.num_processes} waited {timeout} s at {where.coordinator} for "
                               f"process{'es' * plural} {them}, which never came: start {'them' if plural else 'it'} "
                               f"with --coordinator {where.coordinator} --num-processes {where.num_processes} "
                               f"--process-id {'I' if plural else them}, and check that the address and the port are "
                               "reachable from their hosts (or raise --coordinator-timeout)")
            listener.settimeout(min(left, 1.0))
            try:
                connection, _ = listener.accept()
            except (socket.timeout, InterruptedError):
                continue
            with connection:
                said = _said(connection, deadline)
            if said is not None:
                waiting.discard(said)


def _listen(port: int, coordinator: str) -> socket.socket:
    """A socket listening on `port` of every address of this host, as JAX's coordination service listens."""
    for family, address in ((socket.AF_INET6, "::"), (socket.AF_INET, "0.0.0.0")):
        try:
            listener = socket.socket(family, socket.SOCK_STREAM)
        except OSError:
            continue
        try:
            listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            if family == socket.AF_INET6:
                listener.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 0)
            listener.bind((address, port))
            listener.listen(64)
            return listener
        except OSError as exc:
            listener.close()
            if exc.errno == errno.EADDRINUSE or family == socket.AF_INET:
                why = "another program listens on it" if exc.errno == errno.EADDRINUSE else exc.strerror
                raise RunError(f"process 0 cannot start the run's coordinator at {coordinator}: port {port} of this "
                               f"host is taken ({why}): choose a free port in --coordinator, the same for every "
                               "process") from None
    raise RunError(f"process 0 cannot start the run's coordinator at {coordinator}: this host gives no socket")


def _said(connection: socket.socket, deadline: float) -> int | None:
    """The process id a process other than 0 said (`HELLO`), None for anything else. Read to its end: the other
    side closes first, so that what is left of the connection on this host holds no port JAX's service needs."""
    data = b""
    try:
        while len(data) < 64:
            connection.settimeout(max(0.1, min(5.0, deadline - time.monotonic())))
            piece = connection.recv(64)
            if not piece:
                break
            data += piece
    except OSError:
        return None
    if not data.startswith(HELLO):
        return None
    try:
        return int(data[len(HELLO):].strip())
    except ValueError:
        return None


def free_port() -> int:
    """A port nobody on this host listens on now: where a coordinator can be started for the processes of a
    run on one machine (the ones a test or a benchmark starts)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def only_devices(platform: str, devices: Sequence[int | str]) -> dict[str, str]:
    """The environment variables that give a process started on this machine these devices alone: GPUs by
    index (or UUID); on the CPU as many devices as listed, which XLA makes up (`platform` is "gpu" or "cpu")."""
    if platform == "gpu":
        return {"CUDA_VISIBLE_DEVICES": ",".join(map(str, devices))}
    flags = f"{os.environ.get('XLA_FLAGS', '')} --xla_force_host_platform_device_count={len(devices)}"
    return {"JAX_PLATFORMS": "cpu", "XLA_FLAGS": flags.strip()}


def watch(say: Callable[[str], None]) -> None:
    """From now on until `finished`, as soon as the coordination service misses a process (by its heartbeat),
    `say` a sentence naming it and stop this one, whatever it is doing: computing, compiling or waiting for
    that process in a collective. Nothing to watch in a run of one process."""
    import jax

    if jax.process_count() > 1:  # the thread asks JAX nothing: at exit JAX's state is being taken down
        layout = (jax.process_index(), jax.process_count())
        threading.Thread(target=_watch, args=(say, *layout), name="fieldgen-watch", daemon=True).start()


def finished() -> None:
    """Tell the other processes this one trained to the end (leaving is then no failure), and stop watching."""
    client = _client()
    if client is not None:
        import jax

        with _stopping:
            _finished.set()
        client.key_value_set(f"{FINISHED_KEY}/{jax.process_index()}", "1")


def stop_if_another_stopped(error: BaseException, say: Callable[[str], None]) -> None:
    """Where `error` is a collective's failure in a run over several processes because another process
    stopped, `say` so and stop, once the coordination service names it (within a heartbeat); return
    otherwise."""
    import jax

    text, me, count = str(error), jax.process_index(), jax.process_count()
    if count == 1 or not any(word in text for word in ("Gloo", "NCCL", "heartbeat")) \
            and "coordination" not in text.lower():
        return
    deadline = time.monotonic() + HEARTBEAT_SECONDS + 5
    while time.monotonic() < deadline:
        gone = _gone(me, count)
        if gone:
            _stop(say, gone, me, count)
        time.sleep(1)


def _client():
    """The coordination service's client (agents.sharding.coordination_client): whether the others live and
    what they said are not asked of JAX otherwise; multihost_utils.live_devices is a barrier every process
    must enter (no watcher thread can call it) and reads no keys."""
    from fieldgen.agents.sharding import coordination_client

    return coordination_client()


def _gone(me: int, count: int) -> list[int]:
    """The processes the coordination service no longer hears from and that did not finish."""
    client, everyone = _client(), list(range(count))
    try:
        live = client.get_live_nodes(everyone)
    except Exception:  # the coordinator itself is gone
        return [0] if me != 0 else []
    gone = []
    for p in everyone:
        if p not in live:
            try:
                client.key_value_try_get(f"{FINISHED_KEY}/{p}")
            except Exception:  # no such key: it stopped before the end
                gone.append(p)
    return gone


def _watch(say: Callable[[str], None], me: int, count: int) -> None:
    while not _finished.is_set():
        gone = _gone(me, count)
        if gone:
            _stop(say, gone, me, count)
        time.sleep(1)


def _stop(say: Callable[[str], None], gone: list[int], me: int, count: int) -> None:
    """`say` which processes stopped, and end this one at once (JAX's own exit would wait for them); nothing
    once this one has finished."""
    with _stopping:
        if _finished.is_set():
            return
        say(stopped(gone, me, count))
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(1)


def stopped(gone: Sequence[int], me: int | None = None, count: int | None = None) -> str:
    """The sentence that says processes of the run stopped, so this one (`me`, of `count`, where known) stops
    too: the one wording of it, whoever notices first (`watch`, `stop_if_another_stopped`, or the parent of a
    supervised process that JAX ended as process 0 stopped: fieldgen.run.supervisor). Process 0 is named the
    run's coordinator, the process every other one needs."""
    who = f"process{'es' if len(gone) > 1 else ''} {', '.join(map(str, gone))}"
    if count is not None:
        who += f" of {count}"
    if 0 in gone:
        who += " (the run's coordinator)" if len(gone) == 1 else " (process 0 is the run's coordinator)"
    return f"{who} stopped, so this one{'' if me is None else f' (process {me})'} stops too"


def _leave_last(count: int) -> None:
    """Process 0 holds the coordination service, which the others' runtimes need until they have left:
    it waits for them (a heartbeat at most, as one that failed may never leave)."""
    client, everyone = _client(), list(range(count))
    deadline = time.monotonic() + HEARTBEAT_SECONDS
    while client is not None and time.monotonic() < deadline:
        try:
            if set(client.get_live_nodes(everyone)) <= {0}:
                return
        except Exception:
            return
        time.sleep(0.2)
