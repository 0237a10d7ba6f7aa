"""The options of every solver: declared once per solver, checked once at the entry.

Each solver registers with the set of options it takes
(``register("ida", IDA_OPTIONS)``), and every call of a registered
solver, through ``Model.simulate``, ``regmech.solvers.simulate`` or the
function itself, first passes ``prepare``:

* the time arguments every solver shares: ``t_start``, ``t_end``
  (finite, ``t_end > t_start``), ``dt_out`` (positive; default 500
  intervals) and ``max_points``, the most output points a run may ask for
  (default ``MAX_POINTS``): the output grid, every state and derivative at
  every point, is held in memory, so ``dt_out=1e-9`` over 10 s (1e10
  points, tens of GiB) is refused before anything is allocated;
* every option against the solver's ``OptionSet``: an unknown name is
  refused with the solver's valid names, the closest one (``difflib``) and
  the solvers that do take it; a value of the wrong type or outside its
  range with the range and what the option means;
* after the model compiles: a model with nothing to integrate (every
  mass fixed to the ground: no unknown at all) is refused for every solver
  alike, and an ``atol`` array must have one entry per unknown of the
  solver.

Numbers of any numeric type are accepted (numpy scalars, 0-d arrays; see
``regmech._numbers``) and reach the solvers as Python ``float``/``int``.
Ranges are the real limits of the methods, not taste: a relative
tolerance below ``RTOL_MIN = 100 eps`` cannot be met in double precision
(the round-off of one addition to the state is ``eps |y|``; scipy raises
smaller values to this floor), and one of 1 or more controls no digit.
"""

from __future__ import annotations

import difflib
import math

import numpy as np

from .._numbers import as_integer, as_real, describe
from ..errors import ParameterError, StructureError

#: smallest relative tolerance any solver accepts: 100 machine epsilons (2.2e-14)
RTOL_MIN = 100 * float(np.finfo(float).eps)
#: default of ``max_points``, the most output points (grid instants) a run may ask for. A point holds
#: the state, its derivative and the modes, recorded and then stacked: measured peak memory per point of
#: an IDA run (tracemalloc, 5,000 against 25,000 points) 0.3 kB for coupled_clutches (11 unknowns),
#: 1.6 kB for vehicle_launch (33), 10 kB for the 100-car train (200), i.e. about 50 bytes per unknown.
#: A million points is then tens of MB for a small model and 10 GB for the train; pass ``max_points``
#: to go further.
MAX_POINTS = 1_000_000
#: the arguments every solver takes besides its own options
TIME_ARGUMENTS = ("t_start", "t_end", "dt_out", "max_points", "max_time_events", "timeout_s")


class Refused(Exception):
    """Raised by an ``Option`` check: what the value must be (the caller adds solver and option names)."""


class Option:
    """One option of a solver: what it means (``text``) and the check of its value.

    ``normalise(value)`` returns the value the solver receives (Python
    numbers) or raises ``Refused`` with the requirement; ``hint`` is
    added to the message (why the range, typical values).
    """

    requirement = "valid"

    def __init__(self, text: str, *, optional: bool = False, hint: str = ""):
        self.text = text
        self.optional = optional
        self.hint = hint

    def normalise(self, value):
        if value is None and self.optional:
            return None
        out = self._check(value)
        if out is None:
            raise Refused(self.requirement + (" or None" if self.optional else ""))
        return out

    def _check(self, value):  # pragma: no cover - abstract
        raise NotImplementedError

    def check_compiled(self, name, value, c, solver):
        """A check that needs the compiled system (``c``); nothing by default."""


def _interval(lo, hi, lo_closed, hi_closed) -> str:
    if hi is None:
        if lo == 0 and not lo_closed:
            return "a positive number"
        return f"a number {'>=' if lo_closed else '>'} {lo:.3g}"
    return f"a number in {'[' if lo_closed else '('}{lo:.3g}, {hi:.3g}{']' if hi_closed else ')'}"


