"""Elastic and dissipative links: ``Spring``, ``Damper``, ``SpringDamper``, ``Shaft``.

Each is a one-row device with ``rel = x_b - x_a`` (``phi_rel`` or ``s_rel``),
``rel_dot`` its rate, and the transmitted torque/force ``tau = flange_b.tau =
-flange_a.tau`` given by ``law``. Pass ``domain="translational"`` for the
translational versions.
"""

from __future__ import annotations

from ..component import Device, Param


class TwoFlangeCompliant(Device):
    """Base of compliant two-flange devices (MSL PartialCompliant).

    ``phi_rel_start`` [rad] and ``w_rel_start`` [rad/s] (m, m/s when translational) fix the
    start values of ``phi_rel = phi_b - phi_a`` and ``w_rel`` (MSL's ``phi_rel(start=..., fixed=true)``):
    a pre-twisted shaft or a preloaded spring needs no hand conversion to the masses' start values.
    Initialisation meets them exactly with the least mass-weighted change of the free start values;
    start values that contradict them (on the masses, rigid devices, motion sources) are a
    ``StructureError`` naming the device. Not to be confused with ``phi_rel0``, the unstretched
    length of a spring.
    """

    kind = "compliant"
    flanges = (("flange_a", None), ("flange_b", None))
    phi_rel_start = Param(None, optional=True, unit="rad", doc="start value of phi_rel (fixed when given)")
    w_rel_start = Param(None, optional=True, unit="rad/s", doc="start value of w_rel (fixed when given)")

    def start_relative(self):
        out = []
        for level, pname in enumerate(("phi_rel_start", "w_rel_start")):
            value = self._values.get(pname)
            if value is not None:
                out.append((0, level, float(value)))
        return out


class Spring(TwoFlangeCompliant):
    """Linear spring: ``tau = c * (phi_rel - phi_rel0)``; c [N m/rad or N/m] > 0."""

    c = Param(check="positive", unit="N m/rad", doc="stiffness")
    phi_rel0 = Param(0.0, unit="rad", doc="unstretched length")

    def law(self, rel, rel_dot):
        return self.c * (rel - self.phi_rel0)

    def potential(self, e):
        return self.c * (e[0] - self.phi_rel0) ** 2 / 2


class Damper(TwoFlangeCompliant):
    """Linear damper: ``tau = d * w_rel``; d [N m s/rad or N s/m] >= 0."""

    d = Param(check="nonnegative", unit="N m s/rad", doc="damping constant")

    def law(self, rel, rel_dot):
        return self.d * rel_dot


class SpringDamper(TwoFlangeCompliant):
    """Spring and damper in parallel: ``tau = c (phi_rel - phi_rel0) + d w_rel``."""

    c = Param(check="positive", unit="N m/rad", doc="stiffness")
    d = Param(check="nonnegative", unit="N m s/rad", doc="damping constant")
    phi_rel0 = Param(0.0, unit="rad", doc="unstretched length")

    def law(self, rel, rel_dot):
        return self.c * (rel - self.phi_rel0) + self.d * rel_dot

    def potential(self, e):
        return self.c * (e[0] - self.phi_rel0) ** 2 / 2


class Shaft(TwoFlangeCompliant):
    """Shaft: elastic ``tau = stiffness*phi_rel + damping*w_rel``, or rigid
    (``phi_rel = 0``, torque from the constraint) when ``stiffness=None``."""

    stiffness = Param(None, check="positive", optional=True, unit="N m/rad", doc="torsional stiffness; None = rigid")
    damping = Param(0.0, check="nonnegative", unit="N m s/rad", doc="internal damping")

    def device_kind(self):
        return "rigid" if self.stiffness is None else "compliant"

    def law(self, rel, rel_dot):
        return self.stiffness * rel + self.damping * rel_dot

    def potential(self, e):
        return self.stiffness * e[0] ** 2 / 2
