"""Backlash: an elastic link with a dead zone (gear play, coupling slack).

``Backlash(c, b)`` is the dead-zone spring of REFERENCES.md [004] (the excavator
swing drive): no torque inside the play, a linear spring outside it.
``ElastoBacklash(c, d, b)`` is MSL ``Rotational.Components.ElastoBacklash``:
the same with a damper in parallel with the spring, the damping torque
limited so that the contact torque neither jumps at the start of contact nor
pulls (sticks) when the flanges separate.

Both are one-row compliant devices with ``phi_rel = phi_b - phi_a`` and the
transmitted torque ``tau = flange_b.tau = -flange_a.tau``. Pass
``domain="translational"`` for the translational versions (``s_rel``, ``f``;
then ``b`` is in m, ``c`` in N/m, ``d`` in N s/m).

The laws are written with ``sympy.Piecewise``, so they are continuous but
have a kink at contact (``|phi_rel - phi_rel0| = b/2``). Both declare their
contacts as switching surfaces (``switching_surfaces``): every solver locates
them as events, restarts on the other branch (no step straddles the kink) and
reports each contact change in ``Result.events`` (kind "contact": state +1 in
contact on the positive side, ``phi_diff >= b/2``, -1 on the negative side, 0
inside the play).
"""

from __future__ import annotations

import sympy

from ..component import Param
from ._symbolic import smaller
from .elastic import TwoFlangeCompliant

#: below this total backlash [rad or m] the play is ignored (MSL ``bEps``):
#: a vanishing dead zone would only add kinks that do nothing
B_EPS = 1e-10


def damper_saturation(contact, spare):
    """The surface of a limited damper's kink within a contact: ``min(contact, spare)``, with ``contact`` the
    contact's own surface (> 0 in contact) and ``spare`` [m or rad] ``(|tau_c| - |tau_d|) / c`` on the damper's
    limited side (> 0 while the damping torque is below the spring torque it is limited by). Positive in contact
    with the damper free, negative in contact with it saturated (``tau = 2 tau_c``) and when open; stated with the
    contact's code, after it, so the contact state it gives is the contact's.

    Why: the torque has a kink where the damper saturates (each impact starts saturated: ``tau_c = 0`` at touch).
    A step across it integrates the other branch's law, and the solvers' error estimates do not see a kink
    between their stages: on fuzz seed 171 (an end stop, c = 1.96e5, d = 11.8, 93 bounces) DOP853's errors were
    0.048, 0.029, 0.0025 of the range at rtol 1e-5, 1e-6, 1e-7 (its pair at 5.5e-6 / 5.5e-7 differed by less
    than the error); with the kink located 5.7e-4, 4.4e-5, 2.3e-6. Crossing it changes no contact state, so it
    makes no ``Event``; the integration restarts there."""
    return smaller(contact, spare)


def _play_surfaces(phi_diff, b, pos=None, neg=None):
    """The contact surfaces of a play of total width ``b`` centred at 0: ``[(g, +1), (g, -1)]`` with
    ``g+ = phi_diff - b/2`` and ``g- = -phi_diff - b/2`` (> 0 in contact on that side); ``pos``/``neg``
    replace them where the contact also ends by a force condition. (A play below ``B_EPS`` has no kink:
    ``switching_active`` leaves its surfaces out.)"""
    g_pos = phi_diff - b / 2 if pos is None else pos
    g_neg = -phi_diff - b / 2 if neg is None else neg
    return [(g_pos, 1), (g_neg, -1)]


def _contact_spring(c, phi_diff, b_half):
    """Spring torque ``tau_c``: zero inside the play, ``c * (penetration)`` outside it."""
    return sympy.Piecewise((c * (phi_diff - b_half), phi_diff > b_half),
                           (c * (phi_diff + b_half), phi_diff < -b_half),
                           (0, True))


class Backlash(TwoFlangeCompliant):
    """Dead-zone spring (REFERENCES.md [004])::

        phi_diff = phi_rel - phi_rel0
        tau = c * (phi_diff - b/2)   if phi_diff >  b/2
              c * (phi_diff + b/2)   if phi_diff < -b/2
              0                      otherwise

    c [N m/rad] > 0, b [rad] >= 0 the *total* play (b/2 on each side, as in
    MSL), phi_rel0 [rad] the centre of the play. Conservative: its potential
    is ``c * penetration^2 / 2``.
    """

    c = Param(check="positive", unit="N m/rad", doc="stiffness in contact")
    b = Param(0.0, check="nonnegative", unit="rad", doc="total backlash")
    phi_rel0 = Param(0.0, unit="rad", doc="centre of the play")

    def law(self, rel, rel_dot):
        return _contact_spring(self.c, rel - self.phi_rel0, self.b / 2)

    def potential(self, e):
        tau_c = _contact_spring(self.c, e[0] - self.phi_rel0, self.b / 2)
        return tau_c ** 2 / (2 * self.c)

    def switching_surfaces(self, e, de):
        """Contact on either side of the play: ``phi_diff = +-b/2`` (codes +1, -1)."""
        return _play_surfaces(e[0] - self.phi_rel0, self.b)

    def switching_active(self):
        return self.b > B_EPS          # without play the law is one straight line: no kink


