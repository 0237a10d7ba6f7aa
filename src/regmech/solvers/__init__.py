"""Solvers, all behind one calling convention:
``simulate(model, t_end, dt_out=None, solver="auto", *, accuracy=None, t_start=0.0, **options)``.

Each returns a ``Result`` with the same named signals, events and stats.

* ``solver="auto"`` (the default) chooses the method and its settings from the
  model's structure and the accuracy asked for (``regmech.solvers.auto``) and
  runs it under the accuracy contract with ``accuracy`` (default
  ``DEFAULT_ACCURACY`` = 1e-3);
* a named solver with ``accuracy=None`` runs exactly as asked, with its own
  options (``rtol``, ``h``, ...), and no extra runs;
* a named solver with ``accuracy`` runs under the contract
  (``regmech.solvers.accuracy``): the result's estimated global error is at
  most ``accuracy`` or ``AccuracyError`` is raised.
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


def simulate(model, t_end, dt_out=None, solver="auto", *, accuracy=None, t_start=0.0, **options):
    _load()
    from .accuracy import check_accuracy, simulate_with_accuracy
    if accuracy is not None:
        accuracy = check_accuracy(accuracy)
    if solver == "auto":
        from .auto import simulate_auto
        return simulate_auto(model, t_start, t_end, dt_out, accuracy, options)
    fn = SOLVERS.get(solver)
    if fn is None:
        raise ParameterError(f"unknown solver {solver!r}; choose 'auto' or one of {sorted(SOLVERS)}")
    if accuracy is None:
        return fn(model, t_start=t_start, t_end=t_end, dt_out=dt_out, **options)
    return simulate_with_accuracy(model, solver, fn, t_start, t_end, dt_out, accuracy, options)


__all__ = ["simulate", "SOLVERS", "register"]
