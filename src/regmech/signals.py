"""Time signals for sources and normal forces.

Each signal is a function of time ``s(t)`` that also knows its derivatives
and the instants where it is not smooth (``breakpoints``). The solvers stop
exactly at those instants (time events) and integrate each smooth piece on
its own, evaluating the signal by its limit from inside the piece
(``left=True`` at the piece's right end), so a step is never tested inside
the right-hand side.

Parameter names follow the Modelica Standard Library (Blocks.Sources):

* ``Constant(value)``
* ``Step(height=1, start_time=0, offset=0)``:  ``offset + height*[t >= start_time]``
* ``Ramp(height=1, duration=1, start_time=0, offset=0)``
* ``Sine(amplitude=1, freq_hz=1, phase=0, offset=0, start_time=0)``:
  ``offset + [t >= start_time] * amplitude*sin(2*pi*freq_hz*(t - start_time) + phase)``
* ``Table(points)``: linear interpolation of (t, value) pairs, held constant
  outside; a repeated time gives a jump.
* ``Pulse(amplitude=1, width=50, period=1, start_time=0, offset=0)``: a
  rectangular wave, ``width`` in percent of the period (MSL Pulse).

Any callable ``f(t)`` is accepted where a signal is expected; it is wrapped
in ``Function`` (no breakpoints known, derivatives by central differences).

**Checked values.** A component parameter that is a signal holds it *bound*
to the component and the parameter's name (``as_signal``), so that every
value the solvers see is checked in one place:

* the built-in signals above are finite for every t by construction (their
  parameters, the sums and slopes made of them, are checked when they are
  created), so they are used as they are, at no cost per call;
* a callable (``Function``) or a user's ``Signal`` subclass is checked at
  every call: a value that is NaN, infinite or outside the parameter's
  documented range, a value that is not a number, or an exception raised
  by the callable becomes a ``SimulationError`` naming the component, the
  parameter and the time (the original exception chained); a callable that
  cannot be called with one argument is refused when it is given;
* a parameter with a documented range (``Param(bounds=...)``, e.g. a
  clutch's ``f_normalized <= 1``) refuses a built-in signal whose range
  (``Signal.bounds()``) leaves it when the signal is given.
"""

from __future__ import annotations

import inspect
import math
import numbers
import sys
from typing import Callable

import numpy as np

from ._frozen import frozen
from .errors import ParameterError, RegmechError, SimulationError

__all__ = ["Signal", "Constant", "Step", "Ramp", "Sine", "Table", "Pulse", "Function", "as_signal"]

#: the largest finite float: ``-_BIG <= v <= _BIG`` is False for NaN and +-inf (one comparison per call)
_BIG = sys.float_info.max
#: relative slack of a documented range (round-off of a signal that reaches the bound exactly)
BOUNDS_SLACK = 1e-9


