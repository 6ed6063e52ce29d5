"""Files and folders fieldgen writes: each appears complete or not at all, is written by one process at a
time, and replaces only what fieldgen itself wrote.

A write that fails (a full disk, a read-only folder) raises `WriteError`, an OSError whose message
names the path and the reason, and leaves what was there before untouched. A write killed midway
can leave only hidden `.NAME.*.tmp` files or folders behind, which `remove_leftovers` clears.

Every folder fieldgen writes as a whole (a build, an exported policy, a curriculum) or sets up (a run)
holds an ownership record, `.fieldgen`, saying which command wrote it. `replace_folder` replaces a folder
only where that record says it is one of its kind, or where the folder holds nothing but the files its
kind is made of (one written before these records were kept); anything else is refused with `NotOurs`.
Each such folder is also locked while it is written (`locked`): a second process is refused with `InUse`,
saying which process holds it since when; the operating system drops the lock of a process that dies.

A single file a command writes where files of the user's may be (a summary, a figure, a video, a rendered
image) goes through `write_file`: the folder's record also lists each such file and the command that wrote
it, and a file that is there already is replaced only where that record (or the kind of the folder, for the
files a run or a sweep names) says the same command wrote it, and, for a listed file, where it still holds what
that command wrote (the record keeps its digest); anything else is refused with `NotOurs`.
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import dataclasses
import errno
import fcntl
import fnmatch
import hashlib
import json
import math
import os
import shlex
import shutil
import signal
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Callable

from fieldgen.version import VERSION
from fieldgen.video import FORMATS as VIDEO_FORMATS  # eval's videos; npz: an episode kept unrendered

TMP_SUFFIX = ".tmp"
OWNER = ".fieldgen"  # the ownership record in each folder fieldgen wrote
_OLD = ".old"  # a replaced folder moved aside, `.NAME.*.old.tmp`, until the new one stands in its place
_SIGNALS = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}  # held back while a folder is swapped in


class WriteError(OSError):
    """A file or folder fieldgen could not write; `str()` says which and why."""

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {self.strerror}"


class FolderError(Exception):
    """A folder fieldgen may not write now, or not at all; `str()` is the whole message, with what to do."""


class NotOurs(FolderError):
    """A folder fieldgen did not write, where it was asked to write one."""


class InUse(FolderError):
    """A folder another fieldgen process is writing."""


@dataclasses.dataclass(frozen=True)
class Output:
    """A kind of folder fieldgen writes: the command that writes it, and what it is made of (fnmatch
    patterns of its entries; a folder replaced whole may hold nothing else). `record` is the entry that
    marks one written before ownership records were kept; `option` is how the command is told where."""

    command: str
    made_of: tuple[str, ...]
    record: str
    option: str = "--out"
    files: tuple[str, ...] = ()  # files it writes one by one into folders (patterns); by default what it is made of
    inside: tuple[str, ...] = ()  # the commands whose folders it writes such files into (eval: a run's)
    # the keys its record holds (in each row, for a list): a file of the record's name without them is the user's
    record_keys: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.record and not self.record_keys:
            raise ValueError(f"{self.command}: name the keys of its record {self.record} (record_keys)")
        _KINDS.setdefault(self.command, self)

    def own(self, name: str) -> bool:
        """Whether `name` is one of the files this command writes into a folder (by name)."""
        return _matches(name, self.files or self.made_of or (self.record,))


_KINDS: dict[str, Output] = {}  # command -> what it writes (each Output made registers itself)

# the commands that write single files where files of the user's may be (write_file), beside the folders of
# builds, exports, curricula and runs (BUILD, POLICY, CURRICULUM, RUN_FOLDER in their own modules)
EVAL = Output("fieldgen eval", (), "", "--summary", files=("summary.json", "summary_*.json", "selfplay_eval.json",
                                                          *(f"eval{kept}.{suffix}" for kept in ("", "_*")
                                                            for suffix in (*VIDEO_FORMATS, "npz"))),
              inside=("fieldgen train",))
AGGREGATE = Output("fieldgen aggregate", (), "", "--summary")
RENDER = Output("fieldgen render", (), "", "-o", files=("levels.png",), inside=("fieldgen train",))
COMPARE = Output("fieldgen compare", (), "compare.json", "-o", files=("compare.json", "compare.png"),
                 record_keys=("algo", "success_any"))
SWEEP = Output("fieldgen sweep", (), "sweep.json", "out: (or --out)",
               files=("sweep.json", "summary.json", "summary.md", "summary-*.png"), record_keys=("runs",))
VIDEOS = Output("fieldgen videos", (), "")


def write_atomic(path: Path, data: bytes | Iterable[bytes]) -> None:
    """Write to a temporary file beside `path`, then rename it over `path`. `data` may come in pieces,
    written as they are made (a checkpoint larger than one should hold in memory twice)."""
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=TMP_SUFFIX)
    except OSError as exc:
        raise WriteError(exc.errno, exc.strerror, str(path)) from None
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp's 0600 would hide builds from other users
        with os.fdopen(fd, "wb") as f:
            for piece in [data] if isinstance(data, bytes) else data:
                f.write(piece)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise WriteError(exc.errno, exc.strerror, str(path)) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


# -- ownership ------------------------------------------------------------------------------------

def claim(folder: Path, output: Output) -> None:
    """Refuse (NotOurs) to write `folder` unless it is absent, empty, or an `output` fieldgen wrote. A folder
    replaced whole must also hold nothing but what `output` is made of, so that no file of the user's that
    was put in it is deleted with it."""
    if not folder.exists() and not folder.is_symlink():
        return
    where = f"choose another {output.option}"
    _refuse_unlike(folder, "folder", output, f"move it aside or {where}")
    entries = sorted(p.name for p in folder.iterdir() if p.name != OWNER and not _is_leftover(p.name))
    record = _record(folder)
    if record is not None and "written_by" not in record:
        record = None  # a folder of the user's that fieldgen wrote files into, not one it wrote
    if record is None and entries and not holds_record(folder, output):
        raise NotOurs(f"{folder} is not a folder {output.command} wrote (it holds {_some(entries)}); fieldgen "
                      f"replaces only what it wrote itself: move it aside or {where}")
    if record is not None and record.get("written_by") != output.command:
        raise NotOurs(f"{folder} was written by {record.get('written_by')!s}, not {output.command}; move it aside "
                      f"or {where}")
    foreign = [name for name in entries if output.made_of and not _matches(name, output.made_of)]
    if foreign:
        raise NotOurs(f"{folder} holds {_some(foreign)}, which {output.command} did not write; it replaces the "
                      f"folder whole, so move {'that' if len(foreign) == 1 else 'those'} out of it or {where}")


def mark(folder: Path, output: Output) -> None:
    """Record in `folder` that `output.command` wrote it (claim reads it back), keeping the files the record
    lists."""
    try:
        with _record_held(folder):
            before = _record(folder) or {}
            record = {"written_by": output.command, "fieldgen_version": VERSION, "files": _files(before) or {}}
            write_atomic(folder / OWNER, (json.dumps(record) + "\n").encode())
    except WriteError:
        raise
    except OSError as exc:
        raise WriteError(exc.errno, exc.strerror, str(folder)) from None


MAX_RECORD = 4 * 2**20  # an ownership record lists file names: megabytes would be one edited or damaged


def parsed_json(text: bytes | str):
    """The value JSON text holds; ValueError for any text that is not JSON, one nested deeper than Python's
    parser follows included (which it reports as RecursionError), so that every reader of a record fieldgen
    wrote refuses an edited or damaged one in its own words."""
    try:
        return json.loads(text)
    except RecursionError:
        raise ValueError("nested deeper than any record fieldgen writes") from None


def holds_record(folder: Path, kind: Output) -> bool:
    """Whether `folder` holds `kind`'s own record as that command writes it (a mapping with its keys), which marks a
    folder written before ownership records were kept: a file of the user's that has only the record's name
    (a run.json of their own) marks nothing."""
    path = folder / kind.record
    if not kind.record or path.is_symlink() or not path.is_file():
        return False
    try:
        text = path.read_bytes()[:MAX_RECORD]
        if path.suffix in (".yaml", ".yml"):
            import yaml

            value = yaml.safe_load(text)
        else:
            value = parsed_json(text)
    except Exception:  # unreadable, or not JSON / YAML: not a record fieldgen wrote
        return False
    rows = value if isinstance(value, list) and value else [value]
    return all(isinstance(row, dict) and set(kind.record_keys) <= set(row) for row in rows)


def _record(folder: Path) -> dict | None:
    try:
        record = parsed_json((folder / OWNER).read_bytes()[:MAX_RECORD])
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def written_by(folder: Path) -> str | None:
    """The command that wrote `folder` by its ownership record (`fieldgen export`, `fieldgen build`...); None where
    it has none: a folder of the user's, or one kept before records were."""
    record = _record(folder)
    writer = record.get("written_by") if record else None
    return writer if isinstance(writer, str) else None


