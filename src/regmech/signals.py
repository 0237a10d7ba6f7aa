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
"""

from __future__ import annotations

import math
import numbers
from typing import Callable

import numpy as np

from .errors import ParameterError

__all__ = ["Signal", "Constant", "Step", "Ramp", "Sine", "Table", "Pulse", "Function", "as_signal"]


def _finite(owner: str, name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{owner}: parameter '{name}' must be a real number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ParameterError(f"{owner}: parameter '{name}' must be finite, got {value!r}")
    return value


class Signal:
    """Base class: override ``value`` and ``derivative``; list ``breakpoints``."""

    def __call__(self, t: float, left: bool = False) -> float:
        return self.value(t, left)

    def value(self, t: float, left: bool = False) -> float:  # pragma: no cover - abstract
        raise NotImplementedError

    def derivative(self, t: float, order: int = 1, left: bool = False) -> float:
        """d^order s / dt^order at t (one-sided limit when ``left``)."""
        raise NotImplementedError

    def breakpoints(self, t_start: float = -math.inf, t_end: float = math.inf) -> tuple[float, ...]:
        """Instants where the signal or one of its derivatives jumps (periodic
        signals list those in [t_start, t_end])."""
        return ()

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

    def value(self, t, left=False):
        return self.value_

    def derivative(self, t, order=1, left=False):
        return 0.0

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

    def value(self, t, left=False):
        on = t > self.start_time if left else t >= self.start_time
        return self.offset + (self.height if on else 0.0)

    def derivative(self, t, order=1, left=False):
        return 0.0

    def breakpoints(self, t_start=-math.inf, t_end=math.inf):
        return (self.start_time,)

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


class Sine(Signal):
    """``offset + [t >= start_time] * amplitude*sin(2 pi freq_hz (t - start_time) + phase)``."""

    def __init__(self, amplitude: float = 1.0, freq_hz: float = 1.0, phase: float = 0.0,
                 offset: float = 0.0, start_time: float = 0.0):
        self.amplitude = _finite("Sine", "amplitude", amplitude)
        self.freq_hz = _finite("Sine", "freq_hz", freq_hz)
        self.phase = _finite("Sine", "phase", phase)
        self.offset = _finite("Sine", "offset", offset)
        self.start_time = _finite("Sine", "start_time", start_time)

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
        if np.any(np.diff(arr[:, 0]) < 0):
            raise ParameterError("Table: times in 'points' must be non-decreasing")
        self.points = arr
        self._t = arr[:, 0]
        self._v = arr[:, 1]

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

    def is_constant_zero(self):
        return self.offset == 0.0 and self.amplitude == 0.0


class Function(Signal):
    """Wraps a user callable ``f(t)``; derivatives by central differences.

    No breakpoints are known, so a discontinuous callable is integrated
    across its jumps by step-size control alone: prefer ``Step``/``Table``.
    """

    def __init__(self, func: Callable[[float], float], breakpoints=()):
        if not callable(func):
            raise ParameterError(f"Function: {func!r} is not callable")
        self.func = func
        self._bp = tuple(float(b) for b in breakpoints)

    def value(self, t, left=False):
        v = self.func(t)
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise ParameterError(f"signal function {self.func!r} returned {v!r} at t={t}; it must return a real number") from None
        return v

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
        return (4.0 * d(h / 2) - d(h)) / 3.0

    def breakpoints(self, t_start=-math.inf, t_end=math.inf):
        return self._bp


def as_signal(value, owner: str = "signal", name: str = "value") -> Signal:
    """Turn a number, a Signal or a callable into a Signal (ParameterError otherwise)."""
    if isinstance(value, Signal):
        return value
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        if not math.isfinite(float(value)):
            raise ParameterError(f"{owner}: parameter '{name}' must be finite, got {value!r}")
        return Constant(float(value))
    if callable(value):
        return Function(value)
    raise ParameterError(
        f"{owner}: parameter '{name}' must be a number, a regmech.signals signal or a callable f(t), got {value!r}")
