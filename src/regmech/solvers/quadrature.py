"""Accurate time integrals of a run's signals: heat, work, any power (``Result.integral``).

A signal is known at the output rows only. Its integral by the trapezoidal
rule over those rows is as good as the rows resolve it: a brake stopping an
inertia inside one output interval (fuzz seed 10288: 0.6 ms, a friction
table falling with speed) books 0.151 J of heat for a true 0.091 J, and a
damper in an oscillation faster than ``dt_out`` books anything. The error
does not fall with the solver's tolerance, only with ``dt_out``.

Here the integral follows the model's own laws between the rows. On each
output interval ``[t_k, t_k+1]`` (h > 0; an event instant appears twice, so
the modes are constant inside, ``Trajectory``) the ODE state ``u`` is
interpolated by the cubic Hermite polynomial of its values and slopes
``g = u'`` at both ends, and the signal ``p`` is evaluated at the midpoint
from that state (the row of the consistent algebraic values, as the solvers
record their rows). Two tests decide whether the rows resolve the interval:

* the quadrature: Simpson's rule ``S = h (p_k + 4 p_m + p_k+1) / 6`` against
  the trapezoid ``T = h (p_k + p_k+1) / 2``; ``|S - T|`` is the trapezoid's
  error for a smooth integrand, and Simpson's is smaller by the factor
  ``r / 10``, ``r = |S - T| / (h mean|p|)`` (``(h / tau)^2 / 12`` for an
  integrand smooth on the time scale ``tau``; the rule's ``h^5 p^(4) / 2880``
  is about ``r / 20`` of ``|S - T|``);
* the motion: the defect of the interpolant, ``g(t_m, u_m) - u_m'``, times
  ``h / 4`` relative to each state's scale (the state error it stands for).
  Where the motion and ``p`` share their time scale it is about ``36 r^2``;
  far above that (``100 r^2 + tol``) the motion changes inside the interval
  in a way the three values of ``p`` do not show (a brake stopping inside).

The error estimate of an interval is ``r |S - T| / 10``, or ``|S - T|`` where the
interval's ``|S - T| / h^3`` exceeds four times both neighbours' (a kink of
``p`` inside, a friction table's knee: Simpson's error is then as large as
``|S - T|``). Each signal on its own keeps ``S`` on its intervals from the
smallest estimate up while the estimates add up to half its tolerance, unless
the motion test fails. An interval some signal does not keep is integrated
again (once for all the signals; a signal that kept ``S`` there keeps it) from
its first row with the model's right-hand side (``u' = g(t, u)`` in the
interval's modes; scipy's DOP853, or Radau when the interval is stiff for
it) at a tolerance a hundred times tighter, and ``p`` is summed by 3-point
Gauss-Legendre on each of that run's steps (order 6). The signals' kinks
(a friction table's knee) fall inside a step there, but the steps are short.
The Gauss sum ``G`` of each step is checked against the trapezoid ``T`` over
the step's ends, read from the solver's own step values: the dense output
between them can swing where the ends are accurate (DOP853 at its stability
limit on a stiff branch), and a step with ``|G - T| > STEP_RESOLVED h mean|p|``
counts its whole ``|G - T|``; a method whose estimate exceeds the interval's
share of a needing signal's tolerance hands over to the next one.

The error allowed for signal ``p`` is ``tol * scale`` for the whole run;
``scale`` is ``int |p| dt`` (the trapezoid of ``|p|``), for a power [W] not
below ``ROUNDOFF_SHARE`` of the run's largest kinetic energy (an ideal element's
power is round-off), and ``tol`` the run's accuracy (``accuracy=``), else its
``rtol``, else 1e-6. The estimate returned is the sum of the kept intervals'
estimates and of the re-integrations' (their steps' estimates plus their own
tolerance shares).

Every loop is bounded: a re-integration tries DOP853 (``EXPLICIT_RHS_CALLS``
right-hand sides), Radau and LSODA (``MAX_RHS_CALLS`` each); when none gets
through, Simpson's value stands with its whole ``|S - T|`` in the estimate
and a ``RuntimeWarning`` names the signals, the interval and the remedy (a
finer ``dt_out``); after ``MAX_FAILURES`` such intervals, or ``TOTAL_RHS_CALLS`` evaluations in all, the others flagged
keep Simpson's value the same way, untried.
"""

