"""The friction rows of the compiled DAE: each device's equation in its current mode.

A friction or loss element keeps one equation structure in all modes: a row of
the constraint matrix ``G_f`` and one unknown force ``lam``; the mode codes and
the equation of each are tabled in ``regmech.components.friction``.

Row j's equation when not stuck is linear in the multipliers,
``c_own lam_j + c_cpl lam_cpl(j) = rhs(|w_rel|, t)``, as the device states it
(``relation``): a clutch has ``lam_j = mode * tau_k(|w_rel|)``; a lossy gear
couples its loss torque to its own mesh-force row ``cpl(j)``.

This module evaluates those laws for the residual, the Jacobian and the
acceleration-level (KKT) system; *which* mode each device is in is decided by
the hybrid layer (``regmech.hybrid``), which builds on these rows.
"""

from __future__ import annotations

import numpy as np

from ..modes import BACKWARD, FORWARD, FREE, STUCK


class FrictionRows:
    """All friction rows of a compiled system: residual rows, Jacobian weights and KKT relations.

    State kept between calls: ``quadrant`` (the driving side of each rolling lossy gear in the
    current segment, +1/-1; set by the hybrid layer's mode logic).
    """

    def __init__(self, compiled, rows):
        self.c = compiled
        self.rows = rows
        self.devices = [r.device for r in rows]
        self.mf = len(rows)
        self.G = compiled.Gf
        self.offset = compiled.mp + compiled.mv   # first friction multiplier in lam
        self.quadrant = np.ones(self.mf, int)      # driving side of lossy gears in the current segment
        cons = compiled.structure.position + compiled.structure.speed
        index = {id(r): i for i, r in enumerate(cons)}
        self.coupled = np.array([index[id(compiled.structure.rows[d.name][0])] if d.coupled else -1
                                 for d in self.devices], dtype=int)
        self._coupled_rows = [j for j, d in enumerate(self.devices) if d.coupled]
        # dense copy of G for the small matrices of typical drivetrains (sparse matvec costs ~10 us)
        self._Gd = self.G.toarray() if self.G.shape[0] * self.G.shape[1] <= 40000 else None

    # -- helpers --------------------------------------------------------------
    def _left(self, t):
        return t >= self.c._t_right

    def w_rel(self, v):
        """Relative speeds ``G_f v`` of the rows (or relative accelerations, given ``a``)."""
        return self._Gd @ v if self._Gd is not None else self.G @ v

    def initial_modes(self):
        return np.full(self.mf, FREE, dtype=int)     # no force before the first mode logic

    def start_modes(self, t):
        return self.initial_modes()

    def relations(self, t, v, modes):
        """Per row (c_own, c_cpl) and the right-hand sides of the non-stuck rows."""
        left = self._left(t)
        w = self.w_rel(v)
        rel, rhs = [], np.zeros(self.mf)
        for j, dev in enumerate(self.devices):
            if modes[j] == STUCK:
                rel.append((0.0, 0.0))
                continue
            c_own, c_cpl, r, _ = dev.relation(int(modes[j]), int(self.quadrant[j]), abs(w[j]), t, left)
            rel.append((c_own, c_cpl))
            rhs[j] = r
        return tuple(rel), rhs

    def _iterate_quadrants(self, v, lam_all, modes):
        """IDA's residual and Jacobian: the quadrant of each rolling lossy gear from the sign of its
        ``tau_eta`` at the current iterate (the segment's where it is exactly zero).

        The loss law is then MSL's continuous V (forward) / roof (backward) in ``tau_a`` rather than
        the segment's branch continued past the switch, so a switch that the root finding misses
        (``tau_eta`` crossing zero and back inside one step) cannot leave the gear on the other
        side's law, supplying power; BDF's error test sees the kink and IDA stays accurate
        (measured: the same errors as with the segment's branch). The ODE-form solvers keep the
        segment's branch, a smooth continuation that their error estimates need (with the
        kinked law DOP853 at rtol 1e-6 was 1e-3 off), and sample the event functions inside
        each step instead (``ode_driver.EventWatch``).
        """
        quadrant = self.quadrant
        if not self._coupled_rows:
            return quadrant
        w = self.w_rel(v)
        for j in self._coupled_rows:
            m = int(modes[j])
            if m != FORWARD and m != BACKWARD:
                continue
            te = self.devices[j].tau_eta(m, abs(w[j]), lam_all[self.offset + j], lam_all[self.coupled[j]])
            q = 1 if te > 0 else -1 if te < 0 else quadrant[j]
            if q != quadrant[j]:
                if quadrant is self.quadrant:
                    quadrant = quadrant.copy()
                quadrant[j] = q
        return quadrant

    # -- DAE rows ---------------------------------------------------------------
    def residual_rows(self, t, v, a, lam_all, modes):
        left = self._left(t)
        lam_f = lam_all[self.offset:]
        w = self.w_rel(v)
        arel = self.w_rel(a)
        quadrant = self._iterate_quadrants(v, lam_all, modes)     # the law of the side that drives now
        out = np.empty(self.mf)
        for j, dev in enumerate(self.devices):
            m = modes[j]
            if m == STUCK:
                out[j] = arel[j]
                continue
            c_own, c_cpl, r, _ = dev.relation(int(m), int(quadrant[j]), abs(w[j]), t, left)
            out[j] = c_own * lam_f[j] - r
            if c_cpl:
                out[j] += c_cpl * lam_all[self.coupled[j]]
        return out

    def add_pattern(self, pb, woff):
        """Register the friction rows' Jacobian entries; weights start at ``woff``.

        Weights per row j: [d(-rhs)/dw_rel, cj*stuck, stuck, c_own, c_cpl].
        """
        c = self.c
        G = self.G.tocoo()
        r = c.r_fric[G.row]
        k = 5
        pb.weighted(r, c.iv[G.col], G.data, woff + k * G.row + 0)
        dummy = c.is_dummy_v[G.col]
        pb.weighted(r[~dummy], c.iv[G.col[~dummy]], G.data[~dummy], woff + k * G.row[~dummy] + 1)
        pb.weighted(r[dummy], c.iad[c.pos_in_Dv[G.col[dummy]]], G.data[dummy], woff + k * G.row[dummy] + 2)
        j = np.arange(self.mf)
        pb.weighted(c.r_fric, c.ilam[self.offset + j], np.ones(self.mf), woff + k * j + 3)
        cp = self.coupled >= 0
        pb.weighted(c.r_fric[cp], c.ilam[self.coupled[cp]], np.ones(int(cp.sum())), woff + k * j[cp] + 4)
        return k * self.mf

    def weights(self, t, v, cj, modes, lam_all=None):
        left = self._left(t)
        w = self.w_rel(v)
        quadrant = self.quadrant if lam_all is None else self._iterate_quadrants(v, lam_all, modes)
        out = np.zeros(5 * self.mf)
        for j, dev in enumerate(self.devices):
            m = modes[j]
            if m == STUCK:
                out[5 * j + 1] = cj
                out[5 * j + 2] = 1.0
            else:
                c_own, c_cpl, _, drhs = dev.relation(int(m), int(quadrant[j]), abs(w[j]), t, left)
                out[5 * j] = -drhs * np.sign(w[j])
                out[5 * j + 3] = c_own
                out[5 * j + 4] = c_cpl
        return out

    def slopes(self, t, v, modes):
        """d lam / d w_rel of each non-stuck row (the friction characteristic's slope; 0 when stuck)."""
        left = self._left(t)
        w = self.w_rel(v)
        out = np.zeros(self.mf)
        for j, dev in enumerate(self.devices):
            if modes[j] != STUCK:
                c_own, _, _, drhs = dev.relation(int(modes[j]), int(self.quadrant[j]), abs(w[j]), t, left)
                out[j] = drhs * np.sign(w[j]) / c_own
        return out

    def singular_message(self, modes):
        stuck = [self.devices[j] for j in range(self.mf) if modes[j] == STUCK]
        names = ", ".join(f"{type(d).__name__} '{d.name}'" for d in stuck)
        return (f"the stuck friction devices {names} lock the same rigid group more than once, so their holding "
                f"torques are not unique (singular system). Remedy: put a compliance (an elastic Shaft) between "
                f"them, or merge them into one device (in linearize(modes=...): give all but one of them 'held').")
