"""Solvers, all behind one calling convention: ``simulate(model, t_end, dt_out, solver, **options)``.

Each returns a ``Result`` with the same named signals, events and stats.
"""

from __future__ import annotations

from ..errors import ParameterError

SOLVERS: dict = {}


def register(name):
    def deco(fn):
        SOLVERS[name] = fn
        return fn
    return deco


def _load():
    from . import ida  # noqa: F401
    from . import convolution, explicit, scipy_ivp  # noqa: F401
    from . import expm  # noqa: F401


def simulate(model, t_end, dt_out=None, solver="ida", t_start=0.0, timeout_s=None, **options):
    """Run ``solver`` on ``model``; ``timeout_s`` [s] bounds the wall time of the run (every solver checks it
    in its inner loops and stops with ``SimulationTimeout``; see ``common.time_limit``)."""
    _load()
    fn = SOLVERS.get(solver)
    if fn is None:
        raise ParameterError(f"unknown solver {solver!r}; choose one of {sorted(SOLVERS)}")
    from .common import time_limit
    with time_limit(timeout_s):
        return fn(model, t_start=t_start, t_end=t_end, dt_out=dt_out, **options)


__all__ = ["simulate", "SOLVERS", "register"]