class ElastoBacklash(TwoFlangeCompliant):
    """Backlash in series with a spring and damper in parallel (MSL ``ElastoBacklash``).

    With ``phi_diff = phi_rel - phi_rel0``, ``tau_c`` the dead-zone spring
    torque of ``Backlash`` and ``tau_d = d * w_rel``::

        phi_diff > b/2 (contact, pushing forward):
            tau = 0                  if tau_c + tau_d <= 0   (would pull: separated)
                  tau_c + min(tau_c, tau_d)
        phi_diff < -b/2: the mirror image (max instead of min, >= 0)
        otherwise: tau = 0

    Limiting the damping torque by the spring torque (|tau_d| <= |tau_c|)
    makes the torque continuous at the start of contact (the spring torque
    is zero there, so the damping torque is too) and forbids pulling
    contact torques. With ``b <= 1e-10`` it is a plain spring-damper.

    c [N m/rad] > 0, d [N m s/rad] >= 0, b [rad] >= 0 total backlash,
    phi_rel0 [rad]. The potential is the spring's ``c * penetration^2 / 2``;
    everything else the device absorbs is dissipated (never negative).

    MSL replaces the characteristic by a monotone one during initialisation
    (for inverse models); regmech takes the start values as given, so that
    has no counterpart here.
    """

    c = Param(check="positive", unit="N m/rad", doc="stiffness in contact")
    d = Param(check="nonnegative", unit="N m s/rad", doc="damping in contact")
    b = Param(0.0, check="nonnegative", unit="rad", doc="total backlash")
    phi_rel0 = Param(0.0, unit="rad", doc="centre of the play")

    def law(self, rel, rel_dot):
        phi_diff = rel - self.phi_rel0
        b_half = self.b / 2
        tau_d = self.d * rel_dot
        # Each contact branch uses its own plain spring torque (not the
        # Piecewise tau_c), so no condition contains a Piecewise; MSL's min/max
        # are written out as branches, each smooth, so the class Jacobian is
        # differentiated branch by branch.
        tau_c = self.c * (phi_diff - b_half)
        pushing = sympy.Piecewise((0, tau_c + tau_d <= 0), (2 * tau_c, tau_d >= tau_c), (tau_c + tau_d, True))
        tau_c = self.c * (phi_diff + b_half)
        pulling = sympy.Piecewise((0, tau_c + tau_d >= 0), (2 * tau_c, tau_d <= tau_c), (tau_c + tau_d, True))
        return sympy.Piecewise((self.c * phi_diff + tau_d, self.b <= B_EPS),
                               (pushing, phi_diff > b_half),
                               (pulling, phi_diff < -b_half),
                               (0, True))

    def switching_surfaces(self, e, de):
        """Contact on either side (codes +1, -1): the flanges in touch *and* the contact torque pushing.
        ``g+ = min(phi_diff - b/2, (tau_c + tau_d) / c)``: contact starts at ``phi_diff = b/2`` (where
        ``tau_c = 0``) and ends either there or, with damping, where ``tau_c + tau_d`` reaches 0 while
        still in touch (the limited damper lets go); the mirror image on the negative side."""
        phi_diff = e[0] - self.phi_rel0
        b_half = self.b / 2
        w = de[0]
        pos = smaller(phi_diff - b_half, phi_diff - b_half + self.d * w / self.c)
        neg = smaller(-phi_diff - b_half, -(phi_diff + b_half) - self.d * w / self.c)
        # then the damper's saturation within each contact (``damper_saturation``: tau_d = tau_c)
        return _play_surfaces(phi_diff, self.b, pos, neg) + [
            (damper_saturation(pos, phi_diff - b_half - self.d * w / self.c), 1),
            (damper_saturation(neg, -(phi_diff + b_half) + self.d * w / self.c), -1)]

    def switching_active(self):
        return self.b > B_EPS          # a plain spring-damper below it

    def potential(self, e):
        phi_diff = e[0] - self.phi_rel0
        b_half = self.b / 2
        return sympy.Piecewise((self.c * phi_diff ** 2 / 2, self.b <= B_EPS),
                               (self.c * (phi_diff - b_half) ** 2 / 2, phi_diff > b_half),
                               (self.c * (phi_diff + b_half) ** 2 / 2, phi_diff < -b_half),
                               (0, True))


__all__ = ["Backlash", "ElastoBacklash", "B_EPS"]