def _files(record: dict) -> dict[str, str] | None:
    """The files a record lists (name -> the command that wrote it); None in one kept before it listed them."""
    files = record.get("files")
    if not isinstance(files, dict):
        return None
    return {k: v for k, v in files.items() if isinstance(k, str) and isinstance(v, str)}


@contextlib.contextmanager
def _record_held(folder: Path) -> Iterator[None]:
    """Hold `folder`'s record against other processes while it is read and written again (a lock on the folder
    itself, which leaves no file behind)."""
    fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    try:
        with contextlib.suppress(OSError):  # a file system without locks (some network ones): written unguarded
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


# -- single files ---------------------------------------------------------------------------------

def writer_of(path: Path) -> str | None:
    """The command that wrote the file at `path`, by its folder's record: the files the folder's own kind names
    (a run's run.json, a sweep's summary.json), then the files the record lists. For a folder kept before records
    listed files (its record names only its kind, or there is none and the kind is told by its own record file,
    a run's run.json or a sweep's sweep.json): the names other commands give the files they write into folders of
    that kind (eval's summary.json in a run). None for a file fieldgen did not write."""
    folder, name = path.parent, path.name
    record = _record(folder)
    if record is None:
        kind = next((k for k in _KINDS.values() if holds_record(folder, k)), None)
    else:
        kind = _KINDS.get(record.get("written_by"))
    if kind is not None and kind.own(name):
        return kind.command
    files = _files(record) if record else None
    if files is not None or kind is None:
        return (files or {}).get(name)
    return next((other.command for other in _KINDS.values() if kind.command in other.inside and other.own(name)),
                None)


