"""One BLAS thread for the steps of the ODE-form driver (``ode_driver.simulate_ode``).

scipy's explicit Runge-Kutta classes (``scipy:RK45``, ``scipy:DOP853``, ...)
form every step's stages, error estimate and dense output with
``ndarray.dot`` on the (stages x states) array: level-2 products, bound by
memory, not by arithmetic. numpy's OpenBLAS splits such a product across
its threads from a few thousand states on, and its threads then wait for
each other, and for a core, at every call: on the 2-core benchmark machine
the benchmark chain of 10,000 inertias (``scipy:DOP853``, 64 steps, 131
products) spent 0.70 s in ``dot`` with the default two threads while
another process held a core, 0.15 s when it did not, and under a
millisecond with one thread (the whole run 0.10 s instead of 0.57-0.81 s;
``benchmarks/results/blas_threads.md``). The gain of a second
thread on such a product is small even on an idle machine.

So ``one_blas_thread()`` sets numpy's OpenBLAS to one thread
(``openblas_set_num_threads_local``, OpenBLAS 0.3.27 and newer, which
returns the count it replaces) for the length of a run, and restores the
previous count after it, also on an error. In numpy's OpenBLAS 0.3.31 the
count is the process's, not the calling thread's: runs that overlap in
threads of one process (``rm.sweep`` with a thread pool) share one setting,
made by the first to start and restored by the last to end (a count of
them under a lock), so that one run's end cannot restore the count under
another, nor leave the process at one thread. Where numpy links another BLAS
(MKL, Accelerate) or an older OpenBLAS without the call, it does nothing.
``REGMECH_BLAS_THREADS`` set in the environment (a number; 0: leave BLAS
alone) overrides the count.
"""

from __future__ import annotations

import contextlib
import ctypes
import glob
import os

from .forksafe import ForkSafeLock

#: the name of the thread-local setter in OpenBLAS (0.3.27+; it returns the previous count)
_SETTER = "openblas_set_num_threads_local"

_lib: list = []        # [setter or None], found once per process
_guard = ForkSafeLock()      # renewed in a forked child (``forksafe``)
_held = {"runs": 0, "previous": None}       # runs inside ``one_blas_thread`` now, and the count they replaced


def _setter():
    """OpenBLAS's thread-local setter of numpy's own BLAS, or None (another BLAS, or none found)."""
    if _lib:
        return _lib[0]
    found = None
    try:
        import numpy
        here = os.path.dirname(numpy.__file__)
        # where numpy's wheels keep their OpenBLAS: numpy.libs (Linux .so, Windows .dll), numpy/.dylibs (macOS)
        found_libs = [p for pattern in (os.path.join(here, os.pardir, "numpy.libs", "*openblas*"),
                                        os.path.join(here, ".dylibs", "*openblas*"))
                      for p in sorted(glob.glob(pattern)) if p.endswith((".so", ".dll", ".dylib")) or ".so." in p]
        for path in found_libs:
            lib = ctypes.CDLL(path)         # already loaded by numpy: the same library, not a second copy
            fn = getattr(lib, _SETTER, None)
            if fn is not None:
                fn.restype, fn.argtypes = ctypes.c_int, [ctypes.c_int]
                found = fn
                break
    except OSError:         # a library that cannot be opened: leave BLAS alone
        found = None
    _lib.append(found)
    return found


def _threads() -> int:
    """The count a run asks for: 1, or ``REGMECH_BLAS_THREADS`` (0: leave BLAS alone); anything but a whole
    number >= 0 there is refused (a typo must not pass for a setting)."""
    text = os.environ.get("REGMECH_BLAS_THREADS", "").strip()
    if not text:
        return 1
    if not text.isdigit():
        from ..errors import ParameterError
        raise ParameterError(f"REGMECH_BLAS_THREADS={text!r}: give a whole number of BLAS threads for regmech's "
                             f"ODE-form runs (1, the default; 0 leaves numpy's BLAS as it is), or unset it")
    return int(text)


@contextlib.contextmanager
def one_blas_thread():
    """numpy's OpenBLAS at one thread (or ``REGMECH_BLAS_THREADS``) while the block runs; the count before the
    first of overlapping blocks is restored when the last ends."""
    n = _threads()
    fn = _setter() if n else None
    if fn is None:
        yield
        return
    with _guard:
        if _held["runs"] == 0:
            previous = fn(n)
            _held["previous"] = previous if previous >= 1 else None     # a count it cannot restore: leave it
        _held["runs"] += 1
    try:
        yield
    finally:
        with _guard:
            _held["runs"] -= 1
            if _held["runs"] == 0 and _held["previous"] is not None:
                fn(_held["previous"])


__all__ = ["one_blas_thread"]
