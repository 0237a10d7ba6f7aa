"""Blocks with discrete memory: a sample-and-hold at an ECU's task rate, a relay with hysteresis, a shift
schedule.

``SampleHold``: ``y(t) = u(t_k)`` for ``t_k <= t < t_k + T``, ``t_k = t0 + k T`` (k = 0, 1, ...); before
``t0`` it holds ``y0``. ``y`` is a state of rate 0 (``Device.sampled_states``); every sample instant is a
time event of the run (the block's ``clock`` signal declares them as breakpoints), at which the solver stops
and restarts with ``y`` set to the input's value there (``compile.reads.settle``). ``T`` [s] > 0.

``Hysteresis`` (a relay): ``q`` switches to 1 when ``u`` rises above ``u_high`` and to 0 when it falls below
``u_low`` (``u_low < u_high``), and holds between; ``y = y_off + (y_on - y_off) q``. ``q`` is a latch state
(``Device.latch_states``): its switching surface ``u - u_high`` (while off) or ``u_low - u`` (while on) is
located as an event, where ``q`` changes; no step meets the jump of ``y``.

``ShiftSchedule``: the gear ``y`` in 1..n of an automatic transmission from the vehicle speed ``v`` and the
throttle ``thr`` (0..1). Gear k shifts up to k + 1 when ``v`` rises above its up line ``up_k(thr) =
up[k][0] + (up[k][1] - up[k][0]) thr`` and down to k - 1 when ``v`` falls below its down line
``down_k(thr)`` likewise; each change is an event. Hysteresis: the down line of gear k + 1 lies below the up
line of gear k at every throttle (checked), so a shift cannot undo itself (no hunting). ``v`` [m/s] (or any
speed in the lines' unit), ``y`` [1].
"""

from __future__ import annotations

import math
import sys
from typing import ClassVar

import numpy as np
import sympy

from ..component import Param, refuse_positional
from ..errors import ParameterError
from ..signals import Signal
from .base import Block, Input


class SampleClock(Signal):
    """Zero, with breakpoints at ``t0 + k T`` (k >= 0): the sample instants of a ``SampleHold``."""

    def __init__(self, period: float, t0: float):
        self.period, self.t0 = float(period), float(t0)

    def value(self, t, left=False):
        return 0.0

    def derivative(self, t, order=1, left=False):
        return 0.0

    def _k_range(self, t_start, t_end):
        lo = max(0, math.ceil((t_start - self.t0) / self.period))
        hi = math.floor((t_end - self.t0) / self.period)
        return lo, hi

    def breakpoints(self, t_start=-math.inf, t_end=math.inf):
        if not math.isfinite(t_end):
            raise ParameterError("SampleClock.breakpoints needs a finite time range")
        lo, hi = self._k_range(t_start if math.isfinite(t_start) else self.t0, t_end)
        return tuple(self.t0 + k * self.period for k in range(lo, hi + 1))

    def count_breakpoints(self, t_start, t_end):
        if not (math.isfinite(t_start) and math.isfinite(t_end)):
            return sys.maxsize
        lo, hi = self._k_range(t_start, t_end)
        return max(0, hi - lo + 1)

    def bounds(self):
        return (0.0, 0.0)


class SampleHold(Block):
    """Sample-and-hold at period ``T`` (module docstring)."""

    dynamic_outputs = {"y": "y0"}
    sampled_states = {"y": ("u", "T", "t0")}
    u = Input(doc="input, sampled")
    T = Param(check="real", unit="s", doc="sample period > 0")
    t0 = Param(0.0, check="real", unit="s", doc="first sample instant")
    y0 = Param(0.0, check="real", doc="output before the first sample")
    clock = Param(None, check="any", optional=True, doc="(set by the block) the sample instants as a signal")

    def check_block(self):
        if not self.T > 0:
            raise ParameterError(f"SampleHold '{self.name}': the sample period T must be > 0 s, got T={self.T:g}; "
                                 f"give the task rate's period, e.g. T=0.01 for 100 Hz")
        self._values["clock"] = SampleClock(self.T, self.t0)

    def rates(self, e, de):
        return {"y": 0}


class Hysteresis(Block):
    """Relay with hysteresis (module docstring): ``y = y_on`` after ``u`` rose above ``u_high``, ``y_off`` after it
    fell below ``u_low``; ``on0`` the start state (True/False; corrected at the start when ``u`` lies beyond a
    threshold)."""

    outputs = {"y": ""}
    internal = {"q": "q0"}
    latch_states = {"q": ((0, 1.0), (1, -1.0))}
    switching_kind = "latch"
    u = Input(doc="input")
    u_low = Param(check="real", doc="switch-off level")
    u_high = Param(check="real", doc="switch-on level")
    y_on = Param(1.0, check="real", doc="output while on")
    y_off = Param(0.0, check="real", doc="output while off")
    q0 = Param(0.0, check="real", doc="start state: 1 on, 0 off")

    def check_block(self):
        if not self.u_low < self.u_high:
            raise ParameterError(f"Hysteresis '{self.name}': needs u_low < u_high (the band it holds its state in), "
                                 f"got u_low={self.u_low}, u_high={self.u_high}")
        if self.q0 not in (0.0, 1.0):
            raise ParameterError(f"Hysteresis '{self.name}': q0 is the start state, 1 (on) or 0 (off), got {self.q0}")

    def output_laws(self, e, de):
        return {"y": self.y_off + (self.y_on - self.y_off) * self.q}

    def rates(self, e, de):
        return {"q": 0}

    def switching_surfaces(self, e, de):
        # one surface watched at a time: the other one is held at -1 (the latch's new value makes its own
        # surface jump below zero, the other one start below it)
        return [(sympy.Piecewise((self.u - self.u_high, self.q < 0.5), (-1.0, True)), 1),
                (sympy.Piecewise((self.u_low - self.u, self.q > 0.5), (-1.0, True)), -1)]