def _finite(owner: str, name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{owner}: parameter '{name}' must be a real number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ParameterError(f"{owner}: parameter '{name}' must be finite, got {value!r}")
    return value


def _finite_result(owner: str, what: str, value: float) -> None:
    """A quantity made of finite parameters (a sum, a slope) that overflowed: refuse the signal."""
    if not math.isfinite(value):
        raise ParameterError(f"{owner}: {what} overflows ({value!r}); the signal would not be finite. "
                             f"Use parameters of a physical size")


class Signal:
    """Base class: override ``value`` and ``derivative``; list ``breakpoints``.

    The library's signals (``Constant``, ``Step``, ``Ramp``, ``Sine``, ``Table``, ``Pulse``) are values:
    their parameters are fixed when they are made. The compiled paths keep them (the native IDA kernels'
    tables, the vectorised banks of many sines or steps), so a parameter changed in place would reach some
    solvers and not others, and skip the checks of the constructor. Changing one raises a
    ``ParameterError`` that says what to do instead: assign a new signal to the component's parameter
    (``drive.tau = Sine(...)``), which recompiles the model."""

    def __setattr__(self, name, value):
        if self.__dict__.get("_frozen", False):
            raise ParameterError(
                f"{type(self).__name__}: parameter '{name}' cannot be changed in place (the compiled model keeps "
                f"the signal's parameters). Make a new signal and assign it to the component's parameter, e.g. "
                f"drive.tau = {type(self).__name__}(...); that recompiles the model.")
        object.__setattr__(self, name, value)

    def __delattr__(self, name):
        if self.__dict__.get("_frozen", False):
            raise ParameterError(f"{type(self).__name__}: parameter '{name}' cannot be removed (the signal's "
                                 f"parameters are fixed when it is made)")
        object.__delattr__(self, name)

    def _freeze(self):
        """Fix the parameters of a library signal (the end of its constructor; a user's subclass, whose own
        attributes the library never keeps, stays free to set them)."""
        if type(self).__module__ == __name__:
            self._frozen = True

    def __call__(self, t: float, left: bool = False) -> float:
        return self.value(t, left)

    def value(self, t: float, left: bool = False) -> float:  # pragma: no cover - abstract
        raise NotImplementedError

    def derivative(self, t: float, order: int = 1, left: bool = False) -> float:
        """d^order s / dt^order at t (one-sided limit when ``left``)."""
        raise NotImplementedError

    def derivative_noise(self, t: float, order: int = 1) -> float:
        """Bound of the round-off in ``derivative(t, order)`` (0 for an analytic derivative)."""
        return 0.0

    def breakpoints(self, t_start: float = -math.inf, t_end: float = math.inf) -> tuple[float, ...]:
        """Instants where the signal or one of its derivatives jumps (periodic
        signals list those in [t_start, t_end])."""
        return ()

    def count_breakpoints(self, t_start: float, t_end: float) -> int:
        """How many breakpoints lie in (t_start, t_end); periodic signals count without listing
        them, so that a run with too many time events is refused before they are built."""
        return sum(1 for b in self.breakpoints(t_start, t_end) if t_start < b < t_end)

    def bounds(self) -> tuple[float, float] | None:
        """(lowest, highest) value over all t, or None when not known (callables)."""
        return None

    def is_constant_zero(self) -> bool:
        """True when the signal is zero for all t (used by scene reduction)."""
        return False

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in vars(self).items() if not k.startswith("_"))
        return f"{type(self).__name__}({args})"


class Constant(Signal):
    """``s(t) = value``."""

    def __init__(self, value: float = 0.0):
        self.value_ = _finite("Constant", "value", value)
        self._freeze()

    def value(self, t, left=False):
        return self.value_

    def derivative(self, t, order=1, left=False):
        return 0.0

    def bounds(self):
        return self.value_, self.value_

    def is_constant_zero(self):
        return self.value_ == 0.0

    def __repr__(self):
        return f"Constant({self.value_!r})"


class Step(Signal):
    """``s(t) = offset + height * [t >= start_time]``."""

    def __init__(self, height: float = 1.0, start_time: float = 0.0, offset: float = 0.0):
        self.height = _finite("Step", "height", height)
        self.start_time = _finite("Step", "start_time", start_time)
        self.offset = _finite("Step", "offset", offset)
        _finite_result("Step", "offset + height", self.offset + self.height)
        self._freeze()

    def value(self, t, left=False):
        on = t > self.start_time if left else t >= self.start_time
        return self.offset + (self.height if on else 0.0)

    def derivative(self, t, order=1, left=False):
        return 0.0

    def breakpoints(self, t_start=-math.inf, t_end=math.inf):
        return (self.start_time,)

    def bounds(self):
        return min(self.offset, self.offset + self.height), max(self.offset, self.offset + self.height)

    def is_constant_zero(self):
        return self.offset == 0.0 and self.height == 0.0


