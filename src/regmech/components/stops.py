"""End stops and one-sided contacts: ``EndStop`` (travel limits of a flange against its support)
and ``ElastoGap`` (a one-sided elastic contact between two flanges), plus
``MassWithStopAndFriction`` (a sliding mass between two stops with friction to the ground).

Both devices are compliant: in contact a spring ``c`` and a damper ``d`` act on the penetration;
out of contact nothing. The damping force is limited to the spring force (as ``ElastoBacklash``
does), so that

* the contact force is continuous when contact starts (the spring force is zero there, so the
  damping force is too): no jump for the integrator, no impulse;
* the contact never pulls: the force always pushes the flanges out of the contact.

With ``tau_c`` the spring force of the penetration and ``tau_d = d * w_rel``::

    tau = tau_c + clip(tau_d, -|tau_c|, |tau_c|)

Energy: the stored energy is ``c * penetration^2 / 2`` (exported as ``<name>.potential``); the
rest of the power the contact absorbs, ``clip(tau_d, ...) * w_rel``, has the sign of
``d w_rel^2 >= 0``: the contact never supplies energy (with ``d >= 0``).

Contacts are located as events (``switching_surfaces``: in touch *and* pushing, so a damped contact
ends where its force returns to zero) and listed in ``Result.events`` with ``kind="contact"``.

A rigid impact with a coefficient of restitution (speeds reset at the located contact) is not
provided yet: a stiff contact (``c`` giving a contact frequency well above the model's) with the
damping chosen for the wanted restitution is its compliant counterpart. For a linear
spring-damper contact of mass ``m`` the restitution is about ``exp(-pi zeta / sqrt(1 - zeta^2))``
with ``zeta = d / (2 sqrt(c m))`` (less when the damping limit is active at the end of contact).
"""

from __future__ import annotations

import sympy

from ..component import Device, Param, Subsystem
from ..errors import ParameterError
from ..ports import TRANSLATIONAL
from .friction import FrictionContact
from .inertial import Fixed, Mass


def _smaller(a, b):
    """``min(a, b)`` as arithmetic (the kernels' numpy printer has no elementwise Min)."""
    return (a + b - sympy.Abs(a - b)) / 2


def _limited(tau_c, tau_d, pushing_up: bool):
    """``tau_c + clip(tau_d, -|tau_c|, |tau_c|)`` for a spring force of known sign (branches written out,
    so the class Jacobian is differentiated branch by branch)."""
    if pushing_up:          # tau_c >= 0
        return sympy.Piecewise((2 * tau_c, tau_d >= tau_c), (0, tau_d <= -tau_c), (tau_c + tau_d, True))
    return sympy.Piecewise((2 * tau_c, tau_d <= tau_c), (0, tau_d >= -tau_c), (tau_c + tau_d, True))


class EndStop(Device):
    """Travel limits ``lower <= phi_rel <= upper`` of ``flange`` against ``support`` (grounded when
    free), with ``phi_rel = phi_flange - phi_support`` [rad] (``s_rel`` [m] with
    ``domain="translational"``)::

        phi_rel > upper:  tau_c = c (phi_rel - upper) >= 0,  tau = tau_c + clip(d w_rel, -tau_c, tau_c)
        phi_rel < lower:  tau_c = c (phi_rel - lower) <= 0,  tau = tau_c + clip(d w_rel, tau_c, -tau_c)
        otherwise:        tau = 0

    ``tau = flange.tau`` [N m] (the flange receives ``-tau``: pushed back inside). c [N m/rad] > 0
    contact stiffness, d [N m s/rad] >= 0 contact damping. Conservative part ``c pen^2 / 2``
    (``<name>.potential``); the rest is dissipated, never supplied. Regularity: the flange carries
    a mass (rule 1), the support is the ground or another mass.
    """

    kind = "compliant"
    flanges = (("flange", None), ("support", None, True))
    lower = Param(check="real", unit="rad", doc="lower travel limit of phi_rel")
    upper = Param(check="real", unit="rad", doc="upper travel limit of phi_rel")
    c = Param(check="positive", unit="N m/rad", doc="contact stiffness")
    d = Param(0.0, check="nonnegative", unit="N m s/rad", doc="contact damping")

    def validate(self):
        if not self.lower < self.upper:
            raise ParameterError(f"EndStop '{self.name}': needs lower < upper, got lower={self.lower}, "
                                 f"upper={self.upper}")

    def rows(self):
        return [{"flange": 1.0, "support": -1.0}]

    def law(self, rel, rel_dot):
        tau_d = self.d * rel_dot
        hi = _limited(self.c * (rel - self.upper), tau_d, True)
        lo = _limited(self.c * (rel - self.lower), tau_d, False)
        return sympy.Piecewise((hi, rel > self.upper), (lo, rel < self.lower), (0, True))

    def switching_surfaces(self, e, de):
        """Contact at the upper stop (code +1) and at the lower one (-1): in touch and pushing,
        ``g_upper = min(phi_rel - upper, (tau_c + d w_rel) / c)`` (the limited damper lets go where the
        sum reaches 0 while still in touch), the mirror image at ``lower``."""
        rel, w = e[0], de[0]
        up = _smaller(rel - self.upper, rel - self.upper + self.d * w / self.c)
        lo = _smaller(self.lower - rel, self.lower - rel - self.d * w / self.c)
        return [(up, 1), (lo, -1)]

    def potential(self, e):
        rel = e[0]
        return sympy.Piecewise((self.c * (rel - self.upper) ** 2 / 2, rel > self.upper),
                               (self.c * (rel - self.lower) ** 2 / 2, rel < self.lower), (0, True))


