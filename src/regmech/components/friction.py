"""Variable-structure friction devices and their logical equations.

Devices: ``Clutch`` (between two flanges), ``Brake`` (flange to support),
``FrictionContact`` (translational, mass to mass or to ground), and
``BearingFriction`` (speed-dependent torque table, no normal force).

Every device keeps **one equation structure** in all modes (the "universal
equation" of SOURCES.md 003, MSL PartialFriction): a row of the constraint
matrix ``G_f`` (its relative coordinate) and one unknown force ``lam``:

=========  ====  ===========================================
mode       code  equation
=========  ====  ===========================================
Backward   -1    ``lam = -tau_k(|w_rel|)``
Stuck       0    ``a_rel = 0`` (``lam`` = holding torque)
Forward     1    ``lam = +tau_k(|w_rel|)``
Free        2    ``lam = 0``   (normal force <= 0)
=========  ====  ===========================================

with the kinetic capacity ``tau_k(w) = mu(w) * cgeo * fn_max * f_normalized(t)``,
``tau0 = tau_k(0)`` and the static (break-away) capacity ``tau0_max = peak * tau0``.
Index reduction therefore runs once; only the row's equation switches.

Mode logic (``FrictionSet.settle``), as MSL does it:

* sliding -> Stuck when ``w_rel`` reaches zero (root of ``mode * w_rel``,
  decreasing); the new Stuck mode is checked only in the next iteration;
* Stuck -> Forward/Backward when the holding torque leaves
  ``[-tau0_max, tau0_max]`` (root of ``tau0_max - |lam|``); after break-away
  the kinetic torque at zero speed is ``tau0 < tau0_max``, so the device
  accelerates away (hysteresis, no chattering);
* any mode -> Free when the normal force drops to <= 0; Free -> sliding by
  the sign of ``w_rel`` when it becomes positive (Stuck if ``w_rel`` is 0);
* the holding torques of *all* stuck devices come from one KKT solve, and
  the logic iterates until no mode changes.
"""

from __future__ import annotations

import numpy as np

from ..component import Device, Param
from ..errors import ChatteringError, SimulationError, StructureError
from ..ports import ROTATIONAL, TRANSLATIONAL

BACKWARD, STUCK, FORWARD, FREE = -1, 0, 1, 2


class FrictionDevice(Device):
    """Base class: subclasses define ``kinetic(w_abs, t, left)`` and ``engaged``."""

    kind = "friction"
    one_way = False   # True: only w_rel >= 0 (freewheel); no Backward mode

    def kinetic(self, w_abs: float, t: float, left: bool = False) -> tuple[float, float]:
        """Kinetic capacity at relative speed ``w_abs`` >= 0 and its derivative d/dw."""
        raise NotImplementedError

    def normal_force(self, t: float, left: bool = False) -> float:
        """Engagement measure: the device is Free when this is <= 0."""
        return 1.0

    def peak_ratio(self) -> float:
        return self._values.get("peak", 1.0)

    def capacities(self, t, left=False):
        tau0 = self.kinetic(0.0, t, left)[0]
        return tau0, self.peak_ratio() * tau0


class _MuMixin:
    """mu(w) from a constant ``mu`` or a ``mu_table`` of (w, mu) points (w >= 0)."""

    def _mu(self, w_abs):
        tab = self._values.get("mu_table")
        if tab is None:
            return self._values["mu"], 0.0
        ws, mus = tab[:, 0], tab[:, 1]
        if len(ws) == 1:
            return float(mus[0]), 0.0
        k = int(np.clip(np.searchsorted(ws, w_abs, side="right") - 1, 0, len(ws) - 2))
        slope = (mus[k + 1] - mus[k]) / (ws[k + 1] - ws[k])
        if w_abs >= ws[-1]:
            return float(mus[-1]), 0.0
        if w_abs <= ws[0]:
            return float(mus[0]), 0.0
        return float(mus[k] + slope * (w_abs - ws[k])), float(slope)

    def validate(self):
        tab = self._values.get("mu_table")
        if tab is not None and (tab[0, 0] < 0 or np.any(tab[:, 1] < 0)):
            from ..errors import ParameterError
            raise ParameterError(f"{type(self).__name__} '{self.name}': mu_table needs w >= 0 and mu >= 0")
        if self._values.get("peak", 1.0) < 1.0:
            from ..errors import ParameterError
            raise ParameterError(f"{type(self).__name__} '{self.name}': parameter 'peak' must be >= 1 "
                                 f"(static over kinetic friction), got {self._values['peak']}")


