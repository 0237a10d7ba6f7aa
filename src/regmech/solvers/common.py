"""What every solver shares: the output grid, time events, recording."""

from __future__ import annotations

import contextlib
import math
import threading
import time

import numpy as np

from ..errors import AccuracyError, ParameterError, SimulationError, SimulationTimeout
from . import pages


def check_times(t_start, t_end, dt_out):
    """``(t_start, t_end, dt_out)`` as floats, checked (``options.check_times``; the entry has checked the
    number of output points against the run's ``max_points`` already)."""
    from .options import check_time_span
    return check_time_span(t_start, t_end, dt_out)


def output_grid(t_start, t_end, dt_out):
    n = int(math.floor((t_end - t_start) / dt_out + 1e-9))
    grid = t_start + dt_out * np.arange(n + 1)
    if t_end - grid[-1] > 1e-12 * max(1.0, abs(t_end)):
        grid = np.append(grid, t_end)
    grid[-1] = min(grid[-1], t_end)
    return grid


#: default of simulate()'s ``max_time_events``: declared signal breakpoints (time events) in one run.
#: Each one stops and restarts the integration (IDA: a fresh start at order 1, about a millisecond
#: for a small model), so 1e5 of them cost minutes; beyond, the run is refused before it starts.
MAX_TIME_EVENTS = 100_000


def _signals(model):
    """(component, parameter name, signal) of every signal parameter of the model.

    A scan of every parameter of every component (20 ms at 10,000 inertias,
    and a run asks up to three times); the list is kept with the model's
    compiled system, which any change of a parameter or a connection drops
    (``Model._invalidate``), so it is never stale.
    """
    compiled = getattr(model, "_compiled", None)
    cached = getattr(model, "_signal_list", None)
    if compiled is not None and cached is not None and cached[0] is compiled:
        return cached[1]
    from ..signals import Signal
    found = [(comp, pname, val) for comp in model.components.values() for pname, val in comp._values.items()
             if isinstance(val, Signal)]
    if compiled is not None:
        model._signal_list = (compiled, found)
    return found


def check_max_time_events(value) -> int:
    """``max_time_events`` as a Python int (numpy integers and whole floats accepted), or ParameterError."""
    from .._numbers import as_integer, describe
    number = as_integer(value)
    if number is None or number < 0:
        raise ParameterError(f"simulate(): max_time_events must be a whole number >= 0 (the most signal "
                             f"breakpoints, i.e. time events, a run may have), got {describe(value)}")
    return number


def check_signals(model, t_start, t_end, max_time_events=MAX_TIME_EVENTS) -> None:
    """What the signals of ``model`` ask of a run over [t_start, t_end], checked before it starts.

    * The declared time events (breakpoints of every signal in (t_start, t_end), counted without
      listing them: ``Signal.count_breakpoints``) must not exceed ``max_time_events``: a
      ``Pulse(period=1e-8)`` over 1 s would otherwise build 2e8 segments and never return.
    * A prescribed motion must not need an impulse: a Speed source's reference must not jump, a
      Position source's reference neither jump nor change its slope abruptly (a Ramp's or Table's
      corner), inside the run. At ``t_start`` the start values follow the reference, so a jump
      there is fine.

    Raises ``ParameterError`` for a bad ``max_time_events`` and ``SimulationError`` naming the
    component, the signal and the remedy otherwise. Times that are not valid are left to the
    solver's own check.
    """
    max_time_events = check_max_time_events(max_time_events)
    try:
        t_start, t_end = float(t_start), float(t_end)
    except (TypeError, ValueError):
        return
    if not (math.isfinite(t_start) and math.isfinite(t_end) and t_end > t_start):
        return
    counts = [(sig.count_breakpoints(t_start, t_end), comp, pname, sig) for comp, pname, sig in _signals(model)]
    total = sum(n for n, *_ in counts)
    if total > max_time_events:
        n, comp, pname, sig = max(counts, key=lambda entry: entry[0])
        raise SimulationError(
            f"simulate(): the signals of model '{model.name}' declare about {total:,} time events in "
            f"({t_start:g}, {t_end:g}) s, more than max_time_events={max_time_events:,}: {type(comp).__name__} "
            f"'{comp.name}', signal '{pname}' = {sig!r} alone has {n:,}. Each one stops and restarts the "
            f"integration (of the order of a millisecond), so the run would not finish in reasonable time. "
            f"Remedies: where the switching is much faster than the model responds, a smooth signal (e.g. the "
            f"Pulse's mean value, or a Sine); a shorter run; or simulate(..., max_time_events={total}) to run them "
            f"all")
    for comp, pname, sig in _signals(model):
        kind = comp.device_kind() if callable(getattr(comp, "device_kind", None)) else None
        if kind in ("speed", "position") and pname == getattr(comp, "ref_param", None):
            _check_reference(comp, pname, sig, kind, t_start, t_end)


