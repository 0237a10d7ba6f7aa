"""Blocks with states: a first-order lag, an integrator and PI/PID controllers.

Their states are differential unknowns of the DAE (``blocks.base``)::

    Lag          T dy/dt = k u - y                              y(0) = y0        (no feedthrough)
    Integrator   dy/dt = k u, held in [y_min, y_max]:           y(0) = y0        (no feedthrough)
                 at the upper limit dy/dt = min(k u, 0), at the lower one max(k u, 0); reaching or leaving a
                 limit is an event, and which limit holds is a branch state (``q_hi``, ``q_lo``) set there
    PI           e = ref - u                                    control error
                 v = k e + x                                    unlimited output
                 y = min(max(v, y_min), y_max)                  output (reaching a limit is an event)
                 dx/dt = (k / T_i) e + (y - v) / T_t            integral part, back-calculation anti-windup:
                                                                while limited, x is pulled back so that v
                                                                tracks y with time constant T_t (default T_i)
    PID          as PI, with v = k e + x + k T_d (e - d) / T_f  (the derivative of e filtered with T_f)
                 dd/dt = (e - d) / T_f,  T_f = T_d / N          d the filter's state

Units: ``y`` has the unit of what the controller drives (V for a motor's voltage, 1 for a clutch's
normalised force), ``k`` [unit of y per unit of e], ``T_i``, ``T_t``, ``T_d``, ``T`` [s].
Unlimited on a plant ``J w' = k_m i``, ``L i' = u_m - R i - k_m w`` the PI loop is linear, so
``Model.linearize`` gives its exact poles.
"""

from __future__ import annotations

import sympy

from ..component import Param
from ..errors import ParameterError
from .base import OPEN, Block, Input, clip


class Lag(Block):
    """First-order lag ``T dy/dt = k u - y`` (``PT1``); ``y0`` the start value."""

    dynamic_outputs = {"y": "y0"}
    u = Input(doc="input")
    T = Param(check="positive", unit="s", doc="time constant")
    k = Param(1.0, check="real", doc="static gain")
    y0 = Param(0.0, check="real", doc="start value of y")

    def rates(self, e, de):
        return {"y": (self.k * self.u - self.y) / self.T}


class Integrator(Block):
    """``dy/dt = k u`` with optional limits ``y_min``, ``y_max`` (integration stops at a limit while the input
    drives beyond it; each stop is an event); ``y0`` the start value (inside the limits)."""

    dynamic_outputs = {"y": "y0"}
    internal = {"q_hi": None, "q_lo": None}
    branch_states = {"q_hi": 0, "q_lo": 1}
    u = Input(doc="input")
    k = Param(1.0, check="real", doc="gain")
    y0 = Param(0.0, check="real", doc="start value of y")
    y_min = Param(None, check="real", optional=True, doc="lower limit (None: none)")
    y_max = Param(None, check="real", optional=True, doc="upper limit (None: none)")

    def check_block(self):
        _open_limits(self)
        if not self.y_min <= self.y0 <= self.y_max:
            raise ParameterError(f"Integrator '{self.name}': the start y0={self.y0} lies outside the limits "
                                 f"[{_shown(self.y_min)}, {_shown(self.y_max)}]; start inside them")

    def switching_active(self):
        return self.y_min > -OPEN or self.y_max < OPEN

    def rates(self, e, de):
        r = self.k * self.u
        free = 1 - self.q_hi - self.q_lo
        return {"y": free * r + self.q_hi * sympy.Piecewise((r, r < 0), (0.0, True))
                + self.q_lo * sympy.Piecewise((r, r > 0), (0.0, True)), "q_hi": 0, "q_lo": 0}

    def switching_surfaces(self, e, de):
        return [(self.y - self.y_max, 1), (self.y_min - self.y, -1)]


def _open_limits(blk):
    """None limits as -/+ ``OPEN``, and ``y_min < y_max`` checked."""
    if blk._values["y_min"] is None:
        blk._values["y_min"] = -OPEN
    if blk._values["y_max"] is None:
        blk._values["y_max"] = OPEN
    if not blk.y_min < blk.y_max:
        raise ParameterError(f"{type(blk).__name__} '{blk.name}': needs y_min < y_max, got y_min={blk.y_min}, "
                             f"y_max={blk.y_max}; swap them or widen the band")


