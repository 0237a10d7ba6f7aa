"""SUNDIALS IDA (scikit-sundae) on the compiled index-1 DAE, with a hybrid loop.

The run is split into segments at the signals' breakpoints (time events)
and at mode changes of variable-structure devices (state events found by
IDA's root finding). Each segment gets a fresh solver (about 50 us): the
event bookkeeping of scikit-sundae accumulates across ``solve`` calls, so a
solver is never reused after an event. At every segment start the values
are made consistent by the compiler (projection onto the constraints,
accelerations and constraint forces from one sparse KKT solve), so IDA's own
initial-condition search is not needed.

``native=True`` runs linear models, and friction models whose laws are linear in one signal, with no Python
in IDA's loop (``ida_native``: the same SUNDIALS IDA through ctypes, numba-compiled residual, Jacobian, event
functions and output loop; one solver per run, re-initialised at every segment, the mode logic in Python at
the events); other models run as below.

Linear solver: ``dense`` below ``dense_max`` unknowns (60), ``sparse``
(SuperLU_MT) with the analytic Jacobian above; ``linsolver`` overrides.

Absolute tolerances. IDA accepts a step when the weighted RMS of its local
error estimate, with weights ``1 / (rtol |y_i| + atol_i)``, is at most 1. A
scalar ``atol`` (default ``rtol * 1e-2``) is the absolute tolerance of a
motion of magnitude ``atol / (KAPPA rtol)`` (1 m, rad, m/s or rad/s for the
default) or more: a run in which all positions, all speeds or all device
states stayed below a thirtieth of that is made again with their absolute
tolerances scaled to their magnitude (``_rescaled_atol``; the stats count
both runs, a ``RuntimeWarning`` says so, and a repeat that takes more
residual evaluations than three times the first run's, ``REPEAT_BUDGET``,
is stopped and the first run returned, with a warning). An array ``atol`` is used as given. The algebraic unknowns
(forces, dummy accelerations) get ``_atol_vector``'s scaling at every
segment start: ``max(atol, rtol)`` times the largest force present (a
dummy's acceleration: that force over its mass), since the BDF formulas
give them the error of a derivative, an order below the states'.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from .._numbers import abs_max
from ..errors import SimulationError, SimulationTimeout
from ..hybrid import attach, guards_for
from ..result import Event, Result, Stats
from . import register, sundials_log
from .common import (Recorder, StateScale, check_link_spread, check_times, output_grid, run_deadline, time_limit,
                     CallBudgetExceeded, call_budget,
                     signal_breakpoints)
from .options import (Choice, Flag, Integer, OptionSet, Real, atol_option, chatter_options, max_events_option,
                      rtol_option, stiff_check_option)
from .richardson import ABSOLUTE_FLOOR

IDA_OPTIONS = OptionSet(
    "SUNDIALS IDA (variable-order BDF on the DAE, local error control by rtol/atol)",
    rtol=rtol_option(1e-6),
    atol=atol_option(lambda c: c.N, "unknown of the DAE"),
    linsolver=Choice("linear solver of IDA's Newton iteration (default: chosen from the model's size and "
                     "bandwidth)", ("dense", "band", "sparse"), optional=True),
    max_step=Real("largest step [s] IDA may take (default: no limit)", optional=True),
    max_order=Integer("highest order of IDA's BDF formulas (default 5)", 1, 5),
    dense_max=Integer("most unknowns for which the dense linear solver is chosen (default 60)", 0),
    max_events=max_events_option(),
    max_steps=Integer("most IDA steps in one output interval (default 50000)", 1),
    stiff_check=stiff_check_option(),
    native=Flag("run IDA with compiled callbacks and no Python in its loop where the model allows it "
                "(linear models and friction with laws linear in one signal; numba: see "
                "regmech.solvers.ida_native; default: True when numba and SUNDIALS' libraries load, a model the "
                "compiled path cannot serve running the usual path; False: Python callbacks always)"),
    atol_rescale=Flag("repeat a run whose motion turns out small for a scalar atol, with the atol of each kind of "
                      "state scaled to it (default True; False: one run with atol as given)"),
    **chatter_options(),
)

#: the absolute tolerance of a kind of state (positions, speeds, device states) is at most this fraction of
#: ``rtol`` times the kind's magnitude (``_rescaled_atol``)
KAPPA = 0.01
#: a run whose plain ``atol`` exceeded that by more than this factor for some kind is repeated, rescaled
RERUN_FACTOR = 30.0
#: the repeated run may take this many times the first run's residual evaluations (on the compiled path, which
#: does not count them as it goes, ``REPEAT_WALL`` times its wall time plus ``REPEAT_MIN_S`` [s]); beyond, the
#: first run is returned, with a warning. The chains of ``tests/unit/test_ida_tolerances.py`` repeat at 1.9 to
#: 2.0 times the first run's evaluations
REPEAT_BUDGET = 3.0
REPEAT_WALL = 5.0
REPEAT_MIN_S = 0.5
#: smallest factor of ``atol`` in a repeated run (a kind scaled down over six decades of motion below ``s``)
RERUN_FLOOR = 1e-6


class _Ordering:
    """The solver's view of the unknowns: identity, or a bandwidth-reducing permutation
    (``y_solver = y[perm]``) for the band solver. Equations are permuted alike."""

    def __init__(self, n, perm=None):
        self.perm = perm
        if perm is not None:
            self.inv = np.empty_like(perm)
            self.inv[perm] = np.arange(n)
            self._y = np.empty(n)
            self._yp = np.empty(n)
            self._r = np.empty(n)

    def to_solver(self, y):
        return y if self.perm is None else y[self.perm]

    def from_solver(self, ys):
        return ys if self.perm is None else ys[..., self.inv]

    def full(self, y, yp):
        if self.perm is None:
            return y, yp
        self._y[self.perm] = y
        self._yp[self.perm] = yp
        return self._y, self._yp


def choose_linsolver(c, dense_max=60, band_max=40, dense_wide_max=400):
    """IDA's linear solver for the compiled system ``c`` (N unknowns).

    * dense (analytic Jacobian) up to ``dense_max`` unknowns;
    * band on a reverse Cuthill-McKee ordering when the reordered bandwidth
      ``lband + uband + 1`` is at most ``band_max`` (IDA's difference quotients cost
      that many residuals per Jacobian);
    * dense again for wider coupling up to ``dense_wide_max`` unknowns;
    * sparse (SuperLU_MT, a fixed cost of milliseconds per factorisation) beyond.

    Measured (benchmarks/results/linsolver.md, idle and with the other core busy): this choice is
    within 1.3x of the fastest of the three on trains of 5-400 cars, hubs of 10-400 satellites and
    the library scenes; band beats dense 2-4x on long trains, dense beats band on wide coupling, and
    sparse wins only for large wide models (hub of 200+ satellites, N > 400). SuperLU_MT's time also
    varies far more than dense and band with the load on the machine (hub of 40: dense 23 ms in all
    conditions, sparse 30-409 ms), which is why it is not used where dense or band come close.
    """
    if c.N <= dense_max:
        return "dense", _Ordering(c.N)
    band = c.__dict__.get("_band_ordering")
    if band is None:
        from ..compile.assembly import banded_ordering
        band = c._band_ordering = banded_ordering(c.jac.pattern)
    perm, lb, ub = band
    if lb + ub + 1 <= band_max:
        return "band", _Ordering(c.N, perm)
    if c.N <= dense_wide_max:
        return "dense", _Ordering(c.N)
    return "sparse", _Ordering(c.N)


def _band_widths(c, order):
    """(lower, upper) bandwidth of the iteration matrix in the solver's ordering (kept on the compiled system
    with the ordering it was computed for: every segment of every run asks)."""
    key = None if order.perm is None else order.perm.tobytes()
    hit = c.__dict__.get("_band_widths")
    if hit is not None and hit[0] == key:
        return hit[1]
    P = c.jac.pattern if order.perm is None else c.jac.pattern[order.perm][:, order.perm]
    pat = P.tocoo()
    widths = int(max(0, (pat.row - pat.col).max(initial=0))), int(max(0, (pat.col - pat.row).max(initial=0)))
    c._band_widths = (key, widths)
    return widths


def _make_solver(c, modes, rtol, atol, linsolver, max_step, max_order, with_events, order, max_steps=50000,
                 deadline=None, native=False):
    import sksundae

    if native:
        # an eligible model (``ida_native.eligible``, checked by the caller): no callbacks into Python
        from .ida_native import NATIVE_KEEP_MAX, NativeIDA
        key = (float(rtol), linsolver, None if order.perm is None else order.perm.tobytes(), max_step, int(max_order),
               int(max_steps))
        kept = c.__dict__.setdefault("_native_solvers", {})
        solver = kept.get(key)
        if solver is not None and solver.pattern is not c.jac:
            solver = None
        if solver is None:
            lband, uband = _band_widths(c, order) if linsolver == "band" else (0, 0)
            solver = NativeIDA(c, rtol, atol, linsolver, order, max_step, max_order, max_steps, lband, uband,
                               deadline)
            if c.N <= NATIVE_KEEP_MAX:
                # a small model's solver serves its next runs too (the accuracy contract's pairs, sweeps): set up
                # once, re-initialised per segment like the segments of one run
                if len(kept) >= 4:
                    kept.pop(next(iter(kept)))
                kept[key] = solver
        else:
            solver.start_run(deadline)
        return solver

    if order.perm is None and not c.mf and "residual" not in c.__dict__:
        plan = c._plan

        def resfn(t, y, yp, res):
            # ``CompiledSystem.residual`` without friction rows, one call less per evaluation (not when the
            # residual is wrapped on the instance: a work budget counts the calls there)
            plan.residual(t, y, yp, t >= c._t_right, res)
    elif order.perm is None:
        def resfn(t, y, yp, res):
            c.residual(t, y, yp, res, modes)
    else:
        perm, r_full = order.perm, order._r

        def resfn(t, y, yp, res):
            yf, ypf = order.full(y, yp)
            c.residual(t, yf, ypf, r_full, modes)
            res[:] = r_full[perm]

    if deadline is not None:
        # the run's wall-clock limit, checked at every residual evaluation (scikit-sundae passes the
        # SimulationTimeout raised here out of solve())
        unlimited = resfn

        def resfn(t, y, yp, res):
            deadline.check(t)
            unlimited(t, y, yp, res)

    # IDA's step count: scikit-sundae reports only nfev and njev, so the steps are counted here as the
    # distinct times of the residual calls (each attempted step evaluates at its new time; Newton
    # iterations and Jacobian differences repeat that time; no initial-condition solve runs here)
    # The last few distinct times also bound the step on which a root was found (``_relocate_root``): the
    # latest is its end, the latest before the root its start (a rejected attempt lies beyond the end).
    attempts = [None, 0, []]
    uncounted = resfn

    def resfn(t, y, yp, res):
        if t != attempts[0]:
            attempts[0] = t
            attempts[1] += 1
            recent = attempts[2]
            recent.append(t)
            if len(recent) > RECENT_TIMES:
                del recent[0]
        uncounted(t, y, yp, res)

    alg = c.algebraic if order.perm is None else np.sort(order.inv[c.algebraic])
    atol = order.to_solver(atol) if np.ndim(atol) else atol
    opts = dict(rtol=rtol, atol=atol, algebraic_idx=alg, max_num_steps=int(max_steps),
                max_order=max_order, calc_initcond=None)
    if max_step:
        opts["max_step"] = max_step
    if linsolver == "dense":
        rows, cols = c.jac.rows, c.jac.cols

        def jacfn(t, y, yp, res, cj, JJ):
            JJ[:, :] = 0.0
            JJ[rows, cols] = c.jacobian_data(t, y, yp, cj, modes)     # pattern entries are unique
        opts.update(linsolver="dense", jacfn=jacfn)
    elif linsolver == "sparse":
        def jacfn(t, y, yp, res, cj, JJ):
            JJ[:] = c.jacobian_data(t, y, yp, cj, modes)
        opts.update(linsolver="sparse", sparsity=c.jac.pattern, jacfn=jacfn)
    elif linsolver == "band":
        lband, uband = _band_widths(c, order)
        opts.update(linsolver="band", lband=lband, uband=uband)
    else:
        raise SimulationError(f"unknown linsolver {linsolver!r}; use 'dense', 'sparse' or 'band'")
    if with_events:
        guards = guards_for(c)       # the friction functions, then the switching surfaces (hybrid.surfaces)

        def eventsfn(t, y, yp, ev):
            yf, ypf = order.full(y, yp)
            ev[:] = guards.event_values(t, yf, ypf, modes)
        eventsfn.terminal = [True] * guards.n_events
        eventsfn.direction = [-1] * guards.n_events
        opts.update(eventsfn=eventsfn, num_events=guards.n_events)
    with warnings.catch_warnings():
        # the sparse solver needs the pattern, and scikit-sundae warns that its own finite-difference
        # Jacobian (which the pattern would enable) is unused because ours is given: expected here
        warnings.filterwarnings("ignore", message="Custom sparse Jacobian approximation")
        solver = sksundae.ida.IDA(resfn, **opts)
    solver.regmech_attempts = attempts
    return solver


#: distinct residual times kept per solver (``_make_solver``): enough to see past a few rejected attempts
RECENT_TIMES = 8
#: a root is located again when the step that crossed it put the law's accelerations at the root this many
#: times the speed tolerance (per unit step) away from the step's own (``_law_mismatch``)
RELOCATE_MISMATCH = 10.0
#: the re-integration's largest step, as a fraction of the step that crossed the root
RELOCATE_SHRINK = 8.0
#: most re-integrations per root (``_relocate_root``)
RELOCATE_ROUNDS = 3
#: output rows a relocation's restart may step back past because they depart from the law; beyond, it restarts
#: from the segment start
RELOCATE_BACK_ROWS = 400
#: how far before the crossing step, in lengths of that step, the re-integration's bounded steps begin when the
#: restart row follows the law and no row lies between it and the crossing step (``_relocate_root``)
RELOCATE_REACH = 3.0


#: signal classes whose value is a function of time and of their (scalar) attributes alone
_PURE_SIGNALS = ("Constant", "Sine", "Step", "Ramp", "Pulse")


def _start_key(model, c, t_start, modes):
    """What the start values of a run depend on besides the compiled system, or None when they cannot be
    remembered: every signal of the model must be one of regmech's own scalar-parameter signals (a user's
    callable may not give the same values twice)."""
    from .common import _signals
    key = [float(t_start), float(c._t_right), tuple(int(m) for m in modes)]
    for comp, pname, sig in _signals(model):
        if type(sig).__module__ != "regmech.signals" or type(sig).__name__ not in _PURE_SIGNALS:
            return None
        key.append((comp.name, pname, type(sig).__name__, tuple(sorted(vars(sig).items()))))
    return key


def _start_values(model, c, t_start, modes):
    """``c.initial_y(t_start, modes)`` (a projection and two acceleration solves), remembered on the compiled
    system for the next run from the same start (``_start_key``)."""
    key = _start_key(model, c, t_start, modes)
    if key is None:
        return c.initial_y(t_start, modes)
    hit = c.__dict__.get("_ida_start")
    if hit is not None and hit[0] == key:
        return hit[1].copy(), hit[2].copy()
    y, yp = c.initial_y(t_start, modes)
    c._ida_start = (key, y.copy(), yp.copy())
    return y, yp


def _start_settle(model, c, fr, t_start, modes):
    """``fr.settle(t_start, None, modes, initial=True)`` (start values and the first mode logic), remembered
    like ``_start_values`` with the state the mode logic keeps (``ModeLogic.snapshot``)."""
    key = _start_key(model, c, t_start, modes)
    if key is None:
        return fr.settle(t_start, None, modes, initial=True)[:3]
    hit = c.__dict__.get("_ida_start_settle")
    if hit is not None and hit[0] == key:
        _, y, yp, new, snap = hit
        fr.restore(snap)
        return y.copy(), yp.copy(), new.copy()
    y, yp, new, _ = fr.settle(t_start, None, modes, initial=True)
    c._ida_start_settle = (key, y.copy(), yp.copy(), np.array(new), fr.snapshot())
    return y, yp, new


def _blame(c, y, yp):
    """Names of the masses with the largest accelerations and the devices with the largest forces."""
    x, v, a, lam, z = c.unpack(y, yp)
    st = c.structure
    order = np.argsort(-np.abs(np.nan_to_num(a, nan=np.inf)))[:3]
    names = [st.coord_names[k] for k in order]
    if len(lam):
        cons = st.position + st.speed + st.friction
        j = int(np.argmax(np.abs(np.nan_to_num(lam, nan=np.inf))))
        names.append(cons[j].device.name)
    return names


def _on_constraints(c, t, y, modes, rates=True):
    """A consistent restart ``(y, y')`` at ``t`` from the state of ``y``: its dummy coordinates from the constraints,
    its accelerations and algebraic unknowns from the laws of ``modes``, not from IDA's interpolant (``rates``: see
    ``CompiledSystem.assemble_y``)."""
    x, v, z = c.ode_lift(t, c.ode_state(y), modes)
    return c.assemble_y(t, x, v, z, modes, rates=rates)


def _native_available() -> bool:
    """Whether IDA can run with compiled callbacks here (numba and SUNDIALS' libraries, ``ida_native``)."""
    from .ida_native import libraries
    return not isinstance(libraries(), str)


@register("ida", IDA_OPTIONS)
def simulate_ida(model, t_start=0.0, t_end=1.0, dt_out=None, rtol=1e-6, atol=None, linsolver=None,
                 max_step=None, max_order=5, dense_max=60, max_events=100000, max_steps=50000, stiff_check=True,
                 chatter_window=None, chatter_count=50, native=None, atol_rescale=True):
    """IDA with analytic sparse Jacobian and event handling (see module docstring).

    A run whose motion turns out small for the absolute tolerance is repeated
    once with the tolerances scaled to it (``_rescaled_atol``); its stats
    then count both runs and ``stats.extra["atol_rescaled"]`` says so.
    ``atol_rescale=False`` makes the one run (the accuracy contract's first
    run: the contract scales its own pair, ``solvers.accuracy``).
    """
    if native is None:      # not asked: compiled callbacks when numba and SUNDIALS' libraries are there
        native = _native_available()
    call = dict(locals())
    rescale = call.pop("atol_rescale")
    res = _run_ida(**call)
    if not rescale:
        return res
    kind_atol = _rescaled_atol(res._traj.c, res._traj.Y, call["rtol"], call["atol"])
    if kind_atol is None:
        return res
    tol, factors = kind_atol
    first_res, res = res, _FirstRun(res.stats)
    scaled = ", ".join(f"{k} {v:.3g}" for k, v in factors.items())
    atol0 = call["rtol"] * 1e-2 if call["atol"] is None else call["atol"]
    try:
        # the repeat may cost what the first run cost, no more: an explicit call is not made to run for minutes
        # behind the user's back (MSL Translational.Examples.PreLoad at rtol 1e-8: 0.48 s, then 431,003 step
        # attempts in the repeat)
        # (counted in residual evaluations; the compiled path, whose evaluations are not counted, in wall time)
        budget = int(REPEAT_BUDGET * first_res.stats.rhs_calls)
        with call_budget(budget), time_limit(REPEAT_WALL * first_res.stats.wall_time + REPEAT_MIN_S,
                                             "the rescaled repeat's budget"):
            again = _run_ida(**call, kind_atol=tol)
    except SimulationTimeout as exc:
        if not isinstance(exc, CallBudgetExceeded) and "the rescaled repeat's budget" not in str(exc):
            raise           # an outer limit (timeout_s) ended it
        first_res.stats.extra["atol_rescaled"] = dict(factors, stopped=True, repeat_budget_calls=budget)
        warnings.warn(
            f"ida on model '{model.name}': the motion is small for atol={atol0:.3g} (atol times {scaled} would be "
            f"relative to it), and the run repeated with those tolerances took more than {REPEAT_BUDGET:g} times "
            f"the first one's evaluations, so it was stopped and the first run is returned: its error on the small "
            f"motion may exceed rtol's promise. "
            f"Pass atol (a scalar or an array) to choose, or atol_rescale=False to silence this.",
            RuntimeWarning, stacklevel=_user_level())
        return first_res
    except SimulationError as exc:
        single = 0.5 * RERUN_FACTOR * min(factors.values()) * atol0    # small enough not to be repeated
        raise SimulationError(
            f"{exc} (This was a repeated run: the motion of model '{model.name}' is small for atol={atol0:.3g}, "
            f"so the absolute tolerances of its kinds of state were scaled to it, atol times: {scaled}. Loosen "
            f"rtol, or pass atol={single:.3g} to make one run with it.)") from exc
    st, first = again.stats, res.stats
    st.extra["atol_rescaled"] = dict(factors, first_run_rhs_calls=first.rhs_calls,
                                     first_run_wall_time=first.wall_time)
    st.wall_time += first.wall_time
    st.rhs_calls += first.rhs_calls
    st.steps += first.steps
    st.jac_calls += first.jac_calls
    st.compile_time = first.compile_time
    warnings.warn(
        f"ida on model '{model.name}': the motion is small for atol={atol0:.3g}, so the run was made again with the "
        f"absolute tolerances scaled to it (atol times {scaled}; res.stats.extra['atol_rescaled'] counts both runs). "
        f"Pass atol to choose, or atol_rescale=False for one run as given.", RuntimeWarning, stacklevel=_user_level())
    return again


def _user_level() -> int:
    """The ``stacklevel`` of a warning issued by the caller that points at the first frame outside regmech (the
    user's ``simulate`` call)."""
    import sys
    frame, level = sys._getframe(1), 1
    while frame is not None and frame.f_globals.get("__name__", "").startswith("regmech"):
        frame, level = frame.f_back, level + 1
    return level


class _FirstRun:
    """What ``simulate_ida`` keeps of a run that is repeated: its stats."""

    def __init__(self, stats):
        self.stats = stats


def _run_ida(model, t_start, t_end, dt_out, rtol, atol, linsolver, max_step, max_order, dense_max, max_events,
             max_steps, stiff_check, chatter_window, chatter_count, native=False, kind_atol=None):
    """One IDA run with ``simulate_ida``'s options; ``kind_atol``: the absolute tolerances of positions,
    speeds and device states per unknown (``_rescaled_atol``), None for the plain ``atol``."""
    t_start, t_end, dt_out = check_times(t_start, t_end, dt_out)
    deadline = run_deadline("ida", model, t_end)
    tc = time.perf_counter()
    c = model.compile()
    compile_time = time.perf_counter() - tc
    t0 = time.perf_counter()
    c.__dict__.pop("_reference_noise", None)        # sampled again for this run's references (``_reference_noise``)
    atol = rtol * 1e-2 if atol is None else atol
    if linsolver is None:
        linsolver, order = choose_linsolver(c, dense_max)
    elif linsolver == "band":
        order = choose_linsolver(c, 0, np.inf)[1]
    else:
        order = _Ordering(c.N)
    grid = output_grid(t_start, t_end, dt_out)
    bps = signal_breakpoints(model, t_start, t_end)
    fr = attach(c).friction      # the friction rows with their mode logic (hybrid/)
    surf = c.__dict__.get("surfaces")       # switching surfaces of piecewise laws (hybrid.surfaces)
    guards = guards_for(c)
    if surf is not None:
        surf.reset()
    modes = fr.start_modes(t_start) if fr else c.modes0
    c._t_right = bps[0] if bps else np.inf
    stats = Stats(solver="ida", compile_time=compile_time, steps=0)   # step attempts (see _make_solver)
    stats.extra["steps_are_attempts"] = True
    if fr:
        y, yp, modes = _start_settle(model, c, fr, t_start, modes)
    else:
        y, yp = _start_values(model, c, t_start, modes)
    events: list[Event] = []
    # the outputs read only the speeds' derivatives of y'
    # room for the rows of a few dozen events too (each stores two rows): growing the recorder copies every row
    rec = Recorder(c.mf, capacity=len(grid) + 2 * len(bps) + 8 + (EVENT_ROWS if fr else 0), yp_cols=c.iv)
    rec.add(t_start, y, yp, modes)
    t = t_start
    bp_iter = iter(bps + [t_end])
    t_stop = next(bp_iter)
    guard = fr.chatter_guard(chatter_window, chatter_count, "ida") if fr else None
    k_max = float(np.abs(c.stiffness_estimate()).max(initial=0.0)) if c.Sc.shape[0] else 0.0
    # a link so much stiffer than the rest that its force's round-off (eps * spread) exceeds
    # the tolerance: Newton and the error test then fail over and over and IDA crawls
    check_link_spread(c, rtol, "ida", stiff_check)
    if native:
        from .ida_native import eligible
        why_not = eligible(c, linsolver, deadline)
        native = why_not is None
        stats.extra["native"] = True if native else f"not used: {why_not}"
        if native:
            stats.extra["steps_are_attempts"] = False        # the native path reads IDA's own step count
    opts = (rtol, atol, linsolver, max_step, max_order, k_max, order, max_steps, native)
    reuse = {}        # the last segment's solver while it may start the next one (see _solve_segment)
    while t < t_end:
        if deadline is not None:
            deadline.note(stats.steps, len(events))
            deadline.check(t)
        c._t_right = t_stop
        if t_stop - t <= 1e-13 * max(1.0, abs(t)):
            # an event landed on a breakpoint (to round-off): nothing to integrate
            sol = None
        else:
            if surf is not None:
                for (name, old, new, kind) in surf.begin(t, y):      # reached at another event's instant
                    events.append(Event(t, name, old, new, kind))
            sol = _solve_segment(c, model, modes, opts, grid, t, t_stop, y, yp, stats, rec, reuse, deadline,
                                 kind_atol, events)
        if sol is not None and sol.status == DISPROVED:
            # a root that was the interpolant's only (``_relocate_root``): on from the re-integration's state, as after
            # a contact
            t = float(sol.t[-1])
            y, yp = _on_constraints(c, t, np.asarray(sol.y[-1]), modes)
            continue
        if sol is not None and sol.status == 2:
            t_ev = float(sol.t_events[-1])
            y_ev, yp_ev = np.array(sol.y_events[-1]), np.array(sol.yp_events[-1])
            f_crossed, s_crossed = guards.split(sol.i_events[-1])
            friction_hit = fr is not None and np.any(f_crossed)
            if friction_hit:
                rec.add(t_ev, y_ev, yp_ev, modes)
            if len(s_crossed):
                # a contact (a kink of a piecewise law): the state is continuous there, so the run goes on
                # from the event's values on the surface's other side
                for (name, old, new, kind) in surf.cross(s_crossed):
                    events.append(Event(t_ev, name, old, new, kind))
            if friction_hit:
                # the mode logic starts from the dummy coordinates on the constraints, as a contact's restart
                # below: from IDA's interpolant, a position servo's were off, and IDA failed its error test at
                # every step size after the restart (calibration seed 6023, a brake reversing under a servo)
                # (the rates of the algebraic unknowns stay IDA's: the logic reads the holding torques' rates; without
                # position or speed constraints there are no dummy coordinates to put right)
                if c.mp + c.mv:
                    y_on, yp_on = _on_constraints(c, t_ev, y_ev, modes, rates=False)
                    yp_on[c.ilam], yp_on[c.iad] = yp_ev[c.ilam], yp_ev[c.iad]
                    y_ev, yp_ev = y_on, yp_on
                y, yp, new_modes, changes = fr.settle(t_ev, (y_ev, yp_ev), modes, crossed=f_crossed)
                for (name, old, new, kind, *value) in changes:
                    events.append(Event(t_ev, name, old, new, kind, value=value[0] if value else None,
                                        work=value[1] if len(value) > 1 else None))
                # a crossing that changed nothing restarts IDA all the same: counted as silent
                guard.record_settle(t_ev, changes, f_crossed, fr.devices)
                modes = new_modes
                rec.add(t_ev, y, yp, modes)
            else:
                # the law's branch changed: the rates of the algebraic unknowns (constraint forces, dummy
                # accelerations) jump at the kink, and IDA's first predictor on the new branch needs theirs
                # the dummy coordinates from the constraints, not from IDA's interpolant at the root: a steep
                # position servo's dummy speed was 8.5e-7 rad/s off there (fuzz seed 60005, 4e5 rad/s^3),
                # and IDA failed its error test on that offset at every step size after the restart
                y, yp = _on_constraints(c, t_ev, y_ev, modes)
                # one row: the state and (the law being continuous) the accelerations are the same on both
                # sides; the consistent one, not IDA's interpolant, whose accelerations come from the old
                # branch's polynomial (the power balance at the row was off by 4e-4 of its scale)
                rec.add(t_ev, y, yp, modes)
            t = t_ev
            if len(events) > max_events:
                raise SimulationError(f"more than {max_events} mode changes and contacts in model '{model.name}'; "
                                      f"raise max_events or simplify the model")
            continue
        if sol is not None:
            y, yp = np.array(sol.y[-1]), np.array(sol.yp[-1])
        # reached t_stop: a time event (signal breakpoint) or the end
        t = t_stop
        if t >= t_end:
            if fr:
                fr.check_final(t, y, yp, modes)         # no device left sliding the wrong way (``check_final``)
            break
        try:
            t_stop = next(bp_iter)
        except StopIteration:
            t_stop = t_end
        c._t_right = t_stop
        if fr:
            y, yp, new_modes, changes = fr.settle(t, (y, yp), modes)
            for (name, old, new, kind, *value) in changes:
                events.append(Event(t, name, old, new, kind, value=value[0] if value else None,
                                    work=value[1] if len(value) > 1 else None))
                guard.record(t, name)
            modes = new_modes
        else:
            y, yp = _on_constraints(c, t, y, modes)     # (see the contact above)
        rec.add(t, y, yp, modes)
    stats.wall_time = time.perf_counter() - t0
    stats.events = len(events)
    from ..compile.outputs import Trajectory
    sol = None               # IDA's own output rows: recorded, not to be held while the recorder stacks them
    T, Y, YP, L, MO = rec.arrays()
    return Result(Trajectory(c, T, Y, YP, L, MO), events, stats, model.name)


def _rescaled_atol(c, Y, rtol, atol):
    """Absolute tolerances for a second run when the first one's motion was small for a scalar ``atol``.

    IDA's error test weighs each unknown by ``rtol |y_i| + atol_i``. For a
    kind of state (positions, speeds, device states) whose largest magnitude
    ``m_k`` in the run is small, ``atol`` exceeds ``rtol m_k`` and the test
    becomes absolute: the error relative to the motion grows as the motion
    shrinks. Measured on the chain of ``tests/unit/test_ida_tolerances.py``
    (0.8, 15.6, 267 and 27.3 kg, springs 8e3 to 1.6e4 N/m, an ElastoBacklash
    with b = 0, the 267 kg mass on a spring to the ground, a force step of F
    on the 0.8 kg mass; its speed against a tight reference, relative to its
    range, rtol 1e-6, 2 s): F = 300 N (positions to 0.16 m, speeds to 4 m/s)
    2.2e-4, 3 N 5.5e-4, 0.3 N 3.4e-3, 0.03 N 1.5e-2 with ``atol = 1e-8``
    (the model is linear: a relative tolerance promises the same error for
    every F); 1.9e-4, 2.3e-4 and 1.9e-4 at 3, 0.3 and 0.03 N with the
    tolerances below. The rule is ``atol_k <= KAPPA rtol m_k``:

        atol_k = max(atol clip(m_k / s, RERUN_FLOOR, 1), min(atol, 1e3 eps m_k)),   s = atol / (KAPPA rtol)

    (``StateScale`` with saturation ``s``: 1 for the default ``atol = rtol *
    1e-2``, as scipy:DOP853 scales its atol; never below the round-off of the
    kind's magnitude). IDA takes its tolerances once per solver: following a
    growing magnitude would cost a restart, a BDF start-up of about 40
    residual calls, at every decade (measured: +23 % CPU time on the library
    scenes), and a run that keeps the tolerances of a motion at rest is many
    times too tight once it moves (+50 % on train_100). So the run is made
    with ``atol`` and repeated once, with the ``atol_k`` of its magnitudes,
    only when some kind that moved had ``atol`` above ``RERUN_FACTOR`` times
    its ``atol_k`` (``m_k < s / 30``: ``atol > 0.3 rtol m_k``). The same
    chain with and without its FrictionContact, step and sine, F from 300 N
    to 10 N (positions 0.16 to 0.002 m), over 2 s: 1.4e-4 to 5.8e-4 with
    ``atol``, 1.4e-4 to 2.5e-4 rescaled; where ``atol <= 0.3 rtol m_k`` the
    plain ``atol`` was at most 1.6 times the rescaled error (over 0.5 s and
    2 s), not worth a second run. On the library scenes no kind is below
    ``s / 30`` (the smallest: one_way_clutch's angles, 0.29 rad) and nothing
    is repeated.

    Returns None (no second run: an array ``atol``, or a motion large enough),
    or ``(per-unknown atol for x, v and z, {kind: factor})``.
    """
    atol = rtol * 1e-2 if atol is None else atol           # the default of ``_run_ida``
    if np.ndim(atol) or not rtol > 0 or not atol > 0:
        return None
    named = [(name, sl) for name, sl in (("positions", c._sx), ("speeds", c._sv), ("device_states", c._sz))
             if len(range(c.N)[sl])]
    scale = StateScale(atol, [idx for _, idx in named], c.N, saturation=atol / (KAPPA * rtol),
                       floor=RERUN_FLOOR)
    Y = np.asarray(Y, float)
    scale.see(np.maximum(Y.max(axis=0), -Y.min(axis=0)))     # |y| per unknown without an |Y| temporary
    # a kind whose magnitude stays within the contract's floor of no motion at all (``richardson.ABSOLUTE_FLOOR``,
    # 1e-12 SI units) has not moved: its values are round-off. Counted as a motion, a stuck clutch's temperature
    # rise of 1.5e-14 K (calibration seed 9001) had the device states' atol scaled to 1e-6 times atol, and the
    # repeated run at rtol 3.6e-10 took 464,587 steps where the plain run took 1,798 residual calls
    moved = scale.largest > ABSOLUTE_FLOOR
    f = scale.factors()
    if not np.any(moved & (f * RERUN_FACTOR < 1.0)):
        return None
    tol = scale.tolerances()
    roundoff = 1e3 * np.finfo(float).eps * scale.largest
    factors = {}
    for k, (name, idx) in enumerate(named):
        if moved[k]:
            tol[idx] = max(float(tol[idx][0]), min(float(atol), roundoff[k]))
        else:
            tol[idx] = atol          # nothing of this kind moved: nothing to resolve more finely
        factors[name] = float(tol[idx][0] / atol)
    return tol, factors


#: points of the run at which a callable reference's finite-difference noise is sampled (``_reference_noise``)
REFERENCE_NOISE_SAMPLES = 257


def _reference_noise(c, t, span=None, level="a"):
    """The round-off [m/s^2 or rad/s^2] in the accelerations that prescribed motions impose (``level`` "a"), or
    [m/s or rad/s] in the speeds that prescribed positions impose ("v"): their references' derivatives taken by
    finite differences (a Python callable: ``Signal.derivative_noise``), 0 for the analytic derivatives of
    regmech's own signals.

    The noise scales with the reference's value, so it is bounded over the run's ``span`` (its largest value on
    ``REFERENCE_NOISE_SAMPLES`` points, kept for the run: ``_run_ida`` clears it at the start of each run, so a
    reference changed between runs is sampled again), not taken at the segment's start ``t`` alone:
    fuzz seed 60000's segment began where its sine reference was small, its dummy accelerations got a tolerance
    below the noise the reference had 0.15 s later, and IDA halved its steps on that noise until max_steps
    (rtol 1e-10)."""
    sigs = _noisy_references(c)[level]
    if not sigs:
        return 0.0
    if span is None or not span[1] > span[0]:
        times = np.array([t])
    else:
        times = np.linspace(span[0], span[1], REFERENCE_NOISE_SAMPLES)
    cache = c.__dict__.setdefault("_reference_noise", {})
    key = (level, None if len(times) == 1 else (float(times[0]), float(times[-1])))
    if key[1] is not None and key in cache:
        return cache[key]
    noise = 0.0
    for s, k in sigs:
        got = max(float(s.derivative_noise(float(ti), k)) for ti in times)
        noise = max(noise, got if np.isfinite(got) else 0.0)
    if key[1] is not None:
        cache[key] = noise
    return noise


def _noisy_references(c) -> dict:
    """Per ``level`` of ``_reference_noise`` the references ``(signal, derivative order)`` whose derivatives are
    taken by finite differences; fixed for a compiled system (its references are read at compile), so found
    once: every segment of every run asks (most models have none)."""
    got = c.__dict__.get("_noisy_references")
    if got is None:
        pos, spd = getattr(c, "_pos_sig", ()), getattr(c, "_spd_sig", ())
        keep = lambda pairs: [(sig, k) for sig, k in pairs if hasattr(sig, "derivative_noise")]
        got = c._noisy_references = {"v": keep([(sig, 1) for _, sig in pos]),
                                     "a": keep([(sig, 2) for _, sig in pos] + [(sig, 1) for _, sig in spd])}
    return got


def _mass_constants(c) -> tuple:
    """``(largest mass, smallest positive mass, masses of the dummy coordinates at least that)`` of a compiled
    system, for ``_atol_vector`` (found once: it runs at every segment)."""
    got = c.__dict__.get("_atol_masses")
    if got is None:
        m_min = float(c.mass[c.mass > 0].min(initial=1.0))
        m_dummy = np.maximum(c.mass[c.Dv], m_min) if len(c.Dv) else np.ones(0)
        got = c._atol_masses = (float(c.mass.max(initial=1.0)), m_min, m_dummy)
    return got


#: rows the recorder of a run with friction devices keeps room for beyond its output and breakpoint rows (two per
#: event: CoupledClutches' 9 events grew it once per run, copying every row)
EVENT_ROWS = 64

#: the unit round-off (a module constant: ``np.finfo`` costs a microsecond per call)
_EPS = float(np.finfo(float).eps)


def _atol_vector(c, atol, rtol, y, yp, k_max, kind_atol=None, t=None, span=None):
    """Absolute tolerances per unknown.

    Positions, velocities and device states take the user's ``atol``, or
    ``kind_atol`` when the run is repeated for a small motion
    (``_rescaled_atol``). The algebraic forces (constraint forces, holding torques) and dummy
    accelerations get ``max(atol, rtol)`` times the largest force (acceleration) present at the segment
    start, and never below the round-off a stiff link puts on them (``eps * k * |x|``):
    with the plain ``atol`` a force passing through zero gets an error
    weight that Newton's iteration can never meet.
    """
    # the accelerations as ``c.unpack`` gives them (the dummy ones from y); no copies of the rest (every segment)
    a = yp[c._sv].copy()
    a[c.Dv] = y[c._sad]
    f_scale = max(1.0, abs_max(y[c._slam]), abs_max(c.mass * a))
    # the forces and dummy accelerations are held to ``rtol`` of the largest present (``max(atol, rtol)``), not to
    # the positions' ``atol`` (default rtol / 100) of it: they follow from the states (the DAE is of index 1),
    # but the BDF formulas give them the error of a derivative, an order lower than the states'. Held to atol,
    # IDA resolved accelerations far beyond what the positions and speeds needed: fuzz CI seed 4004 (two
    # wheels on one hub, a position servo, a sliding clutch) failed its error test on the rolling constraints'
    # forces at every other step (147,360 attempts, 29 s, states 6.6e-6 of their range off at rtol 1e-8); held
    # to rtol, 3,730 attempts, 0.7 s, 2.5e-7 off
    f_tol = max(float(atol), float(rtol))
    noise = 1e3 * _EPS * k_max * max(1.0, abs_max(y[c._sx]))
    vec = np.full(c.N, float(atol)) if kind_atol is None else np.array(kind_atol, float)
    # a prescribed motion whose reference is a callable imposes accelerations known to the round-off of their
    # finite differences only (fuzz CI seed 2002: 5e-11 rad/s^2 on a speed of 18 rad/s): the dummy accelerations
    # and the forces made of them are not asked for more
    ref = 0.0 if t is None else _reference_noise(c, t, span)
    m_max, m_min, m_dummy = _mass_constants(c)
    vec[c.ilam] = f_tol * f_scale + noise + ref * m_max
    a_scale = max(1.0, abs_max(a))
    # a dummy acceleration carries the tolerated force error over its mass (a massless point: the lightest
    # mass's): on seed 4004 a 2 kg tread's acceleration, held to rtol of the largest acceleration, still
    # failed IDA's error test at every other step over the last 0.12 s (41,046 attempts)
    if len(c.iad):
        vec[c.iad] = f_tol * np.maximum(a_scale, f_scale / m_dummy) + noise / m_min + ref
    if t is not None and len(c.Dv):
        # the speeds a callable position reference imposes carry its first derivative's noise (fuzz seed 60012:
        # 2.9e-12 m/s on a tanh reference against atol 1e-12 at rtol 1e-10; IDA halved its steps on it until
        # max_steps at t = 6e-4 s)
        vec[c.iv[c.Dv]] = np.maximum(vec[c.iv[c.Dv]], _reference_noise(c, t, span, "v"))
    return vec


def _unpermute(sol, order):
    """Solution arrays back in the compiled system's order, row by row in place (a second array of
    all output rows would double the memory of a large model's run)."""
    for name in ("y", "yp", "y_events", "yp_events"):
        val = getattr(sol, name, None)
        if val is not None and len(val):
            arr = np.asarray(val)
            if arr is val and arr.ndim == 2 and arr.flags.writeable:
                for row in arr:
                    row[:] = order.from_solver(row)
                continue
            try:
                setattr(sol, name, order.from_solver(arr))
            except AttributeError:
                sol.__dict__[name] = order.from_solver(arr)


def _reusable(reuse, modes, atol_vec):
    """The previous segment's solver, when the next segment may restart it (``_solve_segment``)."""
    if not reuse or not np.array_equal(reuse["modes"], modes):
        return None
    old = reuse["atol"]
    if np.ndim(old) and not (np.all(atol_vec <= 2.0 * old) and np.all(atol_vec >= 0.5 * old)):
        return None
    return reuse["solver"]


def _restart_note(events, t):
    """What an IDA failure's message adds when the segment began at an event (``events``: the run's so far, the last
    of them at ``t``): the devices that changed there, which the largest accelerations and forces need not name."""
    started_by = [e for e in events[-8:] if e.t == t]
    if not started_by:
        return ""
    changes = "; ".join(str(e).split(": ", 1)[-1] for e in started_by[:4])
    return (f" The segment began at the event at t={started_by[0].t:.9g} ({changes}): if IDA fails right after it, "
            f"the other kind of solver (solver='dop853') or the default call (accuracy=...) may take that restart.")


def _solve_segment(c, model, modes, opts, grid, t, t_stop, y, yp, stats, rec, reuse=None, deadline=None,
                   kind_atol=None, events=()):
    """One IDA run from t to t_stop (or to the first mode event); records the output rows. ``events``: the run's so
    far (a failure's message names those at ``t``, ``_restart_note``).

    After a mode event the solver is a fresh one: scikit-sundae's event bookkeeping lives on the
    events function and accumulates across ``solve`` calls. After a time event with the modes
    unchanged (``reuse``, kept by the caller) the previous solver restarts, if the absolute
    tolerances that the forces present call for are within a factor 2 of those it was built with:
    building one costs about as much as a dozen residual calls, which on a run with thousands of
    time events (a Pulse) was a sixth of the time.
    """
    with_events = guards_for(c) is not None
    rtol, atol, linsolver, max_step, max_order, k_max, order, max_steps, native = opts
    atol_vec = atol if np.ndim(atol) else _atol_vector(c, atol, rtol, y, yp, k_max, kind_atol, t,
                                                       (float(grid[0]), float(grid[-1])) if len(grid) else None)
    if native:
        # one native solver serves every segment of the run: re-initialised (IDAReInit) with the segment's
        # tolerances, modes and event functions (its event bookkeeping is ours, see ``ida_native``)
        solver = reuse.get("native") if reuse is not None else None
        if solver is not None and solver.pattern is not c.jac:
            solver = None       # friction rows added at an event grew the Jacobian's pattern: its slots differ
        if solver is None:
            solver = _make_solver(c, modes, rtol, atol_vec, linsolver, max_step, max_order, with_events, order,
                                  max_steps, deadline, native)
            if reuse is not None:
                reuse["native"] = solver
        solver.set_segment(modes, order.to_solver(atol_vec) if np.ndim(atol_vec) else atol_vec)
    else:
        solver = _reusable(reuse, modes, atol_vec)
    if solver is None:
        with sundials_log.kept() as lines:        # SUNDIALS' lines go into the error, not to the terminal
            try:
                solver = _make_solver(c, modes, rtol, atol_vec, linsolver, max_step, max_order, with_events, order,
                                      max_steps, deadline, native)
            except (RuntimeError, ValueError) as exc:
                raise SimulationError(f"IDA could not be set up at t={t:.9g} in model '{model.name}': {exc}."
                                      f"{sundials_log.said(lines)} Check the solver options (rtol, atol, "
                                      f"max_step, max_order, max_steps).") from exc
        if reuse is not None:
            reuse.update(solver=solver, modes=np.array(modes), atol=atol_vec)
    tol = 1e-12 * max(1.0, abs(t_stop))      # grid points within round-off of an end are that end
    # the grid points inside (t, t_stop), found by bisection: a run with many segments does not
    # scan the whole grid for each of them
    inner = grid[np.searchsorted(grid, t + tol, side="right"):np.searchsorted(grid, t_stop - tol, side="left")]
    tspan = np.concatenate([[t], inner, [t_stop]])
    record = np.ones(len(tspan), bool)
    if len(tspan) == 2:       # two times would make IDA return every internal step
        tspan = np.array([t, 0.5 * (t + t_stop), t_stop])
        record = np.array([True, False, True])
    with sundials_log.kept() as lines:            # SUNDIALS' lines go into the error, not to the terminal
        try:
            sol = solver.solve(tspan, order.to_solver(y), order.to_solver(yp))
            if order.perm is not None and not getattr(sol, "unpermuted", False):
                _unpermute(sol, order)
        except (RuntimeError, ValueError, KeyError) as exc:
            raise SimulationError(f"IDA failed near t={t:.9g} in model '{model.name}': {exc!r};"
                                  f"{sundials_log.said(lines)} components most involved: "
                                  f"{_blame(c, y, yp)}.{_restart_note(events, t)}") from exc
    if reuse is not None and sol.status not in (0, 1) and not native:
        reuse.clear()            # a mode event (its bookkeeping stays on the events function) or a failure
    stats.segments += 1
    stats.steps += solver.regmech_attempts[1]
    solver.regmech_attempts[1] = 0        # a reused solver counts on from zero for the next segment
    stats.rhs_calls += int(getattr(sol, "nfev", 0) or 0)
    stats.jac_calls += int(getattr(sol, "njev", 0) or 0)
    if sol.status < 0:
        last_y = sol.y[-1] if len(sol.y) else y
        last_yp = sol.yp[-1] if len(sol.yp) else yp
        t_fail = sol.t[-1] if len(sol.t) else t
        hint = ("Try a tighter rtol, check parameters (very stiff links or tiny masses) or use rm.Scene to "
                "reduce the model")
        if sol.status == -1:    # too many steps in one output interval
            hint = (f"More than max_steps={max_steps} steps in one output interval: a discontinuity that is not "
                    f"declared (a callable signal that jumps: use Step/Table/Pulse, or Function(f, breakpoints=...)), "
                    f"a very stiff or chattering part, or simply a long interval (raise max_steps or lower dt_out)")
        hint = hint.rstrip(".")
        raise SimulationError(
            f"IDA failed at t={t_fail:.9g} in model '{model.name}': {sol.message}{sundials_log.said(lines)}; "
            f"components most involved: {_blame(c, last_y, last_yp)}. {hint}.{_restart_note(events, t)}"
            f"{c.stiffness_hint()}")
    if lines:
        # an error line from a solve that went on (none is known to occur): not dropped silently
        warnings.warn(f"IDA reported at t={t:.9g}..{t_stop:.9g} in model '{model.name}':"
                      f"{sundials_log.said(lines)}", RuntimeWarning, stacklevel=2)
    if sol.status == 2 and len(solver.regmech_attempts) > 2:
        sol, record = _relocate_root(c, model, modes, opts, sol, record, t, y, yp, t_stop, grid, stats,
                                     solver.regmech_attempts[2], atol_vec, deadline)
    if len(solver.regmech_attempts) > 2:
        solver.regmech_attempts[2].clear()
    n_rows = len(sol.t)
    # rows 1.. of the solution, all at once; the event row (status 2) is recorded by the caller, before and
    # after settling; rows beyond ``tspan`` (none in IDA's normal mode) would be kept
    end = n_rows - 1 if sol.status == 2 else n_rows
    wanted = np.concatenate([record, np.ones(max(0, end - len(record)), bool)])[1:max(end, 1)]
    # all rows wanted (every segment but a two-point one): views, no copy of the output rows
    keep = slice(1, max(end, 1)) if wanted.all() else np.arange(1, max(end, 1))[wanted]
    T = np.asarray(sol.t)[keep]
    rec.add_rows(T, np.asarray(sol.y)[keep], np.asarray(sol.yp)[keep], modes, T >= t_stop)
    return sol


def _law_mismatch(c, t_ev, y_ev, yp_ev, modes, h, rtol, atol_vec):
    """How far the step that found a root departs from the model's law at the root: the largest difference
    between the accelerations of the law at the root's state (``c.accelerations``, the modes before the
    event) and the step's own (its interpolant's y'), times the step ``h``, over the speeds' tolerance
    ``rtol |v| + atol``. About 1 or less on a step whose polynomial follows the law (its local error); far
    more when the law changed inside the step where the step did not sample it (a friction table's knee
    passed between two step ends, fuzz seed 346: 4e7 at rtol 1e-8)."""
    x, v, a, lam, z = c.unpack(y_ev, yp_ev)
    with np.errstate(all="ignore"):
        a_law = c.accelerations(t_ev, x, v, z, modes)[0]
        tol = rtol * np.abs(v) + (atol_vec[c.iv] if np.ndim(atol_vec) else atol_vec)
        off = np.abs(a_law - a) * h / tol
    return float(np.nan_to_num(off, nan=np.inf).max(initial=0.0))


#: the status of a segment's solution whose root ``_relocate_root`` disproved: it ends at the crossing step's end,
#: inside the segment, and the run goes on from there in the same modes
DISPROVED = 3


def _relocate_root(c, model, modes, opts, sol, record, t, y, yp, t_stop, grid, stats, recent, atol_vec, deadline):
    """A root of an event function found on a step that did not follow the law near it, found again.

    Why: IDA's error test sees the law only at the step's ends (its corrector's times). A friction table
    with a knee between those ends is invisible to it when both ends lie on the same linear piece of the
    table: on fuzz seed 346 (a clutch whose friction falls by 66 % within |w_rel| < 0.188 rad/s) the model is
    linear above the knee, IDA's last step ran from |w_rel| = 0.237 to w_rel = -0.447 with the table's top
    all the way, and the stick located on that step's interpolant came 2.2 ms early, at rtol 1e-8 and 1e-10
    alike (the ODE-form solvers have ``ode_driver._relocate`` for the same class). Detected by
    ``_law_mismatch`` at the root; then the segment is integrated again from the last output row at or before
    the crossing step's start that follows the law itself (the same test: rows interpolated on a step that
    straddled a knee do not; at most ``RELOCATE_BACK_ROWS`` of them, else the segment start), with steps
    bounded by ``1 / RELOCATE_SHRINK`` of that step, up to that step's end, and the root is located on those steps
    (at most ``RELOCATE_ROUNDS`` times, until the law is followed). The re-integration's rows replace the original
    ones after its start. A re-integration that fails keeps the original (the root stands as found); one that
    finds no root up to the crossing step's end disproves it: the segment goes on from that end (status
    ``DISPROVED``, the caller restarts there in the same modes).

    The bounded steps begin at the restart row only when the restart stepped back over rows that depart from
    the law (the steps under them did too). When the restart row is the last one before the crossing step and
    follows the law, the steps from it up to ``RELOCATE_REACH`` crossing steps before that step run with the
    run's own step limit, as they did in the run, and only the rest is bounded: a row can lie far before a
    short crossing step (a sparse output grid, or none before the root), and bounding all of that stretch
    cost steps in proportion to its length over the crossing step's (fuzz seed 10288: 85,000 steps of
    7.2e-9 s from the segment start to a stick at 6.1e-4 s, where the run took 90 steps; now 108).

    ``recent``: the last distinct times of the residual calls (``_make_solver``); returns ``(sol, record)``.
    """
    rtol, atol, linsolver, max_step, max_order, k_max, order, max_steps, native = opts
    best, best_record = sol, record
    for _ in range(RELOCATE_ROUNDS):
        t_ev = float(sol.t_events[-1])
        ends = [s for s in recent if s >= t_ev]
        starts = [s for s in recent if t <= s < t_ev]
        if not ends:
            break
        t_b = min(max(ends), t_stop)
        t_a = max(starts) if starts else t
        h = t_b - t_a
        if not h > 0 or _law_mismatch(c, t_ev, np.asarray(sol.y_events[-1]), np.asarray(sol.yp_events[-1]), modes,
                                      h, rtol, atol_vec) <= RELOCATE_MISMATCH:
            break
        # restart: the last recorded output row at or before the crossing step's start, else the segment start
        T = np.asarray(sol.t)
        n_out = len(T) - 1                      # the last row is the root's
        rows = [i for i in range(1, n_out) if T[i] <= t_a and record[min(i, len(record) - 1)]]
        # a row on a step that crossed a knee carries that step's error (its interpolant, not the law): the
        # restart goes back past the rows whose accelerations depart from the law as the crossing step's did
        # (fuzz seed 10484 at dt_out 3.5e-5: a bearing table's knee passed one step before the reversal; the
        # restart from the row just before the crossing step left the reversal 3.6e-6 s late, 0.05 rad/s)
        back = 0
        while rows and back < RELOCATE_BACK_ROWS:
            i = rows[-1]
            if _law_mismatch(c, float(T[i]), np.asarray(sol.y[i]), np.asarray(sol.yp[i]), modes, h, rtol,
                             atol_vec) <= RELOCATE_MISMATCH:
                break
            rows.pop()
            back += 1
        if back >= RELOCATE_BACK_ROWS:
            rows = []                           # far back: from the segment start
        if rows:
            i_r = rows[-1]
            t_r = float(T[i_r])
            xr, vr, ar, lamr, zr = c.unpack(np.asarray(sol.y[i_r]), np.asarray(sol.yp[i_r]))
            y_r, yp_r = c.assemble_y(t_r, xr, vr, zr, modes)
        else:
            i_r, t_r, y_r, yp_r = 0, t, y, yp
        bound = h / RELOCATE_SHRINK if not max_step else min(max_step, h / RELOCATE_SHRINK)
        # the bounded steps begin near the crossing step: from the restart row only when rows were stepped back
        # over (they lie on steps that departed from the law); else the restart row follows the law and the
        # steps up to RELOCATE_REACH crossing steps before the crossing run unbounded, as they did in the run
        # itself (fuzz seed 10288: no output row before a stick at 6.1e-4 s, h = 5.8e-8 s; bounded from the
        # segment start, the re-integration took 85,000 steps of 7.2e-9 s where the run took 90)
        t_s = t_r if back else max(t_r, t_a - RELOCATE_REACH * h)
        tol = 1e-12 * max(1.0, abs(t_b))
        on_grid = grid[np.abs(grid - t_s) <= tol]
        if len(on_grid):
            t_s = float(on_grid[0])         # a grid point at the seam is that point, recorded once
        approach = None
        if t_s > t_r + tol:
            approach = _reintegrate(c, modes, opts, atol_vec, t_r, y_r, yp_r, t_s, grid, max_step,
                                    bool(len(on_grid)), stats, deadline)
            if approach is None:
                break                                   # the original root stands
            solA, recA, solverA = approach
        if approach is not None and solA.status == 2:
            # a root before the bounded stretch: it stands for the crossing step's (checked again next round)
            sol2, rec2, again = solA, recA, solverA
        else:
            if approach is not None:
                xs, vs, _, _, zs = c.unpack(np.asarray(solA.y[-1]), np.asarray(solA.yp[-1]))
                y_s, yp_s = c.assemble_y(t_s, xs, vs, zs, modes)
            else:
                t_s, y_s, yp_s = t_r, y_r, yp_r
            bounded = _reintegrate(c, modes, opts, atol_vec, t_s, y_s, yp_s, t_b, grid, bound, t_b >= t_stop,
                                   stats, deadline)
            if bounded is None:
                break                                   # the original root stands
            sol2, rec2, again = bounded
            if approach is not None:
                sol2 = _Merged(solA, len(solA.t) - 1, sol2)
                rec2 = np.concatenate([recA, rec2[1:]])
        stats.extra["relocated_roots"] = stats.extra.get("relocated_roots", 0) + 1
        if sol2.status != 2:
            # no root up to the crossing step's end: the root was the step's interpolant's, not the law's. The run
            # goes on from the re-integration's state there (``DISPROVED``), not from the root: fuzz seed 92047, a
            # mass sliding through the knee of its friction table in one 0.029 s step, whose interpolant reached
            # zero slip where the law's speed was still 0.39 m/s; restarted stuck, both runs of the accuracy
            # pair agreed and the default call returned 7.2e-3 of the range off against an estimate of 1.3e-5
            merged = _Merged(sol, i_r, sol2)
            if sol2.status != 0 or float(merged.t[-1]) < t_stop:
                merged.status = DISPROVED
            return merged, _merged_record(record, i_r, rec2, len(merged.t))
        sol = _Merged(sol, i_r, sol2)
        record = _merged_record(record, i_r, rec2, len(sol.t))
        best, best_record = sol, record
        recent, t = list(again.regmech_attempts[2]), t_r
    return best, best_record


def _reintegrate(c, modes, opts, atol_vec, t0, y0, yp0, t1, grid, bound, record_end, stats, deadline):
    """IDA from (t0, y0, yp0) to t1 with events and steps of at most ``bound`` (None: no limit) for
    ``_relocate_root``; returns ``(sol, record, solver)``, None when IDA fails (the original root then stands)."""
    rtol, atol, linsolver, max_step, max_order, k_max, order, max_steps, native = opts
    tol = 1e-12 * max(1.0, abs(t1))
    inner = grid[np.searchsorted(grid, t0 + tol, side="right"):np.searchsorted(grid, t1 - tol, side="left")]
    tspan = np.concatenate([[t0], inner, [t1]])
    rec = np.concatenate([[True], np.ones(len(inner), bool), [record_end]])
    if len(tspan) == 2:
        tspan, rec = np.array([t0, 0.5 * (t0 + t1), t1]), np.array([True, False, record_end])
    solver = _make_solver(c, modes, rtol, atol_vec, linsolver, bound, max_order, True, order, max_steps, deadline)
    with sundials_log.kept():
        try:
            sol = solver.solve(tspan, order.to_solver(y0), order.to_solver(yp0))
            if order.perm is not None:
                _unpermute(sol, order)
        except (RuntimeError, ValueError, KeyError):
            return None
    stats.rhs_calls += int(getattr(sol, "nfev", 0) or 0)
    stats.jac_calls += int(getattr(sol, "njev", 0) or 0)
    stats.steps += solver.regmech_attempts[1]
    if sol.status < 0:
        return None
    return sol, rec, solver


def _merged_record(record, i, second, n):
    """The record flags of ``_Merged(first, i, second)``'s ``n`` rows: ``record``'s up to row ``i``, then
    ``second``'s after its first row (rows beyond both recorded)."""
    head = record[:i + 1] if len(record) > i else np.ones(i + 1, bool)
    return np.concatenate([head, second[1:], np.ones(max(0, n - i - len(second)), bool)])[:n]


class _Merged:
    """An IDA solution made of the rows 0..i of ``first`` and the rows after the first of ``second`` (which
    starts at row i's time), with ``second``'s status and events."""

    def __init__(self, first, i, second):
        self.t = np.concatenate([np.asarray(first.t)[:i + 1], np.asarray(second.t)[1:]])
        self.y = np.concatenate([np.asarray(first.y)[:i + 1], np.asarray(second.y)[1:]])
        self.yp = np.concatenate([np.asarray(first.yp)[:i + 1], np.asarray(second.yp)[1:]])
        self.status, self.message = second.status, second.message
        for name in ("t_events", "y_events", "yp_events", "i_events"):
            setattr(self, name, getattr(second, name))
        self.nfev = self.njev = 0            # counted by ``_relocate_root``
