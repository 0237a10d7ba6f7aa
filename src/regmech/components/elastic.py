"""Elastic and dissipative links: ``Spring``, ``Damper``, ``SpringDamper``, ``Shaft``.

Each is a one-row device with ``rel = x_b - x_a`` (``phi_rel`` or ``s_rel``),
``rel_dot`` its rate, and the transmitted torque/force ``tau = flange_b.tau =
-flange_a.tau`` given by ``law``. Pass ``domain="translational"`` for the
translational versions.
"""

from __future__ import annotations

from ..component import Device, Param
from .heat import DissipatesInDamping, DissipatesPower


class TwoFlangeCompliant(Device):
    """Base of compliant two-flange devices (MSL PartialCompliant).

    ``phi_rel_start`` / ``w_rel_start`` fix the start values of ``phi_rel = phi_b - phi_a`` [rad] (m when
    translational) and ``w_rel`` [rad/s] (m/s), as MSL's ``phi_rel(start=..., fixed=true)``: a pre-twisted
    shaft or a preloaded spring without converting to the masses' start values. They are start values, not
    the law's unstretched length ``phi_rel0``.
    """

    kind = "compliant"
    flanges = (("flange_a", None), ("flange_b", None))
    phi_rel_start = Param(None, optional=True, unit="rad",
                          doc="start value of phi_rel = phi_b - phi_a, fixed when given (not the unstretched phi_rel0)")
    w_rel_start = Param(None, optional=True, unit="rad/s", doc="start value of w_rel = w_b - w_a, fixed when given")
    relative_start_params = ("phi_rel_start", "w_rel_start")


class Spring(TwoFlangeCompliant):
    """Linear spring: ``tau = c * (phi_rel - phi_rel0)``; c [N m/rad or N/m] > 0."""

    c = Param(check="positive", unit="N m/rad", doc="stiffness")
    phi_rel0 = Param(0.0, unit="rad", doc="unstretched length")

    def law(self, rel, rel_dot):
        return self.c * (rel - self.phi_rel0)

    def potential(self, e):
        return self.c * (e[0] - self.phi_rel0) ** 2 / 2


class Damper(DissipatesPower, TwoFlangeCompliant):
    """Linear damper: ``tau = d * w_rel``; d [N m s/rad or N s/m] >= 0."""

    d = Param(check="nonnegative", unit="N m s/rad", doc="damping constant")

    def law(self, rel, rel_dot):
        return self.d * rel_dot


class SpringDamper(DissipatesInDamping, TwoFlangeCompliant):
    """Spring and damper in parallel: ``tau = c (phi_rel - phi_rel0) + d w_rel``."""

    c = Param(check="positive", unit="N m/rad", doc="stiffness")
    d = Param(check="nonnegative", unit="N m s/rad", doc="damping constant")
    phi_rel0 = Param(0.0, unit="rad", doc="unstretched length")

    def law(self, rel, rel_dot):
        return self.c * (rel - self.phi_rel0) + self.d * rel_dot

    def potential(self, e):
        return self.c * (e[0] - self.phi_rel0) ** 2 / 2


class Shaft(DissipatesInDamping, TwoFlangeCompliant):
    """Shaft: elastic ``tau = stiffness*phi_rel + damping*w_rel``, or rigid
    (``phi_rel = 0``, torque from the constraint) when ``stiffness=None``."""

    stiffness = Param(None, check="positive", optional=True, unit="N m/rad", doc="torsional stiffness; None = rigid")
    damping = Param(0.0, check="nonnegative", unit="N m s/rad", doc="internal damping")
    damping_param = "damping"

    def device_kind(self):
        return "rigid" if self.stiffness is None else "compliant"

    def law(self, rel, rel_dot):
        return self.stiffness * rel + self.damping * rel_dot

    def potential(self, e):
        return self.stiffness * e[0] ** 2 / 2
