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

from ..modes import BACKWARD, FORWARD, FREE, HELD, STUCK


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
        # inputs of the laws from the state (``friction_inputs``) and the devices' own states
        from .friction_inputs import build_inputs
        self.inputs = build_inputs(compiled, self.devices, compiled._fstate_z)
        self.has_inputs = any(self.inputs)
        self._q_devs = [j for j, ins in enumerate(self.inputs) if ins]
        #: (row j, index of the state in z) of every friction device's own state
        self.state_rows = [(j, zk) for j, own in enumerate(compiled._fstate_z) for zk in own.values()]
        self._ybuf = np.zeros(compiled.N) if self.has_inputs else None

    # -- inputs from the state --------------------------------------------------
    def q_all(self, t, y):
        """Per device its law inputs ``q`` at the unknowns ``y`` (None for a device without inputs)."""
        left = self._left(t)
        out = [None] * self.mf
        for j in self._q_devs:
            out[j] = np.array([inp.value(t, y, left) for inp in self.inputs[j]])
        return out

    def q_from(self, t, x, v, z):
        """``q_all`` from positions, speeds and states (the mode logic's and the KKT solve's view)."""
        if not self.has_inputs:
            return None
        c, y = self.c, self._ybuf
        y[c._sx], y[c._sv], y[c._sz] = x, v, z
        return self.q_all(t, y)

    @staticmethod
    def _call(dev, name, q, *args):
        """``dev.<name>(*args)``, with ``q`` appended for a device that has inputs (only then: a user's
        subclass without inputs may state its laws without the argument)."""
        fn = getattr(dev, name)
        return fn(*args) if q is None else fn(*args, q)

    def state_rates(self, t, v, lam_all, q, modes=None):
        """Indices in ``z`` and rates of the friction devices' own states at speeds ``v`` and forces ``lam``
        (the values each mode pins taken exactly: ``_pinned``)."""
        left = self._left(t)
        w = self.w_rel(v)
        zi, rates = [], []
        done = set()
        for j, zk in self.state_rows:
            if j in done:
                continue
            done.add(j)
            wj, lj = self._pinned(j, w, lam_all, modes)
            r = self.devices[j].state_rates(wj, lj, t, left, q[j])[0]
            rates.extend(r)
            zi.extend(self.c._fstate_z[j].values())
        return np.asarray(zi, np.int64), np.asarray(rates, float)

    # -- helpers --------------------------------------------------------------
    def _pinned(self, j, w, lam_all, modes) -> tuple[float, float]:
        """Row ``j``'s ``(w_rel, lam)`` as its own states' rates read them: exactly 0 where the mode pins it
        (Stuck: no slip; Free, Held: no torque), the solved values otherwise.

        The solvers meet a Stuck row's ``w_rel = 0`` and a Free row's ``lam = 0`` to their tolerances only,
        and a ThermalMass's ``P = lam w_rel`` turned that residue into heat: calibration seed 9001's stuck
        clutch (C = 2.5e-5 J/K) warmed by 2e-14 to 4e-11 K, depending on the tolerances, and cooled as often
        (a loss element supplying power), and the accuracy contract tightened its runs to resolve that noise.
        The law's power is zero in those modes; the rates read it so."""
        pin_w, pin_lam = self._pins(j, modes)
        return (0.0 if pin_w else float(w[j])), (0.0 if pin_lam else float(lam_all[self.offset + j]))

    @staticmethod
    def _pins(j, modes) -> tuple[bool, bool]:
        """Whether row ``j``'s mode pins its slip (Stuck) and its torque (Free, Held) at zero (``_pinned``)."""
        m = None if modes is None else int(modes[j])
        return m == STUCK, m in (FREE, HELD)

    def _left(self, t):
        return t >= self.c._t_right

    def w_rel(self, v):
        """Relative speeds ``G_f v`` of the rows (or relative accelerations, given ``a``)."""
        return self._Gd @ v if self._Gd is not None else self.G @ v

    def initial_modes(self):
        return np.full(self.mf, FREE, dtype=int)     # no force before the first mode logic

    def start_modes(self, t):
        return self.initial_modes()

    def relations(self, t, v, modes, q=None):
        """Per row (c_own, c_cpl) and the right-hand sides of the non-stuck rows (``q``: ``q_all``'s inputs)."""
        left = self._left(t)
        w = self.w_rel(v)
        rel, rhs = [], np.zeros(self.mf)
        for j, dev in enumerate(self.devices):
            if modes[j] == STUCK:
                rel.append((0.0, 0.0))
                continue
            c_own, c_cpl, r, _ = self._call(dev, "relation", None if q is None else q[j],
                                            int(modes[j]), int(self.quadrant[j]), abs(w[j]), t, left)
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
    def residual_rows(self, t, v, a, lam_all, modes, q=None):
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
            if q is None or q[j] is None:       # the hot path: no inputs, the device's own signature
                c_own, c_cpl, r, _ = dev.relation(int(m), int(quadrant[j]), abs(w[j]), t, left)
            else:
                c_own, c_cpl, r, _ = dev.relation(int(m), int(quadrant[j]), abs(w[j]), t, left, q[j])
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
        nw = k * self.mf
        # inputs from the state: friction row j on the columns its inputs read; own states' rows on w_rel's
        # speeds, on lam_j and on the inputs' columns. Weights follow the 5 per row, in this order:
        self._extra = []        # (kind, row j, z index or -1, input k or -1, first weight, count)
        for j in self._q_devs:
            for kq, inp in enumerate(self.inputs[j]):
                n = len(inp.cols)
                pb.weighted(np.full(n, c.r_fric[j]), inp.cols, np.ones(n), woff + nw + np.arange(n))
                self._extra.append(("row", j, -1, kq, nw, n))
                nw += n
        Gr = self.G.tocsr()
        for j, zk in self.state_rows:
            rz = c.r_z[zk]
            cols = Gr.indices[Gr.indptr[j]:Gr.indptr[j + 1]]
            coefs = Gr.data[Gr.indptr[j]:Gr.indptr[j + 1]]
            pb.weighted(np.full(len(cols), rz), c.iv[cols], coefs, np.full(len(cols), woff + nw))
            self._extra.append(("dw", j, zk, -1, nw, 1))
            nw += 1
            pb.weighted([rz], [c.ilam[self.offset + j]], [1.0], [woff + nw])
            self._extra.append(("dlam", j, zk, -1, nw, 1))
            nw += 1
            for kq, inp in enumerate(self.inputs[j]):
                n = len(inp.cols)
                pb.weighted(np.full(n, rz), inp.cols, np.ones(n), woff + nw + np.arange(n))
                self._extra.append(("dq", j, zk, kq, nw, n))
                nw += n
        return nw

    def weights(self, t, v, cj, modes, lam_all=None, y=None):
        left = self._left(t)
        w = self.w_rel(v)
        quadrant = self.quadrant if lam_all is None else self._iterate_quadrants(v, lam_all, modes)
        extra = getattr(self, "_extra", ())
        out = np.zeros(5 * self.mf + sum(e[5] for e in extra))
        q = grads = None
        if self.has_inputs and y is not None:
            q, grads = [None] * self.mf, [None] * self.mf
            for j in self._q_devs:
                vg = [inp.value_and_gradient(t, y, left) for inp in self.inputs[j]]
                q[j] = np.array([val for val, _ in vg])
                grads[j] = [g for _, g in vg]
        for j, dev in enumerate(self.devices):
            m = modes[j]
            if m == STUCK:
                out[5 * j + 1] = cj
                out[5 * j + 2] = 1.0
            else:
                c_own, c_cpl, _, drhs = self._call(dev, "relation", None if q is None else q[j],
                                                   int(m), int(quadrant[j]), abs(w[j]), t, left)
                out[5 * j] = -drhs * np.sign(w[j])
                out[5 * j + 3] = c_own
                out[5 * j + 4] = c_cpl
        if extra and q is not None:
            dq_row = {}
            rates = {}
            for kind, j, zk, kq, start, n in extra:
                if kind == "row":
                    m = int(modes[j])
                    if m == STUCK:
                        continue       # a_rel = 0 reads no input
                    if j not in dq_row:
                        dq_row[j] = self.devices[j].law_gradient(m, int(quadrant[j]), abs(w[j]), t, left, q[j])
                    out[start:start + n] = -dq_row[j][kq] * grads[j][kq]
                    continue
                if (j, zk) not in rates:
                    names = list(self.c._fstate_z[j].values())
                    wj, lj = self._pinned(j, w, lam_all, modes)
                    r = self.devices[j].state_rates(wj, lj, t, left, q[j])
                    rates[(j, zk)] = tuple(np.asarray(x)[names.index(zk)] for x in r)
                _, d_w, d_lam, d_q = rates[(j, zk)]
                pin_w, pin_lam = self._pins(j, modes)     # a pinned input: the rate does not read it (``_pinned``)
                d_w = 0.0 if pin_w else d_w
                d_lam = 0.0 if pin_lam else d_lam
                if kind == "dw":
                    out[start] = -d_w
                elif kind == "dlam":
                    out[start] = -d_lam
                else:
                    out[start:start + n] = -d_q[kq] * grads[j][kq]
        return out

    def slopes(self, t, v, modes):
        """d lam / d w_rel of each non-stuck row (the friction characteristic's slope; 0 when stuck)."""
        if self.has_inputs:
            from ..errors import StructureError
            names = [self.devices[j].name for j in self._q_devs]
            raise StructureError(f"linearize: friction device(s) {names} read inputs from the state (a thermal mass "
                                 f"or a controller's command), which the structural-matrix form cannot hold; use "
                                 f"the simulation for these models")
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