class Clutch(_MuMixin, FrictionDevice):
    """Friction clutch (MSL Clutch): ``w_rel = w_b - w_a``, ``tau = flange_b.tau``,
    ``fn = fn_max * f_normalized(t)`` [N], kinetic torque ``mu(|w_rel|) cgeo fn``."""

    mu = Param(0.5, check="nonnegative", doc="kinetic friction coefficient (ignored with mu_table)")
    mu_table = Param(None, check="table", optional=True, doc="(w_rel [rad/s], mu) points for w_rel >= 0")
    peak = Param(1.0, check="positive", doc="static over kinetic friction at w = 0 (>= 1)")
    cgeo = Param(1.0, check="nonnegative", unit="m", doc="geometry constant (effective radius x surfaces)")
    fn_max = Param(check="nonnegative", unit="N", doc="maximum normal force")
    f_normalized = Param(1.0, check="signal", doc="normalised normal force in [0, 1]")
    flanges = (("flange_a", ROTATIONAL), ("flange_b", ROTATIONAL))

    def normal_force(self, t, left=False):
        return self.fn_max * self.f_normalized.value(t, left)

    def kinetic(self, w_abs, t, left=False):
        fn = max(self.normal_force(t, left), 0.0)
        mu, dmu = self._mu(w_abs)
        return mu * self.cgeo * fn, dmu * self.cgeo * fn


class OneWayClutch(Clutch):
    """One-way clutch (MSL OneWayClutch): a freewheel in parallel with a clutch, one
    constraint torque only. ``w_rel = w_b - w_a >= 0`` always: when ``w_rel`` reaches 0
    the freewheel locks (Stuck) and holds any negative torque; it releases forward when
    the holding torque exceeds ``peak * tau0`` (engaged) or a tiny threshold
    ``1e-4 * mu(0) * cgeo * fn_max`` (disengaged). Engaged (f_normalized > 0) and
    sliding, it transmits ``mu(w_rel) cgeo fn``; disengaged and sliding, nothing (Free).
    Start with ``w_rel >= 0``."""

    one_way = True
    EPS0 = 1e-4

    def capacities(self, t, left=False):
        tau0, tau0_max = super().capacities(t, left)
        if self.normal_force(t, left) <= 0:
            return 0.0, self.EPS0 * self._mu(0.0)[0] * self.cgeo * self.fn_max
        return tau0, max(self.peak, 1.0 + self.EPS0) * tau0


class Brake(Clutch):
    """Brake (MSL Brake): friction between ``flange`` and ``support`` (grounded when free);
    ``w_rel = w_flange - w_support``."""

    flanges = (("flange", ROTATIONAL), ("support", ROTATIONAL, True))

    def rows(self):
        return [{"support": -1.0, "flange": 1.0}]


class FrictionContact(_MuMixin, FrictionDevice):
    """Translational Coulomb contact between ``flange_a`` and ``flange_b`` (a Fixed
    for a contact with the ground): ``f = mu(|v_rel|) * fn(t)``, static ``peak`` times that."""

    mu = Param(0.5, check="nonnegative", doc="kinetic friction coefficient (ignored with mu_table)")
    mu_table = Param(None, check="table", optional=True, doc="(v_rel [m/s], mu) points for v_rel >= 0")
    peak = Param(1.0, check="positive", doc="static over kinetic friction")
    fn = Param(check="signal", unit="N", doc="normal force (number, signal or callable)")
    flanges = (("flange_a", TRANSLATIONAL), ("flange_b", TRANSLATIONAL))
    default_domain = TRANSLATIONAL

    def normal_force(self, t, left=False):
        return self.fn.value(t, left)

    def kinetic(self, w_abs, t, left=False):
        fn = max(self.normal_force(t, left), 0.0)
        mu, dmu = self._mu(w_abs)
        return mu * fn, dmu * fn


