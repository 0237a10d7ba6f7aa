"""Output arrays on ordinary memory pages, not transparent huge pages.

numpy (1.20 and newer, on Linux) asks the kernel for transparent huge pages
(``madvise(MADV_HUGEPAGE)``) on every array of 4 MiB or more. A run's
recorder (``common.Recorder``) is such an array on a large model: the
benchmark chain of 10,000 inertias writes 101 rows of 20,000 unknowns,
17.8 MB, once per run, row by row. The kernel serves a first write to a
huge-page region with a 2 MiB page, and where its free memory is fragmented
(``defrag=madvise``, the common setting, compacts memory for such regions
right there, inside the write) that write waits. How long depends on what
the process and the machine did before: measured on the 2-core benchmark
machine, interleaved with the peers' runs in one process (13 tools, 12
models of 10,000 inertias alive), the rows' first writes took 16 ms and the
zeroed allocation 8 ms of a 112 ms ``scipy:DOP853`` run (medians of 7; runs
between 82 and 137 ms), against about 2 ms in all in a process that ran
nothing else. A recorder is written once and read a few columns at a time,
so huge pages do not pay for themselves there.

``zeros(shape)`` allocates like ``numpy.zeros`` with numpy's huge-page
request switched off for that one allocation (numpy's own switch,
``_set_madvise_hugepage``, is process-wide: it is set and restored under a
lock, so that allocations in overlapping runs in threads cannot leave it
off). Where numpy has no such switch (another platform or version) it is
``numpy.zeros``. A system whose transparent huge pages are ``always`` on still
gives huge pages: that is its administrator's choice.
"""

from __future__ import annotations

import numpy as np

from .forksafe import ForkSafeLock

_guard = ForkSafeLock()      # renewed in a forked child (``forksafe``)


def _switch():
    """numpy's process-wide huge-page switch (returns the previous setting), or None."""
    for where in ("_core", "core"):
        mod = getattr(np, where, None)
        fn = getattr(getattr(mod, "multiarray", None), "_set_madvise_hugepage", None)
        if fn is not None:
            return fn
    return None


_SET = _switch()


def zeros(shape, dtype=float) -> np.ndarray:
    """``numpy.zeros(shape, dtype)`` on ordinary pages (module docstring)."""
    if _SET is None:
        return np.zeros(shape, dtype)
    with _guard:
        previous = _SET(False)
        try:
            return np.zeros(shape, dtype)
        finally:
            _SET(previous)
