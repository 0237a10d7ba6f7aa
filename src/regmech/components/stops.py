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

The rigid counterpart is ``HardStop`` (an impact with a coefficient of restitution ``e``, the
speeds reset at the located contact, then a holding contact). A stiff ``EndStop`` (``c`` giving a
contact frequency well above the model's) with the damping chosen for the wanted restitution is its
compliant counterpart: for a linear spring-damper contact of mass ``m`` the restitution is about
``exp(-pi zeta / sqrt(1 - zeta^2))`` with ``zeta = d / (2 sqrt(c m))`` (less when the damping limit
is active at the end of contact).
"""

from __future__ import annotations

import sympy

from ..component import Device, Param, Subsystem
from ..errors import ParameterError
from ..modes import FREE
from ..ports import TRANSLATIONAL
from ._symbolic import smaller
from .backlash import damper_saturation
from .friction import FrictionContact, FrictionDevice
from .inertial import Fixed, Mass


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
        sum reaches 0 while still in touch), the mirror image at ``lower``; then the damper's saturation
        within each contact (``damper_saturation``: ``d w_rel = tau_c``)."""
        rel, w = e[0], de[0]
        up = smaller(rel - self.upper, rel - self.upper + self.d * w / self.c)
        lo = smaller(self.lower - rel, self.lower - rel - self.d * w / self.c)
        return [(up, 1), (lo, -1), (damper_saturation(up, rel - self.upper - self.d * w / self.c), 1),
                (damper_saturation(lo, self.lower - rel + self.d * w / self.c), -1)]

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
        ``g = min(phi_rel0 - phi_rel, -(tau_c + d w_rel) / c)``; then the damper's saturation within the
        contact (``damper_saturation``: ``d w_rel = tau_c``)."""
        rel, w = e[0], de[0]
        contact = smaller(self.phi_rel0 - rel, self.phi_rel0 - rel - self.d * w / self.c)
        return [(contact, 1), (damper_saturation(contact, self.phi_rel0 - rel + self.d * w / self.c), 1)]


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


class HardStop(FrictionDevice):
    """Rigid travel limits ``lower <= phi_rel <= upper`` of ``flange`` against ``support`` (grounded when
    free) with impacts (Simscape Hard Stop, impact variant; MSL ``MassWithStopAndFriction``), with
    ``phi_rel = phi_flange - phi_support`` [rad] (``s_rel`` [m] with ``domain="translational"``, or
    ``LinearHardStop``), ``w_rel`` its rate [rad/s or m/s].

    * ``lower < phi_rel < upper``: it transmits nothing (``tau = 0``; mode Free, contact state 0).
    * ``phi_rel`` reaches a limit moving into it (``s w_rel > 0``, ``s = +1`` at ``upper``, ``-1`` at
      ``lower``): an event (``Event(kind="impact")``, ``old_mode`` 0, ``new_mode`` ``s``, ``value`` the
      energy lost [J]) at which the relative speed jumps to ``w_rel+ = -e w_rel-`` by an impulse ``P``
      [N m s or N s] on the row, the speeds ``v+ = v- + M^-1 (A^T y + G^T P)`` closest to ``v-`` in the
      mass norm that keep every rigid link, gear and source (rows ``A``, their speeds unchanged) and
      every stuck friction device at zero slip: a velocity-level KKT projection, so the momentum of the
      rest of the system is respected. Energy lost ``-P (w_rel- + w_rel+) / 2 = (1 - e^2) m_eff
      w_rel-^2 / 2`` (``m_eff`` the mass the row sees through the constraints) is booked in
      ``<name>.heat`` [J] at the event (a jump), so the books close.
    * Contact: with ``e = 0``, or when the rebound is Zeno (below), ``w_rel+ = 0`` and the limit becomes a
      holding constraint ``a_rel = 0`` whose torque ``tau`` (``<name>.tau``, the torque the stop takes
      from the flange, as a ``Brake``'s) can only push: ``s tau >= 0`` (mode Stuck, contact state ``s``,
      ``Event(kind="contact")`` 0 -> s). When ``s tau`` would turn negative (the load pulls away) it
      releases (an event, contact ``s`` -> 0, mode Free). A contact whose load pulls at once releases at
      once.
    * Restart: a rebound restarts ``delta = 1e-12 max(1, |upper|, |lower|)`` inside the limit (so that every
      solver watches the limit again from the restart on), and the work of the load over ``delta`` is
      taken from the rebound, ``w_rel+^2 = (e w_rel-)^2 - 2 a_in delta`` (``a_in`` the relative acceleration
      into the limit): the offset feeds no energy into a bounce sequence.
    * Zeno (a bouncing mass under a steady load has infinitely many impacts in finite time): an impact
      goes to contact instead of rebounding when ``e |w_rel-| <= ZENO_SPEED * w_max`` (``w_max`` the
      largest impact speed this stop has had in the run; ``ZENO_SPEED = 1e-6``), when the rebound cannot
      rise above ``delta`` (``(e w_rel-)^2 <= 2 a_in delta``), or when it comes within ``ZENO_DT *
      max(1, |t|)`` s of the stop's previous impact (``ZENO_DT = 1e-10``). Under a constant load ``a`` the
      flights left out last ``2 w_r / (a (1 - e))`` in all, with the cancelled rebound ``w_r <=
      max(1e-6 w_max, sqrt(2 a delta))``, and the offset's work taken from the last rebounds shortens
      them by up to as much again: the contact starts at most ``4 w_r / (a (1 - e))`` before the
      geometric series' limit (measured with w_max = 1.4 rad/s, a = 2 rad/s^2: e = 0.5: 3.5e-6 s after
      21 impacts; e = 0.9: 2.5e-5 s after 128; e = 0.99: 2.6e-4 s of 140.7 s after 1341 impacts). The
      impacts to rest number about ``ln(1e-6) / ln(e)``. Every loop is bounded (``max_events``).

    ``0 <= e <= 1`` [1] the coefficient of restitution. The start must be inside the limits (at a limit
    only when not moving into it; there it holds, or releases at once when the load pulls away).
    Regularity: the flange carries a mass. Solvers: IDA and the ODE-form solvers (scipy's, at every
    located event); ``expm``, the explicit fixed-step methods and ``convolution`` refuse a model with a
    hard stop (their steps and error estimates assume continuous speeds). The stop never supplies
    energy: its torque does no work while it holds (``w_rel = 0``).

    Decisions (as a Modelica/Simscape user would expect): the impact law is Newton's (a relative-speed
    restitution), applied through the model's own mass matrix and constraints; a motion source on the
    stop's path keeps its speed through the impulse (its impulsive work is not in the stop's heat, which
    books only ``-P (w- + w+) / 2``, but in the impact's ``Event.work``, ``Result.impulse_work`` and the
    source's ``res.integral('<source>.power')``: the books close); a hard stop is a friction row of the hybrid
    layer (Free / Stuck), so a holding stop takes part in the holding-torque solve like a stuck brake.

    Limits: stops reaching a limit at the same instant get their impulses one after another in model
    order, each from the speeds the previous one left (a later stop whose body already moves away gets
    none), not as one joint multi-contact (LCP) impulse, so the outcome of truly simultaneous impacts
    can depend on that order. The impulse is a dense solve over the model's coordinates: O(n^3) per
    impact, fine for drivetrain-size models, costly for chains of thousands of masses.
    """

    impact = True
    flanges = (("flange", None), ("support", None, True))
    lower = Param(check="real", unit="rad", doc="lower travel limit of phi_rel")
    upper = Param(check="real", unit="rad", doc="upper travel limit of phi_rel")
    e = Param(check="real", unit="1", doc="coefficient of restitution, 0 <= e <= 1")
    #: an impact whose rebound speed is at most this fraction of the stop's largest impact speed goes to contact
    ZENO_SPEED = 1e-6
    #: an impact this close (times max(1, |t|) [s]) after the stop's previous one goes to contact
    ZENO_DT = 1e-10

    def validate(self):
        if not self.lower < self.upper:
            raise ParameterError(f"{type(self).__name__} '{self.name}': needs lower < upper, got lower={self.lower}, "
                                 f"upper={self.upper}")
        if not 0.0 <= self.e <= 1.0:
            raise ParameterError(f"{type(self).__name__} '{self.name}': the coefficient of restitution e must lie in "
                                 f"[0, 1] (0: plastic, 1: elastic impact), got e={self.e}")

    def rows(self):
        return [{"support": -1.0, "flange": 1.0}]

    # its row carries a force only while it holds (mode Stuck, a_rel = 0); otherwise none
    def relation(self, mode, quadrant, w_abs, t, left=False, q=None):
        return 1.0, 0.0, 0.0, 0.0

    def kinetic(self, w_abs, t, left=False, q=None):
        return 0.0, 0.0

    def capacities(self, t, left=False, q=None):
        return 0.0, 0.0

    def capacity_function(self):
        return lambda t, left=False: (1.0, 0.0, 0.0)

    def contact_state(self, mode, side) -> int:
        """The contact code of a mode: ``side`` (+1 upper, -1 lower) while holding (Stuck, or Held by other stuck
        devices on its motion), 0 when free."""
        return 0 if mode == FREE else int(side)


class LinearHardStop(HardStop):
    """``HardStop`` of a translational flange: limits ``lower <= s_rel <= upper`` [m], force ``f`` [N]."""

    default_domain = TRANSLATIONAL
    lower = Param(check="real", unit="m", doc="lower travel limit of s_rel")
    upper = Param(check="real", unit="m", doc="upper travel limit of s_rel")


__all__ = ["EndStop", "ElastoGap", "HardStop", "LinearHardStop", "MassWithStopAndFriction"]
