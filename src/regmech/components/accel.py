"""Prescribed acceleration: ``Accelerate`` (rotational) and ``LinearAccelerate`` (translational).

MSL ``Accelerate``: the flange follows the acceleration ``a_ref(t)`` from the start speed ``w0``::

    w(t) = w0 + integral_0^t a_ref(s) ds,     a(t) = a_ref(t)        [rad/s, rad/s^2]

It is a prescribed-speed source (``Speed``) whose reference is that integral, so it shares the
speed source's equations, events and checks: the speed is continuous whatever ``a_ref`` does
(a step of acceleration is a corner of the speed, a time event), and the source's torque
``tau`` is what the driven masses need. ``w0`` is the speed at ``t = 0`` (the integral starts
there whatever the run's ``t_start``).
"""

from __future__ import annotations

import bisect
import math

import warnings

from scipy.integrate import IntegrationWarning, quad

from ..component import Param
from ..errors import SimulationError
from ..ports import ROTATIONAL, TRANSLATIONAL
from ..signals import Signal
from .sources import _Prescribed


class IntegralSignal(Signal):
    """``v0 + integral_0^t s(u) du`` of a signal ``s``, piece by piece between its breakpoints (each
    piece is smooth, so ``quad`` is exact for the polynomial pieces of Constant, Step, Ramp, Table and
    accurate to ~1e-14 elsewhere); the integrals of whole pieces are kept."""

    def __init__(self, inner: Signal, v0: float = 0.0, owner: str = "signal"):
        self.inner, self.v0, self.owner = inner, float(v0), owner
        self._cum = {0.0: 0.0}       # breakpoint -> integral from 0 to it

    def _piece(self, a, b):
        if a == b:
            return 0.0
        # an absolute floor too: a piece whose integral is ~0 (a whole period of a Sine) cannot meet a
        # relative tolerance, and quad would warn about round-off on a correct result
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IntegrationWarning)
            val, _ = quad(lambda u: self.inner.value(u, False), a, b, epsabs=1e-15 * (b - a),
                          epsrel=1e-13, limit=200)
        if not math.isfinite(val):
            raise SimulationError(f"{self.owner}: the integral of a_ref over [{a:g}, {b:g}] s is not finite")
        return val

    def _from_zero(self, t):
        lo, hi = (0.0, t) if t >= 0 else (t, 0.0)
        bps = sorted(b for b in self.inner.breakpoints(lo, hi) if lo < b < hi and math.isfinite(b))
        if t < 0:
            return -sum(self._piece(a, b) for a, b in zip([t] + bps, bps + [0.0]))
        # the largest known breakpoint below t, then piece by piece
        known = sorted(k for k in self._cum if 0.0 <= k <= t)
        start = known[-1]
        total = self._cum[start]
        k = bisect.bisect_right(bps, start)
        for b in bps[k:]:
            total += self._piece(start, b)
            start = b
            if len(self._cum) < 100_000:
                self._cum[b] = total
        return total + self._piece(start, t)

    def value(self, t, left=False):
        return self.v0 + self._from_zero(float(t))

    def derivative(self, t, order=1, left=False):
        if order == 1:
            return self.inner.value(t, left)
        return self.inner.derivative(t, order - 1, left)

    def breakpoints(self, t_start=-math.inf, t_end=math.inf):
        return self.inner.breakpoints(t_start, t_end)

    def count_breakpoints(self, t_start, t_end):
        return self.inner.count_breakpoints(t_start, t_end)

    def __repr__(self):
        return f"IntegralSignal({self.inner!r}, v0={self.v0!r})"


class _Accelerate(_Prescribed):
    """Base of the prescribed-acceleration sources: a speed source whose reference is the integral."""

    kind = "speed"
    ref_param = "w_ref"
    #: the parameter holding the start speed (w0 or v0)
    _start_name = "w0"

    def __init__(self, name, **params):
        super().__init__(name, **params)
        self._bind_reference()

    def _bind_reference(self):
        # the speed reference the solvers read (``ref_param``): not a parameter of its own
        self._values["w_ref"] = IntegralSignal(self._values["a_ref"], self._values[self._start_name],
                                               f"{type(self).__name__} '{self.name}'")

    def _changed(self):
        if "w_ref" in self._values:
            self._bind_reference()
        super()._changed()


class Accelerate(_Accelerate):
    """Prescribed acceleration ``a_ref(t)`` [rad/s^2] of ``flange`` relative to ``support`` (grounded when
    free), from the speed ``w0`` [rad/s] at t = 0 (module docstring). Exports ``phi``, ``w``, ``a`` and
    ``tau`` (the torque the source exerts, as ``Speed``)."""

    flanges = (("flange", ROTATIONAL), ("support", ROTATIONAL, True))
    a_ref = Param(check="signal", unit="rad/s^2", doc="reference acceleration")
    w0 = Param(0.0, check="real", unit="rad/s", doc="speed at t = 0")
    rel_names = {ROTATIONAL: ("phi", "w", "a", "tau")}


class LinearAccelerate(_Accelerate):
    """Prescribed acceleration ``a_ref(t)`` [m/s^2] of a translational ``flange`` from the velocity
    ``v0`` [m/s] at t = 0. Exports ``s``, ``v``, ``a``, ``f``."""

    default_domain = TRANSLATIONAL
    flanges = (("flange", TRANSLATIONAL), ("support", TRANSLATIONAL, True))
    a_ref = Param(check="signal", unit="m/s^2", doc="reference acceleration")
    v0 = Param(0.0, check="real", unit="m/s", doc="velocity at t = 0")
    rel_names = {TRANSLATIONAL: ("s", "v", "a", "f")}
    _start_name = "v0"


__all__ = ["Accelerate", "LinearAccelerate", "IntegralSignal"]
