"""One worker thread for a run's slow writes (checkpoints of a gigabyte or more, videos), so that
training goes on while they are serialized, rendered and written."""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from typing import Callable


class Writer:
    """Runs jobs one at a time in the order given. `wait` blocks until all are done and raises the
    first failure here, in the training thread; leaving the `with` block waits too, so the last
    checkpoint lands before the process reports or exits."""

    def __init__(self) -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="fieldgen-writer")
        self._pending: list[Future] = []

    @property
    def busy(self) -> bool:
        return any(not f.done() for f in self._pending)

    def submit(self, job: Callable, *args) -> None:
        self._pending.append(self._pool.submit(job, *args))

    def wait(self) -> None:
        pending, self._pending = self._pending, []
        for future in pending:
            future.result()

    def __enter__(self) -> Writer:
        return self

    def __exit__(self, kind, exc, tb) -> None:
        try:
            self.wait()
        except Exception:
            if kind is None:  # a failed write is the news; otherwise the exception already under way is
                raise
        finally:
            self._pool.shutdown()