class Real(Option):
    """A finite real number in an interval (default: positive)."""

    def __init__(self, text, lo=0.0, hi=None, *, lo_closed=False, hi_closed=False, **kw):
        super().__init__(text, **kw)
        self.lo, self.hi, self.lo_closed, self.hi_closed = lo, hi, lo_closed, hi_closed
        self.requirement = _interval(lo, hi, lo_closed, hi_closed)

    def _check(self, value):
        x = as_real(value)
        if x is None or not math.isfinite(x):
            return None
        if x < self.lo or (x == self.lo and not self.lo_closed):
            return None
        if self.hi is not None and (x > self.hi or (x == self.hi and not self.hi_closed)):
            return None
        return x


class Integer(Option):
    """A whole number in ``lo..hi`` (``1e5`` counts as whole)."""

    def __init__(self, text, lo=1, hi=None, **kw):
        super().__init__(text, **kw)
        self.lo, self.hi = lo, hi
        self.requirement = f"a whole number >= {lo}" if hi is None else f"a whole number in {lo}..{hi}"

    def _check(self, value):
        k = as_integer(value)
        if k is None or k < self.lo or (self.hi is not None and k > self.hi):
            return None
        return k


class Flag(Option):
    requirement = "True or False"

    def _check(self, value):
        return bool(value) if isinstance(value, (bool, np.bool_)) else None


class Choice(Option):
    def __init__(self, text, choices, **kw):
        super().__init__(text, **kw)
        self.choices = tuple(choices)
        self.requirement = "one of " + ", ".join(repr(c) for c in self.choices)

    def _check(self, value):
        return value if isinstance(value, str) and value in self.choices else None


class AbsTol(Real):
    """``atol``: a positive number, or an array of positive numbers with one entry per unknown of the
    solver (``size(c)``: IDA's DAE unknowns, or the ODE state of the ODE-form solvers)."""

    def __init__(self, text, size, size_text, **kw):
        super().__init__(text, **kw)
        self.size, self.size_text = size, size_text
        self.requirement = f"a positive number or an array of positive numbers (one per {size_text})"

    def _check(self, value):
        if isinstance(value, (list, tuple, np.ndarray)) and np.ndim(value) == 1:
            try:
                arr = np.array(value, dtype=float)
            except (TypeError, ValueError):
                return None
            if arr.size and np.all(np.isfinite(arr)) and np.all(arr > 0):
                arr.setflags(write=False)
                return arr
            return None
        return super()._check(value)

    def check_compiled(self, name, value, c, solver):
        if isinstance(value, np.ndarray) and value.size != self.size(c):
            raise ParameterError(
                f"solver '{solver}': the {name} array has {value.size} entries but model '{c.model.name}' needs "
                f"{self.size(c)}, one per {self.size_text}; give that many or a single number")


class OptionSet:
    """The options one solver takes: ``{name: Option}``; ``about`` says what the solver is (in messages)."""

    def __init__(self, about: str = "", **options: Option):
        self.about = about
        self.options = options

    def __iter__(self):
        return iter(self.options)

    def names(self) -> list[str]:
        return list(self.options)

    def check(self, solver: str, given: dict) -> dict:
        """The given options, checked and normalised; ``ParameterError`` for unknown names and bad values."""
        unknown = [k for k in given if k not in self.options]
        if unknown:
            raise ParameterError(unknown_message(solver, self, unknown))
        out = {}
        for name, value in given.items():
            opt = self.options[name]
            try:
                out[name] = opt.normalise(value)
            except Refused as req:
                raise ParameterError(bad_value_message(solver, name, opt, value, str(req))) from None
        return out

    def check_compiled(self, solver: str, values: dict, c) -> None:
        for name, value in values.items():
            self.options[name].check_compiled(name, value, c, solver)


def bad_value_message(solver, name, opt, value, requirement) -> str:
    msg = f"solver '{solver}': {name} must be {requirement}, got {describe(value)}; {name} is the {opt.text}."
    if isinstance(value, str):
        x = as_real(_float_or_none(value))
        if x is not None:
            msg += f" Pass the number itself: {name}={x!r}, not the string {value!r}."
    if opt.hint:
        msg += " " + opt.hint
    return msg


def _float_or_none(text):
    try:
        return float(text)
    except ValueError:
        return None


