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

Not here (yet): a lumped thermal mass whose temperature feeds back into the
friction coefficient (fade). The friction laws are read by the hybrid layer
as functions of the relative speed and time only; a temperature state would
have to reach them there.
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


__all__ = ["DissipatesPower", "DissipatesInDamping", "accumulated", "heat_signals", "HEAT_UNITS"]