from __future__ import annotations

import numpy as np

from ..errors import RegmechError


#: right-hand side evaluations allowed to each implicit method of the re-integration of one output interval
MAX_RHS_CALLS = 20_000
#: re-integrations that may fail in one call before the remaining flagged intervals keep Simpson's value (each
#: failure costs its whole budget: fuzz seed 60011 failed 69 intervals, 2.5-3.7 s each)
MAX_FAILURES = 2
#: right-hand side evaluations of all the re-integrations of one call together: beyond them the intervals left keep
#: Simpson's value, counted whole in the estimate and said (fuzz seed 60105: 65 intervals re-integrated at
#: about 11,000 evaluations each, 97 s to read one heat of a 0.3 s run, which looked like a hang)
TOTAL_RHS_CALLS = 100_000
#: right-hand sides allowed to DOP853 before the re-integration of an interval turns to an implicit method
EXPLICIT_RHS_CALLS = 5_000
#: ODE states up to which Radau differences its Jacobian densely (scipy's own); above, the ODE form's sparse one
DENSE_JACOBIAN_MAX = 200
#: the re-integration's tolerance relative to the integral's (states far more accurate than the sum needs)
TIGHTER = 1e-2
#: Simpson's error estimate as a share of ``r |S - T|``: asymptotically 1/20 (``h^5 p^(4) / 2880`` over
#: ``(h^3 p'' / 12)^2 / (h p)`` on a smooth integrand), with a factor 2 of margin
SIMPSON_SHARE = 0.1
#: an interval whose Hermite defect exceeds this times r^2 (plus tol) is integrated again (``cumulative``)
DEFECT_MARGIN = 100.0
#: a step of a re-integration whose Gauss sum differs from the trapezoid over its ends by more than this share
#: of ``h mean|p|`` is not resolved by the solver's interpolant: its whole difference is counted (``_step_sums``)
STEP_RESOLVED = 0.1
#: a power's integral is asked to within ``tol`` of its own scale, but not finer than ``tol`` times this share of
#: the run's kinetic energy: below that its values are round-off (an ideal gear's power, 1e-19 W beside a tyre's
#: kW), which no re-integration can make more accurate (``_floors``)
ROUNDOFF_SHARE = 1e-9
#: Gauss-Legendre nodes and weights on [0, 1], 3 points (exact for polynomials of degree 5)
_GL_X = 0.5 + 0.5 * np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_GL_W = np.array([5.0, 8.0, 5.0]) / 18.0


class _Budget(Exception):
    pass


class _Segment:
    """The run's hidden state of one output interval set on the compiled system while its laws are evaluated
    there, and put back after: the end of the interval (``_t_right``: time signals read as left limits at it,
    no breakpoint lies inside) and the driving side of each rolling lossy gear (``FrictionRows.quadrant``, which
    the modes do not record: it is read off the interval's first row, the sign of the gear's ``tau_eta``
    there, as the mode logic set it; its changes are events, so it is constant inside)."""

    def __init__(self, c, t_right, quadrant=None):
        self.c, self.t_right, self.quadrant = c, float(t_right), quadrant

    def __enter__(self):
        c = self.c
        self.saved = (c._t_right, c.friction.quadrant if c.mf else None)
        c._t_right = self.t_right
        if self.quadrant is not None:
            c.friction.quadrant = self.quadrant
        return self

    def __exit__(self, *exc):
        c = self.c
        c._t_right = self.saved[0]
        if c.mf:
            c.friction.quadrant = self.saved[1]
        return False