class Ramp(Signal):
    """Linear rise by ``height`` over ``duration`` starting at ``start_time``."""

    def __init__(self, height: float = 1.0, duration: float = 1.0, start_time: float = 0.0,
                 offset: float = 0.0):
        self.height = _finite("Ramp", "height", height)
        self.duration = _finite("Ramp", "duration", duration)
        if self.duration < 0:
            raise ParameterError(f"Ramp: parameter 'duration' must be >= 0, got {duration!r}")
        self.start_time = _finite("Ramp", "start_time", start_time)
        self.offset = _finite("Ramp", "offset", offset)
        _finite_result("Ramp", "offset + height", self.offset + self.height)
        _finite_result("Ramp", "start_time + duration", self.start_time + self.duration)
        if self.duration > 0:
            _finite_result("Ramp", "the slope height / duration", self.height / self.duration)
        self._freeze()

    def _rising(self, t, left):
        t0, t1 = self.start_time, self.start_time + self.duration
        return (t0 < t <= t1) if left else (t0 <= t < t1)

    def value(self, t, left=False):
        t0 = self.start_time
        if t < t0 or (left and t == t0):
            return self.offset
        if t >= t0 + self.duration:
            return self.offset + self.height
        return self.offset + self.height * (t - t0) / self.duration

    def derivative(self, t, order=1, left=False):
        if order == 1 and self.duration > 0 and self._rising(t, left):
            return self.height / self.duration
        return 0.0

    def breakpoints(self, t_start=-math.inf, t_end=math.inf):
        return (self.start_time, self.start_time + self.duration)

    def bounds(self):
        return min(self.offset, self.offset + self.height), max(self.offset, self.offset + self.height)


class Sine(Signal):
    """``offset + [t >= start_time] * amplitude*sin(2 pi freq_hz (t - start_time) + phase)``."""

    def __init__(self, amplitude: float = 1.0, freq_hz: float = 1.0, phase: float = 0.0,
                 offset: float = 0.0, start_time: float = 0.0):
        self.amplitude = _finite("Sine", "amplitude", amplitude)
        self.freq_hz = _finite("Sine", "freq_hz", freq_hz)
        self.phase = _finite("Sine", "phase", phase)
        self.offset = _finite("Sine", "offset", offset)
        self.start_time = _finite("Sine", "start_time", start_time)
        _finite_result("Sine", "|offset| + |amplitude|", abs(self.offset) + abs(self.amplitude))
        # the second derivative (a Position reference's acceleration) must be finite too
        w = 2.0 * math.pi * self.freq_hz
        _finite_result("Sine", "amplitude * (2 pi freq_hz)^2", self.amplitude * w * w)
        self._freeze()

    def _on(self, t, left):
        return t > self.start_time if left else t >= self.start_time

    def value(self, t, left=False):
        if not self._on(t, left):
            return self.offset
        w = 2.0 * math.pi * self.freq_hz
        return self.offset + self.amplitude * math.sin(w * (t - self.start_time) + self.phase)

    def derivative(self, t, order=1, left=False):
        if not self._on(t, left):
            return 0.0
        w = 2.0 * math.pi * self.freq_hz
        arg = w * (t - self.start_time) + self.phase + order * math.pi / 2.0
        return self.amplitude * w**order * math.sin(arg)

    def breakpoints(self, t_start=-math.inf, t_end=math.inf):
        return (self.start_time,)

    def bounds(self):
        if self.is_constant_zero():
            return self.offset, self.offset
        return self.offset - abs(self.amplitude), self.offset + abs(self.amplitude)

    def is_constant_zero(self):
        return self.offset == 0.0 and (self.amplitude == 0.0 or self.freq_hz == 0.0 and math.sin(self.phase) == 0.0)