class BearingFriction(FrictionDevice):
    """Bearing friction (MSL BearingFriction) between ``flange`` and ``support``:
    kinetic torque from ``tau_table`` of (w [rad/s], tau [N m]) for w >= 0,
    break-away torque ``peak * tau_table(0)``."""

    tau_table = Param(check="table", doc="(w >= 0, friction torque) points")
    peak = Param(1.0, check="positive", doc="break-away over kinetic torque at w = 0")
    flanges = (("flange", ROTATIONAL), ("support", ROTATIONAL, True))

    def rows(self):
        return [{"support": -1.0, "flange": 1.0}]

    def kinetic(self, w_abs, t, left=False):
        tab = self.tau_table
        ws, ts = tab[:, 0], tab[:, 1]
        if len(ws) == 1 or w_abs <= ws[0]:
            return float(ts[0]), 0.0
        if w_abs >= ws[-1]:
            return float(ts[-1]), 0.0
        k = int(np.searchsorted(ws, w_abs, side="right") - 1)
        slope = (ts[k + 1] - ts[k]) / (ws[k + 1] - ws[k])
        return float(ts[k] + slope * (w_abs - ws[k])), float(slope)


class ChatterGuard:
    """Stops a run when one device changes mode ``count`` times within ``window`` seconds."""

    def __init__(self, window: float, count: int):
        self.window, self.count = window, count
        self.log: dict[str, list[float]] = {}

    def record(self, t: float, name: str) -> None:
        times = self.log.setdefault(name, [])
        times.append(t)
        while times and times[0] < t - self.window:
            times.pop(0)
        if len(times) >= self.count:
            raise ChatteringError(
                f"friction device '{name}' changed mode {len(times)} times within {self.window:g} s before "
                f"t={t:.9g} (chattering): the stick/slip logic cannot settle. Remedies: add damping or compliance "
                f"next to it (an elastic shaft), use peak > 1 (static above kinetic friction), or give the masses "
                f"on both sides realistic inertia.")


