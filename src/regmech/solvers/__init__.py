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


def simulate(model, t_end, dt_out=None, solver="ida", t_start=0.0, **options):
    _load()
    fn = SOLVERS.get(solver)
    if fn is None:
        raise ParameterError(f"unknown solver {solver!r}; choose one of {sorted(SOLVERS)}")
    return fn(model, t_start=t_start, t_end=t_end, dt_out=dt_out, **options)


__all__ = ["simulate", "SOLVERS", "register"]
