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
Held        3    ``lam = 0``   (zero relative speed kept by other stuck
                               devices: ``FrictionSet._share_redundant``)
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

from ..component import Device, Param, read_only
from ..errors import ChatteringError, SimulationError, StructureError
from ..ports import ROTATIONAL, TRANSLATIONAL

BACKWARD, STUCK, FORWARD, FREE, HELD = -1, 0, 1, 2, 3


class FrictionDevice(Device):
    """Base class: subclasses define ``kinetic(w_abs, t, left)`` and ``engaged``."""

    kind = "friction"
    one_way = False   # True: only w_rel >= 0 (freewheel); no Backward mode
    coupled = False   # True: the row's force is tied to the device's own rigid row (LossyGear)

    def relation(self, mode, quadrant, w_abs, t, left=False):
        """Equation of a non-stuck row: ``c_own lam + c_cpl lam_cpl = rhs``; returns
        (c_own, c_cpl, rhs, d rhs / d|w_rel|)."""
        if mode == FREE or mode == HELD:
            return 1.0, 0.0, 0.0, 0.0
        tk, dk = self.kinetic(w_abs, t, left)
        return 1.0, 0.0, mode * tk, mode * dk

    def kinetic(self, w_abs: float, t: float, left: bool = False) -> tuple[float, float]:
        """Kinetic capacity at relative speed ``w_abs`` >= 0 and its derivative d/dw."""
        raise NotImplementedError

    def normal_force(self, t: float, left: bool = False) -> float:
        """Engagement measure: the device is Free when this is <= 0."""
        return 1.0

    def peak_ratio(self) -> float:
        return self._values.get("peak", 1.0)

    def capacity_function(self):
        """A fast closure ``(t, left) -> (fn, tau0, tau0_max)`` with the parameters bound
        (the event functions call it at every root-finding iterate)."""
        def at(t, left=False):
            tau0, tau0_max = self.capacities(t, left)
            return self.normal_force(t, left), tau0, tau0_max
        return at

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
    ``fn = fn_max * f_normalized(t)`` [N], kinetic torque ``mu(|w_rel|) cgeo fn``.

    ``f_normalized`` <= 1; values <= 0 disengage the clutch (mode Free), as in
    MSL, whose own CoupledClutches drives it with a sine down to -1. A value
    above 1 (beyond round-off) is refused: raise ``fn_max`` instead."""

    mu = Param(0.5, check="nonnegative", doc="kinetic friction coefficient (ignored with mu_table)")
    mu_table = Param(None, check="table", optional=True, doc="(w_rel [rad/s], mu) points for w_rel >= 0")
    peak = Param(1.0, check="positive", doc="static over kinetic friction at w = 0 (>= 1)")
    cgeo = Param(1.0, check="nonnegative", unit="m", doc="geometry constant (effective radius x surfaces)")
    fn_max = Param(check="nonnegative", unit="N", doc="maximum normal force")
    f_normalized = Param(1.0, check="signal", bounds=(None, 1.0),
                         doc="normalised normal force, <= 1 (<= 0: disengaged)",
                         bounds_note="; the normal force is fn_max * f_normalized, so 1 is the full force fn_max and "
                                     "values <= 0 disengage the device (mode Free). Raise fn_max for a larger force")
    flanges = (("flange_a", ROTATIONAL), ("flange_b", ROTATIONAL))

    def normal_force(self, t, left=False):
        return self.fn_max * self.f_normalized.value(t, left)

    def kinetic(self, w_abs, t, left=False):
        fn = max(self.normal_force(t, left), 0.0)
        mu, dmu = self._mu(w_abs)
        return mu * self.cgeo * fn, dmu * self.cgeo * fn

    def capacity_function(self):
        sig, fn_max, k0, peak = self.f_normalized, self.fn_max, self._mu(0.0)[0] * self.cgeo, self.peak

        def at(t, left=False):
            fn = fn_max * sig.value(t, left)
            tau0 = k0 * fn if fn > 0 else 0.0
            return fn, tau0, peak * tau0
        return at


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

    def capacity_function(self):
        return FrictionDevice.capacity_function(self)


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


class LossyGear(FrictionDevice):
    """Gear with mesh efficiency and bearing friction, stuck or rolling (MSL LossyGear).

    Kinematics ``phi_a - phi_s = ratio (phi_b - phi_s)`` (a rigid row, mesh force
    ``lam_g``) and a friction row on ``w_a = w_flange_a - w_support`` whose force is
    the loss torque ``tau_loss`` acting at flange_a: ``flange_a.tau = lam_g + tau_loss =
    tau_a``, ``flange_b.tau = -ratio (tau_a - tau_loss)``.

    ``loss_table`` rows ``(|w_a|, eta_mf1, eta_mf2, |tau_bf1|, |tau_bf2|)``: mesh
    efficiency when flange_a drives (1) or flange_b drives (2), and the resultant
    bearing friction with respect to flange_a. Rolling forward (``w_a > 0``):
    ``tau_loss = (1 - eta_mf1) tau_a + tau_bf1`` when ``tau_eta = tau_a - tau_bf_a >= 0``
    (flange_a drives) else ``(1 - 1/eta_mf2) tau_a + tau_bf2``; backward mirrored.
    Since ``tau_a`` contains ``tau_loss`` the row is linear in both multipliers. Stuck
    (``w_a = 0``): the loss torque holds the gear while it lies between the values at
    ``w = 0+`` and ``0-``; beyond them it starts rolling. The driving side changes at
    an event where ``tau_eta`` crosses zero (``res.events``: kind "driving side", see
    ``FrictionSet._fix_quadrant`` for how the side is decided). An ideal table ``[[0, 1, 1, 0, 0]]``
    keeps the gear in mode Free (``tau_loss = 0``).
    """

    coupled = True
    ratio = Param(check="nonzero", doc="transmission ratio phi_a/phi_b")
    loss_table = Param([[0.0, 1.0, 1.0, 0.0, 0.0]], check="any", doc="(|w_a|, eta_mf1, eta_mf2, tau_bf1, tau_bf2) rows")
    flanges = (("flange_a", ROTATIONAL), ("flange_b", ROTATIONAL), ("support", ROTATIONAL, True))
    rel_names = {ROTATIONAL: (None, None, None, None)}

    def validate(self):
        from ..errors import ParameterError
        try:
            tab = np.atleast_2d(np.asarray(self._values["loss_table"], dtype=float))
        except (TypeError, ValueError):
            tab = None
        if tab is None or tab.ndim != 2 or tab.shape[1] != 5 or not np.all(np.isfinite(tab)):
            raise ParameterError(f"LossyGear '{self.name}': loss_table must be rows (|w_a|, eta_mf1, eta_mf2, "
                                 f"tau_bf1, tau_bf2), got {self._values['loss_table']!r}")
        if np.any(tab[:, 1:3] <= 0) or np.any(tab[:, 1:3] > 1) or np.any(np.diff(tab[:, 0]) <= 0) or tab[0, 0] < 0:
            raise ParameterError(f"LossyGear '{self.name}': efficiencies must lie in (0, 1] and speeds increase from >= 0")
        tab = read_only(tab)                 # the validated table, not the caller's (editable) array
        self._values["loss_table"] = tab
        self._table = tab
        self._ideal = bool(np.allclose(tab, [[0.0, 1.0, 1.0, 0.0, 0.0]], rtol=0, atol=1e-15) and len(tab) == 1)
        self._zero = self._interp(0.0)

    def rows(self):
        r = self.ratio
        return [{"flange_a": 1.0, "flange_b": -r, "support": r - 1.0}, {"flange_a": 1.0, "support": -1.0}]

    def capacity_function(self):
        # no normal force; its limits depend on the mesh force (see event_pair / breakaway)
        return lambda t, left=False: (1.0, 0.0, 0.0)

    def row_kinds(self):
        return ["rigid", "friction"]

    def _interp(self, w_abs):
        tab = self._table
        eta1, eta2, bf1, bf2 = (float(np.interp(w_abs, tab[:, 0], tab[:, k])) for k in range(1, 5))
        bf1, bf2 = abs(bf1), abs(bf2)
        if abs(eta1 - 1.0) < 1e-15 and abs(eta2 - 1.0) < 1e-15:
            bf_a = bf1 / 2.0        # the split between the sides is arbitrary (MSL does the same)
        else:
            bf_a = (bf1 - bf2) / (eta1 - 1.0 / eta2)
        return eta1, eta2, bf1, bf2, bf_a

    @staticmethod
    def _quadrant_loss(mode, q, coeffs):
        """tau_loss = k * tau_a + b for rolling ``mode`` and driving side ``q``."""
        eta1, eta2, bf1, bf2, _ = coeffs
        if mode == FORWARD:
            return (1.0 - eta1, bf1) if q > 0 else (1.0 - 1.0 / eta2, bf2)
        return (1.0 - 1.0 / eta2, -bf2) if q > 0 else (1.0 - eta1, -bf1)

    def relation(self, mode, quadrant, w_abs, t, left=False):
        if mode == FREE or mode == HELD:
            return 1.0, 0.0, 0.0, 0.0
        k, b = self._quadrant_loss(mode, quadrant, self._interp(w_abs))
        # tau_loss = k (lam_g + tau_loss) + b  ->  (1 - k) tau_loss - k lam_g = b
        return 1.0 - k, -k, b, 0.0

    def _limits(self, sa, lam_g):
        """(tauLossMax_p, tauLossMin_m): the loss torque the gear can hold at w = 0."""
        eta1, eta2, bf1, bf2, bf_a = self._zero
        tau_a = lam_g + sa
        hi = (1 - eta1) * tau_a + bf1 if tau_a - bf_a > 0 else (1 - 1 / eta2) * tau_a + bf2
        lo = (1 - 1 / eta2) * tau_a - bf2 if tau_a + bf_a > 0 else (1 - eta1) * tau_a - bf1
        return hi, lo

    def breakaway(self, sa, lam_g):
        hi, lo = self._limits(sa, lam_g)
        scale = 1e-12 * max(1.0, abs(sa), abs(lam_g))
        if sa > hi + scale:
            return FORWARD
        if sa < lo - scale:
            return BACKWARD
        return 0

    def tau_eta(self, mode, w_abs, tau_loss, lam_g):
        """``tau_eta`` [N m] of a rolling gear: ``tau_a - tau_bf_a`` forward, ``tau_a + tau_bf_a``
        backward, with ``tau_bf_a`` at the current speed ``w_abs`` (the torque at which the two
        loss laws of the direction give the same loss). Its sign is the quadrant (``relation``)."""
        bf_a = self._interp(w_abs)[4]
        tau_a = lam_g + tau_loss
        return tau_a - bf_a if mode == FORWARD else tau_a + bf_a

    @staticmethod
    def driving_flange(mode, quadrant):
        """+1 when flange_a drives (power flows from flange_a through the gear to flange_b), -1 when
        flange_b drives: forward, quadrant +1 is the efficiency eta_mf1 (flange_a drives); backward,
        quadrant +1 is eta_mf2 (flange_b drives)."""
        return int(mode) * int(quadrant)

    def event_pair(self, mode, quadrant, w, tau_loss, lam_g, t, left):
        if mode == FREE or mode == HELD:
            return 1.0, 1.0
        if mode == STUCK:
            hi, lo = self._limits(tau_loss, lam_g)
            return hi - tau_loss, tau_loss - lo
        return mode * w, quadrant * self.tau_eta(mode, abs(w), tau_loss, lam_g)

    def first_step(self, old, w, crossed1, crossed2, initial, scale, arel):
        if self._ideal:
            return FREE
        if initial or old == FREE or old == HELD:
            return FORWARD if w > scale else BACKWARD if w < -scale else STUCK
        if old == STUCK:
            return FORWARD if crossed1 else BACKWARD if crossed2 else STUCK
        # found by the root finder, or within round-off of zero and still approaching it, or already
        # past it by round-off (another device's root, located on the far side, at the same instant)
        if crossed1 or (abs(w) <= scale and (w * arel < 0 or old * w < 0)):
            return STUCK
        return old


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
    event functions and the mode logic.

    Row j's equation when not stuck is linear in the multipliers:
    ``c_own lam_j + c_cpl lam_cpl(j) = rhs(w_rel, t)`` (``relation``): a clutch
    has ``lam_j = mode * tau_k(|w_rel|)``; a lossy gear couples its loss torque
    to its own mesh-force row ``cpl(j)``.
    """

    def __init__(self, compiled, rows):
        self.c = compiled
        self.rows = rows
        self.devices = [r.device for r in rows]
        self.mf = len(rows)
        self.n_events = 2 * self.mf
        self.G = compiled.Gf
        self.offset = compiled.mp + compiled.mv   # first friction multiplier in lam
        self.engaged = np.ones(self.mf, bool)      # engagement at the start of the current segment
        self.quadrant = np.ones(self.mf, int)      # driving side of lossy gears in the current segment
        cons = compiled.structure.position + compiled.structure.speed
        index = {id(r): i for i, r in enumerate(cons)}
        self.coupled = np.array([index[id(compiled.structure.rows[d.name][0])] if d.coupled else -1
                                 for d in self.devices], dtype=int)

        # dense copy of G for the small matrices of typical drivetrains (sparse matvec costs ~10 us)
        self._Gd = self.G.toarray() if self.G.shape[0] * self.G.shape[1] <= 40000 else None
        self._at_key, self._at_val = None, None
        self._cap_fns = [d.capacity_function() for d in self.devices]
        self._one_way = np.array([d.one_way for d in self.devices], bool)
        self._ev_key, self._ev_masks = None, None
        self._coupled_rows = [j for j, d in enumerate(self.devices) if d.coupled]
        self._small = None
        self._relief = []      # (row, holder's lam index, sign, tol): see _relief_events
        if self.mf <= 8 and not self._coupled_rows:
            Gc = self.G.tocsr()
            c = compiled
            self._small = [([int(c.iv[k]) for k in Gc.indices[Gc.indptr[j]:Gc.indptr[j + 1]]],
                            [float(x) for x in Gc.data[Gc.indptr[j]:Gc.indptr[j + 1]]],
                            int(c.ilam[self.offset + j]), bool(self._one_way[j]), self._cap_fns[j])
                           for j in range(self.mf)]
            self._ev_out = np.empty(self.n_events)

    # -- pickling: the capacity functions are closures; they are made again from the devices ---------
    def __getstate__(self):
        state = self.__dict__.copy()
        state["_cap_fns"] = None
        if self._small is not None:
            state["_small"] = [row[:-1] for row in self._small]      # the last entry is the capacity function
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._cap_fns = [d.capacity_function() for d in self.devices]
        if self._small is not None:
            self._small = [(*row, fn) for row, fn in zip(self._small, self._cap_fns)]

    # -- helpers --------------------------------------------------------------
    def _left(self, t):
        return t >= self.c._t_right

    def w_rel(self, v):
        return self._Gd @ v if self._Gd is not None else self.G @ v

    def _at(self, t, left):
        """Normal forces and (tau0, tau0_max) of every device at t, cached for the last t
        (IDA evaluates residual and event functions at the same instants)."""
        key = (t, left)
        if self._at_key != key:
            vals = np.array([f(t, left) for f in self._cap_fns]).reshape(self.mf, 3)
            self._at_key, self._at_val = key, (vals[:, 0], vals[:, 1:])
        return self._at_val

    def initial_modes(self):
        return np.full(self.mf, FREE, dtype=int)

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
        self.woff = woff
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

    def _event_values_small(self, t, left, y, modes):
        """The same functions in plain Python for a few devices without lossy gears: IDA calls them
        several times per step, and for three clutches numpy's per-call overhead dominates."""
        out = self._ev_out
        for j, (cols, coefs, il, one_way, cap_fn) in enumerate(self._small):
            m = modes[j]
            fn, tau0, tau0_max = cap_fn(t, left)
            if m == STUCK:
                lam = y[il]
                out[2 * j] = tau0_max - (lam if one_way else abs(lam))
            else:
                w = 0.0
                for k, cf in zip(cols, coefs):
                    w += cf * y[k]
                if m == FREE:
                    out[2 * j] = w if one_way else 1.0
                elif m == HELD:
                    out[2 * j] = 1.0
                else:
                    g = m * w
                    out[2 * j] = g if g != 0.0 else 1e-300
            out[2 * j + 1] = fn if self.engaged[j] else (-fn if fn != 0.0 else 1e-300)
        for j, il, sign, tol in self._relief:
            out[2 * j] = modes[j] * sign * y[il] + tol
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

    # -- events -------------------------------------------------------------------
    def event_values(self, t, y, yp, modes):
        """Two functions per device, each crossing zero *downwards* when its mode must change:

        * stuck: ``tau0_max - |lam|`` (a freewheel: ``tau0_max - lam``, it holds any negative torque);
        * sliding: ``mode * w_rel``; free: 1 (a freewheeling one-way clutch: ``w_rel``, it locks at 0);
          held: 1 (the holders' functions decide);
        * sliding at zero speed while other devices hold the motion (``_relief_events``):
          ``mode * s * lam_holder + tol``, crossing when the holder starts to resist this
          device's kinetic torque instead of sharing the load with it;
        * engagement: ``fn`` while engaged, ``-fn`` while not (a normal force of exactly zero
          is 'not yet engaged': a tiny positive value keeps IDA from deactivating a root
          function that is identically zero at the start).

        Vectorised over the devices; lossy gears give their own pair.
        """
        c = self.c
        left = t >= c._t_right
        if self._small is not None:
            return self._event_values_small(t, left, y, modes)
        w = self.w_rel(y[c.iv])
        lam_all = y[c.ilam]
        lam = lam_all[self.offset:]
        modes = np.asarray(modes)
        fns, caps = self._at(t, left)
        # masks depend on the segment's modes only: computed once per segment
        key = (modes.tobytes(), self.engaged.tobytes())
        if self._ev_key != key:
            stuck = modes == STUCK
            free = modes == FREE
            held = modes == HELD
            slide = ~stuck & ~free & ~held
            self._ev_masks = (stuck, stuck & self._one_way, stuck & ~self._one_way, free & self._one_way,
                              (free & ~self._one_way) | held, slide, np.where(slide, modes, 0))
            self._ev_key = key
        stuck, st_ow, st_2w, fr_ow, fr_2w, slide, sign = self._ev_masks
        first = sign * w
        # a device sliding at exactly zero speed (held by another one, see _share_redundant): a tiny
        # positive value keeps IDA from deactivating a root function identically zero at the start
        first[slide & (first == 0.0)] = 1e-300
        first[st_ow] = caps[st_ow, 1] - lam[st_ow]
        first[st_2w] = caps[st_2w, 1] - np.abs(lam[st_2w])
        first[fr_ow] = w[fr_ow]
        first[fr_2w] = 1.0
        second = fns.copy()
        off = ~self.engaged
        second[off] = np.where(fns[off] != 0.0, -fns[off], 1e-300)
        out = np.empty(self.n_events)
        out[0::2], out[1::2] = first, second
        for j in self._coupled_rows:
            out[2 * j], out[2 * j + 1] = self.devices[j].event_pair(
                int(modes[j]), int(self.quadrant[j]), w[j], lam[j], lam_all[self.coupled[j]], t, left)
        for j, il, sign, tol in self._relief:
            out[2 * j] = modes[j] * sign * y[il] + tol
        return out

    # -- mode logic -----------------------------------------------------------------
    def settle(self, t, state, modes, crossed=None, initial=False):
        """Iterate the mode logic at time t to a consistent set; returns (y, yp, modes, changes).

        ``changes``: ``(device name, old, new, kind)`` per change, ``kind`` "mode" (old and new
        mode) or "driving side" (a lossy gear rolling on with power now flowing the other way;
        old and new are the driving flange, ``LossyGear.driving_flange``).
        """
        c = self.c
        if initial:
            self.quadrant[:] = 1      # a fresh start decides the driving sides from the state alone
        side_old = [d.driving_flange(m0, q) if d.coupled else 0
                    for d, m0, q in zip(self.devices, np.asarray(modes, dtype=int), self.quadrant)]
        left = False   # the new segment: right limits
        if state is None:
            y0, yp0 = c.initial_y(t, np.full(self.mf, FREE))
        else:
            y0, yp0 = state
        x, v, a, lam, z = c.unpack(y0, yp0)
        old = np.array(modes, dtype=int)
        new = old.copy()
        w = self.w_rel(v)
        arel = self.w_rel(a)
        lam_rate = yp0[c.ilam[self.offset:]]        # d lam/dt at the event (IDA's interpolant)
        scale = 1e-9 * max(1.0, float(np.abs(v).max(initial=0.0)))
        crossed = np.zeros(self.n_events) if crossed is None else np.asarray(crossed)
        # devices sliding at zero speed while another one holds the motion (see _relief_events):
        # their speed is zero by the holder's constraint, so its round-off sign says nothing;
        # only their relief event (or an event of the holder, below) changes them
        for j, *_ in ([] if initial else self._relief):
            w[j] = 0.0
        # 1. engagement and the crossings that were found
        for j, dev in enumerate(self.devices):
            engaged = dev.normal_force(t, left) > 0
            if dev.coupled:
                new[j] = dev.first_step(int(old[j]), w[j], crossed[2 * j] != 0, crossed[2 * j + 1] != 0,
                                        initial, scale, arel[j])
                if old[j] in (FORWARD, BACKWARD) and new[j] == old[j] and crossed[2 * j + 1] != 0:
                    self.quadrant[j] = -self.quadrant[j]   # the driving side changed (checked in step 2)
                continue
            if dev.one_way:
                new[j] = self._one_way_step(dev, j, old[j], engaged, w[j], lam[self.offset + j],
                                            crossed[2 * j] != 0, initial, scale, t)
                continue
            if not engaged:
                new[j] = FREE
            elif initial or old[j] == FREE:
                new[j] = FORWARD if w[j] > 0 else BACKWARD if w[j] < 0 else STUCK
            elif old[j] == HELD:
                # its holders kept it at zero speed (to round-off): it holds again unless it has moved
                new[j] = FORWARD if w[j] > scale else BACKWARD if w[j] < -scale else STUCK
            elif old[j] in (FORWARD, BACKWARD) and (crossed[2 * j] != 0 or
                                                     (abs(w[j]) <= scale and
                                                      (w[j] * arel[j] < 0 or old[j] * w[j] < 0))):
                # found by the root finder, or within round-off of zero and still approaching it, or
                # already past it by round-off (several devices reaching zero slip at one instant;
                # a device that has just broken away has w_rel ~ 0 too, but on its own side, leaving)
                new[j] = STUCK
            elif old[j] == STUCK and crossed[2 * j] != 0:
                # the root of tau0_max - |lam| was located (to round-off) on either side of zero:
                # the crossing itself decides, so the restart is where the condition has flipped
                new[j] = FORWARD if lam[self.offset + j] > 0 else BACKWARD
        self._flips = set()
        # 2. stuck devices: holding torques of the whole stuck set from one KKT solve; every device
        #    beyond its tau0_max breaks away at once (as in one Modelica event iteration), then repeat
        for _ in range(4 * self.mf + 4):
            v = self._lock_velocities(t, x, v, new, old)
            try:
                a, lam, dz = c.accelerations(t, x, v, z, new)
            except StructureError:
                if not self._share_redundant(t, x, v, z, new):
                    raise
                continue
            lam_f = lam[self.offset:]
            changed = False
            for j, dev in enumerate(self.devices):
                if dev.coupled:
                    if new[j] == STUCK:
                        d = dev.breakaway(lam_f[j], lam[self.coupled[j]])
                        if d:
                            new[j] = d
                            changed = True
                    elif new[j] in (FORWARD, BACKWARD) and \
                            self._fix_quadrant(j, dev, new, t, x, v, z, a, lam, dz):
                        changed = True
                    continue
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
            # a holder let go: the devices it held (Held, at zero speed) hold again, and the
            # rule of _share_redundant decides among them on the next pass
            new[new == HELD] = STUCK
        else:
            raise SimulationError(f"stick/slip logic did not settle at t={t:.9g} for "
                                  f"{[d.name for d in self.devices]}")
        y, yp = self._assemble_restart(t, x, v, z, new, lam)
        self._relief = self._relief_events(t, y, yp, new, scale)
        self._ev_key = None
        self.engaged = np.array([d.normal_force(t, False) > 0 for d in self.devices])
        changes = []
        if not initial:
            for j, dev in enumerate(self.devices):
                if old[j] != new[j]:
                    changes.append((dev.name, int(old[j]), int(new[j]), "mode"))
                if dev.coupled and old[j] in (FORWARD, BACKWARD) and new[j] in (FORWARD, BACKWARD):
                    side = dev.driving_flange(new[j], self.quadrant[j])
                    if side != side_old[j]:
                        changes.append((dev.name, side_old[j], side, "driving side"))
        return y, yp, new, changes

    def _assemble_restart(self, t, x, v, z, modes, lam):
        """Consistent ``(y, y')`` of the settled modes.

        A lossy gear whose driving side was decided at a tie (``_fix_quadrant``: by where the
        torque goes) may have ``tau_eta`` a round-off on the other side. IDA's residual takes the
        law by the sign of ``tau_eta`` (``_iterate_quadrants``), so the restart values are
        assembled with that law: they then satisfy the residual to round-off (with the segment's
        law they missed it by up to 1e-9 of the torques, and IDA at rtol 1e-10 failed its error
        test at the restart). Both laws agree there to that round-off; the segment keeps its
        quadrant for the event functions.
        """
        c = self.c
        if not self._coupled_rows:
            return c.assemble_y(t, x, v, z, modes)
        keep = self.quadrant.copy()
        self.quadrant = self._iterate_quadrants(v, lam, modes).copy()
        try:
            return c.assemble_y(t, x, v, z, modes)
        finally:
            self.quadrant = keep

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

    def _relief_events(self, t, y, yp, modes, scale):
        """Event rows for devices sliding at zero speed while one stuck device holds their motion.

        Such a device (a holder that passed its capacity, see ``_share_redundant``) acts with
        its kinetic torque ``lam_j = mode_j tau_k`` and the holder ``h`` carries the rest. With
        a virtual motion ``dv`` that keeps the rigid constraints and the other stuck devices and
        moves the holder by ``G_h dv = 1``, the device moves by ``c = G_j dv``: the holder's torque
        acts on the device's coordinate as ``lam_h / c``. Sharing means both resist in the same
        direction, ``mode_j sign(c) lam_h >= 0``; the event function is that product plus a
        tolerance (1e-9 of the device's torque, so that it starts positive when the holder's
        share starts at zero) and crosses zero when the load has fallen below the device's
        kinetic torque: the device then sticks again. With several holders of one motion no
        function is set (the device stays sliding until its own speed leaves zero).
        """
        c = self.c
        x, v, a, lam_all, _ = c.unpack(y, yp)
        w = self.w_rel(v)
        arel = self.w_rel(a)
        lam = lam_all[self.offset:]
        # a device that has just broken away also has w_rel ~ 0, but it accelerates; only one whose
        # relative acceleration is zero as well can be held (the rank tests below are dense: keep them rare)
        a_tol = 1e-9 * max(1.0, float(np.abs(a).max(initial=0.0)))
        sliding = [j for j in range(self.mf)
                   if modes[j] in (FORWARD, BACKWARD) and abs(w[j]) <= scale and abs(arel[j]) <= a_tol]
        stuck = [int(h) for h in np.nonzero(np.asarray(modes) == STUCK)[0]]
        if not sliding or not stuck:
            return []
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
            if len(holders) != 1:
                continue
            h = holders[0]
            others = [k for k in stuck if k != h]
            A = np.vstack([rigid] + [G[k][None, :] for k in others] + [G[h][None, :]])
            rhs = np.zeros(A.shape[0])
            rhs[-1] = 1.0
            dv = np.linalg.lstsq(A, rhs, rcond=None)[0]
            cj = float(G[j] @ dv)
            if abs(cj) < 1e-12:
                continue
            tol = 1e-9 * max(1.0, abs(float(lam[j])))
            out.append((j, int(c.ilam[self.offset + h]), float(np.sign(cj)), tol))
        return out

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

    @staticmethod
    def _one_way_step(dev, j, old, engaged, w, lam, crossed, initial, scale, t):
        """First step of the mode logic for a one-way clutch (no Backward mode)."""
        slide = FORWARD if engaged else FREE
        if old == HELD:
            return STUCK if abs(w) <= scale else slide
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
                f"them, or merge them into one device (in linearize(modes=...): give all but one of them 'held').")

    def chatter_guard(self, window=None, count=50):
        return ChatterGuard(1e-6 if window is None else window, count)