def _owners(name: str) -> list[str]:
    """The registered solvers that take option ``name`` (the six scipy methods as one 'scipy:*')."""
    from . import SOLVERS, _load
    _load()
    owners = sorted(s for s, fn in SOLVERS.items() if name in getattr(fn, "options", ()))
    scipy = [s for s in owners if s.startswith("scipy:")]
    if len(scipy) == sum(s.startswith("scipy:") for s in SOLVERS) and len(scipy) > 1:
        owners = [s for s in owners if not s.startswith("scipy:")] + ["scipy:*"]
    return owners


def unknown_message(solver: str, options: OptionSet, unknown: list[str]) -> str:
    valid = options.names()
    candidates = valid + [t for t in TIME_ARGUMENTS if t not in valid]
    lower = {c.lower(): c for c in candidates}
    parts = []
    for name in unknown:
        close = [lower[c] for c in difflib.get_close_matches(str(name).lower(), list(lower), n=2, cutoff=0.6)]
        notes = []
        if close:
            notes.append("did you mean " + " or ".join(f"'{c}'" for c in close) + "?")
        owners = _owners(name)
        if owners:
            notes.append(f"'{name}' is an option of " + ", ".join(owners))
        parts.append(f"'{name}'" + (f" ({'; '.join(notes)})" if notes else ""))
    about = f" '{solver}' is {options.about}." if options.about else ""
    return (f"solver '{solver}' has no option " + ", ".join(parts) + f".{about} Its options: {', '.join(valid)}; "
            f"every solver also takes {', '.join(TIME_ARGUMENTS)}.")


# ---------------------------------------------------------------- shared option declarations
def rtol_option(default: float) -> Real:
    return Real(f"relative tolerance of the local error control (default {default:g})", RTOL_MIN, 1.0,
                lo_closed=True,
                hint=(f"Below {RTOL_MIN:.2g} (100 machine epsilons) the round-off of the state alone exceeds "
                      f"it, and at 1 or more it controls no digit; usual values are 1e-4 to 1e-10."))


def atol_option(size, size_text) -> AbsTol:
    return AbsTol("absolute tolerance (default rtol * 1e-2), the error allowed on a state near zero",
                  size, size_text, optional=True)


def max_events_option() -> Integer:
    return Integer("most mode changes of friction and loss elements in the run (default 100000)", lo=0)


#: default of ``max_steps`` of the fixed-step solvers (euler, rk4, abm, expm): a step ``h`` that needs more
#: steps over the run is refused before the run (measured 0.5 to 1.3 ms a step on CoupledClutches on a loaded
#: 2-core machine, so the cap is minutes of work, not hours; the full-size long-horizon hard case takes 1e6)
FIXED_MAX_STEPS = 2_000_000


def fixed_max_steps_option() -> Integer:
    return Integer(f"most steps of the run (default {FIXED_MAX_STEPS:,}); a step h that needs more is refused "
                   f"before the run", lo=1)


def chatter_options() -> dict:
    return {"chatter_window": Real("time window [s] of the chattering test (default 1e-6 s)", optional=True),
            "chatter_count": Integer("number of mode changes of one device within chatter_window that count "
                                     "as chattering (default 50)", lo=2)}


def max_growth_option() -> Real:
    return Real("factor of state growth beyond the start and forcing scale that counts as divergence "
                "(default 1e4; None: only non-finite states)", 1.0, optional=True)


def step_option(text: str) -> Real:
    return Real(text, optional=True)


def stiff_check_option() -> Flag:
    return Flag("switch of the up-front refusal of a link spread whose round-off exceeds rtol (default True)")


def tol_option() -> Real:
    return Real("bound of the estimated global error relative to the range of each kind of state (default "
                "1e-3; None: no estimate)", 0.0, 1.0, optional=True)


# ---------------------------------------------------------------- the entry
def check_times(t_start, t_end, dt_out, max_points=MAX_POINTS):
    """``(t_start, t_end, dt_out, max_points)`` checked and as Python numbers (dt_out default: 500 intervals);
    refuses a grid of more than ``max_points`` output points before anything is allocated."""
    t0, t1, dt = check_time_span(t_start, t_end, dt_out)
    cap = as_integer(max_points)
    if cap is None or cap < 2:
        raise ParameterError(f"simulate(): max_points (the most output points a run may ask for) must be a whole "
                             f"number >= 2, got {describe(max_points)}")
    points = output_points(t0, t1, dt)
    if points > cap:
        raise ParameterError(too_many_points(t0, t1, dt, points, cap))
    return t0, t1, dt, cap


