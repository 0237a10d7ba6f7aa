"""Parameter studies: ``rm.sweep(build, params, outputs, executor=None, out=None, **simulate_options)``.

>>> import regmech as rm
>>> from regmech.library import coupled_clutches
>>> table = rm.sweep(coupled_clutches, {"fn_max": [10, 20, 40], "t2": [0.3, 0.5]},
...                  ["J4.w", "clutch2.tau"], t_end=1.5, out="study.csv")

Sampling helpers: ``rm.sweep.grid``, ``rm.sweep.latin_hypercube``,
``rm.sweep.scatter``; the implementation lives in ``regmech.study``. The
command line ``regmech sweep`` is ``main`` here.

This module is callable (``regmech.sweep(...)`` is ``regmech.study.sweep(...)``):
the command line needs a *module* ``regmech.sweep``, and once Python imports
it, it becomes the attribute ``regmech.sweep``, which must still be the
function users call.
"""

from __future__ import annotations

import sys
import types

from .study import SignalSummary, grid, latin_hypercube, scatter, scene_defaults, sweep
from .study.cli import main

__all__ = ["sweep", "grid", "latin_hypercube", "scatter", "SignalSummary", "scene_defaults", "main"]


class _CallableModule(types.ModuleType):
    def __call__(self, *args, **kwargs):
        return sweep(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
