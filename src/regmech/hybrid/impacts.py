"""Rigid impacts of hard stops: the event functions, the impulse (a velocity-level KKT projection), the
holding contact and the Zeno rule (mixin of ``FrictionSet``).

A hard stop (a friction row whose device has ``impact = True``, ``components.stops.HardStop``) is Free
inside its travel and Stuck (``a_rel = 0``, its force ``lam`` the contact force) while it holds at a
limit. Its two event functions, each crossing zero downwards when its state must change:

* Free: ``upper - phi_rel`` and ``phi_rel - lower`` (the limits reached);
* Stuck at side ``s`` (+1 upper, -1 lower): ``s lam + tol`` (the contact force would pull) and 1.

At a limit reached moving into it the speeds jump (``_impact``): ``v+ = v- + M^-1 A^T y`` closest to
``v-`` in the mass norm with the rigid rows at their (source) speeds, the stuck friction rows at zero slip
and the stop's row at ``-e w_rel-`` (or 0: contact). The energy the impulse ``P`` takes,
``-P (w_rel- + w_rel+) / 2``, is reported with the impact's event and booked in the stop's heat.

Stops reached at the same instant get their impulses one after another, each from the speeds the previous
one left (the stops already holding count as stuck rows), not as one joint impulse problem (an LCP).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg.lapack import dgetrf, dgetrs

from ..compile.system import PIVOT_TOL
from ..errors import ModelError, SimulationError
from ..modes import FREE, HELD, STUCK

#: the release function's tolerance: the contact holds while ``s lam >= -RELEASE_TOL * max(1, |lam|_max)``
RELEASE_TOL = 1e-12
#: a stop leaving its limit restarts this far inside it, relative to max(1, |upper|, |lower|) (``_nudge``)
NUDGE = 1e-12


class Impacts:
    """Hard stops among the friction rows (mixin of ``FrictionSet``)."""

    def _setup_impacts(self):
        self._stops = [j for j, d in enumerate(self.devices) if getattr(d, "impact", False)]
        self._stop_set = set(self._stops)
        self.stop_side = np.ones(self.mf)
        st = self.c.structure
        self._f_off = st.offsets(st.friction) if self._stops else np.zeros(self.mf)
        self._stop_tol = np.zeros(self.mf)
        self._reset_impacts()
        G = self.G.tocsr()
        for j in self._stops:
            if not np.any(G.data[G.indptr[j]:G.indptr[j + 1]] != 0.0):
                dev = self.devices[j]
                raise ModelError(
                    f"{type(dev).__name__} '{dev.name}': its flange carries no mass (flange and support are both "
                    f"on the ground), so nothing can hit its limits; connect the flange to an Inertia or Mass")

    def _reset_impacts(self):
        self._stop_wmax = np.zeros(self.mf)          # largest impact speed of each stop in the run
        self._stop_last = np.full(self.mf, -math.inf)  # time of each stop's last impact
        self._impact_log = []                        # (name, old, new, "impact", loss, work) of the current settle

    def rel_positions(self, x):
        """Relative positions ``G_f x + offset`` of the rows."""
        return (self._Gd @ x if self._Gd is not None else self.G @ x) + self._f_off

    def stop_event_values(self, out, y, lam, modes):
        """Write the hard stops' two functions into ``out`` (see the module docstring)."""
        rel = self.rel_positions(y[self.c.ix])
        for j in self._stops:
            dev, m = self.devices[j], int(modes[j])
            if m == STUCK:
                out[2 * j] = self.stop_side[j] * lam[j] + self._stop_tol[j]
                out[2 * j + 1] = 1.0
            elif m == HELD:
                out[2 * j] = out[2 * j + 1] = 1.0
            else:
                out[2 * j] = dev.upper - rel[j]
                out[2 * j + 1] = rel[j] - dev.lower

    def _stop_step(self, j, dev, old, x, v, z, crossed, initial, t, scale):
        """Step 1 of the mode logic for hard stop ``j``: ``(new mode, v)`` (the speeds after an impact)."""
        rel = float(self.rel_positions(x)[j])
        w = float(self.w_rel(v)[j])
        span = dev.upper - dev.lower
        tol_x = 1e-9 * max(1.0, abs(dev.upper), abs(dev.lower), span)
        if initial:
            self._reset_impacts()
            if rel > dev.upper + tol_x or rel < dev.lower - tol_x:
                coord, unit = ("s_rel", "m") if getattr(dev, "domain", None) == "translational" else ("phi_rel", "rad")
                raise SimulationError(
                    f"{type(dev).__name__} '{dev.name}' starts at {coord} = {rel:.9g} {unit}, outside its limits "
                    f"[{dev.lower:g}, {dev.upper:g}] {unit}; give start positions inside them (the start values of "
                    f"the masses on its flanges, or the reference of a motion source driving them)")
            side = 1 if rel >= dev.upper - tol_x else -1 if rel <= dev.lower + tol_x else 0
            if side == 0:
                return FREE, v
            if side * w > scale:
                raise SimulationError(
                    f"{type(dev).__name__} '{dev.name}' starts at its {'upper' if side > 0 else 'lower'} limit "
                    f"moving into it (w_rel = {w:.6g}); start inside the limits or with a speed away from the limit")
            self.stop_side[j] = side
            return STUCK, v          # holding; step 2 releases it at once when the load pulls away
        if old in (STUCK, HELD):
            if crossed[2 * j] != 0:
                # its release function crossed: the contact force would pull; it restarts just inside the limit
                self._nudge(t, x, j, self.stop_side[j], dev, self._modes_now)
                return FREE, v
            return old, v
        if crossed[2 * j] == 0 and crossed[2 * j + 1] == 0:
            return FREE, v
        side = 1 if crossed[2 * j] != 0 else -1
        self.stop_side[j] = side
        if side * w < -scale:
            # already moving away (another stop's impulse at this instant reversed it): no impact; it restarts inside
            self._nudge(t, x, j, side, dev, self._modes_now)
            return FREE, v
        return self._impact(j, dev, side, w, x, v, z, t, scale)

    def _one_way_locks(self, v2, j, modes, scale):
        """The modes of an impulse of stop ``j`` (``modes``, None: the event's) with every one-way clutch that the
        speeds ``v2`` after it would drive backward (``w_rel < 0`` beyond round-off) locked, or None when none would.

        Why: a freewheel locks when its slip would turn negative, within the impact too. Calibration seed 6140: a
        hard stop threw the driven side of a sliding one-way clutch from 115.8 to -109.3 rad/s, the clutch kept its
        Forward mode at w_rel = -112.7, and every solver refused the run ("gap in regmech's mode logic"). With the
        clutch locked, the impulse turns both of its sides together."""
        base = self._modes_now if modes is None else modes
        w = self.w_rel(v2)
        lock = [k for k, d in enumerate(self.devices)
                if k != j and d.one_way and base[k] != STUCK and w[k] < -scale]
        if not lock:
            return None
        out = np.array(base, dtype=int)
        out[lock] = STUCK
        return out

    def _impact(self, j, dev, side, w, x, v, z, t, scale):
        """The impulse of hard stop ``j`` hitting its limit ``side`` at relative speed ``w``; ``(mode, v+)``.

        A rebound restarts ``delta`` inside the limit (``_nudge``); the load's work over ``delta`` is taken from
        the rebound, ``w+^2 = (e w)^2 - 2 a_in delta`` (``a_in`` the relative acceleration into the limit after
        the impact), so the restart does not feed energy into a bounce sequence (a spring pressing the body
        against the stop otherwise kept it bouncing at the speed where the two balance, sqrt(2 a_in delta /
        (1 - e^2)), for ever). A rebound that cannot rise above ``delta`` is a contact (the Zeno rule's third
        clause)."""
        w_in = max(side * w, 0.0)          # a crossing located a hair late on a grazing touch: no speed into it
        self._stop_wmax[j] = max(self._stop_wmax[j], w_in)
        zeno = (dev.e * w_in <= dev.ZENO_SPEED * self._stop_wmax[j]
                or t - self._stop_last[j] <= dev.ZENO_DT * max(1.0, abs(t)))
        self._stop_last[j] = t
        target = 0.0 if zeno else -dev.e * w
        v2, p, work = self._project_row(t, v, j, target, dev)     # not Zeno: a trial, projected again below
        if not zeno:
            # the relative acceleration into the limit just after the impact (free), and the nudge it will get
            modes = np.array(self._modes_now, dtype=int)
            modes[j] = FREE
            a_in = side * float(self.w_rel(self.c.accelerations(t, x, v2, z, modes)[0])[j])
            rel = float(self.rel_positions(x)[j])
            delta = max(side * (rel - self._nudge_goal(dev, side)), 0.0)
            rise = (dev.e * w_in) ** 2 - 2.0 * a_in * delta
            # the final impulse, projected again from v-: only its rigid rows' work counts (booking the trial's too
            # gave a Speed source behind a stop with e = 0.5 -6 J for -3 J)
            if rise <= 0.0:
                zeno = True
                v2, p, work = self._project_row(t, v, j, 0.0, dev)
            else:
                v2, p, work = self._project_row(t, v, j, -side * math.sqrt(rise), dev)
                self._nudge(t, x, j, side, dev, self._modes_now)
        # one-way clutches the rebound would drive backward lock (``_one_way_locks``): each a plastic impact of its
        # two sides after the stop's (momentum kept, energy lost: restitution applied to both sides together fed
        # 51 J into seed 6140's 334), then the stop again if the locked motion still runs into it
        locked = None
        for _ in range(self.mf):
            more = self._one_way_locks(v2, j, locked, scale)
            if more is None:
                break
            locked = more
            v_lock = v2
            v2 = self._lock_velocities(t, x, v2, locked, locked)
            work = work + self._lock_work(v_lock, v2, locked)
            w_now = float(self.w_rel(v2)[j])
            if side * w_now > scale:
                v2, p_again, work_again = self._project_row(t, v2, j, 0.0 if zeno else -dev.e * w_now, dev, locked)
                p += p_again
                work = work + work_again
        w2 = float(self.w_rel(v2)[j])
        by_source = self._source_work(work)
        if locked is None:
            loss = max(-p * (w + w2) / 2.0, 0.0)
        else:       # several impulses: the kinetic energy they took (the locks' losses in it), and what sources gave
            loss = max(0.5 * float(np.sum(self.c.mass * (v * v - v2 * v2))) + sum(by_source.values()), 0.0)
        self._impact_log.append((dev.name, 0, int(side), "impact", float(loss), tuple(by_source.items()) or None))
        return (STUCK if zeno else FREE), v2

    def _lock_work(self, v, v2, locked):
        """Per rigid row, the work of the lock projection ``v -> v2`` (``_lock_velocities``, whose multipliers it does
        not return): ``M (v2 - v) = A^T y`` over the rigid rows and the rows stuck in ``locked``, solved for ``y`` by
        least squares (the jump lies in that range), each rigid row's work ``y_k A_k (v + v2) / 2``. Without it a
        source's work through a freewheel locking in the rebound would be booked as the stop's heat."""
        c = self.c
        if not c.Gpv.shape[0]:
            return np.zeros(0)
        rigid = c.Gpv.toarray()
        G = self._Gd if self._Gd is not None else self.G.toarray()
        rows = [G[k][None, :] for k in range(self.mf) if locked[k] == STUCK]
        A = np.vstack([rigid] + rows)
        y = np.linalg.lstsq(A.T, c.mass * (v2 - v), rcond=None)[0]
        return y[:rigid.shape[0]] * (rigid @ (0.5 * (v + v2)))

    def _source_work(self, work):
        """``{device: J}`` of ``work``, the work the rigid rows' impulses of an impact did on the masses (per row:
        ``_project_row``, ``_lock_work``), where it is above round-off: a motion source on the stop's path keeps its
        speed through the impulse and gives (or takes) that energy at the instant, which its ``power`` signal (a
        function of the rows) cannot show (fuzz seed 94074: a Speed source holding a planetary's carrier took 0.091 J
        at a plastic impact on the ring, and the books of every solver were open by that; ``Result.impulse_work``)."""
        st = self.c.structure
        rows = list(st.position) + list(st.speed)
        scale = 1e-12 * max(1.0, float(np.abs(work).sum()))
        out = {}
        for k, wk in enumerate(np.asarray(work).tolist()):
            if abs(wk) > scale:
                name = rows[k].device.name
                out[name] = out.get(name, 0.0) + wk
        return out

    @staticmethod
    def _nudge_goal(dev, side):
        """Where a stop leaving its limit ``side`` restarts: ``NUDGE * max(1, |upper|, |lower|)`` inside it."""
        limit = dev.upper if side > 0 else dev.lower
        return limit - side * NUDGE * max(1.0, abs(dev.upper), abs(dev.lower))

    def _nudge(self, t, x, j, side, dev, modes):
        """Move the positions ``x`` (in place) so that stop ``j`` leaving its limit ``side`` restarts strictly inside
        its travel, by ``NUDGE`` of its limits' size (mass-weighted, rigid rows and stuck rows kept): its limit
        function then starts positive, so every solver watches it from the restart on (the ODE-form solvers
        arm a function only once it is positive, and a rebound slower than one of their steps was missed)."""
        rel = float(self.rel_positions(x)[j])
        goal = self._nudge_goal(dev, side)
        if side * (rel - goal) <= 0:
            return
        dx, _, _ = self._project_row(t, np.zeros_like(x), j, goal - rel, dev, modes, positions=True)
        x += dx

    def _project_row(self, t, v, j, target, dev, modes=None, positions=False):
        """Speeds closest to ``v`` in the mass norm with the rigid rows at their references, the stuck friction
        rows at zero slip and row ``j`` at ``target``: ``(v+, impulse on row j, work of each rigid row's impulse)``.
        ``positions``: a change of positions instead (``v`` zero, every other row unchanged, row ``j`` moved by
        ``target``; no work, None)."""
        c = self.c
        modes = self._modes_now if modes is None else modes
        rigid = c.Gpv.toarray() if c.Gpv.shape[0] else np.zeros((0, c.n))
        G = self._Gd if self._Gd is not None else self.G.toarray()
        held = [k for k in range(self.mf) if k != j and modes[k] == STUCK]
        A = np.vstack([rigid] + [G[k][None, :] for k in held] + [G[j][None, :]])
        inv_m = 1.0 / np.maximum(c.mass, 1e-300 + 1e-12 * c.mass.max(initial=1.0))
        lu, piv, info = dgetrf((A * inv_m) @ A.T)
        d = np.abs(np.diagonal(lu))
        if info != 0 or not np.all(np.isfinite(d)) or d.min(initial=1.0) <= PIVOT_TOL * d.max(initial=1.0):
            raise SimulationError(
                f"{type(dev).__name__} '{dev.name}' hit its limit at t={t:.9g} s, but its relative motion is already "
                f"fixed by rigid links, motion sources or stuck friction devices, so no impulse can reverse it; "
                f"put a compliance between the stop and what holds it")
        if positions:
            goal = np.concatenate([np.zeros(A.shape[0] - 1), [target]])
        else:
            gp, gv = c._refs(t)
            goal = np.concatenate([gp[1], gv[0], np.zeros(len(held)), [target]])
        r = goal - A @ v
        y = dgetrs(lu, piv, r)[0]
        dv = inv_m * (A.T @ y)
        y2 = dgetrs(lu, piv, r - A @ dv)[0]
        dv += inv_m * (A.T @ y2)
        # the work of the rigid rows' impulses on the masses, y_k A_k (v- + v+) / 2 (exact: the kinetic energy's jump
        # is the sum of these over every row); nonzero only on a row whose speed is a source's reference
        work = (y + y2)[:len(rigid)] * (rigid @ (v + 0.5 * dv)) if not positions else None
        return v + dv, float(y[-1] + y2[-1]), work

    def _stop_release(self, t, x, j, lam_j, modes):
        """Step 2 for a holding stop: True when its contact force would pull (it releases; its positions are
        nudged inside, ``_nudge``)."""
        if self.stop_side[j] * lam_j < -self._stop_tol[j]:
            self._nudge(t, x, j, self.stop_side[j], self.devices[j], modes)
            return True
        return False

    def _stop_snapshot(self):
        return (self.stop_side.copy(), self._stop_tol.copy(), self._stop_wmax.copy(), self._stop_last.copy())

    def _stop_restore(self, snap):
        side, tol, wmax, last = snap
        self.stop_side[:], self._stop_tol[:], self._stop_wmax[:], self._stop_last[:] = side, tol, wmax, last