def _shown(v):
    return "-inf" if v <= -OPEN else "inf" if v >= OPEN else f"{v:g}"


class PI(Block):
    """PI controller on the error ``e = ref - u`` with output limits and back-calculation anti-windup (module
    docstring); ``k`` may be negative (a reverse-acting loop)."""

    outputs = {"y": ""}
    internal = {"x": "x0"}
    u = Input(doc="measurement")
    ref = Input(doc="reference (set point)")
    k = Param(check="nonzero", doc="proportional gain [unit of y per unit of e]")
    T_i = Param(check="positive", unit="s", doc="integral time")
    T_t = Param(None, check="positive", optional=True, unit="s", doc="anti-windup tracking time (default T_i)")
    y_min = Param(None, check="real", optional=True, doc="lower output limit (None: none)")
    y_max = Param(None, check="real", optional=True, doc="upper output limit (None: none)")
    x0 = Param(0.0, check="real", doc="start of the integral part")

    def check_block(self):
        _open_limits(self)
        if self.T_t is None:
            self._values["T_t"] = self.T_i

    def switching_active(self):
        return self.y_min > -OPEN or self.y_max < OPEN

    def _unlimited(self):
        err = self.ref - self.u
        return err, self.k * err + self.x

    def output_laws(self, e, de):
        return {"y": clip(self._unlimited()[1], self.y_min, self.y_max)}

    def rates(self, e, de):
        err, v = self._unlimited()
        return {"x": self.k / self.T_i * err + (clip(v, self.y_min, self.y_max) - v) / self.T_t}

    def switching_surfaces(self, e, de):
        v = self._unlimited()[1]
        return [(v - self.y_max, 1), (self.y_min - v, -1)]


class PID(PI):
    """PID controller: ``PI`` plus the filtered derivative ``k T_d (e - d) / T_f`` with ``dd/dt = (e - d) / T_f``,
    ``T_f = T_d / N`` (module docstring); ``d0`` the filter's start (default: the first error, no kick)."""

    internal = {"x": "x0", "d": "d0"}
    T_d = Param(check="positive", unit="s", doc="derivative time")
    N = Param(10.0, check="positive", doc="derivative filter: T_f = T_d / N")
    d0 = Param(0.0, check="real", doc="start of the derivative filter's state (the error at the start: no kick)")

    def _unlimited(self):
        err = self.ref - self.u
        t_f = self.T_d / self.N
        return err, self.k * err + self.x + self.k * self.T_d * (err - self.d) / t_f

    def rates(self, e, de):
        out = PI.rates(self, e, de)          # (no super(): self is the compiler's stand-in here)
        out["d"] = (self.ref - self.u - self.d) * self.N / self.T_d
        return out


class ShiftElement(Block):
    """The normalised force of a transmission's shift element k from a gear selection (a ``ShiftSchedule``'s
    output): the target is 1 while ``gear`` is k, else 0; the state ``f`` follows it at the first-order rates
    ``df/dt = (target - f) / T`` with ``T = engage_time / 3`` when applying and ``release_time / 3`` when
    releasing (95 % of the way in the given time); the output ``y = min(max(f, 0), 1)`` [1] (``f_normalized``'s
    range). The gear changes only at the schedule's events, so the target jumps only at restarts."""

    outputs = {"y": "1"}
    internal = {"f": "f0"}
    gear = Input(unit="1", doc="selected gear (a ShiftSchedule's y)")
    k = Param(check="positive", doc="the gear of this element")
    engage_time = Param(0.3, check="positive", unit="s", doc="time to apply the element")
    release_time = Param(0.1, check="positive", unit="s", doc="time to release the element")
    f0 = Param(0.0, check="real", doc="start of the normalised force")

    def output_laws(self, e, de):
        return {"y": clip(self.f, 0.0, 1.0)}

    def rates(self, e, de):
        target = sympy.Piecewise((1.0, abs(self.gear - self.k) < 0.5), (0.0, True))
        t_c = sympy.Piecewise((self.engage_time / 3, target > self.f), (self.release_time / 3, True))
        return {"f": (target - self.f) / t_c}


__all__ = ["Lag", "Integrator", "PI", "PID", "ShiftElement"]