def _check_reference(comp, pname, sig, kind, t_start, t_end) -> None:
    """Refuse a prescribed-motion reference that would need an impulse inside (t_start, t_end)."""
    force = "force" if getattr(comp, "domain", "") == "translational" else "torque"
    for b in sig.breakpoints(t_start, t_end):
        if not t_start < b < t_end:
            continue
        levels = [("value", sig.value(b, True), sig.value(b))]
        if kind == "position":
            levels.append(("slope", sig.derivative(b, 1, True), sig.derivative(b, 1)))
        for what, before, after in levels:
            # corners of a Ramp or Table are continuous to round-off only
            if abs(after - before) <= 1e-9 * max(abs(before), abs(after)):
                continue
            where = f"{type(comp).__name__} '{comp.name}': its reference '{pname}' = {sig!r}"
            if kind == "speed":
                raise SimulationError(
                    f"{where} jumps at t={b:.9g} s from {before:.6g} to {after:.6g}. A prescribed speed that jumps "
                    f"needs an infinite {force} (an impulse) on the masses it drives, which no solver integrates. "
                    f"Give a continuous reference (a Ramp, or a Table whose times differ), or drive the mass "
                    f"with a {'Force' if force == 'force' else 'Torque'} source or through a SpringDamper")
            raise SimulationError(
                f"{where} has a {'jump' if what == 'value' else 'corner'} at t={b:.9g} s ({what} from "
                f"{before:.6g} to {after:.6g}): the speed it prescribes would jump, which needs an infinite "
                f"{force} (an impulse) that no solver integrates. A Position reference needs a continuous slope: "
                f"prescribe the speed instead (a Speed source with a Ramp or Table of speeds), use a smooth "
                f"signal (a Sine, or a callable), or drive through a SpringDamper")


def signal_breakpoints(model, t_start, t_end):
    """Instants in (t_start, t_end) where some signal of the model is not smooth (their number is
    bounded before a run by ``check_signals``)."""
    pts = set()
    for _, _, val in _signals(model):
        pts.update(b for b in val.breakpoints(t_start, t_end) if t_start < b < t_end)
    return sorted(pts)


def model_signals(model, c=None) -> list:
    """The ``Signal`` values of the model's components; with the compiled system ``c`` found once and kept with it
    (a change of a parameter drops it). Their parameters are read by the callers at every call (a user's own Signal
    subclass may change)."""
    from ..signals import Signal
    signals = c.__dict__.get("_model_signals") if c is not None else None
    if signals is None:
        signals = [val for comp in model.components.values() for val in comp._values.values()
                   if isinstance(val, Signal)]
        if c is not None:
            c._model_signals = signals
    return signals