def _quadrant(c, y, modes):
    """The driving side of each rolling lossy gear at output row ``y`` (None: the model has none)."""
    fr = c.friction if c.mf else None
    if fr is None or not fr._coupled_rows:
        return None
    # a copy: ``_iterate_quadrants`` returns the segment's own array where no side changes
    return np.array(fr._iterate_quadrants(y[c._sv], y[c._slam], modes), int, copy=True)


def _rows(traj, times, states, modes, t_right, quadrants=None):
    """The output rows (``y``, ``y'``) of ODE states at ``times`` (``consistent_row``): point i in the modes
    ``modes[i]`` and the segment state of its output interval (``_Segment``: ``t_right[i]``, ``quadrants[i]``)."""
    from .ode_driver import consistent_row
    c = traj.c
    Y = np.empty((len(times), c.N))
    YP = np.empty((len(times), c.N))
    for i, (tq, u) in enumerate(zip(times, states)):
        with _Segment(c, t_right[i], None if quadrants is None else quadrants[i]):
            Y[i], YP[i] = consistent_row(c, float(tq), u, modes[i])
    return Y, YP


def _sub(traj, times, Y, YP, modes):
    """A trajectory of rows that are not output rows (the signals' recipes read it as they read the run)."""
    from ..compile.outputs import Trajectory
    return Trajectory(traj.c, np.asarray(times, float), Y, YP, np.zeros(len(times), bool), np.asarray(modes))


def _rhs(c, modes, t_right, counter, quadrant=None, limit=None):
    limit = MAX_RHS_CALLS if limit is None else limit

    def f(t, u):
        counter[0] += 1
        if counter[0] > limit:
            raise _Budget()
        with _Segment(c, t_right, quadrant):
            return c.ode_rhs(t, u, modes)
    return f


def _solve(c, t0, t1, u0, modes, rtol, atol, quadrant, method, limit):
    """One method's solution of the motion over ``[t0, t1]`` in the interval's modes (scipy's ``solve_ivp``
    with dense output), the right-hand sides it spent; None where it failed or ran out of its budget."""
    from scipy.integrate import solve_ivp

    from .ode_driver import OdeProblem
    counter = [0]
    f = _rhs(c, modes, t1, counter, quadrant, limit)
    opts = {}
    if method == "Radau" and len(u0) > DENSE_JACOBIAN_MAX:
        problem = OdeProblem(c, modes)

        def jac(t, u):
            with _Segment(c, t1, quadrant):
                return problem.jacobian(t, u)
        opts["jac"] = jac
    try:
        with np.errstate(all="ignore"):
            sol = solve_ivp(f, (t0, t1), u0, method=method, rtol=rtol, atol=atol, dense_output=True, **opts)
    except (_Budget, ValueError, ArithmeticError, np.linalg.LinAlgError, RegmechError):
        # the method failed in this interval (fuzz seed 60110: Radau's motion, frozen in the interval's
        # modes, ran to inf and scipy's LU refused its matrix with a ValueError that reached the user's
        # ``res['bearing1.heat']``): the next method tries, and Simpson's value stands if none gets through
        sol = None
    return (sol if sol is not None and sol.success else None), counter[0]


