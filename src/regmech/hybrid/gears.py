"""Lossy gears in the mode logic: their first step at an event, their event functions, and the
driving side (quadrant) of a rolling gear.

The gear states its laws (``components.friction.LossyGear``: the loss law of each quadrant, the
loss torque it can hold at rest ``limits``, ``tau_eta`` whose sign is the driving side); this
module decides with them.
"""

from __future__ import annotations

import numpy as np

from ..modes import BACKWARD, FORWARD, FREE, HELD, STUCK


def gear_first_step(dev, old, w, crossed1, crossed2, initial, scale, arel, impacted=False, at_rest=False):
    """The gear's mode after the crossings found at an event (step 1 of ``settle``); ``impacted``: a hard stop's
    impulse changed the speeds at this event (``impacts``); ``at_rest``: its relative acceleration is round-off and
    no relief event keeps it rolling (``ModeLogic._still_relieved``)."""
    if dev.ideal:
        return FREE
    if initial or old == FREE or old == HELD:
        return FORWARD if w > scale else BACKWARD if w < -scale else STUCK
    if old == STUCK:
        return FORWARD if crossed1 else BACKWARD if crossed2 else STUCK
    if impacted and old * w < -scale:
        # an impact's impulse reversed its rolling (fuzz seed 80273: a hard stop on the gear's output flange
        # threw it from 9.3 to -3.7 rad/s): it rolls the other way now, as a friction device slides
        return -old
    # found by the root finder, or within round-off of zero and still approaching it, or already
    # past it by round-off (another device's root, located on the far side, at the same instant), or at rest
    # there (its acceleration round-off, its side a tie): stuck, it has its static limits, and the break-away
    # test of ``settle`` decides, by where the load goes at a tie (``ModeLogic._gear_tie_probe``)
    if crossed1 or (abs(w) <= scale and (w * arel < 0 or old * w < 0 or at_rest)):
        return STUCK
    return old


def gear_events(dev, mode, quadrant, w, tau_loss, lam_g):
    """The gear's two event functions, each crossing zero downwards when its mode must change:
    stuck: the margins ``hi - tau_loss`` and ``tau_loss - lo`` to the loss torque it can hold;
    rolling: ``mode * w_a`` (it stops) and ``quadrant * tau_eta`` (the driving side changes).

    A gear rolling at exactly zero speed (left there by the mode logic: released from a hard stop at the edge of
    its capacity) gets ``1e-300`` for its speed function, as a friction device sliding at zero slip does
    (``FrictionSet.event_values``): a function that starts a segment at zero is disarmed by the ODE driver until it
    is positive and left inactive by IDA's root finding, so a gear that then rolled backward was never stopped.
    Calibration seed 5110 (a motor on a hard stop through a lossy gear to a wheel): DOP853 rolled it "forward" at
    w_a down to -0.0136 rad/s for 18 ms, its loss supplying power, until the next event's check refused the run."""
    if mode == FREE or mode == HELD:
        return 1.0, 1.0
    if mode == STUCK:
        # the same offset for the margins of a stuck gear: an idle gear with no load has its loss torque and both
        # limits at zero, and its margins crossed at round-off over and over (calibration seed 8031: a lossy
        # planetary at rest, ChatteringError at t = 2e-7 s); a load past the limit by the offset is within
        # ``logic.GEAR_TIE`` of it, where the load a moment later decides (``ModeLogic._gear_tie_probe``)
        hi, lo = dev.limits(tau_loss, lam_g)
        tie = _event_tie(tau_loss, lam_g)
        return hi - tau_loss + tie, tau_loss - lo + tie
    # the driving side changes when tau_eta crosses zero; an offset of 1e-10 of the torques (below the
    # tie threshold of _fix_quadrant, which then decides by where the torque goes) keeps a gear whose
    # tau_eta stays at round-off (an unloaded idler at constant speed: a Gearbox's idle gears) from
    # firing a root at every step (it chattered, ChatteringError, at t ~ 1e-11 s)
    tie = _event_tie(tau_loss, lam_g)
    speed = mode * w
    return (speed if speed != 0.0 else 1e-300), quadrant * dev.tau_eta(mode, abs(w), tau_loss, lam_g) + tie


def _event_tie(tau_loss, lam_g) -> float:
    """The offset of a gear's torque functions (``gear_events``): 1e-10 of its torques, at least of 1 N m."""
    return 1e-10 * max(1.0, abs(tau_loss), abs(lam_g))