class ElastoGap(Device):
    """One-sided elastic contact between ``flange_a`` and ``flange_b`` (MSL ``ElastoGap``): in
    contact when ``phi_rel = phi_b - phi_a < phi_rel0`` (the gap closed)::

        tau_c = c (phi_rel - phi_rel0) <= 0,  tau = tau_c + clip(d w_rel, tau_c, -tau_c)  in contact
        tau = 0                                                                           otherwise

    ``tau = flange_b.tau`` (compression pushes the flanges apart). c [N/m] > 0, d [N s/m] >= 0,
    ``phi_rel0`` [m] the gap (relative position where contact starts). Translational by default;
    ``domain="rotational"`` for a rotational gap (units rad, N m/rad, N m s/rad). Potential
    ``c pen^2 / 2``; never supplies energy.
    """

    kind = "compliant"
    default_domain = TRANSLATIONAL
    flanges = (("flange_a", None), ("flange_b", None))
    c = Param(check="positive", unit="N/m", doc="contact stiffness")
    d = Param(0.0, check="nonnegative", unit="N s/m", doc="contact damping")
    phi_rel0 = Param(0.0, check="real", unit="m", doc="relative position at which contact starts")

    def law(self, rel, rel_dot):
        tau = _limited(self.c * (rel - self.phi_rel0), self.d * rel_dot, False)
        return sympy.Piecewise((tau, rel < self.phi_rel0), (0, True))

    def potential(self, e):
        return sympy.Piecewise((self.c * (e[0] - self.phi_rel0) ** 2 / 2, e[0] < self.phi_rel0), (0, True))

    def switching_surfaces(self, e, de):
        """Contact (code +1): the gap closed and the contact force pushing,
        ``g = min(phi_rel0 - phi_rel, -(tau_c + d w_rel) / c)``."""
        rel, w = e[0], de[0]
        return [(_smaller(self.phi_rel0 - rel, self.phi_rel0 - rel - self.d * w / self.c), 1)]


class MassWithStopAndFriction(Subsystem):
    """A sliding mass between two end stops with stick/slip friction to the ground (the setting of
    MSL ``MassWithStopAndFriction``, built from regmech parts).

    Parts: ``mass`` (``Mass`` m [kg]), ``stop`` (``EndStop`` with travel ``[s_min, s_max]`` [m], contact
    stiffness ``c`` [N/m] and damping ``d`` [N s/m]), ``friction`` (``FrictionContact`` with normal
    force ``fn`` [N], coefficient ``mu`` or a ``mu_law`` such as ``Stribeck``) and ``ground``. Ports
    ``flange_a``, ``flange_b`` (the mass). Signals ``<name>.mass.s``, ``.mass.v``, ``.stop.f``,
    ``.friction.mode``.
    """

    default_domain = TRANSLATIONAL
    m = Param(check="positive", unit="kg", doc="mass")
    s_min = Param(check="real", unit="m", doc="lower travel limit")
    s_max = Param(check="real", unit="m", doc="upper travel limit")
    c = Param(1e7, check="positive", unit="N/m", doc="contact stiffness of the stops")
    d = Param(0.0, check="nonnegative", unit="N s/m", doc="contact damping of the stops")
    fn = Param(0.0, check="signal", unit="N", doc="normal force of the friction (0: no friction)")
    mu = Param(0.5, check="nonnegative", unit="1", doc="kinetic friction coefficient")
    peak = Param(1.0, check="positive", unit="1", doc="static over kinetic friction")
    mu_law = Param(None, check="any", optional=True, unit="1", doc="a friction law (Stribeck) instead of mu")
    s0 = Param(None, optional=True, unit="m", doc="start position (fixed when given)")
    v0 = Param(None, optional=True, unit="m/s", doc="start velocity (fixed when given)")
    ports = {"flange_a": "mass.flange_a", "flange_b": "mass.flange_b"}

    def build(self):
        mass = self.part(Mass("mass", m=self.m, s0=self.s0, v0=self.v0))
        stop = self.part(EndStop("stop", lower=self.s_min, upper=self.s_max, c=self.c, d=self.d,
                                 domain=TRANSLATIONAL))
        fric = self.part(FrictionContact("friction", mu=self.mu, peak=self.peak, fn=self.fn, mu_law=self.mu_law))
        ground = self.part(Fixed("ground", domain=TRANSLATIONAL))
        self.link(mass.flange_b, stop.flange)
        self.link(stop.support, ground.flange)
        self.link(mass.flange_b, fric.flange_a)
        self.link(fric.flange_b, ground.flange)


__all__ = ["EndStop", "ElastoGap", "MassWithStopAndFriction"]
