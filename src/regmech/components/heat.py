"""Heat: what the friction and loss elements turn into heat.

Every friction and loss element exports (as derived signals, computed from
the run, ``Device.derived``)

    <name>.heat_flow   [W]   the power it dissipates now (>= 0)
    <name>.heat        [J]   the energy it has dissipated since the start

Friction devices (``Clutch``, ``Brake``, ``OneWayClutch``, ``FrictionContact``,
``BearingFriction``, ``LossyGear``) and ``Damper`` dissipate all the power
they absorb, ``heat_flow = sum_r tau_r de_r``; a ``SpringDamper`` or an
elastic ``Shaft`` dissipates ``d w_rel^2`` (the rest of its power is stored
in the spring); electric machines their ``p_loss``.

``heat`` is integrated over the output instants by the trapezoidal rule (an
event instant appears twice, as left and right limits, so a jump of the heat
flow at an event is integrated exactly); its error falls with ``dt_out^2``,
so a fine output grid gives an accurate heat (halve ``dt_out`` to check).

A lumped thermal mass of an element (heat capacity ``C`` [J/K], conductance
to ambient ``G`` [W/K])::

    C dT/dt = heat_flow(t) - G (T - T_amb)

is ``temperature(res, name, C, G, T0, T_amb)``, after the run, exact for a
heat flow linear between output instants. Not here (yet): a temperature that
feeds back into the friction coefficient (fade). The friction laws are read
by the hybrid layer as functions of the relative speed and time only, and a
friction force is a constraint multiplier that no device law can read; a
temperature state with fade needs both to reach the hybrid layer.
"""

from __future__ import annotations

import numpy as np

HEAT_UNITS = {"heat_flow": "W", "heat": "J"}


def accumulated(t, p) -> np.ndarray:
    """``int_0^t p dt`` at the output instants, by the trapezoidal rule [J]."""
    t, p = np.asarray(t, float), np.asarray(p, float)
    if len(t) < 2:
        return np.zeros_like(t)
    return np.concatenate([[0.0], np.cumsum(np.diff(t) * (p[1:] + p[:-1]) / 2)])


def heat_signals(t, heat_flow) -> dict:
    """``heat_flow`` [W] and its accumulated ``heat`` [J]."""
    return {"heat_flow": heat_flow, "heat": accumulated(t, heat_flow)}


def temperature(res, name: str, C: float, G: float = 0.0, T0: float = 20.0, T_amb: float | None = None):
    """Temperature [deg C or K, as ``T0``] of a lumped thermal mass heated by element ``name``'s
    ``heat_flow``: ``C dT/dt = heat_flow - G (T - T_amb)`` with ``C`` [J/K] > 0, ``G`` [W/K] >= 0
    (0: adiabatic), ``T_amb`` (default ``T0``). Solved exactly on each output interval for a heat flow
    linear between the instants (the trapezoidal ``heat`` makes the same assumption)."""
    import math

    from ..errors import ParameterError
    for pname, val, ok in (("C", C, lambda v: v > 0), ("G", G, lambda v: v >= 0), ("T0", T0, lambda v: True)):
        if isinstance(val, bool) or not isinstance(val, (int, float, np.floating, np.integer)) \
                or not math.isfinite(val) or not ok(val):
            raise ParameterError(f"temperature('{name}'): {pname} must be a finite number"
                                 f"{' > 0' if pname == 'C' else ' >= 0' if pname == 'G' else ''}, got {val!r}")
    T_amb = T0 if T_amb is None else T_amb
    p = res[f"{name}.heat_flow"]
    t = res.t
    a = G / C
    theta = np.empty(len(t))
    theta[0] = T0 - T_amb
    for k in range(1, len(t)):
        h = t[k] - t[k - 1]
        p0, slope = p[k - 1], (p[k] - p[k - 1]) / h if h > 0 else 0.0
        x = a * h
        if x < 1e-4:        # series of the exact integrals (no cancellation for a slow or no loss to ambient)
            decay = 1.0 - x + x * x / 2
            i0 = h * (1.0 - x / 2 + x * x / 6)                 # int_0^h e^{-a(h-s)} ds
            i1 = h * h * (0.5 - x / 6 + x * x / 24)            # int_0^h e^{-a(h-s)} s ds
        else:
            decay = math.exp(-x)
            i0 = -math.expm1(-x) / a
            i1 = (h - i0) / a
        theta[k] = theta[k - 1] * decay + (p0 * i0 + slope * i1) / C
    return theta + T_amb


class DissipatesPower:
    """Mixin of devices that turn all the power they absorb into heat (friction, dampers)."""

    derived_units = HEAT_UNITS

    def derived(self, t, left, e, de, tau, z):
        p = np.zeros(len(t))
        for tr, dr in zip(tau, de):
            p = p + np.asarray(tr, float) * np.asarray(dr, float)
        return heat_signals(t, p)


class DissipatesInDamping:
    """Mixin of spring-dampers: heat ``d * w_rel^2`` with ``d`` the parameter ``damping_param``."""

    derived_units = HEAT_UNITS
    damping_param = "d"

    def derived(self, t, left, e, de, tau, z):
        d = self._values.get(self.damping_param) or 0.0
        return heat_signals(t, d * np.asarray(de[0], float) ** 2)


__all__ = ["DissipatesPower", "DissipatesInDamping", "accumulated", "heat_signals", "temperature", "HEAT_UNITS"]
