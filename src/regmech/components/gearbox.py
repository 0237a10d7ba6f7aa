"""Stepped transmissions: ``Gearbox`` and ``DualClutchTransmission``.

Both are *macros* (``Subsystem``): they expand to ``Inertia``, ``IdealGear`` or
``LossyGear`` and ``Clutch`` parts with names a user can read in the results,
so the equations are those of the hand-built box and keep one structure in
every gear and during every shift (the shift elements switch modes, nothing
else changes).

``Gearbox`` (a power-shift or automated box, shift elements on the output
shaft)::

    flange_a ── input (J_in) ══ gear1 (ratio r1) ══ idler1 (J_gear) ── shift1 ──┐
                            ║                                                   │
                            ╚══ gear2 (ratio r2) ══ idler2 (J_gear) ── shift2 ──┼── output (J_out) ── flange_b
                            ...                                                  │

Each gear mesh ``gear<k>`` is rigid (``phi_input = r_k phi_idler_k``, or a
``LossyGear`` with the mesh efficiency ``eta_k`` in both directions of power
flow); its idler gear ``idler<k>`` is a real inertia, so each shift element
``shift<k>`` (a ``Clutch``) has a mass on both sides in every state
(regularity rule 3): it slips or locks with its own capacity, and only the
engaged one carries torque.

A shift from gear i to gear j at the command time ``t_s`` (the
``gear`` signal changes there) is::

    shift<i>: f_normalized 1 -> 0 over [t_s, t_s + release_time]          (torque interruption)
    shift<j>: f_normalized 0 -> 1 over [t_s + delay, t_s + delay + engage_time]
    (delay = shift_delay, default release_time: the new element starts when the old one is open)

so the output torque falls to zero while no element is engaged, the new element then engages
slipping (kinetic torque ``capacity_j * f_normalized``, the input speed is pulled towards
``r_j w_out``) and locks up when the slip reaches zero. A ``shift_delay`` shorter than
``release_time`` overlaps the two (a clutch-to-clutch power shift with less interruption).
Gear 0 is neutral (every element open).

Kinematics: ``w_in = r_k w_out`` in gear k (locked), power ``tau_in w_in = tau_out w_out`` with
ideal meshes and ``P_out = eta_k P_in`` with efficiency ``eta_k`` when the input drives.
"""

from __future__ import annotations

import math

import numpy as np

from .._numbers import as_real
from ..component import Param, StateRead, Subsystem
from ..errors import ParameterError
from ..signals import Signal, Table
from .friction import Clutch, LossyGear
from .gears import IdealGear
from .inertial import Inertia

#: segments of a gear signal sampled to make sure it is piecewise constant (see ``gear_schedule``)
_SAMPLES = (0.25, 0.5, 0.75)


def _where(comp) -> str:
    return f"{type(comp).__name__} '{comp.name}'"


def per_gear(comp, pname: str, value, n: int, check: str) -> list[float]:
    """``value`` (a number or a list of n numbers) as n floats, each ``check``ed ("positive",
    "nonnegative", "nonzero", "efficiency"); a ParameterError naming the parameter otherwise."""
    if isinstance(value, (list, tuple, np.ndarray)):
        vals = list(value)
        if len(vals) != n:
            raise ParameterError(f"{_where(comp)}: parameter '{pname}' has {len(vals)} entries for {n} gears; "
                                 f"give one value per gear (or one number for all)")
    else:
        vals = [value] * n
    out = []
    for k, v in enumerate(vals):
        x = as_real(v)
        ok = x is not None and math.isfinite(x) and {
            "positive": lambda: x > 0, "nonnegative": lambda: x >= 0, "nonzero": lambda: x != 0,
            "efficiency": lambda: 0 < x <= 1}[check]()
        if not ok:
            want = {"positive": "a finite number > 0", "nonnegative": "a finite number >= 0",
                    "nonzero": "a finite non-zero number", "efficiency": "a number in (0, 1]"}[check]
            raise ParameterError(f"{_where(comp)}: parameter '{pname}' for gear {k + 1} must be {want}, got {v!r}")
        out.append(float(x))
    return out


