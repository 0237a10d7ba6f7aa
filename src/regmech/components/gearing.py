"""Gearing with two degrees of freedom: ``Differential`` and ``Planetary``.

Both are one-row rigid devices (SOURCES.md 003: "differential, W = 2"): three
flanges bound by one linear relation between their angles, so two of the
three stay free. The constraint force ``lam`` of the row is the only torque
unknown; the flange torques are its multiples by the row's coefficients,
which is where the torque ratios come from (``flange.tau = coef * lam``,
the torque the device exerts on itself; the bodies receive the opposite).

Efficiency losses are not modelled: the loss of a differential or planetary
set depends on which link is stopped or carries power (SOURCES.md 003,
"efficiency with the third link stopped"), which needs the stick/slip
machinery of the friction devices; see each class's docstring.
"""

from __future__ import annotations

from ..component import Device, Param
from ..ports import ROTATIONAL


class Differential(Device):
    """Open (bevel) differential: ``phi_c - phi_s = ratio * ((phi_l + phi_r)/2 - phi_s)``.

    Flanges: ``carrier`` (input, e.g. the crown wheel with its housing),
    ``left`` and ``right`` (the side shafts), ``support`` (the axle housing,
    grounded when left unconnected). All angles in rad, torques in N m.

    ``ratio`` (dimensionless, non-zero) is the reduction from the carrier to
    the mean of the sides; 1 for the bare bevel set, the final-drive ratio
    when the carrier flange stands for the pinion shaft.

    Device coordinate (the constraint ``e = 0``)::

        e = phi_c - (ratio/2) phi_l - (ratio/2) phi_r + (ratio - 1) phi_s

    Torques (``lam`` = the exported ``tau``, the carrier torque)::

        carrier.tau = lam,  left.tau = right.tau = -(ratio/2) lam,
        support.tau = (ratio - 1) lam

    so the side torques are always equal (the open differential's defining
    property): a wheel on ice carries almost no torque, hence neither does the
    other one, and the free wheel spins at twice the mean speed.

    Efficiency (internal friction, the locking effect of limited-slip units)
    is not included: it needs the stick/slip machinery and comes later.
    """

    kind = "rigid"
    ratio = Param(1.0, check="nonzero", doc="carrier angle / mean angle of the sides")
    flanges = (("carrier", ROTATIONAL), ("left", ROTATIONAL), ("right", ROTATIONAL),
               ("support", ROTATIONAL, True))
    rel_names = {ROTATIONAL: (None, None, None, "tau")}

    def rows(self):
        half = self.ratio / 2.0
        return [{"carrier": 1.0, "left": -half, "right": -half, "support": self.ratio - 1.0}]


class Planetary(Device):
    """Ideal planetary gear set (MSL ``IdealPlanetary``), Willis' relation::

        (1 + ratio) * phi_carrier = phi_sun + ratio * phi_ring

    ``ratio`` = ring teeth / sun teeth (> 0 for a real set, e.g. 100/50 = 2).
    Flanges ``sun``, ``carrier``, ``ring``; angles in rad, torques in N m.
    The relation involves only differences of angles, so no support flange is
    needed (a rotating housing changes nothing).

    Device coordinate ``e = phi_sun + ratio*phi_ring - (1 + ratio)*phi_carrier``;
    its constraint force ``lam`` is the sun torque (exported as ``tau``)::

        sun.tau = lam,  ring.tau = ratio * lam,  carrier.tau = -(1 + ratio) * lam

    i.e. sun : ring : carrier = 1 : ratio : -(1 + ratio), as in MSL.
    With the ring held, sun in and carrier out: ``phi_sun = (1 + ratio) phi_carrier``.

    Mesh efficiency is not included: the loss depends on the power flow through
    the stopped or free link (SOURCES.md 003), which needs the stick/slip
    machinery (as MSL's LossyGear) and comes in a later step.
    """

    kind = "rigid"
    ratio = Param(check="positive", doc="number of ring teeth / number of sun teeth")
    flanges = (("sun", ROTATIONAL), ("carrier", ROTATIONAL), ("ring", ROTATIONAL))
    rel_names = {ROTATIONAL: (None, None, None, "tau")}

    def rows(self):
        r = self.ratio
        return [{"sun": 1.0, "ring": r, "carrier": -(1.0 + r)}]


__all__ = ["Differential", "Planetary"]