def _refuse_unlike(path: Path, kind: str, output: Output, where: str) -> None:
    """Refuse (NotOurs) a link, or an entry of the other kind, where `output` would write a `kind` (file, folder)."""
    is_kind = path.is_file() if kind == "file" else path.is_dir()
    if path.is_symlink() or not is_kind:
        what = "a link" if path.is_symlink() else "a folder" if kind == "file" else "a file"
        raise NotOurs(f"{path} is {what}, not a {kind} {output.command} wrote; fieldgen replaces only what it wrote "
                      f"itself: {where}")


def check_file(path: Path, output: Output, how: str | None = None, folder_made: bool = True) -> None:
    """Refuse (NotOurs) to write the file `path` for `output.command` where something is there that the same
    command did not write (a file of the user's, another command's, a run's own record, a folder, a link), and
    (FolderError) where its folder cannot take it (a file in its place, or read-only; missing, where the command
    makes no folder: not `folder_made`): a command checks before its work what would otherwise fail only once the
    work is done. `how` is what else the user may do (by default: choose another path with `output.option`)."""
    how = how or _another(output)
    _check_folder(path, how, folder_made)
    _check_replace(path, output, how)


def _another(output: Output) -> str:
    """What else a user may do where a command's file cannot be written: name another path."""
    return f"choose another {output.option}"


