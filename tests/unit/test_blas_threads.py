"""``solvers.blas.one_blas_thread``: numpy's OpenBLAS at one thread during an ODE-form run, restored after it (also
after an error, and after overlapping runs in threads); ``REGMECH_BLAS_THREADS`` overrides the count (0: BLAS left
alone)."""

import ctypes
import glob
import os

import numpy as np
import pytest

from regmech.solvers import blas


def _getter():
    for path in sorted(glob.glob(os.path.join(os.path.dirname(np.__file__), os.pardir, "numpy.libs",
                                              "*openblas*.so*"))):
        lib = ctypes.CDLL(path)
        for name in ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads"):
            fn = getattr(lib, name, None)
            if fn is not None:
                fn.restype = ctypes.c_int
                return fn
    return None


get = _getter()
pytestmark = pytest.mark.skipif(get is None or blas._setter() is None,
                                reason="numpy does not link an OpenBLAS with openblas_set_num_threads_local here")


def _with_threads(n):
    """Run the block with the calling thread's BLAS count at ``n`` (to see it restored)."""
    return blas._setter()(n)


def test_one_thread_inside_and_the_count_restored_after():
    previous = _with_threads(3)
    try:
        with blas.one_blas_thread():
            assert get() == 1
        assert get() == 3
        with pytest.raises(RuntimeError):
            with blas.one_blas_thread():
                raise RuntimeError("a failing run")
        assert get() == 3
    finally:
        _with_threads(previous)


def test_the_environment_overrides_the_count(monkeypatch):
    previous = _with_threads(3)
    try:
        monkeypatch.setenv("REGMECH_BLAS_THREADS", "2")
        with blas.one_blas_thread():
            assert get() == 2
        monkeypatch.setenv("REGMECH_BLAS_THREADS", "0")
        with blas.one_blas_thread():
            assert get() == 3
        from regmech.errors import ParameterError
        monkeypatch.setenv("REGMECH_BLAS_THREADS", "two")
        with pytest.raises(ParameterError, match="REGMECH_BLAS_THREADS='two'"):
            with blas.one_blas_thread():
                pass
        assert get() == 3
    finally:
        _with_threads(previous)


def test_an_ode_form_run_holds_one_thread(monkeypatch):
    """The ODE-form driver runs inside ``one_blas_thread``, and the count is restored after it."""
    import regmech as rm
    from regmech.components import Fixed, Inertia, SpringDamper
    from regmech.solvers import ode_driver
    m = rm.Model("osc")
    f = m.add(Fixed("f"))
    sd = m.add(SpringDamper("sd", c=40.0, d=0.4))
    J = m.add(Inertia("J", J=1.0, phi0=1.0))
    m.connect(sd.flange_a, f.flange)
    m.connect(sd.flange_b, J.flange_a)
    seen = []
    real = ode_driver._run_segment

    def spy(*args, **kw):
        seen.append(get())
        return real(*args, **kw)
    monkeypatch.setattr(ode_driver, "_run_segment", spy)
    previous = _with_threads(2)
    try:
        m.simulate(0.5, solver="scipy:DOP853", rtol=1e-6)
        assert seen and set(seen) == {1}
        assert get() == 2
    finally:
        _with_threads(previous)


def test_overlapping_runs_in_threads_restore_the_count_once():
    """Two runs in threads of one process, the first ending while the second runs (a review of the first version:
    the second then restored the first's setting of one thread, and the process stayed at one)."""
    import threading
    previous = _with_threads(2)
    try:
        inside_b, a_done, seen = threading.Event(), threading.Event(), []

        def run_a():
            with blas.one_blas_thread():
                inside_b.wait(5)
            a_done.set()

        def run_b():
            with blas.one_blas_thread():
                inside_b.set()
                a_done.wait(5)
                seen.append(get())          # still one thread: b runs on
        ta, tb = threading.Thread(target=run_a), threading.Thread(target=run_b)
        ta.start()
        tb.start()
        ta.join(10)
        tb.join(10)
        assert seen == [1]
        assert get() == 2
    finally:
        _with_threads(previous)
