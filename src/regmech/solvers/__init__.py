"""Solvers, all behind one calling convention:
``simulate(model, t_end, dt_out=None, solver="auto", *, accuracy=None, t_start=0.0, **options)``.

Each returns a ``Result`` with the same named signals, events and stats.
Each registers with the options it takes (``register(name, OptionSet)``);
the time arguments and the options of every call are checked there, once
for all solvers (``regmech.solvers.options``).

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

import difflib
import functools
import inspect
import time

from .._numbers import describe
from ..errors import ParameterError
from .common import MAX_TIME_EVENTS, check_max_time_events, check_signals, check_timeout, progress_bar, time_limit
from .options import MAX_POINTS, TIME_ARGUMENTS, OptionSet, check_motion, check_times

SOLVERS: dict = {}


def register(name: str, options: OptionSet):
    """Register solver ``fn(model, t_start, t_end, dt_out, **options)`` under ``name``.

    The registered (and returned) function checks its arguments first
    (``options.check_times``, ``OptionSet.check``), compiles the model,
    refuses one with nothing to integrate (``options.check_motion``) and
    checks what needs the compiled model; then it runs ``fn``, which gets
    Python numbers in range and only the options it declares.
    """
    def deco(fn):
        params = inspect.signature(fn).parameters
        declared = [p for p in params if p not in ("model", "t_start", "t_end", "dt_out")]
        if sorted(declared) != sorted(options):
            # a developer's slip: the declared option set and the function must list the same options
            raise TypeError(f"solver {name!r}: options declared {sorted(options)} but the function takes "
                            f"{sorted(declared)}")

        @functools.wraps(fn)
        def run(model, t_start=0.0, t_end=1.0, dt_out=None, max_points=MAX_POINTS, max_time_events=MAX_TIME_EVENTS,
                timeout_s=None, **given):
            # timeout_s [s]: every solver checks the active limit in its inner loops (common.time_limit)
            with time_limit(timeout_s):
                return checked_run(model, t_start, t_end, dt_out, max_points, max_time_events, given)

        def checked_run(model, t_start, t_end, dt_out, max_points, max_time_events, given):
            if not callable(getattr(model, "compile", None)):
                raise ParameterError(f"solver '{name}': simulate() takes a regmech.Model, got {describe(model)}")
            t_start, t_end, dt_out, _ = check_times(t_start, t_end, dt_out, max_points)
            # the signals (values in range, time events countable) before anything is compiled
            check_signals(model, t_start, t_end, check_max_time_events(max_time_events))
            values = options.check(name, given)
            tc = time.perf_counter()
            c = model.compile()
            compile_time = time.perf_counter() - tc
            check_motion(c)
            options.check_compiled(name, values, c)
            res = fn(model, t_start=t_start, t_end=t_end, dt_out=dt_out, **values)
            res.stats.compile_time += compile_time      # the solver found it compiled
            return res

        run.options = options
        run.defaults = {p: params[p].default for p in declared}
        SOLVERS[name] = run
        return run
    return deco


def _load():
    from . import ida  # noqa: F401
    from . import convolution, explicit, scipy_ivp  # noqa: F401
    from . import expm  # noqa: F401


def simulate(model, t_end, dt_out=None, solver="auto", *, accuracy=None, t_start=0.0, **options):
    """Run ``model`` with ``solver`` (see the module docstring; ``register`` for what is checked first)."""
    _load()
    if solver in ("auto", "ida") and options.get("native", True) is not False:
        from .ida_native import libraries
        libraries()         # numba's IDA kernels, loaded before any run's clock starts (reported below)
    # one wall-clock limit over everything the call runs (auto's choice, the contract's companion runs)
    progress = options.pop("progress", None)
    with time_limit(options.pop("timeout_s", None)), \
            progress_bar(progress, getattr(model, "name", "model"), t_start, t_end):
        res = _simulate(model, t_end, dt_out, solver, accuracy, t_start, options)
    from .ida_native import load_time
    loaded = load_time()
    if loaded > 0.0 and hasattr(res, "stats"):
        # this call loaded numba's compiled IDA kernels (once per process; the first time on a machine it compiles
        # them into numba's cache): a one-off beside the run's own time, said in ``str(res.stats)``
        res.stats.extra["native_load_s"] = loaded
    if hasattr(res, "integrator"):
        from .quadrature import cumulative
        res.integrator = cumulative        # heat and res.integral follow the model's laws between the rows
    return res


def _simulate(model, t_end, dt_out, solver, accuracy, t_start, options):
    from .accuracy import check_accuracy, simulate_with_accuracy
    if accuracy is not None:
        accuracy = check_accuracy(accuracy)
    if (solver == "auto" or accuracy is not None) and callable(getattr(model, "compile", None)):
        # auto's traits and the contract's grid read the output grid and the signals' breakpoints before
        # any solver's own entry checks them: the caps hold here first (a 1e-8 s dt_out over 1e3 s was a
        # numpy MemoryError of 745 GiB; a 1e-8 s Pulse, 1e8 breakpoints listed)
        t0, t1, dt, _ = check_times(t_start, t_end, dt_out, options.get("max_points", MAX_POINTS))
        check_signals(model, t0, t1, check_max_time_events(options.get("max_time_events", MAX_TIME_EVENTS)))
    if solver == "auto":
        from .auto import simulate_auto
        return simulate_auto(model, t_start, t_end, dt_out, accuracy, options)
    fn = _solver(solver)
    if accuracy is None:
        res = fn(model, t_start=t_start, t_end=t_end, dt_out=dt_out, **options)
        traj = getattr(res, "_traj", None)
        if traj is not None:
            # a named solver's run has no estimate to hold it: a passive model's energy book does (the contract's
            # runs are held by its estimate, and its fixed-step retries by the step Richardson suggests)
            from .passive import check as check_passive_energy
            given = ", ".join(f"{k}={options[k]:g}" for k in ("rtol", "atol", "h", "tol")
                              if isinstance(options.get(k), (int, float)))
            check_passive_energy(traj.c, traj.t, traj.Y, solver, given)
        rtol = options.get("rtol", options.get("tol"))
        if rtol is not None and hasattr(res, "stats"):
            res.stats.extra.setdefault("rtol", rtol)     # the tolerance Result.integral aims at
        return res
    return simulate_with_accuracy(model, solver, fn, t_start, t_end, dt_out, accuracy, options)


def _solver(solver):
    fn = SOLVERS.get(solver) if isinstance(solver, str) else None
    if fn is None:
        close = difflib.get_close_matches(str(solver), list(SOLVERS) + ["auto"], n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ParameterError(f"unknown solver {solver!r}{hint}; choose 'auto' or one of {sorted(SOLVERS)}")
    return fn


def check_options(t_end, dt_out=None, solver="auto", t_start=0.0, max_points=MAX_POINTS, **options) -> dict:
    """Check the arguments of ``simulate`` without a model (what needs the compiled model is checked when it
    runs); returns them normalised. ``rm.sweep`` and the command line call it before starting any run, so a
    misspelt option stops a study at once instead of failing every run of it."""
    _load()
    t_start, t_end, dt_out, max_points = check_times(t_start, t_end, dt_out, max_points)
    out = {"t_end": t_end, "dt_out": dt_out, "solver": solver, "t_start": t_start, "max_points": max_points}
    if options.get("accuracy") is not None:
        from .accuracy import check_accuracy
        out["accuracy"] = check_accuracy(options.pop("accuracy"))
    options.pop("accuracy", None)
    if "max_time_events" in options:
        out["max_time_events"] = check_max_time_events(options.pop("max_time_events"))
    if "progress" in options:
        out["progress"] = options.pop("progress")
    if "timeout_s" in options:
        out["timeout_s"] = check_timeout(options.pop("timeout_s"), "simulate(timeout_s=...)")
    if solver == "auto":
        # the solver's own options are checked against the one auto chooses, when the model is known
        from .auto import SETTINGS
        given = [k for k in SETTINGS if k in options]
        if given:
            raise ParameterError(f"simulate(): {', '.join(given)} set the tolerance or step of one solver, but "
                                 f"solver='auto' chooses them from accuracy=; name the solver to set them")
        return {**out, **options}
    return {**out, **_solver(solver).options.check(solver, options)}


__all__ = ["simulate", "check_options", "SOLVERS", "register", "TIME_ARGUMENTS"]