def _check_folder(path: Path, how: str, folder_made: bool) -> None:
    folder = path.parent
    blocker = file_in_the_way(folder)
    if blocker is not None:
        raise FolderError(f"cannot write {path}: {blocker} is {kind_of_blocker(blocker)}, not a folder; move it "
                          f"aside or {how}")
    if not folder.is_dir():
        if folder_made:
            return  # said by whoever makes the folder
        raise FolderError(f"cannot write {path}: there is no folder {folder} to write it in; make it, or {how}")
    # asked, not tried: a file made and removed to find out would change the folder a check must leave as it was
    if not os.access(folder, os.W_OK | os.X_OK):  # permissions, or a read-only disk (root's too)
        raise FolderError(f"cannot write {path}: its folder is read-only or not the user's to write in; fix the "
                          f"folder's permissions or {how}")


def _check_replace(path: Path, output: Output, how: str) -> None:
    if not path.exists() and not path.is_symlink():
        return
    where = f"move it aside or {how}"
    _refuse_unlike(path, "file", output, where)
    writer = writer_of(path)
    if writer is None:
        raise NotOurs(f"{path} is not a file fieldgen wrote; fieldgen replaces only what it wrote itself: {where}")
    if writer != output.command:
        raise NotOurs(f"{path} was written by {writer}, not {output.command}; it replaces only its own files: "
                      f"{where}")
    written = _digests(_record(path.parent)).get(path.name)
    if written is not None and _digest(path) != written:
        raise NotOurs(f"{path} has changed since {writer} wrote it (edited, or another file put in its place); "
                      f"fieldgen replaces only what it wrote itself: {where}")


def write_file(path: Path, data: bytes | Iterable[bytes], output: Output, how: str | None = None) -> None:
    """Write the file `path` as `output.command` (refused, as by check_file, where it would replace what that
    command did not write; a folder that cannot take it is a WriteError, which each writer words), record in
    the folder that it wrote it, then write it whole (write_atomic)."""
    _check_replace(path, output, how or _another(output))
    own(path, output)
    digest = hashlib.sha256()

    def hashed() -> Iterator[bytes]:
        for piece in [data] if isinstance(data, bytes) else data:
            digest.update(piece)
            yield piece

    write_atomic(path, hashed())
    _remember(path, digest.hexdigest())


def own(path: Path, output: Output) -> None:
    """Record in the folder of `path` that `output.command` writes it (before it is written: a file listed and
    never written is no one's, one written and never listed would be refused). A record kept before it listed
    files gains the files fieldgen wrote by the same rules `writer_of` reads it by."""
    try:
        _own(path, output)
    except OSError as exc:  # the folder is missing, a file, or cannot be written: said of the file asked for
        raise WriteError(exc.errno, exc.strerror, str(path)) from None


def _own(path: Path, output: Output) -> None:
    folder = path.parent
    with _record_held(folder):
        record = _record(folder)
        files = _files(record) if record else None
        if files is None:
            files = {}
            earlier = record is not None or any(holds_record(folder, k) for k in _KINDS.values())
            if earlier:  # a folder an earlier fieldgen wrote: the files it wrote there become listed
                with contextlib.suppress(OSError):
                    for entry in folder.iterdir():
                        writer = writer_of(entry) if entry.is_file() and not entry.is_symlink() else None
                        if writer is not None and entry.name != OWNER:
                            files[entry.name] = writer
        kind = _KINDS.get(record.get("written_by")) if record else None
        if files.get(path.name) == output.command or (kind is not None and kind.own(path.name)
                                                     and kind.command == output.command):
            if record is not None and _files(record) is not None:
                return
        files[path.name] = output.command
        record = {**(record or {}), "files": files}
        record.setdefault("fieldgen_version", VERSION)
        write_atomic(folder / OWNER, (json.dumps(record) + "\n").encode())


def _remember(path: Path, digest: str) -> None:
    """Record the digest of what was just written to `path`, a file its folder's record lists (a file a folder's
    own kind names, a run's plots, is rewritten as it goes and never listed): a file changed since, by an edit or
    another file put in its place, is then the user's, and `check_file` refuses to replace it."""
    folder = path.parent
    try:
        with _record_held(folder):
            record = _record(folder)
            if record is None or path.name not in (_files(record) or {}):
                return
            record["digests"] = {**_digests(record), path.name: digest}
            write_atomic(folder / OWNER, (json.dumps(record) + "\n").encode())
    except OSError as exc:
        raise WriteError(exc.errno, exc.strerror, str(path)) from None


