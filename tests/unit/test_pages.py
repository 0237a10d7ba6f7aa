"""``solvers.pages.zeros``: a run's output arrays are allocated with numpy's huge-page request off, and numpy's
process-wide switch is left as it was (also after an error, and after allocations in overlapping threads)."""

import threading

import numpy as np
import pytest

import regmech as rm
from regmech.solvers import pages

pytestmark = pytest.mark.skipif(pages._SET is None, reason="this numpy has no huge-page switch")


def _setting():
    """numpy's current huge-page setting (reading it means setting it: set it back at once)."""
    now = pages._SET(True)
    pages._SET(now)
    return now


def test_zeros_are_zeros_and_the_setting_is_restored():
    before = _setting()
    try:
        for start in (True, False):
            pages._SET(start)
            z = pages.zeros((3, 5))
            assert z.shape == (3, 5) and z.dtype == float and not z.any()
            assert _setting() is start
            with pytest.raises(ValueError):
                pages.zeros((-1, 4))                 # numpy refuses: the setting still comes back
            assert _setting() is start
    finally:
        pages._SET(before)


def test_overlapping_allocations_in_threads_leave_the_setting_on():
    before = _setting()
    pages._SET(True)
    try:
        barrier = threading.Barrier(4)

        def work():
            barrier.wait()
            for _ in range(200):
                pages.zeros((64, 64))
        threads = [threading.Thread(target=work) for _ in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert _setting() is True
    finally:
        pages._SET(before)


def test_a_runs_recorder_is_allocated_with_the_request_off(monkeypatch):
    """The recorder of an ODE-form run and of an IDA run: every allocation through ``pages.zeros`` happens with
    numpy's request off, and at least the output rows' array is allocated that way."""
    seen = []
    real = pages._SET

    def spy(flag):
        seen.append(flag)
        return real(flag)
    monkeypatch.setattr(pages, "_SET", spy)
    before = _setting()
    for solver in ("scipy:DOP853", "ida"):
        seen.clear()
        m = rm.library.coupled_clutches()
        res = m.simulate(1.5, dt_out=1e-2, solver=solver)
        assert np.all(np.isfinite(res["J1.w"]))
        assert seen and seen[0] is False, solver
        assert seen[1::2] == [before] * (len(seen) // 2), solver          # each allocation put it back
    assert _setting() is before


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="no fork here")
def test_a_child_forked_while_another_thread_allocates_does_not_wait_forever():
    """The lock held by another thread at ``fork`` is held in the child for good: the child gets a lock of its own
    (``os.register_at_fork``), in ``pages`` and in ``blas``."""
    import os
    from regmech.solvers import blas
    for module in (pages, blas):
        module._guard.acquire()                  # as if another thread were inside its critical section
        try:
            pid = os.fork()
            if pid == 0:                         # the child: its lock is free
                os._exit(0 if module._guard.acquire(timeout=5) else 1)
            _, status = os.waitpid(pid, 0)
            assert os.waitstatus_to_exitcode(status) == 0, module.__name__
        finally:
            module._guard.release()