def too_many_points(t0, t1, dt, points, cap) -> str:
    more = (f"pass max_points={math.ceil(points)} if the memory is there (about 50 bytes per unknown of the "
            f"model per point)") if points < 1e15 else "nothing else can hold it"
    return (f"simulate(): dt_out={dt:g} s from t_start={t0:g} s to t_end={t1:g} s asks for {points:,.0f} output "
            f"points, more than max_points={cap} (every point holds the whole state in memory). Use dt_out >= "
            f"{_round_up((t1 - t0) / max(cap - 1, 1)):g} s, or {more}.")


def _round_up(x: float) -> float:
    """The smallest of 1, 2, 5 times a power of ten that is at least ``x`` (a dt_out to suggest)."""
    decade = 10.0 ** math.floor(math.log10(x))
    return next(f * decade for f in (1, 2, 5, 10) if f * decade >= x * (1 - 1e-12))


def check_time_span(t_start, t_end, dt_out):
    """``(t_start, t_end, dt_out)`` checked and as floats (``dt_out`` None: 500 intervals)."""
    values = {}
    for name, v in (("t_start", t_start), ("t_end", t_end)):
        x = as_real(v)
        if x is None or not math.isfinite(x):
            raise ParameterError(f"simulate(): {name} must be a finite number [s], got {describe(v)}")
        values[name] = x
    t0, t1 = values["t_start"], values["t_end"]
    if t1 <= t0:
        raise ParameterError(f"simulate(): t_end ({t1:g} s) must be greater than t_start ({t0:g} s)")
    if not math.isfinite(t1 - t0):
        raise ParameterError(f"simulate(): the span from t_start={t0:g} s to t_end={t1:g} s overflows double "
                             f"precision; simulate a span below 1e300 s")
    if dt_out is None:
        dt = (t1 - t0) / 500.0
    else:
        dt = as_real(dt_out)
        if dt is None or not math.isfinite(dt) or dt <= 0:
            raise ParameterError(f"simulate(): dt_out (output interval [s]) must be a positive number, got "
                                 f"{describe(dt_out)}")
    return t0, t1, dt


def output_points(t_start: float, t_end: float, dt_out: float) -> float:
    """Number of points of ``common.output_grid(t_start, t_end, dt_out)`` (a float: it may be huge)."""
    ratio = (t_end - t_start) / dt_out
    if not math.isfinite(ratio) or ratio > 1e15:
        return ratio + 1.0
    n = math.floor(ratio + 1e-9)
    return float(n + 1 + (t_end - (t_start + dt_out * n) > 1e-12 * max(1.0, abs(t_end))))


def check_motion(c) -> None:
    """Refuse a model with nothing to integrate: no unknown at all (every mass is fixed to the ground, no
    point is driven by a source and no device has a state of its own).

    A model whose motion is all prescribed (Position sources) has unknowns, the forces that the motion
    takes, and runs: the device laws along a given motion are evaluated that way."""
    if c.N > 0:
        return
    st = c.structure
    held = [b.name for node in st.nodes if node.grounded for b in node.bodies]
    why = (f"{_names(held)} {'is' if len(held) == 1 else 'are'} fixed to the ground" if held else
           "the model has no mass")
    raise StructureError(
        f"model '{c.model.name}' has nothing to integrate: no mass is free to move ({why}), no point is driven "
        f"by a source and no device has a state of its own, so there is no unknown for a solver to compute. "
        f"Join a mass to the ground through a device that lets it move (a Spring, Damper, elastic Shaft, Clutch "
        f"or Brake) instead of connecting it to the Fixed directly, or drive it with a source.")


def _names(names: list[str], most: int = 6) -> str:
    shown = ", ".join(f"'{n}'" for n in names[:most])
    return shown + (f" and {len(names) - most} more" if len(names) > most else "")


__all__ = ["OptionSet", "Option", "Real", "Integer", "Flag", "Choice", "AbsTol", "RTOL_MIN", "MAX_POINTS",
           "TIME_ARGUMENTS", "check_times", "check_motion", "output_points"]