def _digests(record: dict | None) -> dict[str, str]:
    """The digests a record keeps (file name -> SHA-256 of what fieldgen wrote there); none in one kept before."""
    digests = record.get("digests") if record else None
    if not isinstance(digests, dict):
        return {}
    return {k: v for k, v in digests.items() if isinstance(k, str) and isinstance(v, str)}


def _digest(path: Path) -> str | None:
    """The SHA-256 of the file at `path`, read in pieces; None where it cannot be read."""
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(2**20), b""):
                digest.update(block)
    except OSError:
        return None
    return digest.hexdigest()


def _matches(name: str, patterns: tuple[str, ...]) -> bool:
    return any(fnmatch.fnmatchcase(name, p) for p in patterns)


def _some(names: list[str]) -> str:
    shown = ", ".join(names[:3])
    return shown + (f" and {len(names) - 3} more" if len(names) > 3 else "")


# -- one writer at a time -------------------------------------------------------------------------

_held: dict[Path, list] = {}  # lock file -> [its descriptor, how many times this process took it]


def take(folder: Path) -> None:
    """Lock `folder` for this process until `release` (or the process ends); taking it again nests. The lock
    is a hidden file beside the folder, `.NAME.lock`, so that it outlives the folder being swapped; a lock
    left by a process that died is no lock (the system drops it), and the file goes with its last holder."""
    path = _lock_path(folder)
    if path in _held:
        _held[path][1] += 1
        return
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666 & ~_umask())
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.read(fd, 4096)
                os.close(fd)
                raise InUse(_in_use(folder, holder)) from None
            with contextlib.suppress(FileNotFoundError):
                if os.fstat(fd).st_ino == os.stat(path).st_ino:
                    break  # else its last holder removed the file between our open and our lock: open the new one
            os.close(fd)
    except FileExistsError:
        blocker = _in_the_way(folder)
        why = ("a link that leads nowhere (a loop of links, or to nothing) is in the way of the folder"
               if blocker.is_symlink() else "a file is in the way of the folder")
        raise WriteError(errno.ENOTDIR, why, str(blocker)) from None
    except OSError as exc:
        raise WriteError(exc.errno, exc.strerror, str(folder)) from None
    holder = {"pid": os.getpid(), "host": socket.gethostname(), "since": time.strftime("%Y-%m-%d %H:%M:%S"),
              "command": shlex.join([Path(sys.argv[0]).name, *sys.argv[1:]])}
    with contextlib.suppress(OSError):  # who holds it is only told to others: the lock holds without it
        os.ftruncate(fd, 0)
        os.write(fd, json.dumps(holder).encode())
    _held[path] = [fd, 1]


def release(folder: Path) -> None:
    """Undo one `take` of `folder`; the last removes the lock file and unlocks."""
    _release(_lock_path(folder))


def _release(path: Path, whole: bool = False) -> None:
    entry = _held.get(path)
    if entry is None:
        return
    entry[1] = 0 if whole else entry[1] - 1
    if entry[1] == 0:
        del _held[path]
        with contextlib.suppress(OSError):
            path.unlink()  # while locked: a process waiting on this file finds it gone and opens a new one
        os.close(entry[0])


@atexit.register
def release_all() -> None:
    """Every lock this process holds (a command that ends, whatever it left held)."""
    for path in list(_held):
        _release(path, whole=True)


@contextlib.contextmanager
def locked(folder: Path) -> Iterator[None]:
    take(folder)
    try:
        yield
    finally:
        release(folder)


def _lock_path(folder: Path) -> Path:
    folder = Path(os.path.abspath(folder))
    return folder.parent / f".{folder.name}.lock"


def _in_use(folder: Path, holder: bytes) -> str:
    try:
        info = json.loads(holder)
        who = f"process {int(info['pid'])}"
        if info.get("host") != socket.gethostname():
            who += f" on {info.get('host')}"
        who += f" since {info['since']} ({info['command']})"
    except (ValueError, KeyError, TypeError):
        who = "another process"
    return (f"{folder} is in use by {who}; one fieldgen command writes a folder at a time: wait for that one to "
            "end (or stop it), then run this again")


