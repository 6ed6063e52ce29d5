"""Files and folders replaced whole: everything fieldgen writes appears complete or not at all.

A write that fails (a full disk, a read-only folder) raises `WriteError`, an OSError whose message
names the path and the reason, and leaves what was there before untouched. A write killed midway
can leave only hidden `.NAME.*.tmp` files or folders behind, which `remove_leftovers` clears.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import Callable

TMP_SUFFIX = ".tmp"


class WriteError(OSError):
    """A file or folder fieldgen could not write; `str()` says which and why."""

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {self.strerror}"


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


def replace_folder(folder: Path, fill: Callable[[Path], None]) -> None:
    """Make `folder` anew: `fill(staging)` writes a hidden sibling folder, which then takes `folder`'s
    place. A reader sees the old folder or the new one, never a mix; a kill between the two renames
    leaves no folder (and the old one hidden, for `remove_leftovers`), never a wrong one."""
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(dir=folder.parent, prefix=f".{folder.name}.", suffix=TMP_SUFFIX))
    except FileExistsError:  # mkdir's word for a file where a folder should be
        in_the_way = next(p for p in (folder.parent, *folder.parent.parents) if p.exists() and not p.is_dir())
        raise WriteError(errno.ENOTDIR, "a file is in the way of the folder", str(in_the_way)) from None
    except OSError as exc:
        raise WriteError(exc.errno, exc.strerror, str(folder)) from None
    try:
        os.chmod(staging, 0o777 & ~_umask())
        fill(staging)
        old = None
        if folder.exists():
            old = Path(tempfile.mkdtemp(dir=folder.parent, prefix=f".{folder.name}.", suffix=TMP_SUFFIX))
            os.replace(folder, old / folder.name)
        os.replace(staging, folder)
    except OSError as exc:
        shutil.rmtree(staging, ignore_errors=True)
        raise WriteError(exc.errno, exc.strerror, str(folder)) from None
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def remove_leftovers(folder: Path, name: str | None = None) -> list[Path]:
    """Delete what killed writes left behind (hidden `.*.tmp` files and folders): in `folder` and below, or
    with `name` only those of `folder/name` (a build beside others that may be written at the same time)."""
    if name is None:
        found = sorted(p for p in folder.rglob(f".*{TMP_SUFFIX}") if p.name.startswith("."))
    else:
        found = sorted(folder.glob(f".{name}.*{TMP_SUFFIX}"))
    for path in found:  # best effort: a folder we may not write keeps them, and says so when written to
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                path.unlink()
    return found


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask
