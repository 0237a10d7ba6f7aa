"""Bounding a run in wall-clock time, and telling a clear regmech error from a crash.

``time_limit(seconds)`` arms a real-time interval timer (``SIGALRM``); when it
fires, ``RunTimeout`` is raised in the main thread at the next Python
bytecode, which includes the residual and right-hand-side callbacks every
solver makes, so a run that would go on for hours (an explicit method
crawling through a stiff problem) is stopped. ``RunTimeout`` derives from
``BaseException`` so that the solvers' ``except Exception`` clauses (which
turn solver failures into ``SimulationError``) do not swallow it. Outside
the main thread, or on a platform without ``setitimer``, no limit applies.
"""

from __future__ import annotations

import contextlib
import signal
import threading


class RunTimeout(BaseException):
    """The benchmark's wall-clock limit of one run was reached (not a regmech error)."""


@contextlib.contextmanager
def time_limit(seconds: float | None):
    if not seconds or not hasattr(signal, "setitimer") or threading.current_thread() is not threading.main_thread():
        yield
        return

    def _fire(signum, frame):
        raise RunTimeout(f"stopped after {seconds:g} s (the benchmark's time limit per run)")

    old = signal.signal(signal.SIGALRM, _fire)
    signal.setitimer(signal.ITIMER_REAL, float(seconds))
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, old)


class WorkBudgetExceeded(BaseException):
    """A run made more residual / right-hand-side evaluations than its budget (a deterministic bound)."""


@contextlib.contextmanager
def work_budget(model, max_calls: int | None):
    """Bound a run by the number of evaluations of the model's equations, not by the clock.

    Wraps the compiled system's ``residual`` (IDA) and ``ode_rhs`` (every
    ODE-form solver) *on the instance* and raises ``WorkBudgetExceeded``
    after ``max_calls`` evaluations in total, so a solver that crawls
    (tiny steps, Newton failures) is stopped at the same point on any
    machine. The wrappers are removed on exit.
    """
    if not max_calls:
        yield
        return
    c = model.compile()
    count = [0]

    def wrap(name):
        inner = getattr(c, name)

        def counted(*args, **kw):
            count[0] += 1
            if count[0] > max_calls:
                raise WorkBudgetExceeded(f"more than {max_calls} evaluations of the model equations")
            return inner(*args, **kw)
        return counted

    saved = {name: c.__dict__.get(name) for name in ("residual", "ode_rhs")}
    for name in saved:
        setattr(c, name, wrap(name))
    try:
        yield count
    finally:
        for name, val in saved.items():
            if val is None:
                delattr(c, name)
            else:
                setattr(c, name, val)


def first_line(exc: BaseException, limit: int = 300) -> str:
    """The exception's message, one line, at most ``limit`` characters."""
    text = " ".join(str(exc).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def names_a_component(message: str, model) -> bool:
    """Whether an error message names one of the model's components (quoted or plain)."""
    return any(f"'{name}'" in message or f" {name} " in f" {message} " for name in model.components)


def classify_error(exc: BaseException, model) -> tuple[str, str]:
    """``(status, reason)`` of a run that raised: ``error`` for a regmech error
    (the run stopped with a message meant for the user), ``crash`` for anything
    else (a bug: regmech should have wrapped it)."""
    from regmech.errors import RegmechError
    if isinstance(exc, RunTimeout):
        return "timeout", first_line(exc)
    kind = type(exc).__name__
    if isinstance(exc, RegmechError):
        return "error", f"{kind}: {first_line(exc)}"
    return "crash", f"{kind} (not a regmech error): {first_line(exc)}"
