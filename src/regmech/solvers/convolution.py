"""The analytic-numerical convolution method (REFERENCES.md [004]) on the ODE form: ``convolution``.

Every state is treated as a first-order lag ``T_i u_i' + u_i = f_i(t, u)``
whose input is ``f_i = u_i + T_i g_i(t, u)``; over a step of length h the
lag is integrated exactly (convolution with ``w(t) = e^{-t/T}/T``) with f
replaced by a straight line. With ``E = exp(-h/T)`` the paper's formulas are

    predictor (line through f_{i-1}, f_i):
        u_{i+1} = u_i E + (1 - E) f_i + (1 - (T/h)(1 - E)) (f_i - f_{i-1})
    corrector (line through f_i, f_{i+1}):
        u_{i+1} = u_i E + f_{i+1} - f_i E - (T/h)(f_{i+1} - f_i)(1 - E)

Substituting ``f = u + T g`` gives the same formulas without the large
``T g`` terms that cancel as ``T`` grows (derived here, checked in the tests):
with ``z = h/T``, ``r = 1/T``, ``phi1(z) = (1 - e^-z)/z``,
``phi2(z) = (z - 1 + e^-z)/z^2``,

    u_P = u_i + h phi1 g_i + h phi2 (h/h_prev) [(g_i - g_{i-1}) + r (u_i - u_{i-1})]
    u_C = u_i + h phi1 g_i + h phi2 [(g(t_{i+1}, u_C) - g_i) + r (u_C - u_i)]

(``1 - E = z phi1`` and ``h - T(1 - E) = h z phi2``). For a pure integrator
(``T -> inf``: ``z = r = 0``, ``phi1 = 1``, ``phi2 = 1/2``) they are exactly
the 2nd-order Adams-Bashforth predictor and the trapezoidal (Adams-Moulton)
corrector; ``phi1``, ``phi2`` come from their Taylor series when z is small
(no cancellation). For a very fast lag (``z -> inf``) the corrector tends to
the lag's equilibrium ``u_C = f(t_{i+1}, u_C)``.

The corrector is implicit: ``f_{i+1}`` is taken at the new state itself.
``corrector="implicit"`` (default) solves it to convergence by Newton's method
(``ConvolutionStepper._solve_corrector``) with the matrix
``I - h phi2 (J + diag(r))``, J the ODE Jacobian, starting from the predictor.
``corrector="pece"`` is the paper's literal single pass: the corrector is
evaluated once with ``f_{i+1} = f(t_{i+1}, u_P)``.

Why it matters (measured on the excavator swing drive, REFERENCES.md [004], with
fixed steps; benchmarks/results/solvers_ode.md). Each state's *own* time
constant is integrated exactly by both, which is what the paper's claim of
stability at any step rests on. But the coupling *between* states (the
shaft stiffness between motor and turntable, the back-emf between armature
current and motor speed) enters only through ``f``: in the single pass it is
extrapolated explicitly and the method is an explicit two-step scheme,
stable on this scene only up to h = 0.026 s (linear analysis: 0.0257 s),
below explicit rk4 (0.057 s). Solved to convergence, the corrector's
one-step amplification on ``u' = J u`` has a spectral radius of at most 1 at
every step tried (up to 10 s) and the scene runs at any step (3 s in one
step); the accuracy is that of a second-order method (turntable speed error
0.06 rad/s at h = 0.05 s, 0.24 rad/s at 0.1 s, of 7.85 rad/s). The price:
about 3 evaluations of g per step instead of 2, plus the LU, i.e. about
twice the time of the single pass where that one is stable (torsional
chains of 10 and 100 masses, same tables).

Newton: the Jacobian (grouped finite differences on the structural pattern,
``ode_driver.grouped_fd_jacobian``) and the LU of the Newton matrix are
kept across steps while Newton converges and h stays (fixed steps: one LU
per Jacobian). Converged when the estimated remaining correction is below
``max(10 eps/rtol, min(0.03, sqrt(rtol)))`` in the weighted RMS norm. When
it does not converge: a Jacobian evaluated at the step start (if the kept
one is older), then one at the last iterate (a backlash contact or another
kink of the right-hand side inside the step: the Jacobian beyond it), then
the step is halved (adaptive: rejected; fixed: taken as two halves,
counted as ``subdivided``, at most 8 levels).

Time constants: ``T_i = -1/J_ii`` from the diagonal of ``J = dg/du`` where
``J_ii < 0``, a pure integrator otherwise (positions always: ``x' = v``).
They are recomputed with the Jacobian: at every (re)start, after two
rejected steps in a row, when Newton fails with an old Jacobian and every
``jac_every`` accepted steps (default: never in between).

Step control: the corrector's local error is estimated by Milne's device
from the predictor-corrector difference, ``err = (u_C - u_P) / 6`` (exact
for the Adams pair; 1/6 is kept for finite T), and
``h_new = h * min(5, max(0.2, 0.9 * ||err||^(-1/3)))`` with the weighted RMS
norm ``||e|| = rms(e / (atol + rtol |u|))``; one evaluation at ``u_C``
after each accepted step (PECE: 2 evaluations per step; implicit: usually
3, two Newton iterations and that one). The first step
after a (re)start has no ``f_{i-1}``: its predictor holds f constant and the
whole difference (order 1) is used. A step that would fall below
``16 eps |t|`` is accepted as it is (counted as ``forced``): this is what lets
the method pass through a discontinuity of the right-hand side that is not
declared as an event. ``h`` (option) switches step control off: fixed
steps of at most h that land exactly on the output instants (``rtol`` and
``atol`` then only set the Newton tolerance).

Divergence: like every ODE-form solver the run stops with ``SimulationError``
when the state grows beyond what its start and forcing explain
(``regmech.solvers.divergence``, option ``max_growth``).

Step cap. An adaptive run stops with ``SimulationError`` after more than
``max_steps`` accepted steps (default ``DEFAULT_MAX_STEPS`` = 50,000;
``common.StepBudget``: time reached, last step, fastest link, remedies);
fixed steps (``h``) are not capped, their number is ``t_end / h``. Where
the steps go (hard-case suite at CI size, rtol 1e-8, profiled with
cProfile): the method is of order 2, so at tight rtol its steps are set by
the tolerance (``long_horizon``: an undamped chain, 26,444 steps in the
first 5 s of 100, about 530,000 in all; ``belt_limit_cycle``: 7,445 steps
in 4 s of 20, 240 us each, half of it the model's right-hand side;
``square_wave_throttle``: steps near 1e-4 s after the first throttle edge,
700 us each on the vehicle, two thirds of it the right-hand side). On
``stretched_1e7`` the corrector's one-step amplification of the fastest
(4e6 rad/s) mode is -0.9986 at h = 1e-4 s (``step_matrix``; -0.9999 at
1e-3 s): like the trapezoidal rule the method is A-stable but does not
damp a stiff oscillation, which keeps ringing and holds the error estimate
of the stiff end's speeds near 1 at h = 1e-4 s (about 88,000 steps for the
10 s run); it is now refused at the cap. No rejected steps or Newton
failures worth mentioning in any of the four (at most 13 rejections,
0 failures). The one inefficiency found, ``phi_functions`` recomputed at
every attempt although h and the time constants mostly stay, is cached
(stretched_1e7: 0.83 -> 0.64 s for its first 0.5 s, medians of 5; 2-4 %
on the others). The default cap is above the longest run of the benchmark
ladder (vehicle_launch at rtol 1e-9: 42,525 steps, 28 s); a refused run of
a small model costs 7 to 12 s on the development machine (145-240 us per
step), of the vehicle about 35 s.

Output inside a step is the cubic Hermite interpolant from the values and
slopes at both ends.

With step control (no ``h``), a model whose link spread puts round-off beyond
``rtol`` is refused up front as by IDA (``common.check_link_spread``;
``stiff_check=False`` runs anyway): on the 1e7 chain of the hard cases Newton
then failed at almost every step.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ParameterError, SimulationError
from . import register
from .common import StepBudget, check_link_spread, refuse_impacts
from .divergence import MAX_GROWTH
from .ode_driver import EPS, KnotClock, Stepper, hermite, simulate_ode
from .options import (Choice, Integer, OptionSet, Real, atol_option, chatter_options, max_events_option,
                      max_growth_option,
                      rtol_option, step_option, stiff_check_option)
from .richardson import simulate_fixed_step

SERIES_BELOW = 0.5      # z below which phi1, phi2 come from their Taylor series
_SERIES_TERMS = 16      # z^16/18! < 1e-20 at z = 0.5
_C1 = np.array([1.0 / math.factorial(k + 1) for k in range(_SERIES_TERMS)])   # phi1 = sum C1_k (-z)^k
_C2 = np.array([1.0 / math.factorial(k + 2) for k in range(_SERIES_TERMS)])   # phi2 = sum C2_k (-z)^k
#: the series truncated after K terms is exact to 1e-17 (relative) for z up to _Z_OK[K]
_Z_OK = np.array([(1e-17 * math.factorial(k + 1)) ** (1.0 / k) if k else 0.0 for k in range(_SERIES_TERMS + 1)])


#: ``corrector`` option: the implicit corrector solved by Newton (default), or the paper's single pass
CORRECTORS = ("implicit", "pece")

#: default ``max_steps`` of an adaptive run (see "Step cap" in the module docstring)
DEFAULT_MAX_STEPS = 50_000


def phi_functions(z):
    """``phi1(z) = (1 - e^-z)/z`` and ``phi2(z) = (z - 1 + e^-z)/z^2`` for z >= 0 (arrays).

    Exactly 1 and 1/2 at z = 0 (pure integrators, most entries); Taylor series
    (Horner) ``phi1 = sum (-z)^k/(k+1)!``, ``phi2 = sum (-z)^k/(k+2)!`` below
    ``SERIES_BELOW``; closed forms with ``expm1`` above (no cancellation left there).
    """
    z = np.atleast_1d(np.asarray(z, float))
    p1 = np.ones_like(z)
    p2 = np.full_like(z, 0.5)
    idx = np.nonzero(z)[0]
    if idx.size:
        zz = z[idx]
        small = zz < SERIES_BELOW
        if small.any():
            x = -zz[small]
            terms = min(_SERIES_TERMS, int(np.searchsorted(_Z_OK, -x.min())) + 1)   # fewer for small steps
            s1 = np.full_like(x, _C1[terms - 1])
            s2 = np.full_like(x, _C2[terms - 1])
            for k in range(terms - 2, -1, -1):
                s1 = s1 * x + _C1[k]
                s2 = s2 * x + _C2[k]
            p1[idx[small]] = s1
            p2[idx[small]] = s2
        if not small.all():
            zb = zz[~small]
            em1 = np.expm1(-zb)              # e^-z - 1
            p1[idx[~small]] = -em1 / zb
            p2[idx[~small]] = (zb + em1) / (zb * zb)
    return p1, p2


def lag_rates(jac_diag):
    """``1/T_i``: ``-J_ii`` where the diagonal is negative, 0 (pure integrator, T -> inf) otherwise."""
    return np.maximum(-np.asarray(jac_diag, float), 0.0)


def predictor(u, g, u_prev, g_prev, h, h_prev, rate, phis=None):
    """Explicit step: the lag input extrapolated along the line through f_{i-1}, f_i (constant f without history).

    ``phis`` = ``phi_functions(h * rate)`` when already known."""
    p1, p2 = phi_functions(h * rate) if phis is None else phis
    out = u + h * p1 * g
    if u_prev is not None:
        out = out + h * p2 * (h / h_prev) * ((g - g_prev) + rate * (u - u_prev))
    return out


def corrector(u, g, u_new, g_new, h, rate, phis=None):
    """Implicit step with the lag input along the line through f_i and f_{i+1} (evaluated at u_new)."""
    p1, p2 = phi_functions(h * rate) if phis is None else phis
    return u + h * p1 * g + h * p2 * ((g_new - g) + rate * (u_new - u))


def step_matrix(J, h, corrector_kind):
    """One step of the method on ``u' = J u`` as a matrix, time constants from diag(J).

    With ``B = h phi1 J`` and ``C = h phi2 (J + diag(r))``: the implicit corrector is
    ``u_{i+1} = (I + (I - C)^-1 B) u_i``; the single pass (PECE, equal steps) acts on ``(u_i, u_{i-1})`` by
    the companion matrix ``[[I + B + C B + C^2, -C^2], [I, 0]]``."""
    n = J.shape[0]
    eye = np.eye(n)
    rate = lag_rates(np.diag(J))
    p1, p2 = phi_functions(h * rate)
    B = h * p1[:, None] * J
    C = h * p2[:, None] * (J + np.diag(rate))
    if corrector_kind == "implicit":
        return eye + np.linalg.solve(eye - C, B)
    return np.block([[eye + B + C @ B + C @ C, -C @ C], [eye, np.zeros((n, n))]])


class NewtonMatrix:
    """``M = I - h diag(p2) (J + diag(r))``, the Newton matrix of the implicit corrector, for one Jacobian.

    ``factor(hp2)`` returns a solver for M with ``hp2 = h p2`` (None when M is singular or not finite: the
    attempt then counts as a failed Newton iteration). Dense LAPACK below ``DENSE_BELOW`` states (a small
    dense matrix is built and factorised in microseconds), sparse SuperLU above, with the values of M
    computed on the fixed pattern of ``K = J + diag(r)`` (no sparse matrix arithmetic per step).
    """

    DENSE_BELOW = 64

    def __init__(self, J, rate):
        n = J.shape[0]
        if n < self.DENSE_BELOW:
            self.K = np.asarray(J.toarray() if sp.issparse(J) else J, float) + np.diag(rate)
            return
        Jc = sp.coo_matrix(J)
        idx = np.arange(n)
        # every diagonal entry stored (coo -> csc sums duplicates and keeps zeros)
        K = sp.coo_matrix((np.concatenate([Jc.data, rate]), (np.concatenate([Jc.row, idx]),
                                                              np.concatenate([Jc.col, idx]))), shape=(n, n)).tocsc()
        K.sort_indices()
        cols = np.repeat(idx, np.diff(K.indptr))
        self.diag = np.nonzero(K.indices == cols)[0]
        self.K = K

    def factor(self, hp2):
        try:
            if isinstance(self.K, np.ndarray):
                M = -hp2[:, None] * self.K
                M[np.diag_indices_from(M)] += 1.0
                lu = scipy.linalg.lu_factor(M, check_finite=True)
                if not np.all(np.diag(lu[0]) != 0):
                    return None
                return lambda b: scipy.linalg.lu_solve(lu, b, check_finite=False)
            K = self.K
            data = -hp2[K.indices] * K.data
            data[self.diag] += 1.0
            M = sp.csc_matrix((data, K.indices, K.indptr), shape=K.shape)
            return spla.splu(M).solve
        except (RuntimeError, ValueError, np.linalg.LinAlgError):   # singular or non-finite: no Newton here
            return None


class ConvolutionStepper(Stepper):
    """Convolution steps (implicit corrector by Newton, or PECE), with step control or fixed steps ``h``."""

    #: Newton iterations allowed per attempt of the implicit corrector
    MAX_NEWTON = 8
    #: halvings of a fixed step whose corrector does not converge even with a fresh Jacobian
    MAX_SUBDIVISIONS = 8
    #: adaptive steps over which Newton failures are counted: as many failures as steps stops the run
    FAILURE_WINDOW = 500

    def __init__(self, problem, t0, u0, t_bound, knots, rtol=1e-6, atol=1e-8, h=None, first_step=None,
                 max_step=None, jac_every=None, corrector="implicit", budget=None, clock=KnotClock):
        self.problem = problem
        self.budget = budget                    # common.StepBudget of the run (adaptive steps only)
        self._phi_cache = (None, None, None)    # (h, rate array, phi_functions(h * rate))
        self.t = self.t_old = float(t0)
        self.t_bound = float(t_bound)
        self.u = np.array(u0, float)
        self.g = problem.rhs(self.t, self.u)
        self.u_old, self.g_old = self.u, self.g
        self.u_prev = self.g_prev = None        # history point i-1 (none after a (re)start)
        self.h_prev = None
        self.rtol, self.atol = rtol, atol
        self.implicit = corrector == "implicit"
        # Newton converged when the estimated remaining correction is below this (weighted RMS norm)
        self.newton_tol = max(10 * EPS / rtol, min(0.03, rtol ** 0.5))
        self.fixed_h = self.fixed_step = h
        self.max_step = np.inf if max_step is None else float(max_step)
        self.jac_every = jac_every
        self.nsteps = self.nrejected = self.njev = 0
        self.forced = 0
        self.counts = {"newton_iterations": 0, "newton_failures": 0, "lu_decompositions": 0, "subdivided": 0}
        self._since_jac = 0
        self._crate = 0.7                      # Newton contraction estimate carried between steps (as LSODE)
        self._newton = None                    # (h, NewtonMatrix) for the current Jacobian
        self._refresh_rates()
        self.clock = clock(t0, knots, t_bound, h) if h is not None else None
        if h is not None:
            self.h = h
        elif first_step is not None:
            self.h = first_step
        else:
            self.h = self._initial_step()

    # -- time constants and Jacobian -----------------------------------------
    def _refresh_rates(self, t=None, u=None, where="start"):
        """J = dg/du at the step start (or at (t, u)); the time constants T_i = -1/J_ii and the Newton
        matrix follow it. ``where`` records where it was taken in the current step ("start", "end")."""
        if t is None:
            J = self.problem.jacobian(self.t, self.u, self.g)
        else:
            J = self.problem.jacobian(t, u)
        self.rate = lag_rates(J.diagonal())
        self.newton_matrix = NewtonMatrix(J, self.rate)
        self._since_jac = 0
        self._jac_taken = where
        self._newton = None

    def _phis(self, h):
        """``phi_functions(h * rate)``, kept while h and the time constants stay (most steps keep both:
        the step control holds h to keep the LU); profiled at 15 % of a step on a 12-state chain."""
        h_c, rate_c, phis = self._phi_cache
        if h_c != h or rate_c is not self.rate:
            phis = phi_functions(h * self.rate)
            self._phi_cache = (h, self.rate, phis)
        return phis

    def _newton_solver(self, h, hp2):
        # equal steps computed on different output intervals differ in the last bits: same matrix for Newton
        if self._newton is None or abs(self._newton[0] - h) > 1e-9 * h:
            self._newton = (h, self.newton_matrix.factor(hp2))
            self.counts["lu_decompositions"] += 1
        return self._newton[1]

    def _scale(self, u, u_new=None):
        mag = np.abs(u) if u_new is None else np.maximum(np.abs(u), np.abs(u_new))
        return self.atol + self.rtol * mag

    def _initial_step(self):
        """Hairer-Wanner style starting step for an order-2 method (0 on an empty segment)."""
        span = self.t_bound - self.t
        if span <= 0:
            return 0.0
        if self.u.size == 0:
            # all motion prescribed: no state whose error needs control, one step covers the segment
            # (the mean over an empty state below would be NaN and end the segment without its outputs)
            return span
        sc = self._scale(self.u)
        d0 = np.sqrt(np.mean((self.u / sc) ** 2))
        d1 = np.sqrt(np.mean((self.g / sc) ** 2))
        h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        h0 = min(h0, span)
        g1 = self.problem.rhs(self.t + h0, self.u + h0 * self.g)
        d2 = np.sqrt(np.mean(((g1 - self.g) / sc) ** 2)) / h0
        h1 = max(1e-6, h0 * 1e-3) if max(d1, d2) <= 1e-15 else (0.01 / max(d1, d2)) ** (1 / 3)
        return min(100 * h0, h1, self.max_step)

    # -- stepping -------------------------------------------------------------
    def step(self):
        if self.fixed_h is not None:
            t0, u0, g0 = self.t, self.u, self.g
            h, t_new = self.clock.next_step(self.t)
            self._fixed_step(t_new, 0)
            # the interpolant spans the whole step even when it was taken in parts
            self.t_old, self.u_old, self.g_old = t0, u0, g0
            return
        consecutive_rejects = 0
        while True:
            h = min(self.h, self.max_step)
            t_new = self.t + h
            if t_new >= self.t_bound or self.t_bound - t_new < 1e-3 * h:
                t_new = self.t_bound
                h = t_new - self.t
            err = self._attempt(h, t_new)
            order = 3.0 if self.u_prev is not None else 2.0
            if err is None:                     # the corrector did not converge with a fresh Jacobian
                self.nrejected += 1
                consecutive_rejects += 1
                self.h = max(16 * EPS * max(1.0, abs(self.t)), 0.5 * h)
                if h <= 16 * EPS * max(1.0, abs(self.t)):
                    raise SimulationError(f"solver 'convolution': the implicit corrector does not converge at "
                                          f"t={self.t:.6g} s even with a step of {h:.3g} s in model "
                                          f"'{self.problem.c.model.name}'; try corrector='pece' or 'ida'")
                continue
            if err <= 1.0:
                factor = 5.0 if err == 0 else min(5.0, 0.9 * err ** (-1.0 / order))
                if consecutive_rejects:
                    factor = min(1.0, factor)
                if self.implicit and 1.0 <= factor <= 1.2:
                    factor = 1.0            # keep h, and with it the LU of the Newton matrix (as RADAU5 does)
                self._accept(t_new)
                self.h = h * factor
                self._charge()
                return
            h_min = 16 * EPS * max(1.0, abs(self.t))
            if h <= h_min:
                self.forced += 1
                self._accept(t_new)
                self.h = h
                self._charge()
                return
            self.nrejected += 1
            consecutive_rejects += 1
            self.h = max(h_min, h * max(0.2, 0.9 * err ** (-1.0 / order)))
            if consecutive_rejects == 2:
                self._refresh_rates()

    def _charge(self):
        if self.budget is not None:
            self.budget.charge(self, self.problem)
        self._watch_failures()

    def _watch_failures(self):
        """Stop when Newton failed at least once per accepted step over the last ``FAILURE_WINDOW`` steps.

        Measured on ``stretched_1e7`` (link stiffnesses spread over 1.7e13): the run advances normally
        until the chain has nearly settled (t = 8.34 s of 10); then the speeds' error weights fall to
        ``atol`` while the stiffest link's force carries round-off ``eps k |x|`` far above it, Newton
        cannot meet its tolerance and the steps fall to 1e-7 s: 73,000 Newton failures and 21,000
        rejections for the last 0.01 s of the run, 45 s, until the step cap stopped it (now 3.8 s,
        refused here). A converging run stays far below one failure per step."""
        if self.nsteps % self.FAILURE_WINDOW:
            return
        failures = self.counts["newton_failures"]
        mark, self._failure_mark = getattr(self, "_failure_mark", (0, self.t_old)), (failures, self.t)
        if failures - mark[0] < self.FAILURE_WINDOW:
            return
        c = self.problem.c
        raise SimulationError(
            f"solver 'convolution': the implicit corrector failed to converge {failures - mark[0]} times in the "
            f"last {self.FAILURE_WINDOW} steps (t from {mark[1]:.6g} to {self.t:.6g} s, last step "
            f"{self.t - self.t_old:.3g} s) in model '{c.model.name}': the right-hand side is not smooth at this "
            f"tolerance, usually the round-off of a very stiff link's force (eps * k * |x|) above what rtol and "
            f"atol allow, or a discontinuity that is not declared. Loosen rtol/atol, make the stiffest link "
            f"rigid or reduce the model with rm.Scene(..., band_hz=...), or use 'scipy:Radau'."
            f"{c.stiffness_hint(always=True)}")

    def _fixed_step(self, t_new, depth):
        """One fixed step to t_new; halved (recursively) where the corrector does not converge."""
        if self._attempt(t_new - self.t, t_new) is not None:
            self._accept(t_new)
            return
        if depth >= self.MAX_SUBDIVISIONS:
            raise SimulationError(f"solver 'convolution': the implicit corrector does not converge at "
                                  f"t={self.t:.6g} s even with the step {self.fixed_h:g} s divided by "
                                  f"{2 ** depth} in model '{self.problem.c.model.name}'; use a smaller h, "
                                  f"corrector='pece' or 'ida'")
        self.nrejected += 1
        self.counts["subdivided"] += 1
        t_mid = self.t + 0.5 * (t_new - self.t)
        self._fixed_step(t_mid, depth + 1)
        self._fixed_step(t_new, depth + 1)

    def _attempt(self, h, t_new):
        """Predict and correct; returns the weighted error norm (fills the candidate step), or None when
        the implicit corrector did not converge even with fresh Jacobians (see ``_solve_corrector``)."""
        # Jacobians still to try when Newton fails: at the step start (unless J is from there), then beyond
        fallbacks = ["end"] if self._jac_taken == "start" else ["start", "end"]
        v_start = None                          # Newton's first iterate: the predictor, or where it stopped
        while True:
            phis = self._phis(h)
            u_p = predictor(self.u, self.g, self.u_prev, self.g_prev, h, self.h_prev, self.rate, phis)
            if self.implicit:
                u_c, v_last = self._solve_corrector(h, t_new, u_p if v_start is None else v_start, phis)
                if u_c is None:
                    self.counts["newton_failures"] += 1
                    if not fallbacks:
                        return None
                    if fallbacks.pop(0) == "start":
                        self._refresh_rates()   # a stale Jacobian is the usual reason: retry with a fresh one
                    elif np.all(np.isfinite(v_last)):
                        # a kink of the right-hand side (backlash contact) lies in the step: the Jacobian
                        # beyond it, at the last iterate, is the one Newton needs; go on from there
                        self._refresh_rates(t_new, v_last, where="end")
                        v_start = v_last
                    continue
            else:
                u_c = corrector(self.u, self.g, u_p, self.problem.rhs(t_new, u_p), h, self.rate, phis)
            break
        self._cand = (h, u_c)
        diff = u_c - u_p
        if self.u_prev is not None:
            diff = diff / 6.0
        return float(np.sqrt(np.mean((diff / self._scale(self.u, u_c)) ** 2))) if diff.size else 0.0

    def _solve_corrector(self, h, t_new, v, phis):
        """The implicit corrector by (simplified) Newton from v (the predictor): (u_C, last iterate), u_C
        None when it does not converge.

        ``F(v) = v - u_i - h phi1 g_i - h phi2 (g(t_{i+1}, v) - g_i + r (v - u_i)) = 0``,
        Newton matrix ``I - h phi2 (J + r)`` (its LU kept while h and J stay).
        Converged when ``rate / (1 - rate) * ||dv|| < newton_tol`` (weighted RMS norm, ``rate`` the
        observed contraction ``||dv_k|| / ||dv_{k-1}||``, carried over from the last step for the first
        iteration, at least 0.1). Failed when the corrections grow twice in a row (once is allowed: across
        a kink of the right-hand side the first correction lands on the other side and the next one can be
        larger before Newton settles there), grow by more than 2, or after ``MAX_NEWTON`` iterations.
        """
        p1, p2 = phis
        hp2 = h * p2
        solve = self._newton_solver(h, hp2)
        if solve is None:
            return None, v
        base = self.u + h * p1 * self.g - hp2 * (self.g + self.rate * self.u)
        scale = self._scale(self.u, v)
        dv_norm_old = None
        growing = 0
        for _ in range(self.MAX_NEWTON):
            self.counts["newton_iterations"] += 1
            with np.errstate(over="ignore", invalid="ignore"):
                residual = base + hp2 * (self.problem.rhs(t_new, v) + self.rate * v) - v
            if not np.all(np.isfinite(residual)):
                return None, v
            dv = solve(residual)
            dv_norm = float(np.sqrt(np.mean((dv / scale) ** 2))) if dv.size else 0.0
            if dv_norm_old is None:
                rate = self._crate
            else:
                rate = dv_norm / dv_norm_old if dv_norm_old > 0 else 0.0
                self._crate = max(0.1, min(rate, 0.9))
                growing = growing + 1 if rate >= 1 else 0
                if growing == 2 or rate > 2:
                    return None, v + dv
            v = v + dv
            if dv_norm == 0 or (rate < 1 and rate / (1 - rate) * dv_norm < self.newton_tol):
                return v, v
            dv_norm_old = dv_norm
        return None, v

    def _accept(self, t_new):
        h, u_c = self._cand
        g_c = self.problem.rhs(t_new, u_c)
        self.u_prev, self.g_prev, self.h_prev = self.u, self.g, h
        self.t_old, self.u_old, self.g_old = self.t, self.u, self.g
        self.t, self.u, self.g = t_new, u_c, g_c
        self.nsteps += 1
        self._since_jac += 1
        self._jac_taken = None
        if self.jac_every and self._since_jac >= self.jac_every and self.t < self.t_bound:
            self._refresh_rates()

    def interpolate(self, tq):
        if tq == self.t:
            return self.u
        return hermite(self.t_old, self.u_old, self.g_old, self.t, self.u, self.g, tq)

    def stats(self):
        return {"forced": self.forced, **self.counts}

    amplification_exact = True

    def amplification(self, J, h, eigenvalues=None):
        if not J.size:
            return None
        M = step_matrix(J, h, "implicit" if self.implicit else "pece")
        return float(np.max(np.abs(np.linalg.eigvals(M))))

    def divergence_remedy(self):
        if not self.implicit:
            return (" The single-pass corrector (corrector='pece') treats the coupling between states "
                    "explicitly; use the implicit corrector (corrector='implicit', the default), a smaller h, "
                    "or 'ida'.")
        return super().divergence_remedy()


CONVOLUTION_OPTIONS = OptionSet(
    "the analytic-numerical convolution method on the ODE form (step control by rtol/atol, or a fixed step h)",
    rtol=rtol_option(1e-6),
    atol=atol_option(lambda c: c.ode_size(), "state of the ODE form"),
    h=step_option("fixed step [s] (default: step control by rtol/atol)"),
    tol=Real("with a fixed step h: bound of the Richardson estimate of the global error relative to the range of "
             "each kind of state (default None: no estimate)", 0.0, 1.0, optional=True),
    first_step=step_option("first step [s] of the step control (default: estimated)"),
    max_step=step_option("largest step [s] of the step control (default: no limit)"),
    jac_every=Integer("accepted steps between Jacobian updates (default: only when needed)", 1, optional=True),
    corrector=Choice("corrector (default 'implicit': Newton; 'pece': the paper's single pass)", CORRECTORS),
    max_events=max_events_option(),
    max_growth=max_growth_option(),
    max_steps=Integer(f"most accepted steps over the whole run under step control (default {DEFAULT_MAX_STEPS})",
                      1),
    stiff_check=stiff_check_option(),
    **chatter_options(),
)


@register("convolution", CONVOLUTION_OPTIONS)
def simulate_convolution(model, t_start=0.0, t_end=1.0, dt_out=None, rtol=1e-6, atol=None, h=None,
                         first_step=None, max_step=None, jac_every=None, corrector="implicit", max_events=100000,
                         chatter_window=None, chatter_count=50, max_growth=MAX_GROWTH, max_steps=DEFAULT_MAX_STEPS,
                         stiff_check=True, tol=None):
    """The analytic-numerical convolution method (see regmech.solvers.convolution).

    With fixed steps (``h``), ``tol`` (default None: no estimate) bounds the Richardson estimate of the
    global error (order 2, ``regmech.solvers.richardson``) as for the other fixed-step solvers.
    """
    refuse_impacts(model, "convolution")
    if tol is not None and h is None:
        raise ParameterError("solver 'convolution': tol (the Richardson estimate of fixed steps) needs a step h; "
                             "with step control (no h) ask for accuracy=... instead")
    atol = rtol * 1e-2 if atol is None else atol
    budget = None if h is not None else StepBudget("convolution", max_steps, t_end)
    if h is None:
        check_link_spread(model.compile(), rtol, "convolution", stiff_check)

    def stepper_factory(clock):
        def make(problem, t0, u0, t_bound, knots):
            fs = None if first_step is None else min(first_step, t_bound - t0)
            return ConvolutionStepper(problem, t0, u0, t_bound, knots, rtol=rtol, atol=atol, h=h, first_step=fs,
                                      max_step=max_step, jac_every=jac_every, corrector=corrector, budget=budget,
                                      clock=clock)
        return make

    driver = dict(max_events=max_events, chatter_window=chatter_window, chatter_count=chatter_count,
                  max_growth=max_growth)
    if h is None:
        res = simulate_ode(model, "convolution", stepper_factory(KnotClock), t_start, t_end, dt_out, **driver)
    else:
        def after_main(r):
            r.stats.extra["h"] = float(h)

        # order 2: the Adams pair behind the predictor-corrector (module docstring)
        res = simulate_fixed_step(model, "convolution", lambda clock, companion: stepper_factory(clock),
                                  h=float(h), order=2, tol=tol, t_start=t_start, t_end=t_end, dt_out=dt_out,
                                  after_main=after_main, **driver)
    res.stats.extra["corrector"] = corrector
    return res