class FrictionSet:
    """All friction rows of a compiled system: residual rows, Jacobian weights,
    event functions and the mode logic."""

    def __init__(self, compiled, rows):
        self.c = compiled
        self.rows = rows
        self.devices = [r.device for r in rows]
        self.mf = len(rows)
        self.n_events = 2 * self.mf
        self.G = compiled.Gf
        self.offset = compiled.mp + compiled.mv   # first friction multiplier in lam
        self.engaged = np.ones(self.mf, bool)      # engagement at the start of the current segment

    # -- helpers --------------------------------------------------------------
    def _left(self, t):
        return t >= self.c._t_right

    def w_rel(self, v):
        return self.G @ v

    def initial_modes(self):
        return np.full(self.mf, FREE, dtype=int)

    def start_modes(self, t):
        return self.initial_modes()

    def known_forces(self, t, v, modes):
        """lam of sliding (+-tau_k) and free (0) devices; stuck entries are 0 here."""
        left = self._left(t)
        w = self.w_rel(v)
        out = np.zeros(self.mf)
        for j, dev in enumerate(self.devices):
            m = modes[j]
            if m in (FORWARD, BACKWARD):
                out[j] = m * dev.kinetic(abs(w[j]), t, left)[0]
        return out

    # -- DAE rows ---------------------------------------------------------------
    def residual_rows(self, t, v, a, lam_f, modes):
        left = self._left(t)
        w = self.w_rel(v)
        arel = self.G @ a
        out = np.empty(self.mf)
        for j, dev in enumerate(self.devices):
            m = modes[j]
            if m == STUCK:
                out[j] = arel[j]
            elif m == FREE:
                out[j] = lam_f[j]
            else:
                out[j] = lam_f[j] - m * dev.kinetic(abs(w[j]), t, left)[0]
        return out

    def add_pattern(self, pb, woff):
        """Register the friction rows' Jacobian entries; weights start at ``woff``.

        Weights per row j: [slide_j, cj*stuck_j, stuck_j, notstuck_j].
        """
        c = self.c
        G = self.G.tocoo()
        r = c.r_fric[G.row]
        self.woff = woff
        # d/dv (sliding law): -m * dtau_k/dw * sign(w) * G  (weight slide_j)
        pb.weighted(r, c.iv[G.col], G.data, woff + 4 * G.row + 0)
        dummy = c.is_dummy_v[G.col]
        pb.weighted(r[~dummy], c.iv[G.col[~dummy]], G.data[~dummy], woff + 4 * G.row[~dummy] + 1)
        pb.weighted(r[dummy], c.iad[c.pos_in_Dv[G.col[dummy]]], G.data[dummy], woff + 4 * G.row[dummy] + 2)
        j = np.arange(self.mf)
        pb.weighted(c.r_fric, c.ilam[self.offset + j], np.ones(self.mf), woff + 4 * j + 3)
        return 4 * self.mf

    def weights(self, t, v, cj, modes):
        left = self._left(t)
        w = self.w_rel(v)
        out = np.zeros(4 * self.mf)
        for j, dev in enumerate(self.devices):
            m = modes[j]
            if m == STUCK:
                out[4 * j + 1] = cj
                out[4 * j + 2] = 1.0
            else:
                out[4 * j + 3] = 1.0
                if m in (FORWARD, BACKWARD):
                    dk = dev.kinetic(abs(w[j]), t, left)[1]
                    out[4 * j] = -m * dk * np.sign(w[j])
        return out

    # -- events -------------------------------------------------------------------
    def event_values(self, t, y, yp, modes):
        """Two functions per device, each crossing zero *downwards* when its mode must change."""
        c = self.c
        left = self._left(t)
        v = y[c.iv]
        w = self.w_rel(v)
        lam = y[c.ilam[self.offset:]]
        out = np.empty(self.n_events)
        for j, dev in enumerate(self.devices):
            m = modes[j]
            fn = dev.normal_force(t, left)
            if m == STUCK:
                hold = lam[j] if dev.one_way else abs(lam[j])     # a freewheel holds any negative torque
                out[2 * j] = dev.capacities(t, left)[1] - hold
            elif m == FREE:
                out[2 * j] = w[j] if dev.one_way else 1.0         # a freewheeling one-way clutch locks at 0
            else:
                out[2 * j] = m * w[j]
            if not self.engaged[j]:
                # a normal force of exactly zero is 'not yet engaged': a tiny positive value keeps
                # IDA from deactivating a root function that is identically zero at the start
                out[2 * j + 1] = -fn if fn != 0.0 else 1e-300
            else:
                out[2 * j + 1] = fn
        return out

    # -- mode logic -----------------------------------------------------------------
    def settle(self, t, state, modes, crossed=None, initial=False):
        """Iterate the mode logic at time t to a consistent set; returns (y, yp, modes, changes)."""
        c = self.c
        left = False   # the new segment: right limits
        if state is None:
            y0, yp0 = c.initial_y(t, np.full(self.mf, FREE))
        else:
            y0, yp0 = state
        x, v, a, lam, z = c.unpack(y0, yp0)
        old = np.array(modes, dtype=int)
        new = old.copy()
        w = self.w_rel(v)
        arel = self.G @ a
        lam_rate = yp0[c.ilam[self.offset:]]        # d lam/dt at the event (IDA's interpolant)
        scale = 1e-9 * max(1.0, float(np.abs(v).max(initial=0.0)))
        crossed = np.zeros(self.n_events) if crossed is None else np.asarray(crossed)
        # 1. engagement and the crossings that were found
        for j, dev in enumerate(self.devices):
            engaged = dev.normal_force(t, left) > 0
            if dev.one_way:
                new[j] = self._one_way_step(dev, j, old[j], engaged, w[j], lam[self.offset + j],
                                            crossed[2 * j] != 0, initial, scale, t)
                continue
            if not engaged:
                new[j] = FREE
            elif initial or old[j] == FREE:
                new[j] = FORWARD if w[j] > 0 else BACKWARD if w[j] < 0 else STUCK
            elif old[j] in (FORWARD, BACKWARD) and (crossed[2 * j] != 0 or
                                                     (abs(w[j]) <= scale and w[j] * arel[j] < 0)):
                # found by the root finder, or within round-off of zero and still approaching it
                # (a device that has just broken away has w_rel ~ 0 too, but is leaving)
                new[j] = STUCK
            elif old[j] == STUCK and crossed[2 * j] != 0:
                # the root of tau0_max - |lam| was located (to round-off) on either side of zero:
                # the crossing itself decides, so the restart is where the condition has flipped
                new[j] = FORWARD if lam[self.offset + j] > 0 else BACKWARD
        # 2. stuck devices: holding torques of the whole stuck set from one KKT solve; every device
        #    beyond its tau0_max breaks away at once (as in one Modelica event iteration), then repeat
        for _ in range(4 * self.mf + 4):
            v = self._lock_velocities(t, x, v, new, old)
            a, lam, dz = c.accelerations(t, x, v, z, new)
            lam_f = lam[self.offset:]
            changed = False
            for j, dev in enumerate(self.devices):
                if new[j] != STUCK:
                    continue
                tau0, tau0_max = dev.capacities(t, left)
                # a load within round-off of the capacity and still rising breaks away with the others
                # (symmetric devices, e.g. two wheels on one open differential, reach it together)
                tie = 1e-9 * tau0_max
                if lam_f[j] > tau0_max * (1 + 1e-12) or (lam_f[j] > tau0_max - tie and lam_rate[j] > 0):
                    new[j] = FORWARD if (not dev.one_way or dev.normal_force(t, left) > 0) else FREE
                    changed = True
                elif (lam_f[j] < -tau0_max * (1 + 1e-12) or (lam_f[j] < -tau0_max + tie and lam_rate[j] < 0)) \
                        and not dev.one_way:
                    new[j] = BACKWARD
                    changed = True
            if not changed:
                break
        else:
            raise SimulationError(f"stick/slip logic did not settle at t={t:.9g} for "
                                  f"{[d.name for d in self.devices]}")
        y, yp = c.assemble_y(t, x, v, z, new)
        self.engaged = np.array([d.normal_force(t, False) > 0 for d in self.devices])
        changes = [(self.devices[j].name, int(old[j]), int(new[j])) for j in range(self.mf)
                   if old[j] != new[j] and not initial]
        return y, yp, new, changes

    @staticmethod
    def _one_way_step(dev, j, old, engaged, w, lam, crossed, initial, scale, t):
        """First step of the mode logic for a one-way clutch (no Backward mode)."""
        slide = FORWARD if engaged else FREE
        if initial:
            if w < -scale:
                raise SimulationError(
                    f"OneWayClutch '{dev.name}' starts with w_rel = {w:.6g} < 0, which a freewheel cannot "
                    f"have; give start speeds with w(flange_b) >= w(flange_a)")
            return slide if w > scale else STUCK
        if old == STUCK:
            return (FORWARD if engaged else FREE) if crossed else STUCK
        if crossed or abs(w) <= scale:
            return STUCK
        return slide

    def _lock_velocities(self, t, x, v, new, old):
        """Make w_rel exactly zero for devices that are (or were) stuck: a mass-weighted
        (impulse) projection, so momentum is conserved."""
        lock = (new == STUCK) | (old == STUCK)
        if not lock.any():
            return v
        w = self.w_rel(v)
        if np.all(w[lock] == 0.0):
            return v
        c = self.c
        fixed = np.full(c.n, np.nan)
        _, v2 = c.project(t, x, v, None, None, np.where(lock, STUCK, FREE))
        return v2

    def singular_message(self, modes):
        stuck = [self.devices[j] for j in range(self.mf) if modes[j] == STUCK]
        names = ", ".join(f"{type(d).__name__} '{d.name}'" for d in stuck)
        return (f"the stuck friction devices {names} lock the same rigid group more than once, so their holding "
                f"torques are not unique (singular system). Remedy: put a compliance (an elastic Shaft) between "
                f"them, or merge them into one device.")

    def chatter_guard(self, window=None, count=50):
        return ChatterGuard(1e-6 if window is None else window, count)