class Table(Signal):
    """Linear interpolation of ``points`` = [(t0, v0), (t1, v1), ...], constant outside.

    Times must be non-decreasing; a time given twice makes a jump there (the
    second value holds from that instant on).
    """

    def __init__(self, points):
        try:
            arr = np.asarray(points, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(f"Table: 'points' must be (t, value) pairs, got {points!r}") from None
        if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] < 1:
            raise ParameterError(f"Table: 'points' must be an (n, 2) array of (t, value) pairs, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ParameterError("Table: 'points' contains NaN or inf")
        dt = np.diff(arr[:, 0])
        if np.any(dt < 0):
            raise ParameterError("Table: times in 'points' must be non-decreasing")
        with np.errstate(all="ignore"):
            slopes = np.diff(arr[:, 1])[dt > 0] / dt[dt > 0]
        if not np.all(np.isfinite(slopes)):
            raise ParameterError("Table: a slope between two points overflows (times too close for the change of "
                                 "value); give the jump as a repeated time instead")
        # a read-only copy: editing the caller's array (or this one) cannot change the signal afterwards
        arr = frozen(arr, "Table", "points")
        self.points = arr
        self._t = arr[:, 0]
        self._v = arr[:, 1]
        self._freeze()

    def _segment(self, t, left):
        # index k with t in piece [t_k, t_{k+1}); left limits use (t_k, t_{k+1}]
        side = "left" if left else "right"
        return int(np.searchsorted(self._t, t, side=side)) - 1

    def value(self, t, left=False):
        k = self._segment(t, left)
        if k < 0:
            return float(self._v[0])
        if k >= len(self._t) - 1:
            return float(self._v[-1])
        t0, t1 = self._t[k], self._t[k + 1]
        if t1 == t0:
            return float(self._v[k + 1])
        return float(self._v[k] + (self._v[k + 1] - self._v[k]) * (t - t0) / (t1 - t0))

    def derivative(self, t, order=1, left=False):
        if order != 1:
            return 0.0
        k = self._segment(t, left)
        if k < 0 or k >= len(self._t) - 1 or self._t[k + 1] == self._t[k]:
            return 0.0
        return float((self._v[k + 1] - self._v[k]) / (self._t[k + 1] - self._t[k]))

    def breakpoints(self, t_start=-math.inf, t_end=math.inf):
        return tuple(sorted(set(float(x) for x in self._t)))

    def count_breakpoints(self, t_start, t_end):
        lo, hi = np.searchsorted(self._t, [t_start, t_end], side="right")
        return int(len(np.unique(self._t[lo:hi][self._t[lo:hi] < t_end])))

    def bounds(self):
        return float(self._v.min()), float(self._v.max())

    def is_constant_zero(self):
        return bool(np.all(self._v == 0.0))

    def __repr__(self):
        return f"Table({self.points.tolist()!r})"


class Pulse(Signal):
    """Rectangular pulses (MSL Pulse): ``offset + amplitude`` during the first ``width``
    percent of each ``period`` after ``start_time``, ``offset`` otherwise."""

    def __init__(self, amplitude: float = 1.0, width: float = 50.0, period: float = 1.0,
                 start_time: float = 0.0, offset: float = 0.0):
        self.amplitude = _finite("Pulse", "amplitude", amplitude)
        self.width = _finite("Pulse", "width", width)
        self.period = _finite("Pulse", "period", period)
        self.start_time = _finite("Pulse", "start_time", start_time)
        self.offset = _finite("Pulse", "offset", offset)
        if not 0 < self.width <= 100:
            raise ParameterError(f"Pulse: parameter 'width' must be in (0, 100] percent, got {width!r}")
        if self.period <= 0:
            raise ParameterError(f"Pulse: parameter 'period' must be > 0, got {period!r}")
        _finite_result("Pulse", "offset + amplitude", self.offset + self.amplitude)
        self._freeze()

    def _pulse_start(self, k):
        return self.start_time + k * self.period

    def value(self, t, left=False):
        if t < self.start_time or (left and t == self.start_time):
            return self.offset
        # the same arithmetic as breakpoints(), so the jump sits exactly at a listed instant
        # (a modulo would put it one ulp beside it, inside the next integration segment)
        on_time = self.width / 100.0 * self.period
        k = int(math.floor((t - self.start_time) / self.period))
        for kk in (k - 1, k, k + 1):
            t0 = self._pulse_start(kk)
            if kk >= 0 and ((t0 < t <= t0 + on_time) if left else (t0 <= t < t0 + on_time)):
                return self.offset + self.amplitude
        return self.offset

    def derivative(self, t, order=1, left=False):
        return 0.0

    def breakpoints(self, t_start=-math.inf, t_end=math.inf):
        if not math.isfinite(t_end):
            raise ParameterError("Pulse.breakpoints needs a finite time range")
        pts = []
        k = max(0, int(math.floor((t_start - self.start_time) / self.period)))
        on_time = self.width / 100.0 * self.period
        while True:
            t0 = self._pulse_start(k)
            if t0 > t_end:
                break
            pts += [t0, t0 + on_time]
            k += 1
        return tuple(p for p in pts if t_start <= p <= t_end)

    def count_breakpoints(self, t_start, t_end):
        """Pulse starts and ends in (t_start, t_end), counted from the period (to round-off at the ends;
        at ``width=100`` an end and the next start may differ by round-off, so both are counted)."""
        if t_end <= t_start:
            return 0
        if not (math.isfinite(t_start) and math.isfinite(t_end)):
            return sys.maxsize

        def inside(first):      # k >= 0 with t_start < first + k * period < t_end
            k_lo = max(0.0, math.floor((t_start - first) / self.period) + 1.0)
            k_hi = math.ceil((t_end - first) / self.period) - 1.0
            return max(0.0, k_hi - k_lo + 1.0)

        n = inside(self.start_time) + inside(self.start_time + self.width / 100.0 * self.period)
        return int(min(n, sys.maxsize))

    def bounds(self):
        return min(self.offset, self.offset + self.amplitude), max(self.offset, self.offset + self.amplitude)

    def is_constant_zero(self):
        return self.offset == 0.0 and self.amplitude == 0.0


def _where(owner) -> str:
    """How an error names the owner: "Clutch 'clutch1'" for a component (its name at the time of the
    error, so a subsystem's part reads 'wheel.road_contact'), the text itself for a string."""
    if owner is None:
        return "signal"
    if isinstance(owner, str):
        return owner
    return f"{type(owner).__name__} '{getattr(owner, 'name', '?')}'"


def _check_arity(func, where: str, name: str) -> None:
    """Refuse a callable that cannot be called as f(t) (one positional argument)."""
    try:
        sig = inspect.signature(func)
    except (TypeError, ValueError):      # a builtin without a signature: it is tried at the first call
        return
    try:
        sig.bind(0.0)
    except TypeError:
        label = getattr(func, "__name__", type(func).__name__)
        raise ParameterError(
            f"{where}: parameter '{name}' is the callable {label}{sig}, but a signal is called as f(t) with the "
            f"time t [s] as its one argument; give a function of t alone (e.g. lambda t: ...) or a "
            f"regmech.signals signal (Step, Ramp, Sine, Table, ...)") from None


class _Bound:
    """The checks of a signal that the library cannot vouch for (a callable, a user's Signal
    subclass), bound to the component and the parameter it drives (see the module docstring)."""

    _owner = None
    _name = "value"
    _lo = -_BIG
    _hi = _BIG
    _range = (None, None)
    _note = ""

    def _bind(self, owner, name: str, bounds, note: str):
        self._owner, self._name, self._note = owner, name, note
        lo, hi = bounds if bounds is not None else (None, None)
        self._lo = -_BIG if lo is None else lo - BOUNDS_SLACK * max(1.0, abs(lo))
        self._hi = _BIG if hi is None else hi + BOUNDS_SLACK * max(1.0, abs(hi))
        self._range = (lo, hi)
        return self

    def _label(self) -> str:
        return f"{_where(self._owner)}: signal '{self._name}'"

    def _source(self) -> str:
        return "the signal"

    def _raised(self, exc: BaseException, t) -> SimulationError:
        return SimulationError(
            f"{self._label()}: {self._source()} raised {type(exc).__name__}: {exc} at t={float(t):.9g} s; it is "
            f"called with the time t [s] and must return a finite number for every t of the run (fix it, or use a "
            f"regmech.signals signal)")

    def _not_a_number(self, v, t) -> SimulationError:
        return SimulationError(
            f"{self._label()}: {self._source()} returned {v!r} at t={float(t):.9g} s; it must return a real "
            f"number")

    def _refused(self, v: float, t, what: str = "value") -> SimulationError:
        if not math.isfinite(v):
            return SimulationError(
                f"{self._label()}: its {what} is {v!r} at t={float(t):.9g} s; signals must be finite. Check "
                f"{self._source()} (0/0, a log or square root of a negative number, an overflow, a lookup "
                f"outside a table) or use a regmech.signals signal")
        lo, hi = self._range
        side = f"above its upper bound {hi:g}" if hi is not None and v > hi else f"below its lower bound {lo:g}"
        return SimulationError(
            f"{self._label()}: its value is {v:.9g} at t={float(t):.9g} s, {side}{self._note}")

    def _checked(self, v, t) -> float:
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise self._not_a_number(v, t) from None
        if self._lo <= v <= self._hi:
            return v
        raise self._refused(v, t)

    def _checked_derivative(self, d, t) -> float:
        try:
            d = float(d)
        except (TypeError, ValueError):
            raise self._not_a_number(d, t) from None
        if -_BIG <= d <= _BIG:
            return d
        raise self._refused(d, t, "derivative")


#: round-off of a user's callable, in units of eps |f| (a few operations, each within half an ulp)
FUNCTION_ULPS = 4.0


class Function(_Bound, Signal):
    """Wraps a user callable ``f(t)``; derivatives by central differences.

    No breakpoints are known, so a discontinuous callable is integrated
    across its jumps by step-size control alone: prefer ``Step``/``Table``.
    Every value is checked (see the module docstring): an exception, a
    non-number, NaN, inf or a value outside the parameter's range is a
    ``SimulationError`` naming the component, the parameter and the time.
    """

    def __init__(self, func: Callable[[float], float], breakpoints=()):
        if not callable(func):
            raise ParameterError(f"Function: {func!r} is not callable")
        _check_arity(func, "Function", "func")
        self.func = func
        try:
            self._bp = tuple(float(b) for b in breakpoints)
        except (TypeError, ValueError):
            raise ParameterError(f"Function: breakpoints must be times in s, got {breakpoints!r}") from None
        if not all(math.isfinite(b) for b in self._bp):
            raise ParameterError(f"Function: breakpoints must be finite, got {breakpoints!r}")

    def _source(self) -> str:
        return f"the callable {getattr(self.func, '__qualname__', None) or repr(self.func)}"

    def __getstate__(self):
        # a lambda or a nested function has no name pickle could find it by: it is pickled by value
        # (``regmech._portable``), and what cannot be pickled is named with the component and the signal
        from ._portable import portable
        state = self.__dict__.copy()
        state["func"] = portable(self.func, self._label())
        return state

    def value(self, t, left=False):
        try:
            v = self.func(t)
        except RegmechError:
            raise
        except Exception as exc:
            raise self._raised(exc, t) from exc
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise self._not_a_number(v, t) from None
        if self._lo <= v <= self._hi:      # False for NaN and +-inf too
            return v
        raise self._refused(v, t)

    def derivative(self, t, order=1, left=False):
        # central differences with Richardson extrapolation; steps balance truncation against
        # round-off (eps^(1/3) for the first derivative, eps^(1/4) for the second)
        if order == 1:
            h = 1e-4 + 1e-9 * abs(t)
            d = lambda k: (self.value(t + k) - self.value(t - k)) / (2 * k)  # noqa: E731
        elif order == 2:
            h = 2e-3 + 1e-8 * abs(t)
            d = lambda k: (self.value(t + k) - 2 * self.value(t) + self.value(t - k)) / (k * k)  # noqa: E731
        else:
            return 0.0
        return self._checked_derivative((4.0 * d(h / 2) - d(h)) / 3.0, t)

    def derivative_noise(self, t, order=1):
        """Bound of the round-off in ``derivative``: with the values off by ``delta = FUNCTION_ULPS eps |f|``
        each, the extrapolated central difference is off by up to ``3 delta / h`` (first derivative) or
        ``68 delta / (3 h^2)`` (second). Measured on ``-18.26 - 0.4406 (1 - exp(-t / 0.08126))`` (fuzz CI seed
        2002): 4.9e-11 rad/s^2 at most over 0.6 s, the bound 5e-10. IDA's error test must not ask an
        acceleration or a force made of it for more (``solvers.ida._atol_vector``): at rtol 1e-10 it did, and
        IDA halved its steps on the noise until max_steps."""
        if order not in (1, 2):
            return 0.0
        delta = FUNCTION_ULPS * np.finfo(float).eps * max(abs(self.value(t)), 1e-300)
        if order == 1:
            return 3.0 * delta / (1e-4 + 1e-9 * abs(t))
        return 68.0 / 3.0 * delta / (2e-3 + 1e-8 * abs(t)) ** 2

    def breakpoints(self, t_start=-math.inf, t_end=math.inf):
        return self._bp


class _Checked(_Bound, Signal):
    """A user's ``Signal`` subclass, bound to a component parameter: the same checks as ``Function``
    around its ``value`` and ``derivative``; everything else is the signal's own."""

    def __init__(self, inner: Signal):
        self.inner = inner

    def _source(self) -> str:
        return f"{type(self.inner).__name__}.value"

    def value(self, t, left=False):
        try:
            v = self.inner.value(t, left)
        except RegmechError:
            raise
        except Exception as exc:
            raise self._raised(exc, t) from exc
        return self._checked(v, t)

    def derivative(self, t, order=1, left=False):
        try:
            d = self.inner.derivative(t, order, left)
        except RegmechError:
            raise
        except Exception as exc:
            raise self._raised(exc, t) from exc
        return self._checked_derivative(d, t)

    def derivative_noise(self, t, order=1):
        return self.inner.derivative_noise(t, order)

    def breakpoints(self, t_start=-math.inf, t_end=math.inf):
        return self.inner.breakpoints(t_start, t_end)

    def count_breakpoints(self, t_start, t_end):
        return self.inner.count_breakpoints(t_start, t_end)

    def bounds(self):
        return self.inner.bounds()

    def is_constant_zero(self):
        return self.inner.is_constant_zero()

    def __repr__(self):
        return repr(self.inner)


#: signals whose values are finite for every t by construction: used unwrapped, no check per call
TRUSTED = (Constant, Step, Ramp, Sine, Table, Pulse)


def _check_range(sig: Signal, where: str, name: str, bounds, note: str) -> None:
    """Refuse a built-in signal whose range leaves the parameter's documented range."""
    lo, hi = bounds
    s_lo, s_hi = sig.bounds()
    if hi is not None and s_hi > hi + BOUNDS_SLACK * max(1.0, abs(hi)):
        raise ParameterError(f"{where}: parameter '{name}' = {sig!r} reaches {s_hi:g}, above its upper bound "
                             f"{hi:g}{note}")
    if lo is not None and s_lo < lo - BOUNDS_SLACK * max(1.0, abs(lo)):
        raise ParameterError(f"{where}: parameter '{name}' = {sig!r} reaches {s_lo:g}, below its lower bound "
                             f"{lo:g}{note}")


def as_signal(value, owner="signal", name: str = "value", bounds=None, note: str = "") -> Signal:
    """Turn a number, a Signal or a callable into a Signal bound to ``owner`` (a component or a text
    naming it) and its parameter ``name`` (ParameterError when it cannot be one).

    ``bounds`` = (lo, hi) (None: open) is the parameter's documented range, ``note`` the sentence that
    explains it in an error. Built-in signals come back as they are (their range is checked here);
    a callable becomes a checked ``Function``, another ``Signal`` a checked wrapper (see the module
    docstring); a ``Function`` or wrapper bound elsewhere is bound anew to this owner.
    """
    where = _where(owner)
    if isinstance(value, type) and issubclass(value, Signal):
        raise ParameterError(f"{where}: parameter '{name}' is the class {value.__name__}; give an instance, "
                             f"e.g. {value.__name__}(...)")
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        if not math.isfinite(float(value)):
            raise ParameterError(f"{where}: parameter '{name}' must be finite, got {value!r}")
        value = Constant(float(value))
    if isinstance(value, Signal):
        if type(value) in TRUSTED:
            if bounds is not None:
                _check_range(value, where, name, bounds, note)
            return value
        if type(value) is Function:
            sig = object.__new__(Function)
            sig.func, sig._bp = value.func, value._bp
            return sig._bind(owner, name, bounds, note)
        inner = value.inner if isinstance(value, _Checked) else value
        return _Checked(inner)._bind(owner, name, bounds, note)
    if callable(value):
        _check_arity(value, where, name)
        sig = Function.__new__(Function)
        sig.func, sig._bp = value, ()
        return sig._bind(owner, name, bounds, note)
    raise ParameterError(
        f"{where}: parameter '{name}' must be a number, a regmech.signals signal or a callable f(t), got {value!r}")