def gear_schedule(comp, gear, n: int) -> list[tuple[float, int]]:
    """The gear selection as a list of (t, gear) with increasing times, gear in 0..n (0 neutral).

    ``gear``: an int (fixed gear), a list of (t, gear) pairs (the gear selected from t on; the
    first pair may be at any t <= its successors and the gear before it is the first pair's), or a
    piecewise-constant ``Signal`` (``Step``, a ``Table`` with repeated times): its breakpoints are the
    shift commands. A callable has no known breakpoints and is refused (give the schedule)."""
    where = _where(comp)
    if isinstance(gear, (bool, np.bool_)):
        raise ParameterError(f"{where}: parameter 'gear' must be a gear number, a list of (t, gear) or a "
                             f"piecewise-constant signal, got {gear!r}")
    if isinstance(gear, Signal):
        try:
            times = [t for t in gear.breakpoints(0.0, math.inf) if math.isfinite(t) and t > 0]
        except ParameterError:
            raise ParameterError(f"{where}: the gear signal {gear!r} switches without end (its breakpoints need a "
                                 f"finite time range); give the shifts as a list of (t, gear) pairs or a Table "
                                 f"with repeated times") from None
        if len(times) > 10_000:
            raise ParameterError(f"{where}: the gear signal has {len(times)} breakpoints; give a schedule")
        edges = [0.0] + sorted(times)
        pairs = [(0.0, gear.value(0.0))]
        for k, t0 in enumerate(edges):
            t1 = edges[k + 1] if k + 1 < len(edges) else t0 + 1.0
            vals = [gear.value(t0 + s * (t1 - t0)) for s in _SAMPLES] + [gear.value(t0)]
            if max(vals) != min(vals):
                raise ParameterError(f"{where}: the gear signal varies between t={t0:g} and t={t1:g} s; a gear "
                                     f"selection is piecewise constant (Step, or a Table with repeated times)")
            if k > 0:
                pairs.append((t0, vals[0]))
    elif callable(gear):
        raise ParameterError(f"{where}: parameter 'gear' is a callable, whose shift instants are unknown; give a "
                             f"list of (t, gear) pairs or a piecewise-constant signal (Step, Table)")
    elif isinstance(gear, (list, tuple, np.ndarray)):
        try:
            pairs = [(float(t), g) for t, g in gear]
        except (TypeError, ValueError):
            raise ParameterError(f"{where}: parameter 'gear' must be (t, gear) pairs, got {gear!r}") from None
        if not pairs:
            raise ParameterError(f"{where}: parameter 'gear' is an empty schedule; give at least one (t, gear)")
    else:
        pairs = [(0.0, gear)]
    out = []
    for t, g in pairs:
        gx = as_real(g)
        if gx is None or not math.isfinite(t) or gx != int(gx) or not 0 <= gx <= n:
            raise ParameterError(f"{where}: gear {g!r} at t={t} is not a gear of this box; gears are the integers "
                                 f"0 (neutral) to {n} and times finite")
        if out and t <= out[-1][0]:
            raise ParameterError(f"{where}: the gear schedule needs strictly increasing times, got {t} after "
                                 f"{out[-1][0]}")
        if not out or int(gx) != out[-1][1]:
            out.append((t, int(gx)))
    return out


def engagement_tables(comp, schedule, n, release, delay, engage) -> list[Table]:
    """``f_normalized`` of each of the n shift elements for a schedule (see the module docstring).

    A shift must be complete (the new element fully applied) before the next command: otherwise a
    ParameterError naming both times."""
    g0 = schedule[0][1]
    pts = [[(schedule[0][0], 1.0 if k + 1 == g0 else 0.0)] for k in range(n)]
    done = -math.inf
    for (t_prev, g_old), (t_s, g_new) in zip(schedule, schedule[1:]):
        if t_s < done:
            raise ParameterError(f"{_where(comp)}: the shift at t={t_s:g} s comes before the previous one is complete "
                                 f"(t={done:g} s: release {release:g} s, delay {delay:g} s, engagement {engage:g} s); "
                                 f"space the shifts or shorten the ramps")
        if g_old:
            pts[g_old - 1] += [(t_s, 1.0), (t_s + release, 0.0)]
        if g_new:
            pts[g_new - 1] += [(t_s + delay, 0.0), (t_s + delay + engage, 1.0)]
        done = t_s + max(release, delay + engage)
    return [Table(p) for p in pts]