class Recorder:
    """Collects output rows (t, y, yp, left flag, modes).

    The rows go straight into preallocated arrays (``capacity``: the rows
    expected, e.g. the output grid and the breakpoints; grown by half when
    events add more), so ``arrays`` returns views instead of stacking a list
    of rows at the end: on a 10,000-inertia chain the stacking and the
    per-row copies cost a tenth of a DOP853 run. Rows come one at a time
    (``add``), filled in place (``row_buffers`` hands out the next row,
    ``commit`` records it), or a block at a time (``add_rows``: a segment of
    IDA's output, copied once). ``yp_cols``: the columns of ``yp`` to keep
    (None: all).
    """

    def __init__(self, modes_width: int, capacity: int = 64, yp_cols=None):
        self.mw = modes_width
        self.k = 0
        self.capacity = max(int(capacity), 4)
        self.yp_cols = None if yp_cols is None else np.asarray(yp_cols, np.intp)
        self.T = np.empty(self.capacity)
        self.L = np.zeros(self.capacity, bool)
        self.MO = np.zeros((self.capacity, modes_width), int)
        self.Y = self.YP = None
        self.yp_width = 0

    @property
    def t(self):
        return self.T[:self.k]

    def _reserve(self, width, rows=1, rates=True):
        """Room for ``rows`` more rows of ``width`` unknowns; ``rates``: of y' too (else y' may stay unallocated
        until a row writes it: ``row_buffer``)."""
        if self.Y is None:
            self.capacity = max(self.capacity, self.k + rows)
            self.T = np.resize(self.T, self.capacity)
            self.L = np.resize(self.L, self.capacity)
            self.MO = np.resize(self.MO, (self.capacity, self.mw))
            # zeros (calloc: fresh pages of a large array are zero without being written), so that a row handed
            # out by ``row_buffers`` is zero already: on a 10,000-inertia chain, zeroing each output row of y and
            # y' cost 14 % of a DOP853 run (the pages' first touch)
            self.Y = pages.zeros((self.capacity, width))
            self.yp_width = width if self.yp_cols is None else len(self.yp_cols)
        if self.k + rows > self.capacity:
            grown = max(self.k + rows, self.capacity + max(self.capacity // 2, 16))
            self.T = np.resize(self.T, grown)
            self.L = np.resize(self.L, grown)
            self.MO = np.resize(self.MO, (grown, self.mw))
            Y = pages.zeros((grown, self.Y.shape[1]))
            Y[:self.k] = self.Y[:self.k]
            if self.YP is not None:
                YP = pages.zeros((grown, self.YP.shape[1]))
                YP[:self.k] = self.YP[:self.k]
                self.YP = YP
            self.Y, self.capacity = Y, grown
        if rates and self.YP is None:
            # the rows before (if any) wait for their y' (``row_buffer``): zero until filled
            self.YP = pages.zeros((self.capacity, self.yp_width))

    def add(self, t, y, yp, modes, left=False):
        self._reserve(len(y))
        self.Y[self.k] = y
        self.YP[self.k] = yp if self.yp_cols is None else np.asarray(yp)[self.yp_cols]
        self.commit(t, modes, left)

    def add_rows(self, t, Y, YP, modes, left):
        """Several rows at once (``t``, ``left``: 1-D; ``Y``, ``YP``: one row each), one mode set for all."""
        n = len(t)
        if n == 0:
            return
        self._reserve(np.shape(Y)[1], n)
        k = self.k
        self.T[k:k + n] = t
        self.L[k:k + n] = left
        self.Y[k:k + n] = Y
        self.YP[k:k + n] = YP if self.yp_cols is None else np.asarray(YP)[:, self.yp_cols]
        if self.mw:
            self.MO[k:k + n] = modes
        self.k = k + n

    def row_buffers(self, width):
        """``(y, y')`` of the next row, zero (rows are allocated zero and handed out once), to fill in place
        before ``commit`` (all ``yp`` columns kept)."""
        self._reserve(width)
        return self.Y[self.k], self.YP[self.k]

    def row_buffer(self, width):
        """``y`` of the next row (zero), to fill in place before ``commit``; its ``y'`` is left to whoever fills
        the rates later (the ODE driver's ``deferred_rates``): while no row writes ``y'``, its array is not even
        allocated. On a 10,000-inertia chain, allocating it zero (16 MB that the allocator clears when it
        recycles memory) and checking it finite cost 3-4 % of a RK45 run whose accelerations nobody read."""
        self._reserve(width, rates=False)
        return self.Y[self.k]

    def row_block(self, width, rows):
        """``y`` of the next ``rows`` rows (zero) as one ``(rows, width)`` view, to fill in place before
        ``commit_block``; their ``y'`` is left as ``row_buffer`` leaves it."""
        self._reserve(width, rows, rates=False)
        return self.Y[self.k:self.k + rows]

    def commit_block(self, ts, modes):
        """Records the rows that ``row_block`` handed out at the instants ``ts`` (right-hand values)."""
        k, n = self.k, len(ts)
        self.T[k:k + n] = ts
        self.L[k:k + n] = False
        if self.mw:
            self.MO[k:k + n] = modes
        self.k = k + n

    def commit(self, t, modes, left=False):
        k = self.k
        self.T[k] = float(t)
        self.L[k] = bool(left)
        if self.mw:
            self.MO[k] = modes
        self.k = k + 1

    def arrays(self):
        """``(T, Y, YP, L, MO)`` of the rows so far; ``YP`` is None when no row has written ``y'`` (every row's
        rates are left to ``row_buffer``'s caller, which checks them when it fills them)."""
        k = self.k
        if self.Y is None:
            Y, YP = np.zeros((k, 0)), np.zeros((k, 0))
        else:
            Y, YP = self.Y[:k], (self.YP[:k] if self.YP is not None else None)
        if not (np.all(np.isfinite(Y)) and (YP is None or np.all(np.isfinite(YP)))):
            bad = np.zeros(k, bool) if YP is None else ~np.all(np.isfinite(YP), axis=1)
            bad = int(np.nonzero(~np.all(np.isfinite(Y), axis=1) | bad)[0][0])
            raise SimulationError(f"the solution became non-finite (NaN/inf) at t={self.T[bad]:.6g}; the model or "
                                  f"the solver settings are unstable there (try a tighter tolerance or a stable "
                                  f"solver)")
        return self.T[:k].copy(), Y, YP, self.L[:k].copy(), self.MO[:k].copy()


def scale_hint(c) -> str:
    """The lightest mass and the fastest link of the model, for a failure that their scales may explain
    (a sentence for an error message, with a leading space)."""
    hint = ""
    massive = np.nonzero(c.mass > 0)[0]
    if massive.size:
        k = int(massive[np.argmin(c.mass[massive])])
        hint = f" The lightest mass is '{c.structure.coord_names[k]}' ({c.mass[k]:.3g})."
    return hint + c.stiffness_hint(always=True)


# ----------------------------------------------------------------- step budget
#: what a run that reaches its step budget can do instead (appended to the error message)
STEP_CAP_REMEDIES = ("use an implicit solver ('ida', 'scipy:Radau', 'scipy:BDF' or 'convolution'), reduce the "
                     "model with rm.Scene(model, ..., band_hz=...) (links above the band become rigid), loosen "
                     "rtol or shorten the run, or raise max_steps")


#: check_link_spread refuses rtol below eps * (w_max / w_min)^2 / SPREAD_RTOL_FACTOR
SPREAD_RTOL_FACTOR = 100.0


def spread_rtol_floor(c):
    """``(rtol_min, device, omega, ratio)``: the smallest rtol ``check_link_spread`` accepts, with the stiffest
    link; None without links."""
    link = c.fastest_link()
    if link is None:
        return None
    dev, w, ratio = link
    return float(np.finfo(float).eps * ratio ** 2 / SPREAD_RTOL_FACTOR), dev, w, ratio


def check_link_spread(c, rtol, solver: str, stiff_check=True):
    """Refuse a tolerance that the link spread makes unreachable in double precision.

    A link ``spread = (w_max / w_min)^2`` times stiffer than the softest one
    (``link_frequencies``) turns the round-off of its elongation, ``eps |x|``,
    into a force error of ``eps * spread`` relative to the forces of the rest
    of the model, and the accelerations carry it. Beyond ``100 rtol`` the
    answer cannot meet ``rtol`` (measured on the 1e7 chain of the hard cases:
    errors of 1.3e-4 of the range at rtol 1e-8 with scipy Radau and LSODA) and
    an implicit method with error control crawls (IDA: Newton and the error
    test fail over and over). ``stiff_check=False`` runs it anyway.
    """
    if not stiff_check:
        return
    link = c.fastest_link()
    if link is None:
        return
    dev, w, ratio = link
    spread = ratio ** 2
    if np.finfo(float).eps * spread > SPREAD_RTOL_FACTOR * rtol:
        # an accuracy that cannot be had, hence AccuracyError (a SimulationError): the contract of
        # solvers.accuracy passes it on as the refusal of its accuracy
        raise AccuracyError(
            f"solver '{solver}' on model '{c.model.name}': the stiffest link, {type(dev).__name__} '{dev.name}' "
            f"(local mode {w / 2 / np.pi:.3g} Hz), is {ratio:.3g} times faster than the softest; "
            f"the round-off of its force (eps * {spread:.3g} = {np.finfo(float).eps * spread:.2g} of the other "
            f"forces) exceeds what rtol={rtol:g} allows, so the answer cannot meet the tolerance. Make the link "
            f"rigid (Shaft(stiffness=None)) or let rm.Scene(band_hz=...) do it; stiff_check=False runs it anyway.",
            component=dev.name, estimate=float(np.finfo(float).eps * spread))


#: smallest factor by which a small state's absolute tolerance is scaled down (``StateScale``)
ATOL_FLOOR = 1e-3


class StateScale:
    """The magnitude of each kind of state seen so far in a run, and the absolute tolerances it gives.

    A solver's state has kinds (positions, speeds, device states), each an
    index set (``kinds``: slices or index arrays into a vector of ``size``
    entries). ``m_k`` is the largest ``|u_i|`` of kind k so far in the run
    and, for a scalar ``atol``,

        atol_i = atol * clip(m_k / saturation, floor, 1)      (u_i of kind k)

    entries outside every kind keep ``atol``; an array ``atol`` is returned
    unchanged. So the scalar ``atol`` is the absolute tolerance of a motion
    of magnitude ``saturation`` (default 1: 1 m, 1 rad, 1 m/s, ...) or more,
    and a motion that stays small gets a proportionally smaller one: with
    the plain ``atol`` the error test of a state much smaller is absolute
    (``atol >> rtol |u|``), i.e. looser than ``rtol`` by ``atol / (rtol
    |u|)``. ``floor`` (default ``ATOL_FLOOR``) bounds the scaling. Per kind,
    not per state: a state that stays small beside large ones of its kind (a car the
    coupler wave has not reached yet) keeps its kind's tolerance, so it costs
    no extra steps. The scaling never loosens a tolerance. One object per
    run: its segments share it.
    """

    def __init__(self, atol, kinds, size, saturation=1.0, floor=ATOL_FLOOR):
        self.atol = atol
        self.scalar = np.ndim(atol) == 0
        self.saturation = float(saturation)
        self.floor = float(floor)
        self.size = int(size)
        self.kinds = [k for k in kinds if (len(range(self.size)[k]) if isinstance(k, slice) else len(k))]
        self.largest = np.zeros(len(self.kinds))
        self._abs = None

    def see(self, u) -> bool:
        """Take the magnitudes of a state ``u`` (or of rows of states, ``u[..., i]``) into account; whether
        that changed the tolerances (a kind's magnitude grew below its saturation)."""
        u = np.asarray(u, float)
        if u.ndim == 1:
            # |u| into one reused vector, then a maximum per kind (a fresh |part| per kind: 7.2 us a step on 2,000
            # states, now 4.4 us)
            if self._abs is None or self._abs.shape != u.shape:
                self._abs = np.empty(u.shape)
            mag = np.abs(u, out=self._abs)
        else:
            mag = np.abs(u)
        changed = False
        for k, idx in enumerate(self.kinds):
            part = mag[..., idx]
            if part.size:
                m = float(part.max())
                if m > self.largest[k]:
                    # its factor clip(m_k / saturation, floor, 1) moves unless it stays at 1 or at the floor
                    old = self.largest[k] / self.saturation
                    self.largest[k] = m
                    new = m / self.saturation
                    changed |= not (old >= 1.0 or new <= self.floor)
        return changed

    def factors(self):
        """``clip(m_k / saturation, floor, 1)`` per kind."""
        return np.clip(self.largest / self.saturation, self.floor, 1.0)

    def tolerances(self):
        if not self.scalar:
            return self.atol
        out = np.full(self.size, float(self.atol))
        for f, idx in zip(self.factors(), self.kinds):
            out[idx] = float(self.atol) * f
        return out


class StepBudget:
    """The steps of one whole run (every segment) against ``max_steps``; shared by the run's steppers.

    A stepper calls ``charge(stepper, problem)`` after every accepted step;
    when the run has taken more than ``max_steps`` steps it stops with a
    ``SimulationError`` that says where (time reached, last step size) and
    why: for an explicit method (``stability_bound`` = the ``h * rho`` up to
    which it is stable on the negative real axis) whether the last step sat
    at the stability limit set by the spectral radius ``rho`` of ``dg/du``
    (stiff for the method) or below it (the steps are set by the tolerance:
    a long run for the method's order); in both cases the fastest link is
    named (``CompiledSystem.link_frequencies``), with the number of its
    periods in the run. The cap is on accepted steps, the unit the run's
    ``Stats.steps`` reports; the cost of one step (which sets what a refused
    run costs) is measured per solver where the default is chosen.
    """

    def __init__(self, name: str, max_steps: int, t_end: float, stability_bound: float | None = None,
                 cap: float | None = None):
        if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < 1:
            raise ParameterError(f"solver '{name}': max_steps must be a positive integer, got {max_steps!r}")
        self.name = name
        self.max_steps = int(max_steps)
        self.t_end = float(t_end)
        self.stability_bound = stability_bound
        self.cap = cap          # ``h * rho`` of regmech's own cap on the method's step (DOP853), or None
        self.steps = 0

    def charge(self, stepper, problem) -> None:
        self.steps += 1
        if self.steps > self.max_steps:
            raise self.error(stepper, problem)

    def error(self, stepper, problem) -> SimulationError:
        c = problem.c
        t, h = float(stepper.t), float(stepper.t - stepper.t_old)
        where = (f"solver '{self.name}' took more than max_steps={self.max_steps} steps in model "
                 f"'{c.model.name}' and stopped at t={t:.6g} s of t_end={self.t_end:.6g} s (last step "
                 f"h={h:.3g} s)")
        why, stiff = self._diagnosis(stepper, problem, h)
        named = c.stiffness_hint(always=True) if stiff else ""
        link = c.fastest_link()
        if not named and link is not None:
            dev, w, _ = link
            named = (f" The fastest link is {type(dev).__name__} '{dev.name}' (local mode {w / 2 / math.pi:.3g} Hz, "
                     f"about {w / (2 * math.pi) * self.t_end:.3g} periods in the run).")
        return SimulationError(f"{where}: {why}.{named} To finish: {STEP_CAP_REMEDIES}.")

    def _diagnosis(self, stepper, problem, h) -> tuple[str, bool]:
        """Why the run needs so many steps, and whether the stiffness of the model is the reason."""
        if self.stability_bound is None:
            return ("the steps are set by the tolerance (this implicit method has no stability limit on them): "
                    "the run is long for this rtol, or the model moves fast everywhere"), False
        from .ode_driver import _spectral_radius
        rho = _spectral_radius(problem, stepper.t, stepper.u)
        if not rho or h <= 0:
            return "an explicit method that needs this many steps is usually held back by stiffness", True
        ratio = h * rho / self.stability_bound
        if self.cap is not None and h * rho >= 0.9 * self.cap:
            more = (self.t_end - stepper.t) * rho / self.cap
            return (f"h * rho = {h * rho:.3g} with the spectral radius rho = {rho:.3g} 1/s of the Jacobian, at "
                    f"regmech's cap on this method's step at this rtol ({self.cap:.3g}, below its stability limit "
                    f"{self.stability_bound:g}: scipy_ivp.stability_cap): the model is stiff for it (about "
                    f"{more:.3g} more steps to go)"), True
        if ratio > 0.3:
            more = (self.t_end - stepper.t) * rho / self.stability_bound
            return (f"h * rho = {h * rho:.3g} with the spectral radius rho = {rho:.3g} 1/s of the Jacobian, at "
                    f"the stability limit {self.stability_bound:g} of this explicit method: the model is stiff "
                    f"for it (about {more:.3g} more steps to go)"), True
        # DOP853 is the highest order on offer: suggesting it to itself would send the user in a circle
        higher = "" if "853" in self.name else " (a higher-order method such as 'dop853' takes fewer steps)"
        return (f"h * rho = {h * rho:.3g} is well below this method's stability limit {self.stability_bound:g} "
                f"(rho = {rho:.3g} 1/s): the steps are set by the tolerance, i.e. the run is long for this "
                f"method's order at this rtol{higher}"), False


# ----------------------------------------------------------------- time limit
#: the wall-clock limit active in this thread (``time_limit``), read by every solver at the start of a run
_ACTIVE = threading.local()


class _Limit:
    """A wall-clock limit: ends at ``at`` (``time.monotonic()`` seconds), ``seconds`` long, set by ``origin``."""

    __slots__ = ("at", "seconds", "origin")

    def __init__(self, seconds: float, origin: str):
        self.at = time.monotonic() + seconds
        self.seconds = seconds
        self.origin = origin


def check_timeout(seconds, where: str = "simulate()"):
    """``timeout_s`` as a float, or None (no limit); anything but a positive finite number is refused."""
    if seconds is None:
        return None
    if isinstance(seconds, bool) or not isinstance(seconds, (int, float, np.integer, np.floating)) \
            or not math.isfinite(seconds) or seconds <= 0:
        raise ParameterError(f"{where}: timeout_s must be a positive number of seconds (or None for no limit), "
                             f"got {seconds!r}")
    return float(seconds)


@contextlib.contextmanager
def time_limit(seconds, origin: str = "simulate(timeout_s=...)"):
    """Run the body under a wall-clock limit of ``seconds`` (None: no limit of its own).

    The limit is *cooperative*: every solver takes the active limit at the
    start of a run (``run_deadline``) and checks it in its inner loops (IDA:
    every residual evaluation; the ODE-form driver, hence every fixed-step,
    scipy and convolution run and the companion runs of the error estimates:
    every step), so a run stops within one residual evaluation or one step
    after the limit with ``SimulationTimeout``. Limits nest (a study's limit
    per run around the simulations inside it): the earliest end holds.
    """
    seconds = check_timeout(seconds, origin)
    if seconds is None:
        yield
        return
    outer = getattr(_ACTIVE, "limit", None)
    mine = _Limit(seconds, origin)
    _ACTIVE.limit = mine if outer is None or mine.at < outer.at else outer
    try:
        yield
    finally:
        _ACTIVE.limit = outer


class Deadline:
    """The active limit as one solver run sees it; ``check(t)`` raises ``SimulationTimeout`` past its end and moves
    the active progress bar (``progress``) to ``t``; ``note(steps, events)`` gives the bar the run's counts."""

    __slots__ = ("at", "limit", "solver", "model_name", "t_end", "progress", "calls")

    def __init__(self, limit, solver: str, model_name: str, t_end: float, progress=None, calls=None):
        # without a limit (a progress bar alone) the end lies 1e9 s ahead: finite, for the compiled kernels' ns clock
        self.at = limit.at if limit is not None else time.monotonic() + NO_LIMIT_S
        self.limit = limit
        self.solver = solver
        self.model_name = model_name
        self.t_end = float(t_end)
        self.progress = progress
        self.calls = calls          # [checks left] of the active ``call_budget``, shared by the runs under it

    def check(self, t) -> None:
        if self.progress is not None:
            self.progress.update(t, self.solver)
        if self.calls is not None:
            self.calls[0] -= 1
            if self.calls[0] < 0:
                raise CallBudgetExceeded(f"solver '{self.solver}' on model '{self.model_name}' used up its budget of "
                                         f"evaluations at t={float(t):.6g} s")
        if time.monotonic() > self.at:
            raise self.error(t)

    def note(self, steps, events) -> None:
        if self.progress is not None:
            self.progress.steps, self.progress.events = int(steps), int(events)

    def error(self, t) -> SimulationTimeout:
        lim = self.limit
        return SimulationTimeout(
            f"timed out after {lim.seconds:g} s ({lim.origin}): solver '{self.solver}' on model "
            f"'{self.model_name}' had reached t={float(t):.6g} s of t_end={self.t_end:.6g} s. Raise the limit, "
            f"shorten the run, or make it cheaper (a looser rtol, another solver, a model reduced with "
            f"rm.Scene(band_hz=...))")


#: a Deadline without a limit ends this far ahead [s]
NO_LIMIT_S = 1e9
#: the progress bar is redrawn at most this often [s]
PROGRESS_EVERY_S = 0.2
#: with ``progress=None`` (an interactive session), the bar appears once a run has taken this long [s]
PROGRESS_DELAY_S = 3.0


class _Progress:
    """A tqdm bar over the simulated time ``[t_start, t_end]`` with the current run's solver, step attempts and
    events, redrawn at most every ``PROGRESS_EVERY_S`` from the solvers' checks (``Deadline.check``)."""

    def __init__(self, model_name, t_start, t_end, delay):
        import sys
        from tqdm import tqdm
        self.t_start, self.steps, self.events, self.last = float(t_start), 0, 0, 0.0
        self.bar = tqdm(total=float(t_end) - float(t_start), desc=str(model_name), unit="s", delay=delay,
                        leave=False, file=sys.stderr, dynamic_ncols=True,
                        bar_format="{desc}: {percentage:3.0f}%|{bar}| t={n:.4g}/{total:.4g} s [{elapsed}{postfix}]")

    def update(self, t, solver):
        now = time.monotonic()
        if now - self.last < PROGRESS_EVERY_S:
            return
        self.last = now
        self.bar.n = min(max(float(t) - self.t_start, 0.0), self.bar.total)
        self.bar.set_postfix_str(f"{solver}, {self.steps} steps, {self.events} events", refresh=False)
        self.bar.refresh()

    def close(self):
        self.bar.close()


@contextlib.contextmanager
def progress_bar(progress, model_name, t_start, t_end):
    """A progress bar over the body's runs: ``progress`` True (shown at once), False (none) or None (shown after
    ``PROGRESS_DELAY_S`` when stderr is a terminal and no test runs: an interactive session's long run)."""
    import os
    import sys
    if progress is None:
        interactive = getattr(sys.stderr, "isatty", lambda: False)() and "PYTEST_CURRENT_TEST" not in os.environ
        progress, delay = interactive, PROGRESS_DELAY_S
    elif isinstance(progress, bool):
        delay = 0.0
    else:
        raise ParameterError(f"simulate(progress=...) must be True, False or None, got {progress!r}")
    outer = getattr(_ACTIVE, "progress", None)
    if not progress or outer is not None:
        yield
        return
    bar = _Progress(model_name, t_start, t_end, delay)
    _ACTIVE.progress = bar
    try:
        yield
    finally:
        _ACTIVE.progress = None
        bar.close()


class CallBudgetExceeded(SimulationTimeout):
    """A run under ``call_budget`` evaluated its equations more often than the budget allows."""


@contextlib.contextmanager
def call_budget(calls: int):
    """Run the body with at most ``calls`` checks of the deadline (one per residual evaluation on IDA's Python
    path, one per step of the ODE-form driver): ``CallBudgetExceeded`` beyond (a cost bound counted in work, not
    in wall time)."""
    outer = getattr(_ACTIVE, "calls", None)
    _ACTIVE.calls = [int(calls)]
    try:
        yield
    finally:
        _ACTIVE.calls = outer


def run_deadline(solver: str, model, t_end) -> Deadline | None:
    """The limit of the run about to start, with the active progress bar and call budget (None when none is active
    in this thread)."""
    limit = getattr(_ACTIVE, "limit", None)
    progress = getattr(_ACTIVE, "progress", None)
    calls = getattr(_ACTIVE, "calls", None)
    if limit is None and progress is None and calls is None:
        return None
    return Deadline(limit, solver, getattr(model, "name", "?"), t_end, progress, calls)


def refuse_impacts(model, solver: str) -> None:
    """Raise ``SimulationError`` naming the hard stops (devices with rigid impacts, ``impact = True``) of
    ``model``: solver ``solver`` cannot apply their speed jumps (its error estimate or its step assumes
    continuous speeds), and stepping across an impact would be a silently wrong answer."""
    c = model.compile()
    stops = c.__dict__.get("_impact_devices")
    if stops is None:
        # found once per compiled system: ``getattr`` on a device without the attribute goes through
        # ``Component.__getattr__`` and a caught error (2-3 us), 25 ms of every fixed-step run of a 10,000-inertia
        # chain (a third of it)
        stops = c._impact_devices = [d for d in c.structure.devices if getattr(d, "impact", False)]
    if stops:
        names = ", ".join(f"{type(d).__name__} '{d.name}'" for d in stops[:6]) + (" ..." if len(stops) > 6 else "")
        raise SimulationError(
            f"solver '{solver}' cannot run model '{model.name}': {names} {'has' if len(stops) == 1 else 'have'} "
            f"rigid impacts (speeds that jump at located events), which this solver does not apply. Use "
            f"solver='ida' (or 'auto') or an adaptive scipy solver such as 'scipy:DOP853'; or an EndStop (a "
            f"compliant contact) instead of the hard stop.")
