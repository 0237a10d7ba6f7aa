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


def simulate(model, t_end, dt_out=None, solver="ida", t_start=0.0, max_time_events=None, **options):
    """Run ``model`` with ``solver``. ``max_time_events`` (default ``common.MAX_TIME_EVENTS``, for
    every solver): the most signal breakpoints the run may stop at; the signals are checked first
    (``common.check_signals``)."""
    _load()
    fn = SOLVERS.get(solver)
    if fn is None:
        raise ParameterError(f"unknown solver {solver!r}; choose one of {sorted(SOLVERS)}")
    from .common import MAX_TIME_EVENTS, check_signals
    if hasattr(model, "components"):
        check_signals(model, t_start, t_end, MAX_TIME_EVENTS if max_time_events is None else max_time_events)
    return fn(model, t_start=t_start, t_end=t_end, dt_out=dt_out, **options)


__all__ = ["simulate", "SOLVERS", "register"]