# -- replacing whole ------------------------------------------------------------------------------

def replace_folder(folder: Path, fill: Callable[[Path], None], output: Output) -> None:
    """Make `folder` anew: `fill(staging)` writes a hidden sibling folder, which then takes `folder`'s
    place in one exchange of names. A reader sees the old folder or the new one, never a mix, and a process
    stopped at any moment (SIGKILL included) leaves the old one or the new one in place, with at most
    hidden leftovers that the next replace of the same folder clears. Refused (NotOurs) where `folder` is
    not an `output` fieldgen wrote, and (InUse) while another process writes it."""
    with locked(folder):
        remove_leftovers(folder.parent, folder.name)
        claim(folder, output)
        try:
            staging = Path(tempfile.mkdtemp(dir=folder.parent, prefix=f".{folder.name}.", suffix=TMP_SUFFIX))
        except OSError as exc:
            raise WriteError(exc.errno, exc.strerror, str(folder)) from None
        try:
            os.chmod(staging, 0o777 & ~_umask())
            fill(staging)
            mark(staging, output)
            _swap(staging, folder)
        except OSError as exc:
            shutil.rmtree(staging, ignore_errors=True)
            raise WriteError(exc.errno, exc.strerror, str(folder)) from None
        except BaseException:
            shutil.rmtree(staging, ignore_errors=True)
            raise
        shutil.rmtree(staging, ignore_errors=True)  # the old folder, now under the staging name


def _swap(staging: Path, folder: Path) -> None:
    """Put `staging` at `folder`, and what was at `folder` (if anything) at `staging`. Where the system can
    exchange two names at once (Linux), nothing else is needed; elsewhere the old folder is first moved to
    an `.old.tmp` name that `remove_leftovers` puts back if the process dies before the new one is in."""
    if not folder.exists():
        os.replace(staging, folder)
        return
    if _exchange(staging, folder):
        return
    old = staging.with_name(staging.name.removesuffix(TMP_SUFFIX) + _OLD + TMP_SUFFIX)
    with _signals_deferred():
        os.replace(folder, old)
        os.replace(staging, folder)
        os.replace(old, staging)


@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """Ctrl-C, kill and a closed terminal (SIGINT, SIGTERM, SIGHUP) wait until the block is done, then act as
    they would have. Handlers, not a signal mask: a mask holds for one thread, and the system may hand the
    signal to any other."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    previous = {sig: signal.signal(sig, lambda number, frame: caught.append(number)) for sig in _SIGNALS}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        for sig in dict.fromkeys(caught):
            os.kill(os.getpid(), sig)


_RENAME_EXCHANGE = 2


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths' names in one step (Linux renameat2 with RENAME_EXCHANGE); False where the system or its
    file system cannot."""
    renameat2 = getattr(_libc(), "renameat2", None)
    if renameat2 is None:
        return False
    at_cwd = -100
    if renameat2(at_cwd, os.fsencode(a), at_cwd, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP):
        return False
    raise OSError(code, os.strerror(code), str(b))


_LIBC: list = []


def _libc():
    if not _LIBC:
        try:
            _LIBC.append(ctypes.CDLL(None, use_errno=True))
        except OSError:
            _LIBC.append(None)
    return _LIBC[0]


def remove_leftovers(folder: Path, name: str | None = None) -> list[Path]:
    """Delete what killed writes left behind (hidden `.*.tmp` files and folders): in `folder` and below, or
    with `name` only those of `folder/name` (a build beside others that may be written at the same time).
    A replaced folder moved aside by a replace that was stopped before the new one came in is put back."""
    if name is None:
        found = sorted(p for p in folder.rglob(f".*{TMP_SUFFIX}") if p.name.startswith("."))
    else:
        found = sorted(folder.glob(f".{name}.*{TMP_SUFFIX}"))
        aside = [p for p in found if p.name.endswith(_OLD + TMP_SUFFIX) and p.is_dir()]
        if aside and not (folder / name).exists():
            with contextlib.suppress(OSError):
                os.replace(aside[0], folder / name)
                found.remove(aside[0])
    for path in found:  # best effort: a folder we may not write keeps them, and says so when written to
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                path.unlink()
    return found