def _step_sums(traj, names, sol, t1, modes, quadrant):
    """``(G, est)`` over one solution's steps for each signal: ``G`` the 3-point Gauss-Legendre sums of ``p``
    from the dense output, ``est`` their error estimates (``STEP_RESOLVED``)."""
    steps = np.asarray(sol.t, float)
    a, b = steps[:-1], steps[1:]
    hs = b - a
    # the Gauss nodes of every step and the step ends: p at the ends, from the solution's own step values (not
    # the interpolant), checks the interpolant between them
    tq = np.concatenate([(a[:, None] + hs[:, None] * _GL_X[None, :]).ravel(), steps])
    uq = np.concatenate([sol.sol(tq[:-len(steps)]).T, np.asarray(sol.y, float).T])
    mq = np.repeat(np.asarray(modes)[None, :], len(tq), axis=0)
    Y, YP = _rows(traj, tq, uq, mq, np.full(len(tq), t1), None if quadrant is None else [quadrant] * len(tq))
    sub = _sub(traj, tq, Y, YP, mq)
    n3 = 3 * len(a)
    G = np.empty(len(names))
    est = np.empty(len(names))
    for j, nm in enumerate(names):
        pv = np.asarray(sub.get(nm), float)
        pq, pe = pv[:n3].reshape(len(a), 3), pv[n3:]
        g = hs * (pq @ _GL_W)
        trap = hs * (pe[:-1] + pe[1:]) / 2
        diff = np.abs(g - trap)
        mean = hs * (np.sum(np.abs(pq), axis=1) + np.abs(pe[:-1]) + np.abs(pe[1:])) / 5
        r = np.minimum(1.0, diff / np.where(mean > 0, mean, np.inf))
        # a step the interpolant resolves: Gauss's error far below r |G - T| (as Simpson's in ``cumulative``);
        # one it does not (DOP853 at its stability limit on a stiff branch, whose dense output swings between
        # accurate step ends: a tyre's 0.02 W read as 100 W at the nodes) counts its whole |G - T|
        est[j] = float(np.sum(np.where(r > STEP_RESOLVED, diff, diff * r * SIMPSON_SHARE)))
        G[j] = float(np.sum(g))
    return G, est


def _reintegrate(traj, names, k, u0, modes, tol_state, scale_u, share, need, quadrant=None):
    """``int p dt`` of each signal of ``names`` over output interval k, integrating the motion again from row k
    (module docstring); returns (the integrals, their error estimates, right-hand sides spent), or (None, None,
    spent) when no method got through the interval within its budget. ``share``: each signal's error allowed on
    the interval; a method's result is taken when the signals that need it (``need``) are within theirs, else
    the next method tries and the best result stands with its estimate."""
    c = traj.c
    t0, t1 = float(traj.t[k]), float(traj.t[k + 1])
    rtol = max(tol_state * TIGHTER, 1e-12)
    atol = np.maximum(rtol * scale_u, 1e-300)
    spent = 0
    best = None
    # DOP853 first, on a short leash (an interval that is stiff for it would cost its stability limit's steps),
    # then Radau (scipy's own dense difference Jacobian on a small model, the ODE form's sparse one on a large:
    # the grouped differences missed entries of a gearbox with lossy gears, fuzz seed 60011, and Radau's Newton
    # iteration failed), then LSODA
    for method, limit in (("DOP853", EXPLICIT_RHS_CALLS), ("Radau", MAX_RHS_CALLS), ("LSODA", MAX_RHS_CALLS)):
        if limit <= 0:
            continue
        sol, calls = _solve(c, t0, t1, u0, modes, rtol, atol, quadrant, method, limit)
        spent += calls
        if sol is None:
            continue
        vals, est = _step_sums(traj, names, sol, t1, modes, quadrant)
        # the motion's own error (its tolerance a hundred times tighter than the integral's) on top
        est = est + share * TIGHTER
        worst = float(np.max(np.where(need, est / np.where(share > 0, share, np.inf), 0.0)))
        if best is None or worst < best[2]:
            best = (vals, est, worst)
        if worst <= 1.0:
            break
    if best is None:
        return None, None, spent
    return best[0], best[1], spent


def _kink_suspects(diff, h, live):
    """Intervals where ``p`` may have a kink inside: ``|S - T| / h^3`` (``p''`` of a smooth integrand) more than
    4 times that of each live neighbour interval (a smooth curvature changes slowly from one interval to the
    next), or with no live neighbour to compare with."""
    curv = np.max(diff, axis=0) / h ** 3
    n = len(live)
    left = np.full(n, np.nan)
    right = np.full(n, np.nan)
    adj = np.flatnonzero(np.diff(live) == 1)          # live[i + 1] is the interval right after live[i]
    left[adj + 1] = curv[adj]
    right[adj] = curv[adj + 1]
    bound = np.fmax(left, right)                       # the larger neighbour (NaN only where there is none)
    with np.errstate(invalid="ignore"):
        return ~(curv <= 4.0 * bound)


