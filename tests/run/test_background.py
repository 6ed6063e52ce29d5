"""The run's writer thread: jobs in order, failures raised in the training thread, nothing left behind."""

from __future__ import annotations

import threading
import time

import pytest

from fieldgen.run.background import Writer


def test_jobs_run_in_order_off_the_calling_thread():
    done, threads = [], set()

    def job(i):
        time.sleep(0.01 * (3 - i))  # later jobs are quicker: order comes from the queue, not luck
        threads.add(threading.current_thread().name)
        done.append(i)

    with Writer() as writer:
        for i in range(3):
            writer.submit(job, i)
    assert done == [0, 1, 2]
    assert threads and threading.current_thread().name not in threads


def test_a_failed_write_is_raised_by_wait_and_on_leaving():
    def full():
        raise OSError(28, "No space left on device")

    writer = Writer()
    writer.submit(full)
    with pytest.raises(OSError, match="No space left"):
        writer.wait()
    writer.wait()  # reported once
    with pytest.raises(OSError, match="No space left"):
        with Writer() as writer:
            writer.submit(full)


def test_leaving_on_an_interrupt_finishes_the_write_and_keeps_the_interrupt():
    done = []

    def slow():
        time.sleep(0.1)
        done.append(True)

    with pytest.raises(KeyboardInterrupt):
        with Writer() as writer:
            writer.submit(slow)
            assert writer.busy
            raise KeyboardInterrupt
    assert done == [True] and not writer.busy
