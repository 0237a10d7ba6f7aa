"""The analytic-numerical convolution method (SOURCES.md 004) on the ODE form: ``convolution``.

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
    u_C = u_i + h phi1 g_i + h phi2 [(g(t_{i+1}, u_P) - g_i) + r (u_P - u_i)]

(``1 - E = z phi1`` and ``h - T(1 - E) = h z phi2``). For a pure integrator
(``T -> inf``: ``z = r = 0``, ``phi1 = 1``, ``phi2 = 1/2``) they are exactly
the 2nd-order Adams-Bashforth predictor and the trapezoidal (Adams-Moulton)
corrector; ``phi1``, ``phi2`` come from their Taylor series when z is small
(no cancellation). For a very fast lag (``z -> inf``) the corrector tends to
the lag's equilibrium ``u_C = f(t_{i+1}, u_P)``.

Time constants: ``T_i = -1/J_ii`` from the diagonal of ``J = dg/du`` (grouped
finite differences on the structural pattern) where ``J_ii < 0``, a pure
integrator otherwise (positions always: ``x' = v``). They are recomputed at
every (re)start, after two rejected steps in a row and every ``jac_every``
accepted steps (default: never in between).

Step control: the corrector's local error is estimated by Milne's device
from the predictor-corrector difference, ``err = (u_C - u_P) / 6`` (exact
for the Adams pair; 1/6 is kept for finite T), and
``h_new = h * min(5, max(0.2, 0.9 * ||err||^(-1/3)))`` with the weighted RMS
norm ``||e|| = rms(e / (atol + rtol |u|))``; one evaluation at ``u_C``
after each accepted step (PECE, 2 evaluations per step). The first step
after a (re)start has no ``f_{i-1}``: its predictor holds f constant and the
whole difference (order 1) is used. A step that would fall below
``16 eps |t|`` is accepted as it is (counted as ``forced``): this is what lets
the method pass through a discontinuity of the right-hand side that is not
declared as an event. ``h`` (option) switches step control off: fixed
steps of at most h that land exactly on the output instants.

Output inside a step is the cubic Hermite interpolant from the values and
slopes at both ends.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ParameterError
from . import register
from .ode_driver import EPS, KnotClock, Stepper, hermite, simulate_ode

SERIES_BELOW = 0.5      # z below which phi1, phi2 come from their Taylor series
_SERIES_TERMS = 16      # z^16/18! < 1e-20 at z = 0.5
_C1 = np.array([1.0 / math.factorial(k + 1) for k in range(_SERIES_TERMS)])   # phi1 = sum C1_k (-z)^k
_C2 = np.array([1.0 / math.factorial(k + 2) for k in range(_SERIES_TERMS)])   # phi2 = sum C2_k (-z)^k
#: the series truncated after K terms is exact to 1e-17 (relative) for z up to _Z_OK[K]
_Z_OK = np.array([(1e-17 * math.factorial(k + 1)) ** (1.0 / k) if k else 0.0 for k in range(_SERIES_TERMS + 1)])


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


class ConvolutionStepper(Stepper):
    """PECE convolution steps with step control (or fixed steps when ``h`` is given)."""

    def __init__(self, problem, t0, u0, t_bound, knots, rtol=1e-6, atol=1e-8, h=None, first_step=None,
                 max_step=None, jac_every=None):
        self.problem = problem
        self.t = self.t_old = float(t0)
        self.t_bound = float(t_bound)
        self.u = np.array(u0, float)
        self.g = problem.rhs(self.t, self.u)
        self.u_old, self.g_old = self.u, self.g
        self.u_prev = self.g_prev = None        # history point i-1 (none after a (re)start)
        self.h_prev = None
        self.rtol, self.atol = rtol, atol
        self.fixed_h = h
        self.max_step = np.inf if max_step is None else float(max_step)
        self.jac_every = jac_every
        self.nsteps = self.nrejected = self.njev = 0
        self.forced = 0
        self._since_jac = 0
        self._refresh_rates()
        self.clock = KnotClock(t0, knots, t_bound, h) if h is not None else None
        self.h = self._initial_step() if h is None and first_step is None else (first_step or h)

    # -- time constants -----------------------------------------------------
    def _refresh_rates(self):
        J = self.problem.jacobian(self.t, self.u, self.g)
        self.rate = lag_rates(J.diagonal())
        self._since_jac = 0

    def _scale(self, u, u_new=None):
        mag = np.abs(u) if u_new is None else np.maximum(np.abs(u), np.abs(u_new))
        return self.atol + self.rtol * mag

    def _initial_step(self):
        """Hairer-Wanner style starting step for an order-2 method."""
        sc = self._scale(self.u)
        d0 = np.sqrt(np.mean((self.u / sc) ** 2))
        d1 = np.sqrt(np.mean((self.g / sc) ** 2))
        h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        h0 = min(h0, self.t_bound - self.t)
        g1 = self.problem.rhs(self.t + h0, self.u + h0 * self.g)
        d2 = np.sqrt(np.mean(((g1 - self.g) / sc) ** 2)) / h0
        h1 = max(1e-6, h0 * 1e-3) if max(d1, d2) <= 1e-15 else (0.01 / max(d1, d2)) ** (1 / 3)
        return min(100 * h0, h1, self.max_step)

    # -- stepping -------------------------------------------------------------
    def step(self):
        if self.fixed_h is not None:
            h, t_new = self.clock.next_step(self.t)
            self._attempt(h, t_new)
            self._accept(t_new)
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
            if err <= 1.0:
                factor = 5.0 if err == 0 else min(5.0, 0.9 * err ** (-1.0 / order))
                if consecutive_rejects:
                    factor = min(1.0, factor)
                self._accept(t_new)
                self.h = h * factor
                return
            h_min = 16 * EPS * max(1.0, abs(self.t))
            if h <= h_min:
                self.forced += 1
                self._accept(t_new)
                self.h = h
                return
            self.nrejected += 1
            consecutive_rejects += 1
            self.h = max(h_min, h * max(0.2, 0.9 * err ** (-1.0 / order)))
            if consecutive_rejects == 2:
                self._refresh_rates()

    def _attempt(self, h, t_new):
        """Predict, evaluate, correct; returns the weighted error norm (fills the candidate step)."""
        rhs = self.problem.rhs
        phis = phi_functions(h * self.rate)
        u_p = predictor(self.u, self.g, self.u_prev, self.g_prev, h, self.h_prev, self.rate, phis)
        g_p = rhs(t_new, u_p)
        u_c = corrector(self.u, self.g, u_p, g_p, h, self.rate, phis)
        self._cand = (h, u_c)
        diff = u_c - u_p
        if self.u_prev is not None:
            diff = diff / 6.0
        return float(np.sqrt(np.mean((diff / self._scale(self.u, u_c)) ** 2))) if diff.size else 0.0

    def _accept(self, t_new):
        h, u_c = self._cand
        g_c = self.problem.rhs(t_new, u_c)
        self.u_prev, self.g_prev, self.h_prev = self.u, self.g, h
        self.t_old, self.u_old, self.g_old = self.t, self.u, self.g
        self.t, self.u, self.g = t_new, u_c, g_c
        self.nsteps += 1
        self._since_jac += 1
        if self.jac_every and self._since_jac >= self.jac_every and self.t < self.t_bound:
            self._refresh_rates()

    def interpolate(self, tq):
        if tq == self.t:
            return self.u
        return hermite(self.t_old, self.u_old, self.g_old, self.t, self.u, self.g, tq)

    def stats(self):
        return {"forced": self.forced}


@register("convolution")
def simulate_convolution(model, t_start=0.0, t_end=1.0, dt_out=None, rtol=1e-6, atol=None, h=None,
                         first_step=None, max_step=None, jac_every=None, max_events=100000, chatter_window=None,
                         chatter_count=50, **unused):
    """The analytic-numerical convolution method (see regmech.solvers.convolution)."""
    if unused:
        raise ParameterError(f"solver 'convolution' takes rtol, atol, h, first_step, max_step, jac_every, "
                             f"max_events, chatter_window, chatter_count; got unknown {sorted(unused)}")
    for nm, val in (("rtol", rtol), ("h", h), ("first_step", first_step), ("max_step", max_step)):
        if val is not None and not (isinstance(val, (int, float)) and math.isfinite(val) and val > 0):
            raise ParameterError(f"solver 'convolution': {nm} must be a positive number, got {val!r}")
    atol = rtol * 1e-2 if atol is None else atol

    def make(problem, t0, u0, t_bound, knots):
        fs = None if first_step is None else min(first_step, t_bound - t0)
        return ConvolutionStepper(problem, t0, u0, t_bound, knots, rtol=rtol, atol=atol, h=h, first_step=fs,
                                  max_step=max_step, jac_every=jac_every)

    res = simulate_ode(model, "convolution", make, t_start, t_end, dt_out, max_events=max_events,
                       chatter_window=chatter_window, chatter_count=chatter_count)
    if h is not None:
        res.stats.extra["h"] = float(h)
    return res