def _floors(traj, names):
    """The absolute floor of each signal's scale (``ROUNDOFF_SHARE``): for a power [W], that share of the run's
    largest kinetic energy ``max_t sum m v^2 / 2`` [J]; 0 for any other signal."""
    from ..units import signal_unit
    c = traj.c
    V = np.asarray(traj.Y)[:, c.iv]
    kinetic = float(np.max(0.5 * (V ** 2) @ np.asarray(c.mass, float), initial=0.0))
    out = np.zeros(len(names))
    for j, nm in enumerate(names):
        try:
            unit = signal_unit(c.model.components, nm)
        except Exception:       # a signal whose component declares no unit: no floor
            unit = None
        if unit == "W":
            out[j] = ROUNDOFF_SHARE * kinetic
    return out


def _midpoints(traj, names, live, U, G_rows, modes_rows, quads, counter):
    """The Hermite midpoints of the live intervals (module docstring): ``(PM, defect)``, the signals there and
    the interpolant's defect relative to each state's scale."""
    c = traj.c
    t, h = traj.t, np.diff(traj.t)
    scale_u = _state_scales(U)
    mid_t = np.empty(len(live))
    mid_u = np.empty((len(live), U.shape[1]))
    dmid = np.empty_like(mid_u)
    for i, k in enumerate(live):
        t0, t1, hk = float(t[k]), float(t[k + 1]), float(h[k])
        if G_rows is not None:
            g0, g1 = G_rows[k], G_rows[k + 1]
        else:
            f = _rhs(c, modes_rows[k], t1, counter, quads[i], limit=np.inf)   # two a row: bounded by the rows
            g0, g1 = f(t0, U[k]), f(t1, U[k + 1])
        mid_t[i] = 0.5 * (t0 + t1)
        mid_u[i] = 0.5 * (U[k] + U[k + 1]) + hk * (g0 - g1) / 8.0
        dmid[i] = 1.5 * (U[k + 1] - U[k]) / hk - 0.25 * (g0 + g1)
    Y, YP = _rows(traj, mid_t, mid_u, modes_rows[live], t[live + 1], quads)
    gm = np.array([c.ode_state(yp) for yp in YP]).reshape(len(live), U.shape[1])
    sub = _sub(traj, mid_t, Y, YP, modes_rows[live])
    PM = np.array([np.asarray(sub.get(nm), float) for nm in names])
    hl = h[live]
    defect = np.max(np.abs(gm - dmid) * (hl / 4.0)[:, None] / scale_u[None, :], axis=1) if U.shape[1] else \
        np.zeros(len(live))
    return PM, defect


def _state_scales(U):
    scale_u = np.maximum(np.max(np.abs(U), axis=0), np.ptp(U, axis=0))
    return np.where(scale_u > 0, scale_u, 1.0)


def _select(err, frac, unresolved):
    """Which signal keeps Simpson's value on which live interval: each signal on its own (its tolerance is its
    own: a signal at round-off beside another must not send the other's intervals to be integrated again), from
    its smallest estimate up while their sum stays within half its tolerance, never where the motion is not
    resolved. Returns ``keep`` (signals x intervals)."""
    keep = np.repeat(~unresolved[None, :], err.shape[0], axis=0)
    for j in range(err.shape[0]):
        order = np.flatnonzero(keep[j])[np.argsort(frac[j, keep[j]], kind="stable")]
        keep[j, order[np.cumsum(frac[j, order]) > 0.5]] = False
    return keep