class Gearbox(Subsystem):
    """Stepped transmission with one shift element per gear (see the module docstring).

    Ports: ``flange_a`` (the input inertia: connect the engine side, a clutch or a converter
    turbine), ``flange_b`` (the output inertia). Parts: ``input``, ``output``, ``gear<k>``
    (``IdealGear``, or ``LossyGear`` when ``efficiency`` < 1), ``idler<k>`` and ``shift<k>``
    (``Clutch``) for k = 1..n. Signals: ``<box>.shift<k>.mode`` (0 locked, +-1 slipping,
    2 open), ``<box>.shift<k>.tau`` (torque of the element [N m]), ``<box>.input.w``,
    ``<box>.output.w``.

    Equations (gear k locked): ``w_in = ratio_k w_out``; ideal mesh:
    ``tau_out = ratio_k tau_in`` (less the inertia torques); lossy mesh: the loss torque of
    ``LossyGear`` with ``eta_mf1 = eta_mf2 = eta_k``. A shift element is a ``Clutch`` with
    ``mu = 1``, ``cgeo = 1`` and ``fn_max = capacity_k``: its kinetic torque is
    ``capacity_k * f_normalized(t)`` [N m], its static torque ``peak`` times that.

    Regularity: the idlers are the masses that let each element slip or lock on its own;
    ``J_gear`` is the idler's inertia about its own shaft [kg m^2] (a realistic 1e-3 to
    1e-2; a vanishing one gives a stiff model, not a wrong one).
    """

    ratios = Param(check="any", unit="1", doc="gear ratios w_in/w_out, one per gear (negative: reverse)")
    gear = Param(1, check="any", unit="1", doc="gear selection: int, list of (t, gear), a piecewise-constant signal, "
                                                 "or a block's output (blocks.ShiftSchedule: the gear from the run)")
    gear0 = Param(1, check="any", unit="1", doc="start gear when 'gear' is a block's output (its element starts applied)")
    capacity = Param(check="any", unit="N m", doc="kinetic torque of each shift element fully applied (number or list)")
    efficiency = Param(None, check="any", optional=True, unit="1", doc="mesh efficiency per gear in (0, 1] (None: ideal)")
    peak = Param(1.2, check="positive", unit="1", doc="static over kinetic torque of the shift elements (>= 1)")
    J_in = Param(0.01, check="positive", unit="kg m^2", doc="input shaft inertia")
    J_out = Param(0.02, check="positive", unit="kg m^2", doc="output shaft inertia")
    J_gear = Param(0.002, check="any", unit="kg m^2", doc="idler gear inertia (number or list)")
    release_time = Param(0.1, check="positive", unit="s", doc="ramp of the released element")
    engage_time = Param(0.3, check="positive", unit="s", doc="ramp of the applied element")
    shift_delay = Param(None, check="nonnegative", optional=True, unit="s",
                        doc="command to start of engagement (None: release_time)")
    w_in0 = Param(None, optional=True, unit="rad/s", doc="start speed of the input (fixed when given)")
    w_out0 = Param(None, optional=True, unit="rad/s", doc="start speed of the output (fixed when given)")
    ports = {"flange_a": "input.flange_a", "flange_b": "output.flange_b"}

    def validate(self):
        ratios = self._values["ratios"]
        if not isinstance(ratios, (list, tuple, np.ndarray)) or len(ratios) < 1:
            raise ParameterError(f"{_where(self)}: parameter 'ratios' must be a list of gear ratios, got {ratios!r}")
        n = len(ratios)
        self._ratios = per_gear(self, "ratios", ratios, n, "nonzero")
        self._capacity = per_gear(self, "capacity", self._values["capacity"], n, "positive")
        self._J_gear = per_gear(self, "J_gear", self._values["J_gear"], n, "positive")
        eff = self._values["efficiency"]
        self._eta = None if eff is None else per_gear(self, "efficiency", eff, n, "efficiency")
        if self.peak < 1.0:
            raise ParameterError(f"{_where(self)}: parameter 'peak' must be >= 1 (static over kinetic torque), "
                                 f"got {self.peak}")
        if isinstance(self._values["gear"], StateRead):
            # a gear selected in the run (a ``blocks.ShiftSchedule``'s output): each element's force follows it
            # through a ``blocks.ShiftElement`` (parts ``select<k>``), no time schedule
            self._schedule, self._tables = None, None
            return
        self._schedule = gear_schedule(self, self._values["gear"], n)
        delay = self.release_time if self.shift_delay is None else self.shift_delay
        self._tables = engagement_tables(self, self._schedule, n, self.release_time, delay, self.engage_time)

    @property
    def n_gears(self) -> int:
        return len(self._ratios)

    @property
    def schedule(self) -> list[tuple[float, int]] | None:
        """The gear selection as (t, gear) pairs (gear 0 is neutral); None for a gear selected in the run."""
        return None if self._schedule is None else list(self._schedule)

    def engagement(self, k: int) -> Table:
        """The ``f_normalized`` signal of shift element k (1-based)."""
        return self._tables[k - 1]

    def gear_at(self, t: float) -> int:
        """The gear selected at time t [s] (the command; the element may still be slipping)."""
        if self._schedule is None:
            raise ParameterError(f"{_where(self)}: its gear is {self._values['gear']!r}, selected in the run; read it "
                                 f"from a result (res['{self._values['gear']!r}'])")
        g = self._schedule[0][1]
        for ts, gk in self._schedule:
            if t >= ts:
                g = gk
        return g

    def build(self):
        inp = self.part(Inertia("input", J=self.J_in, w0=self.w_in0))
        out = self.part(Inertia("output", J=self.J_out, w0=self.w_out0))
        for k in range(self.n_gears):
            i = k + 1
            if self._eta is None or self._eta[k] == 1.0:
                mesh = self.part(IdealGear(f"gear{i}", ratio=self._ratios[k]))
            else:
                eta = self._eta[k]
                mesh = self.part(LossyGear(f"gear{i}", ratio=self._ratios[k], loss_table=[[0.0, eta, eta, 0.0, 0.0]]))
            idler = self.part(Inertia(f"idler{i}", J=self._J_gear[k]))
            if self._tables is None:
                from ..blocks.continuous import ShiftElement
                gear = self._values["gear"]
                sel = self.part(ShiftElement(f"select{i}", gear=gear, k=float(i), engage_time=self.engage_time,
                                             release_time=self.release_time, f0=1.0 if i == self.gear0 else 0.0))
                force = sel.y
            else:
                force = self._tables[k]
            elem = self.part(Clutch(f"shift{i}", mu=1.0, cgeo=1.0, peak=self.peak, fn_max=self._capacity[k],
                                    f_normalized=force))
            self.link(inp.flange_b, mesh.flange_a)
            self.link(mesh.flange_b, idler.flange_a)
            self.link(idler.flange_b, elem.flange_a)
            self.link(elem.flange_b, out.flange_a)