def _lines(name, what, lines, n):
    arr = np.asarray(lines, float) if lines is not None else None
    if arr is None or arr.shape != (n - 1, 2) or not np.all(np.isfinite(arr)):
        raise ParameterError(f"ShiftSchedule '{name}': {what} must be {n - 1} pairs (speed at throttle 0, speed at "
                             f"throttle 1), one per shift of {n} gears, got {lines!r}")
    return arr


class ShiftSchedule(Block):
    """Gear selection of an automatic transmission (module docstring): ``up[k]`` the up line of gear k + 1 (a pair of
    speeds at throttle 0 and 1), ``down[k]`` the down line of gear k + 2 (to gear k + 1), k = 0..n-2; output ``y``
    the gear (1..n), ``gear0`` the start gear (corrected at the start to the speed)."""

    outputs = {"y": "1"}
    internal = {"q": "gear0"}
    latch_states = {"q": ((0, 1.0), (1, -1.0))}
    switching_kind = "latch"
    v = Input(doc="vehicle speed (in the lines' unit)")
    thr = Input(doc="throttle 0..1", default=0.0)
    up = Param(check="any", doc="(n-1, 2) up lines: speed at throttle 0 and 1")
    down = Param(check="any", doc="(n-1, 2) down lines: speed at throttle 0 and 1")
    gear0 = Param(1.0, check="real", doc="start gear")
    #: the lines of the class of one schedule (they are part of the laws: each distinct schedule is its own class)
    _up: ClassVar[np.ndarray | None] = None
    _down: ClassVar[np.ndarray | None] = None
    _public: ClassVar[type | None] = None
    _classes: ClassVar[dict] = {}

    def __new__(cls, name=None, *args, **params):
        public = cls._public or cls
        refuse_positional(public, (name, *args))
        up, down = _schedule_lines(name, params.get("up"), params.get("down"))
        key = (up.tobytes(), down.tobytes(), up.shape)
        sub = ShiftSchedule._classes.get(key)
        if sub is None:
            sub = type(public.__name__, (public,), {"_up": up, "_down": down, "_public": public,
                                                    "__module__": public.__module__,
                                                    "__qualname__": public.__qualname__, "__doc__": public.__doc__})
            ShiftSchedule._classes[key] = sub
        return object.__new__(sub)

    def __reduce_ex__(self, protocol):
        return _schedule_shell, (self.up, self.down), self.__dict__

    def check_block(self):
        up, down = _schedule_lines(self.name, self.up, self.down)
        self._values["up"], self._values["down"] = up, down
        n_gears = len(up) + 1
        if self.gear0 != int(self.gear0) or not 1 <= self.gear0 <= n_gears:
            raise ParameterError(f"ShiftSchedule '{self.name}': gear0 must be a gear 1..{n_gears}, got {self.gear0}")

    def output_laws(self, e, de):
        return {"y": self.q}

    def rates(self, e, de):
        return {"q": 0}

    def switching_surfaces(self, e, de):
        # (self._up, self._down: class attributes, read through the compiler's stand-in too)
        up = [float(a) + (float(b) - float(a)) * self.thr for a, b in self._up]
        down = [float(a) + (float(b) - float(a)) * self.thr for a, b in self._down]
        n = len(up) + 1
        q = self.q
        up_g = sympy.Piecewise(*[(self.v - up[k], q < k + 1.5) for k in range(n - 1)], (-1.0, True))
        down_g = sympy.Piecewise((-1.0, q < 1.5), *[(down[k] - self.v, q < k + 2.5) for k in range(n - 1)],
                                 (-1.0, True))
        return [(up_g, 1), (down_g, -1)]


def _schedule_shell(up, down):
    """Unpickling helper: an empty ``ShiftSchedule`` of the class of its lines."""
    return ShiftSchedule.__new__(ShiftSchedule, "schedule", up=up, down=down)


def _schedule_lines(name, up, down):
    """The (n-1, 2) up and down lines, checked (ParameterError naming the block and the fix)."""
    arr = np.asarray(up, float) if up is not None else None
    n = (len(arr) + 1) if arr is not None and arr.ndim == 2 else 2
    up = _lines(name, "up", up, n)
    down = _lines(name, "down", down, n)
    if np.any(down >= up):
        k = int(np.nonzero(np.any(down >= up, axis=1))[0][0])
        raise ParameterError(f"ShiftSchedule '{name}': the down line of gear {k + 2} {down[k].tolist()} must lie below "
                             f"the up line of gear {k + 1} {up[k].tolist()} at every throttle (the band between "
                             f"them is the hysteresis that stops hunting)")
    up.setflags(write=False)
    down.setflags(write=False)
    return up, down


__all__ = ["SampleHold", "SampleClock", "Hysteresis", "ShiftSchedule"]