def cumulative(traj, names, tol=1e-6):
    """``{name: (I, estimate)}`` for each signal of ``names``: ``I[i] = int_{t_0}^{t_i} p dt`` at every output
    row and an estimate of its largest error; and counts (intervals looked at, re-integrated, right-hand sides
    spent). The signals share the midpoint rows and the re-integrations; each keeps to its own tolerance."""
    c = traj.c
    t = traj.t
    names = list(names)
    P = np.array([np.asarray(traj.get(nm), float) for nm in names]).reshape(len(names), len(t))
    n = len(t)
    stats = {"intervals": 0, "reintegrated": 0, "rhs_calls": 0}
    if n < 2 or not names:
        return {nm: (np.zeros(n), 0.0) for nm in names}, stats
    h = np.diff(t)
    trap = h[None, :] * (P[:, 1:] + P[:, :-1]) / 2
    inc = np.concatenate([np.zeros((len(names), 1)), trap], axis=1)
    span = float(t[-1] - t[0])
    scale = np.sum(h[None, :] * (np.abs(P[:, 1:]) + np.abs(P[:, :-1])) / 2, axis=1)
    live = np.flatnonzero((h > 0) & np.any((P[:, 1:] != 0) | (P[:, :-1] != 0), axis=0))
    if span <= 0.0 or not len(live) or not np.any(scale > 0):
        return {nm: (np.cumsum(inc[j]), 0.0) for j, nm in enumerate(names)}, stats
    # each signal's error allowed for the whole run: tol of its own scale, not below round-off (``_floors``)
    tol_abs = tol * np.maximum(scale, _floors(traj, names))
    stats["intervals"] = int(len(live))
    modes_rows = np.asarray(traj.modes)
    if modes_rows.ndim != 2:
        modes_rows = np.zeros((n, 0), np.int64)
    # ODE states at the rows, their slopes in each interval's modes (the end's as a left limit), the Hermite
    # midpoints, and the rows of the consistent values there: all intervals first, then one signal evaluation
    Y_rows = np.asarray(traj.Y)
    U = np.concatenate([Y_rows[:, c.ix[c.Kx]], Y_rows[:, c.iv[c.Kv]], Y_rows[:, c.iz]], axis=1)   # ode_state
    # the slopes u' = (v_K, a_K, z') at the rows from the rows themselves (a model without internal states:
    # the rows keep the accelerations, no right-hand side to evaluate); z' is not kept, so a model with
    # internal states evaluates g at both ends of each interval in its modes
    G_rows = None
    if c.nz == 0:
        G_rows = np.concatenate([Y_rows[:, c.iv[c.Kx]], np.asarray(traj.YPv)[:, c.Kv]], axis=1)
    counter = [0]
    quads = [_quadrant(c, traj.Y[k], modes_rows[k]) for k in live]
    PM, defect = _midpoints(traj, names, live, U, G_rows, modes_rows, quads, counter)
    hl = h[live]
    simpson = hl[None, :] * (P[:, live] + 4.0 * PM + P[:, live + 1]) / 6.0
    share = tol_abs[:, None] * (hl / span)[None, :]
    diff = np.abs(simpson - trap[:, live])
    # Simpson's own error: for an integrand smooth on the time scale tau, |S - T| ~ h^3 |p''| / 12 is the
    # trapezoid's error and Simpson's h^5 |p^(4)| / 2880 is about r / 20 of it, r = |S - T| / (h mean|p|) ~
    # (h / tau)^2 / 12 (SIMPSON_SHARE keeps a factor 2 of margin on that)
    mean_p = hl[None, :] * (np.abs(P[:, live]) + np.abs(PM) + np.abs(P[:, live + 1])) / 3.0
    r = np.minimum(1.0, diff / np.where(mean_p > 0, mean_p, np.inf))
    err = diff * r * SIMPSON_SHARE
    # the midpoint's state error is covered by r |S - T| where the motion and p share their time scale (the
    # Hermite state's relative error ~ (h/tau)^4 / 384 against r ~ (h/tau)^2 / 12: the defect ~ 36 r^2); a
    # defect far above that says the motion changes inside the interval in a way p's three values do not show
    # (a brake stopping inside it): integrated again whatever the estimate
    unresolved = defect > DEFECT_MARGIN * np.max(r, axis=0) ** 2 + tol
    suspect = _kink_suspects(diff, hl, live)
    err[:, suspect] = diff[:, suspect]          # a kink inside: Simpson's error is as large as |S - T|
    frac = np.divide(err, tol_abs[:, None], out=np.zeros_like(err), where=tol_abs[:, None] > 0)
    keep = _select(err, frac, unresolved)
    inc[:, live + 1] = np.where(keep, simpson, inc[:, live + 1])
    estimate = np.sum(np.where(keep, err, 0.0), axis=1)
    failed = _redo(traj, names, live, U, modes_rows, quads, tol, share, keep, frac, simpson, diff, inc, estimate,
                   stats)
    if failed:
        import warnings
        worst = int(np.argmax(estimate / np.where(tol_abs > 0, tol_abs, np.inf)))
        warnings.warn(f"the integrals of {', '.join(repr(nm) for nm in names)} could not follow the model's laws "
                      f"over {len(failed)} output interval(s) (the first [{failed[0][0]:.9g}, {failed[0][1]:.9g}] s): "
                      f"Simpson's rule on the rows stands there, estimated error of '{names[worst]}' "
                      f"{estimate[worst]:.3g} (res.integral(name, error=True)); a finer dt_out puts rows inside",
                      RuntimeWarning, stacklevel=3)
        stats["failed"] = len(failed)
    stats["rhs_calls"] += counter[0]
    bad = ~np.isfinite(inc)
    if bad.any():
        # a law that gives no number between the rows (the rows themselves are finite: the solvers checked them)
        j, k = (int(x[0]) for x in np.nonzero(bad))
        from ..errors import SimulationError
        raise SimulationError(f"the integral of '{names[j]}' is not finite over the output interval "
                              f"[{t[k - 1]:.9g}, {t[k]:.9g}] s: the model's laws give no number between its rows "
                              f"there; check the parameters and signals of the component '{names[j].rpartition('.')[0]}'")
    return {nm: (np.cumsum(inc[j]), float(estimate[j])) for j, nm in enumerate(names)}, stats


