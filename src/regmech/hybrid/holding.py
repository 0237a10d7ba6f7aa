"""Holding torques of stuck devices: locking their relative speed, sharing a motion that several of
them lock ("holding in turn"), and the relief of a device that slides at zero speed while another
holds its motion.

The holding torques themselves come from one KKT solve of the acceleration-level equations of the
whole system with every stuck row as a constraint (``CompiledSystem.accelerations``, factorised once
per mode set), so that several devices locked on one rigid group are compared with their capacities
together (MSL CoupledClutches at t = 0.831 s and 1.000 s).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg.lapack import dgetrf, dgetrs

from ..compile.system import PIVOT_TOL
from ..errors import StructureError
from ..modes import BACKWARD, FORWARD, FREE, HELD, STUCK
from ..structure.system import START_RTOL

#: the most unknowns (coordinates and rows) for which stuck devices are locked densely (``_lock_dense``);
#: the same single-threaded range as ``compile.kkt.DENSE_MAX``
LOCK_DENSE_MAX = 128


class Holding:
    """Stuck devices and their holding torques (mixin of ``FrictionSet``)."""

    def _lock_velocities(self, t, x, v, new, old):
        """Make w_rel exactly zero for devices that are (or were) stuck: a mass-weighted
        (impulse) projection, so momentum is conserved."""
        lock = (new == STUCK) | (old == STUCK)
        if not lock.any():
            return v
        w = self.w_rel(v)
        if np.all(w[lock] == 0.0):
            return v
        v2 = self._lock_dense(t, v, lock)
        if v2 is None:
            try:
                _, v2 = self.c.project(t, x, v, None, None, np.where(lock, STUCK, FREE))
            except StructureError:
                # a device that was stuck and now breaks away cannot always be put at exactly zero slip: with a
                # motion source and a device sticking now on its loop, the source sets its slip (fuzz seed
                # 10021: a limited-slip lock breaking away as a brake on its side sticks while a Speed source
                # passes zero). Only the devices stuck from now on are locked then; their conflicts are real.
                now = new == STUCK
                if np.array_equal(now, lock):
                    raise
                return self._lock_velocities(t, x, v, new, new)
        return v2

    def _lock_dense(self, t, v, lock):
        """The projection of ``_lock_velocities`` for a small system, dense, or None.

        The velocities closest to ``v`` in the mass norm that meet the rigid rows at velocity
        level (``G_pv v = g``, sources included) and ``w_rel = 0`` of the locked rows ``A``:
        ``v + M^-1 A^T y`` with ``(A M^-1 A^T) y = r``, one step of refinement, as
        ``CompiledSystem.project`` does it with sparse matrices (about 3 ms a call for
        CoupledClutches, most of it sparse bookkeeping, against some 50 us dense). None (the
        caller then projects with ``project``, which also reports conflicting constraints by
        name) when the system is large, the rows are dependent, or the result misses them.
        """
        c = self.c
        if self._Gd is None or c.n + c.mp + c.mv + self.mf > LOCK_DENSE_MAX:
            return None
        # the matrix depends on the set of locked rows only: its factors are kept per set (a run meets a few)
        cache = c.__dict__.setdefault("_lock_factors", {})
        key = lock.tobytes()
        hit = cache.get(key)
        if hit is None:
            rigid = c.__dict__.get("_lock_rigid")
            if rigid is None:
                rigid = c._lock_rigid = c.Gpv.toarray()
            A = np.vstack([rigid, self._Gd[lock]])
            inv_m = 1.0 / np.maximum(c.mass, 1e-300 + 1e-12 * c.mass.max(initial=1.0))
            lu, piv, info = dgetrf((A * inv_m) @ A.T)
            d = np.abs(np.diagonal(lu))
            ok = not (info != 0 or not np.all(np.isfinite(d)) or d.min(initial=1.0) <= PIVOT_TOL * d.max(initial=1.0))
            if len(cache) > 64:
                cache.clear()
            hit = cache[key] = (A, inv_m, lu, piv, ok)
        A, inv_m, lu, piv, ok = hit
        if not ok:
            return None
        gp, gv = c._refs(t)
        r = np.concatenate([gp[1], gv[0], np.zeros(int(lock.sum()))]) - A @ v
        dv = inv_m * (A.T @ dgetrs(lu, piv, r)[0])
        dv += inv_m * (A.T @ dgetrs(lu, piv, r - A @ dv)[0])
        scale = np.maximum(1.0, np.abs(r) + np.abs(A) @ np.abs(dv))
        if not np.all(np.isfinite(dv)) or np.max(np.abs(A @ dv - r) / scale, initial=0.0) > 1e-3 * START_RTOL:
            return None
        return v + dv

    def _share_redundant(self, t, x, v, z, modes) -> bool:
        """Resolve stuck devices that lock a motion already locked by others.

        Rule (documented in the README, "holding in turn"): going through the stuck
        devices in model order, a device whose relative motion is already fixed by
        the rigid constraints and the stuck devices before it is *Held*: it stays at
        zero relative speed and transmits no torque, so the holding torque is unique
        and carried by the first device. When that holder's load passes its static
        capacity it does not let the motion go: it acts with its kinetic torque at
        zero speed (sliding, held) and the held devices hold again, next in model
        order (``settle``). The motion breaks away when the last holder's share
        passes its capacity: for two devices, at ``kinetic(first) + static(second)``.
        When the load falls back so that the holder would resist the kinetic torque
        of a device sliding at zero speed, that device sticks again
        (``_relief_events``). Friction thus never drives the motion it holds.
        Returns False when no stuck friction row is redundant (the model itself is
        singular).
        """
        c = self.c
        A = [c.Gpv.toarray()] if c.Gpv.shape[0] else []
        rank = np.linalg.matrix_rank(np.vstack(A)) if A else 0
        dependent = []
        for j in np.nonzero(np.asarray(modes) == STUCK)[0]:
            row = self.G[j].toarray()
            r = np.linalg.matrix_rank(np.vstack(A + [row]))
            if r > rank:
                A.append(row)
                rank = r
            else:
                dependent.append(j)
        if not dependent:
            return False
        modes[dependent] = HELD
        return True

    def _fixed_by(self, rows, j):
        """Whether device ``j``'s relative motion is fixed by the rigid rows and the friction rows of the devices
        ``rows`` (dense ranks: for the few small systems the mode logic asks this of)."""
        c = self.c
        rigid = c.Gpv.toarray() if c.Gpv.shape[0] else np.zeros((0, c.n))
        G = self.G.toarray()
        base = np.vstack([rigid] + [G[k][None, :] for k in rows])
        r0 = np.linalg.matrix_rank(base) if base.shape[0] else 0
        return np.linalg.matrix_rank(np.vstack([base, G[j][None, :]])) == r0

    def _stick_first(self, t, x, v, z, modes, j, a_tol):
        """Modes in which device ``j``, reaching zero slip on a loop that a motion source drives through a
        stuck device ``h``, sticks while ``h`` slides; or None.

        Neither can hold with the other: the source sets the loop's motion. Stuck ``j`` and sliding ``h``
        is the answer when ``h``'s kinetic torque is within ``j``'s static capacity and ``h`` then slips
        the way it is driven (``mode_h * a_rel_h >= 0``): the device reaching zero slip sticks first, as a
        compliance between them would decide (the holder's load rises with the source's motion and lets go
        at its own capacity first) and as MSL's friction elements do (stuck unless the load exceeds the
        static capacity). Otherwise (None) ``j`` slides the way the source drags it. ``h`` is the one stuck
        device whose constraint, with the rigid rows and the other stuck devices, fixes ``j``'s motion;
        with several such holders no choice is made here (None)."""
        c = self.c
        if c.n + c.mp + c.mv + self.mf > LOCK_DENSE_MAX or self.devices[j].coupled:
            return None
        stuck = [int(k) for k in np.nonzero(np.asarray(modes) == STUCK)[0] if k != j]
        holders = [h for h in stuck if self._fixed_by(stuck, j) and not self._fixed_by([k for k in stuck if k != h], j)]
        if len(holders) != 1 or self.devices[holders[0]].coupled or self.devices[holders[0]].one_way:
            return None
        h = holders[0]
        q = self.q_from(t, x, v, z)             # inputs of the laws from the state (None without any)
        tau0, tau0_max = self._call(self.devices[j], "capacities", None if q is None else q[j], t, t >= c._t_right)
        for d in (FORWARD, BACKWARD):
            trial = np.array(modes, dtype=int)
            trial[j], trial[h] = STUCK, d
            try:
                a, lam, _ = c.accelerations(t, x, v, z, trial)
            except StructureError:
                continue
            if d * self.w_rel(a)[h] >= -a_tol and abs(lam[self.offset + j]) <= tau0_max * (1 + 1e-12):
                return trial
        return None

    def _relief_events(self, t, y, yp, modes, scale, view):
        """Event rows for devices sliding at zero speed while one stuck device holds their motion.

        Such a device (a holder that passed its capacity, see ``_share_redundant``) acts with
        its kinetic torque ``lam_j = mode_j tau_k`` and the holder ``h`` carries the rest. With
        a virtual motion ``dv`` that keeps the rigid constraints and the other stuck devices and
        moves the holder by ``G_h dv = 1``, the device moves by ``c = G_j dv``: the holder's torque
        acts on the device's coordinate as ``lam_h / c``. Sharing means both resist in the same
        direction, ``mode_j sign(c) lam_h >= 0``; the event function is that product plus a
        tolerance (1e-9 of the device's torque, so that it starts positive when the holder's
        share starts at zero) and crosses zero when the load has fallen below the device's
        kinetic torque: the device then sticks again. With several holders of one motion, each of
        them needed (a chain of stuck clutches and a brake behind a lossy gear rolling at rest), the
        function is that of the holder whose share is the smallest: at rest the holders of a chain
        carry one load (up to the loads applied between them), and the first share to reach zero
        ends the sharing; only for a lossy gear (a friction device held by several keeps sliding until
        its own slip leaves zero). Without a function the device's own slip, zero to round-off, crossed at
        every restart (MSL Rotational.Examples.HeatLosses with a node inertia after its lossy gear:
        201 silent crossings within 1.4 us, ChatteringError). ``view``: the restart's relative speeds
        and accelerations (``ModeLogic._restart_view``).
        """
        c = self.c
        ml = np.asarray(modes).tolist()
        # a device that has just broken away also has w_rel ~ 0, but it accelerates; only one whose
        # relative acceleration is zero as well can be held (the rank tests below are dense: keep them rare)
        w, arel, a_tol, _ = view
        sliding = [j for j in range(self.mf)
                   if ml[j] in (FORWARD, BACKWARD) and abs(w[j]) <= scale and abs(arel[j]) <= a_tol]
        stuck = [h for h in range(self.mf) if ml[h] == STUCK]
        if not sliding or not stuck:
            return []            # no device is sliding at rest while another holds: nothing below can apply
        lam = c.unpack(y, yp)[3][self.offset:]
        rigid = c.Gpv.toarray() if c.Gpv.shape[0] else np.zeros((0, c.n))
        G = self.G.toarray()

        def spans(rows, target):
            base = np.vstack([rigid] + [G[k][None, :] for k in rows])
            return np.linalg.matrix_rank(np.vstack([base, target[None, :]])) == np.linalg.matrix_rank(base)

        out = []
        for j in sliding:
            if not spans(stuck, G[j]):
                continue                 # its motion is free: it is really sliding
            holders = [h for h in stuck if not spans([k for k in stuck if k != h], G[j])]
            if len(holders) > 1 and not self.devices[j].coupled:
                # a friction device held by several: it stays sliding until its own speed leaves zero (the paths
                # of the rule of holding in turn, fuzz seed 102, rest on that)
                continue
            best = None
            for h in holders:
                others = [k for k in stuck if k != h]
                A = np.vstack([rigid] + [G[k][None, :] for k in others] + [G[h][None, :]])
                rhs = np.zeros(A.shape[0])
                rhs[-1] = 1.0
                dv = np.linalg.lstsq(A, rhs, rcond=None)[0]
                cj = float(G[j] @ dv)
                if abs(cj) < 1e-12:
                    continue
                share = ml[j] * np.sign(cj) * float(lam[h])
                if best is None or share < best[0]:
                    best = (share, h, float(np.sign(cj)))
            if best is None:
                continue
            tol = 1e-9 * max(1.0, abs(float(lam[j])))
            out.append((j, int(c.ilam[self.offset + best[1]]), best[2], tol))
        return out