class DualClutchTransmission(Subsystem):
    """Dual-clutch transmission: odd gears on shaft 1 behind clutch ``K1``, even gears on shaft 2
    behind ``K2``, synchronisers select a gear on each shaft.

    ::

        flange_a ── drum (J_in) ── K1 ── shaft1 (J_shaft) ══ gear1, gear3, ... ══ idler<k> ── sync<k> ──┐
                               └── K2 ── shaft2 (J_shaft) ══ gear2, gear4, ... ══ idler<k> ── sync<k> ──┴─ output ── flange_b

    A shift from gear i (shaft A) to gear j (shaft B) commanded at ``t_s``:

    1. pre-selection: ``sync<j>`` engages over ``sync_time`` (its own capacity ``sync_capacity``) and
       brings the idle shaft B to ``r_j w_out`` while its clutch is open (it slips, then locks);
    2. handover from ``t_s + sync_time`` over ``handover_time``: ``K_B`` ramps 0 -> 1 while ``K_A``
       ramps 1 -> 0 (no torque interruption: the torque passes from one clutch to the other, then
       ``K_B`` slips until the engine has come down to the new gear's speed, and locks);
    3. ``sync<i>`` opens over ``sync_time`` after the handover.

    ``launch_time``: the clutch of the first gear closes from open over that time from the start
    (a launch from rest: it slips while the engine pulls the car away, then locks); without it the
    box starts with that clutch closed.

    A synchroniser slips at ``sync_capacity * f`` while it synchronises and, once locked, holds up to
    ``sync_hold * f`` (the dog teeth: a static torque far above its slipping torque, ``peak`` of its
    ``Clutch`` = ``sync_hold / sync_capacity``).

    Two successive gears on the same shaft (e.g. 1 -> 3) are refused: a DCT shifts between shafts
    (skip-shifts go through the other shaft). Parts: ``drum``, ``K1``, ``K2``, ``shaft1``, ``shaft2``,
    ``gear<k>``, ``idler<k>``, ``sync<k>``, ``output``. ``capacity`` is the kinetic torque of each
    clutch fully applied [N m].
    """

    ratios = Param(check="any", unit="1", doc="gear ratios; odd gears (1, 3, ..) on shaft 1, even on shaft 2")
    gear = Param(1, check="any", unit="1", doc="gear selection: int, list of (t, gear) or a piecewise-constant signal")
    capacity = Param(check="positive", unit="N m", doc="kinetic torque of K1 and K2 fully applied")
    sync_capacity = Param(200.0, check="positive", unit="N m", doc="kinetic torque of a synchroniser")
    sync_hold = Param(1e4, check="positive", unit="N m",
                      doc="static torque of an engaged synchroniser (its dog teeth), >= sync_capacity")
    peak = Param(1.2, check="positive", unit="1", doc="static over kinetic torque (>= 1)")
    J_in = Param(0.02, check="positive", unit="kg m^2", doc="clutch drum inertia")
    J_shaft = Param(0.01, check="positive", unit="kg m^2", doc="inner/outer input shaft inertia")
    J_gear = Param(0.002, check="any", unit="kg m^2", doc="idler gear inertia (number or list)")
    J_out = Param(0.02, check="positive", unit="kg m^2", doc="output shaft inertia")
    sync_time = Param(0.1, check="positive", unit="s", doc="synchroniser ramp")
    handover_time = Param(0.3, check="positive", unit="s", doc="clutch-to-clutch crossover")
    launch_time = Param(None, check="positive", optional=True, unit="s",
                        doc="launch: the clutch of the first gear closes over this time from t = 0 (None: closed)")
    w_in0 = Param(None, optional=True, unit="rad/s",
                  doc="start speed of the drum and (without launch) of the shaft of the first gear (fixed when given)")
    w_out0 = Param(None, optional=True, unit="rad/s", doc="start speed of the output (fixed when given)")
    ports = {"flange_a": "drum.flange_a", "flange_b": "output.flange_b"}

    def validate(self):
        ratios = self._values["ratios"]
        if not isinstance(ratios, (list, tuple, np.ndarray)) or len(ratios) < 2:
            raise ParameterError(f"{_where(self)}: parameter 'ratios' must list at least two gear ratios, got {ratios!r}")
        n = len(ratios)
        self._ratios = per_gear(self, "ratios", ratios, n, "nonzero")
        self._J_gear = per_gear(self, "J_gear", self._values["J_gear"], n, "positive")
        if self.peak < 1.0:
            raise ParameterError(f"{_where(self)}: parameter 'peak' must be >= 1, got {self.peak}")
        if self.sync_hold < self.sync_capacity:
            raise ParameterError(f"{_where(self)}: sync_hold = {self.sync_hold:g} N m is below sync_capacity = "
                                 f"{self.sync_capacity:g} N m; an engaged synchroniser holds at least what it slips at")
        sched = gear_schedule(self, self._values["gear"], n)
        if sched[0][1] == 0 or any(g == 0 for _, g in sched):
            raise ParameterError(f"{_where(self)}: a DCT has no neutral in its schedule here; open a clutch upstream")
        self._schedule = sched
        sync, hand = self.sync_time, self.handover_time
        k_pts = {1: [], 2: []}
        s_pts = [[] for _ in range(n)]
        g0 = sched[0][1]
        t0 = sched[0][0]
        for s in (1, 2):
            k_pts[s].append((t0, 1.0 if self.shaft_of(g0) == s else 0.0))
        done = -math.inf
        if self.launch_time is not None:
            # a launch from rest: the clutch of the first gear closes from open (it slips, then locks)
            k_pts[self.shaft_of(g0)] = [(t0, 0.0), (t0 + self.launch_time, 1.0)]
            done = t0 + self.launch_time
        for k in range(n):
            s_pts[k].append((t0, 1.0 if k + 1 == g0 else 0.0))
        for (_, g_old), (t_s, g_new) in zip(sched, sched[1:]):
            a, b = self.shaft_of(g_old), self.shaft_of(g_new)
            if a == b:
                raise ParameterError(f"{_where(self)}: the shift {g_old} -> {g_new} at t={t_s:g} s stays on shaft {a}; "
                                     f"a dual-clutch box shifts between its shafts (go through a gear of the other)")
            if t_s < done:
                raise ParameterError(f"{_where(self)}: the shift at t={t_s:g} s comes before the previous one is "
                                     f"complete (t={done:g} s); space the shifts")
            s_pts[g_new - 1] += [(t_s, 0.0), (t_s + sync, 1.0)]
            k_pts[b] += [(t_s + sync, 0.0), (t_s + sync + hand, 1.0)]
            k_pts[a] += [(t_s + sync, 1.0), (t_s + sync + hand, 0.0)]
            s_pts[g_old - 1] += [(t_s + sync + hand, 1.0), (t_s + 2 * sync + hand, 0.0)]
            done = t_s + 2 * sync + hand
        self._k_tables = {s: Table(p) for s, p in k_pts.items()}
        self._s_tables = [Table(p) for p in s_pts]

    @staticmethod
    def shaft_of(gear: int) -> int:
        """1 for odd gears, 2 for even gears."""
        return 1 if gear % 2 else 2

    @property
    def schedule(self) -> list[tuple[float, int]]:
        return list(self._schedule)

    def build(self):
        drum = self.part(Inertia("drum", J=self.J_in, w0=self.w_in0))
        out = self.part(Inertia("output", J=self.J_out, w0=self.w_out0))
        shafts = {}
        g0 = self._schedule[0][1]
        for s in (1, 2):
            # the loaded shaft starts with the drum (its clutch is closed); the idle one at rest unless told
            w0 = self.w_in0 if s == self.shaft_of(g0) and self.launch_time is None else None
            shaft = shafts[s] = self.part(Inertia(f"shaft{s}", J=self.J_shaft, w0=w0))
            k = self.part(Clutch(f"K{s}", mu=1.0, cgeo=1.0, peak=self.peak, fn_max=self.capacity,
                                 f_normalized=self._k_tables[s]))
            self.link(drum.flange_b, k.flange_a)
            self.link(k.flange_b, shaft.flange_a)
        for k, r in enumerate(self._ratios):
            i = k + 1
            mesh = self.part(IdealGear(f"gear{i}", ratio=r))
            idler = self.part(Inertia(f"idler{i}", J=self._J_gear[k]))
            sync = self.part(Clutch(f"sync{i}", mu=1.0, cgeo=1.0, peak=self.sync_hold / self.sync_capacity,
                                    fn_max=self.sync_capacity,
                                    f_normalized=self._s_tables[k]))
            self.link(shafts[self.shaft_of(i)].flange_b, mesh.flange_a)
            self.link(mesh.flange_b, idler.flange_a)
            self.link(idler.flange_b, sync.flange_a)
            self.link(sync.flange_b, out.flange_a)


__all__ = ["Gearbox", "DualClutchTransmission", "gear_schedule", "engagement_tables"]