def _redo(traj, names, live, U, modes_rows, quads, tol, share, keep, frac, simpson, diff, inc, estimate, stats):
    """Integrate again the live intervals some signal does not keep (``_select``), the most needed first (within
    the budgets the others keep Simpson's value with its whole ``|S - T|``); each signal takes the new value
    where it needs it, with the re-integration's estimate. Fills ``inc`` and ``estimate``; returns the intervals
    no method got through."""
    t = traj.t
    need = ~keep
    redo = np.flatnonzero(np.any(need, axis=0))
    # the most needed first: the largest share of any needing signal's tolerance
    redo = redo[np.argsort(-np.max(np.where(need[:, redo], frac[:, redo], 0.0), axis=0), kind="stable")]
    scale_u = _state_scales(U)
    failed = []
    for i in redo:
        k = int(live[i])
        vals, est, calls = None, None, 0
        if len(failed) < MAX_FAILURES and stats["rhs_calls"] < TOTAL_RHS_CALLS:
            vals, est, calls = _reintegrate(traj, names, k, U[k], modes_rows[k], tol, scale_u, share[:, i],
                                            need[:, i], quads[i])
        stats["rhs_calls"] += calls
        mine = need[:, i]
        if vals is None:
            # no method got through (a law the ODE form cannot follow there): Simpson stays, its error counted
            # whole (|S - T|) and said
            inc[mine, k + 1] = simpson[mine, i]
            estimate[mine] += diff[mine, i]
            failed.append((float(t[k]), float(t[k + 1])))
            continue
        inc[mine, k + 1] = vals[mine]
        estimate[mine] += est[mine]
        stats["reintegrated"] += 1
    return failed