class GearSides:
    """The driving side of rolling lossy gears (mixin of ``FrictionSet``)."""

    def _fix_quadrant(self, j, dev, modes, t, x, v, z, a, lam, dz):
        """Lossy gear rolling: make the assumed driving side (quadrant) agree with the torque.

        The quadrant is the sign of ``tau_eta`` (``LossyGear.tau_eta``) of the solution computed
        with it. For one gear the loss law ``tau_loss = k tau_a + b`` is a V (forward) or a roof
        (backward) in ``tau_a`` with slopes ``k`` of ``1 - eta_mf1`` in [0, 1) and ``1 - 1/eta_mf2``
        <= 0, while the rest of the system gives ``tau_a = A + beta tau_loss`` with ``0 <= beta
        <= 1`` (positive definite masses; ``beta = J_a r^2 / (J_b + J_a r^2)`` for two inertias,
        whatever the sign of the ratio r). ``tau_loss - k (A + beta tau_loss) = b`` has then exactly
        one solution over both branches: one quadrant is consistent, and a wrong one is put right by
        one flip. The budget is one flip per set of the other devices' modes and gears' sides (they
        change ``A``); it was one per gear and event, and a flip made while a brake on the same
        motion was still stuck could not be undone after the brake broke away (the gear supplied
        840 W).

        At the switch itself (an event of ``tau_eta``, or any instant where ``|tau_eta|`` is at
        round-off) both quadrants give the same loss, and the sign of ``tau_eta`` is round-off
        or the algebraic error of the solver: the side it moves to decides. That direction does
        not depend on the quadrant used (both give the same accelerations there, and
        ``d tau_a/dt = (dA/dt) / (1 - beta k)`` with ``1 - beta k > 0``), so it comes from a
        forward difference along the motion with the current one. Deciding by the round-off
        sign instead left the gear on the wrong law with its event function negative and never
        re-armed: the gear then supplied power, by an amount that depended on the tolerance.
        """
        c = self.c
        m = int(modes[j])
        i_own, i_cpl = self.offset + j, self.coupled[j]
        w = float(self.w_rel(v)[j])
        te = dev.tau_eta(m, abs(w), lam[i_own], lam[i_cpl])
        torque = max(1.0, abs(lam[i_own]), abs(lam[i_cpl]))     # N m, the scale of round-off in te
        q = 1 if te > 0 else -1
        if abs(te) <= 1e-9 * torque:
            q = int(self.quadrant[j])           # kept when the torque does not move either (tangency)
            d = min(1e-7 * max(1.0, abs(t)), 0.25 * (c._t_right - t))    # stay inside the segment
            if d > 0:
                _, lam2, _ = c.accelerations(t + d, x + d * v, v + d * a, z + d * dz, modes)
                w2 = float(self.w_rel(v + d * a)[j])
                step = dev.tau_eta(m, abs(w2), lam2[i_own], lam2[i_cpl]) - te
                if abs(step) > 64 * np.finfo(float).eps * torque:
                    q = 1 if step > 0 else -1
        if q == self.quadrant[j]:
            return False
        # one flip per set of the other devices' modes and gears' sides; a second one for the same set
        # would undo it: only a law with a jump (eta = 1 with tau_bf1 != tau_bf2) at its jump does that
        others = self.quadrant.copy()
        others[j] = 0
        key = (j, modes.tobytes(), others.tobytes())
        if key in self._flips:
            return False
        self._flips.add(key)
        self.quadrant[j] = q
        return True

    def _assemble_restart(self, t, x, v, z, modes, lam, known=None):
        """Consistent ``(y, y')`` of the settled modes.

        A lossy gear whose driving side was decided at a tie (``_fix_quadrant``: by where the
        torque goes) may have ``tau_eta`` a round-off on the other side. IDA's residual takes the
        law by the sign of ``tau_eta`` (``_iterate_quadrants``), so the restart values are
        assembled with that law: they then satisfy the residual to round-off (with the segment's
        law they missed it by up to 1e-9 of the torques, and IDA at rtol 1e-10 failed its error
        test at the restart). Both laws agree there to that round-off; the segment keeps its
        quadrant for the event functions. ``known``: the accelerations of ``modes`` at (t, x, v, z) when the
        caller has them (used without lossy gears, whose law may change here).
        """
        c = self.c
        if not self._coupled_rows:
            return c.assemble_y(t, x, v, z, modes, known=known)
        keep = self.quadrant.copy()
        self.quadrant = self._iterate_quadrants(v, lam, modes).copy()
        try:
            return c.assemble_y(t, x, v, z, modes)
        finally:
            self.quadrant = keep