def _is_leftover(name: str) -> bool:
    return name.startswith(".") and name.endswith(TMP_SUFFIX)


def _in_the_way(folder: Path) -> Path:
    """The file, or the link that leads nowhere (a loop, a missing target), where a folder above `folder` should
    be; the nearest parent where the system raced us to it."""
    return file_in_the_way(folder.parent) or folder.parent


def file_in_the_way(folder: Path) -> Path | None:
    """The file, or the link that leads nowhere (a loop, a missing target), at `folder` or where a folder above it
    should be; None where nothing is: a folder that cannot be made is then told by what blocks it, not by the
    system's "Not a directory" about a path below."""
    return next((p for p in (folder, *folder.parents) if (p.is_symlink() or p.exists()) and not p.is_dir()), None)


def kind_of_blocker(blocker: Path) -> str:
    """What file_in_the_way (or stands_unlike) found, in the words every message about it uses."""
    if blocker.is_dir():
        return "a folder"
    return "a link that leads nowhere (a loop of links, or to nothing)" if blocker.is_symlink() else "a file"


def stands_unlike(path: Path, is_kind) -> bool:
    """Whether something stands at `path` that is not of the kind a command writes there (`is_kind`: Path.is_file or
    Path.is_dir), a link that leads nowhere included: what it must refuse before its work rather than fail at."""
    return path.is_symlink() and not path.exists() or path.exists() and not is_kind(path)


def named_twice(paths: Iterable[Path]) -> str | None:
    """The first path named twice (as itself, through a link, or a path that leads to it), as a sentence's start
    that each caller ends with why once is enough; None where each is named once."""
    seen: dict[str, Path] = {}
    for path in paths:
        real = os.path.realpath(path)  # a loop of links is left to the caller's own check, not raised here
        if (first := seen.get(real)) is not None:
            also = "" if str(first) == str(path) else f" (also as {path})"
            return f"{first} is named twice{also}"
        seen[real] = path
    return None


def append_jsonl(path: Path | None, row: dict) -> None:
    """Add one benchmark result row to a JSON-lines file (nothing when path is None): the file rewritten whole beside itself
    and renamed over, so a full disk or a kill leaves the rows before intact; a value that is no number (NaN, as a
    ratio with no reference row) is written null, which every JSON reader takes."""
    if path is not None:
        before = path.read_bytes() if path.exists() else b""
        torn = b"\n" if before and not before.endswith(b"\n") else b""  # a last line cut before this code
        write_atomic(path, [before, torn, (json.dumps(_finite(row), allow_nan=False) + "\n").encode()])


def _finite(value):
    """`value` with every float that is not finite replaced by None, through dicts and lists."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


NO_SPACE, NO_PERMISSION = {errno.ENOSPC, errno.EDQUOT}, {errno.EACCES, errno.EPERM}


def way_on(folder: Path, flag: str, error: OSError | None = None, said: bool = False) -> str:
    """How to go on where `folder` could not be written: move aside what stands where a folder should
    (file_in_the_way), for which no space or permission helps; else, after the system's words for `error` unless
    the message `said` them already, what helps with that error (space for a full disk, permissions where they
    refuse, another place on a read-only disk or one where no folder can be made), or, where the error is not
    known, any of them; and always another place with `flag` (--out, -o)."""
    blocker = file_in_the_way(folder)
    if blocker is not None:  # the system's words are about a path below it: "Not a directory"
        return f"{blocker} is {kind_of_blocker(blocker)}, not a folder; move it aside or choose another {flag}"
    why = f"{error.strerror}; " if error is not None and error.strerror and not said else ""
    code = None if error is None else error.errno
    if code in NO_SPACE:
        return f"{why}free some space or choose another {flag}"
    if code in NO_PERMISSION:
        return f"{why}fix the folder's permissions or choose another {flag}"
    if code is not None:  # a read-only disk, or a place where no folder can be made (/proc): another place
        return f"{why}choose another {flag}"
    return f"{why}free some space, fix the folder's permissions or choose another {flag}"


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask
