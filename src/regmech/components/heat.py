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

A result of ``simulate`` integrates ``heat`` from the model's laws between
the output rows (``Result.integral``, ``regmech.solvers.quadrature``): an
output interval that the rows do not resolve (a brake stopping inside it)
is integrated again from its first row, so the heat is right whatever
``dt_out``. ``derived`` below gives the trapezoid over the rows (an event
instant appears twice, so a jump of the heat flow there is exact): what a
result made otherwise (not by ``simulate``) shows.

A lumped thermal mass of an element (heat capacity ``C`` [J/K], conductance
to ambient ``G`` [W/K])::

    C dT/dt = heat_flow(t) - G (T - T_amb)

is ``temperature(res, name, C, G, T0, T_amb)``, after the run, exact for a
heat flow linear between output instants (no feedback into the friction).

Inside the DAE, with fade: ``Clutch(..., thermal=ThermalMass(C, G, T_amb, T0,
fade))`` (also ``Brake``, ``OneWayClutch``, ``FrictionContact``, ``LinearBrake``,
``BearingFriction``) gives the device a temperature state ``<name>.T`` [K]::

    C dT/dt = P - G (T - T_amb),     P = lam * w_rel  (the power its friction absorbs, >= 0)

in every mode (sliding: ``P = tau_k |w_rel|``; stuck, free: ``P = 0`` exactly, the rates reading
the slip or the torque that the mode pins, ``FrictionRows._pinned``), and its
friction coefficient is ``mu(|w_rel|) * fade(T)`` (``fade``: (T [K], factor) points, linear
between them, constant beyond; capacities ``tau0`` and ``tau0_max`` fade too, so a hot
stuck clutch breaks away earlier). Books: ``heat_stored = C (T - T0)`` and
``heat_to_ambient = int G (T - T_amb) dt`` [J] add up to the dissipated ``heat``; the power to ambient
``heat_flow_to_ambient = G (T - T_amb)`` [W] is a signal too, and a result of ``simulate`` integrates
``heat_to_ambient`` from it between the rows as it does ``heat`` (the trapezoid over the rows closed the
books only to about 1e-5 of the heat where a clutch stopped slipping inside an output interval).
The solvers integrate the rise ``T - T_amb`` (``FrictionDevice.friction_state_datum``), so that
their relative tolerance weighs the heating, not the ambient's 293 K; ``<name>.T`` is ``T``.
"""

from __future__ import annotations

import numpy as np

from .._frozen import frozen

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


class ThermalMass:
    """A lumped thermal mass of a friction element, inside the DAE (module docstring)::

        C dT/dt = P - G (T - T_amb),   mu_eff = mu(|w_rel|) * fade(T)

    ``C`` [J/K] > 0 heat capacity, ``G`` [W/K] >= 0 conductance to ambient (0: adiabatic), ``T_amb``
    [K] ambient temperature (default 293.15), ``T0`` [K] start temperature (default ``T_amb``),
    ``fade`` (T [K], factor >= 0) points with increasing T (None: no fade; one point: a constant
    factor), linear between them and constant beyond the ends.
    """

    def __init__(self, C: float, G: float = 0.0, T_amb: float = 293.15, T0: float | None = None, fade=None):
        import math

        from ..errors import ParameterError
        T0 = T_amb if T0 is None else T0
        for pname, val, ok, want in (("C", C, lambda v: v > 0, " > 0 [J/K]"), ("G", G, lambda v: v >= 0, " >= 0 [W/K]"),
                                     ("T_amb", T_amb, lambda v: v > 0, " > 0 [K]"),
                                     ("T0", T0, lambda v: v > 0, " > 0 [K]")):
            if isinstance(val, bool) or not isinstance(val, (int, float, np.floating, np.integer)) \
                    or not math.isfinite(val) or not ok(val):
                raise ParameterError(f"ThermalMass: {pname} must be a finite number{want}, got {val!r}")
        self.C, self.G, self.T_amb, self.T0 = float(C), float(G), float(T_amb), float(T0)
        self.fade = None
        if fade is not None:
            try:
                tab = np.atleast_2d(np.array(fade, dtype=float))
            except (TypeError, ValueError):
                tab = None
            if tab is None or tab.ndim != 2 or tab.shape[1] != 2 or not np.all(np.isfinite(tab)) \
                    or np.any(np.diff(tab[:, 0]) <= 0) or np.any(tab[:, 1] < 0):
                raise ParameterError(f"ThermalMass: fade must be (T [K], factor >= 0) points with increasing T, "
                                     f"got {fade!r}")
            self.fade = tab = frozen(tab, "ThermalMass", "fade")

    def factor(self, T: float) -> tuple[float, float]:
        """``(fade(T), d fade / dT)`` [1, 1/K]."""
        tab = self.fade
        if tab is None:
            return 1.0, 0.0
        Ts, fs = tab[:, 0], tab[:, 1]
        if len(Ts) == 1 or T <= Ts[0]:
            return float(fs[0]), 0.0
        if T >= Ts[-1]:
            return float(fs[-1]), 0.0
        k = int(np.searchsorted(Ts, T, side="right") - 1)
        slope = (fs[k + 1] - fs[k]) / (Ts[k + 1] - Ts[k])
        return float(fs[k] + slope * (T - Ts[k])), float(slope)

    def rate(self, P: float, T: float) -> float:
        """``dT/dt`` [K/s] at absorbed power ``P`` [W] and temperature ``T`` [K]."""
        return (P - self.G * (T - self.T_amb)) / self.C

    def __repr__(self) -> str:
        return (f"ThermalMass(C={self.C:g}, G={self.G:g}, T_amb={self.T_amb:g}, T0={self.T0:g}"
                f"{'' if self.fade is None else f', fade={self.fade.tolist()}'})")


class DissipatesPower:
    """Mixin of devices that turn all the power they absorb into heat (friction, dampers)."""

    derived_units = HEAT_UNITS
    #: the signals that are time integrals of others: a result of ``simulate`` integrates them from the model's laws
    #: between the output rows (``Trajectory.integral_rate``, ``solvers.quadrature``), not by ``derived``'s trapezoid
    derived_integrals = {"heat": "heat_flow", "heat_to_ambient": "heat_flow_to_ambient"}

    def derived(self, t, left, e, de, tau, z):
        p = np.zeros(len(t))
        for tr, dr in zip(tau, de):
            p = p + np.asarray(tr, float) * np.asarray(dr, float)
        out = heat_signals(t, p)
        th = getattr(self, "_values", {}).get("thermal")
        if th is not None and "T" in z:
            T = np.asarray(z["T"], float)
            out["heat_stored"] = th.C * (T - th.T0)
            out["heat_flow_to_ambient"] = th.G * (T - th.T_amb)
            out["heat_to_ambient"] = accumulated(t, out["heat_flow_to_ambient"])
        return out


class DissipatesInDamping:
    """Mixin of spring-dampers: heat ``d * w_rel^2`` with ``d`` the parameter ``damping_param``."""

    derived_units = HEAT_UNITS
    damping_param = "d"

    def derived(self, t, left, e, de, tau, z):
        d = self._values.get(self.damping_param) or 0.0
        return heat_signals(t, d * np.asarray(de[0], float) ** 2)


#: the extra signals of an element with a ``ThermalMass``
THERMAL_UNITS = {**HEAT_UNITS, "heat_stored": "J", "heat_to_ambient": "J", "heat_flow_to_ambient": "W"}

__all__ = ["ThermalMass", "THERMAL_UNITS", "DissipatesPower", "DissipatesInDamping", "accumulated", "heat_signals", "temperature", "HEAT_UNITS"]
