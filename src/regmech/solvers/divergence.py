"""Divergence of an ODE-form integration: a state growing far beyond what the model can explain.

A numerically unstable step (an explicit method beyond its stability limit,
the convolution method's single-pass corrector on coupled oscillations)
multiplies the unresolved modes by a fixed factor ``q > 1`` *per step*, so
the state grows geometrically in the step count. A drivetrain does not grow
like that: its masses and links are passive, the sources are bounded on a
finite run, and a forced response grows at most polynomially in time
(a constant torque on a free mass: ``v ~ t``, ``x ~ t^2``; a ramp: one power
more). ``GrowthWatch`` separates the two with the state's own history and
the forcing, without units and without a Jacobian.

Criterion (``N(u) = max_j |u_j|`` over the ODE state ``u = [x_K, v_K, z]``).
The run is declared diverged at the end of a step at time ``t`` when

    N(u(t)) > max_growth * R(t),
    R(t) = max( max{ N(u(s)) : s <= s_half },
                max{ D_k : segment k started after t_a + (t - t_a)/4 } )

* ``t_a``: the start of the run, or the end of the first step that leaves
  an exactly zero state (a run from rest; that step itself is not tested).
  ``s_half``: the last step end at or before the half-way time
  ``t_a + (t - t_a)/2``. The *first half* of the elapsed time is the
  reference: a response growing like ``(t - t_s)^p`` from some ``t_s <= t_a``
  is at most ``((t - t_a)/(s_half - t_a))^p`` times its value at ``s_half``,
  whatever ``t``, whereas a geometric blow-up ``q^n`` outgrows any fixed
  factor once the run is long enough. The test is made only when a step
  ends in ``[t_a + 0.4 (t - t_a), t_a + 0.5 (t - t_a)]``, so that this bound is
  ``2.5^p`` at most; an adaptive method's first steps, each several times
  longer than all before it, are not tested (fixed steps: the first 10).
* ``D_k = L_k * max_s N(g(s, 0))``: the forcing of segment k (from a time
  event or a mode change at ``t_k`` to the next time event, length ``L_k``):
  the rates the sources alone produce on the model at rest (state set to
  zero, the segment's modes) at the ends and the three Gauss points of the
  segment, times the time they act. A forcing that switches on late (a
  ``Step`` torque at 0.99 t_end; a brake that breaks away after holding a
  load for a long time, so that the forces it held start to accelerate it)
  makes the state grow by a factor the first half of the run cannot
  explain; ``D_k`` covers it until the response has had a quarter of the
  elapsed time to enter the reference (from then on
  ``((t - t_k)/(t_half - t_k))^p <= 3^p``). The rates are taken at the zero
  state, not at the state reached, so that a state that has begun to
  diverge cannot raise its own limit.
* ``max_growth`` (default ``MAX_GROWTH = 1e4``): polynomial growth of degree
  up to 8 stays below it (``3^8 = 6561``, ``2.5^8 = 1526``); measured on the
  library scenes with the adaptive ODE-form solvers at default settings and
  with rk4 at h = t_end/4000: at most 12.3 (benchmarks/results/solvers_ode.md);
  a physically unstable model (negative damping) would have to grow by
  ``e^{sigma (t - t_a)/2} > 1e4``.

A second, more sensitive test catches a slow blow-up (a few per cent per
step) before it has grown by ``max_growth``: the signature of a numerical
instability is a growing component that changes completely from one step to
the next. With the step-to-step curvature of the state (times ``t_k``,
steps ``h_k = t_k - t_{k-1}``)

    d_k = (u_k - u_{k-1}) - (h_k / h_{k-1}) (u_{k-1} - u_{k-2}),   r_k = N(d_k) / N(u_k)

(``d_k ~ h^2 u''``, so ``r_k`` is small while the steps resolve the motion),
the run is declared diverged when over the last ``ROUGH_STEPS = 10`` steps
every ``r_k > ROUGH = 0.5`` and ``N`` grew by more than ``ROUGH_GROWTH = 4``.
Measured: legitimate runs (library scenes with convolution, RK45, Radau,
BDF at default settings and rk4 at h = t_end/4000; the excavator with rk4
and the convolution method at every stable step) never keep ``r_k`` above
0.14 for 10 steps in a row; diverging ones keep it above 1. Both
conditions are needed: a stable implicit method rings on a stiff mode
(``r_k`` near 4, the trapezoidal factor -1 per step) without growing, and a
forced response grows while smooth.

The driver asks the method for a second opinion before it stops a run as rough
(``ode_driver.RoughVerdict``): a numerical instability needs a step factor
``q = max |R(h lambda)|`` above 1 on some eigenvalue of dg/du at the state
reached, and a high-order method that crosses a resolved oscillation in a
few steps per period is rough without it. DOP853 at rtol 1e-4 on the
undamped chain of the hard cases (``long_horizon``, 100 s) took 6 steps
per period of the fastest mode and the modes' beating grew the state
fourfold within ten steps: it was stopped at t = 7.3 s with ``q = 1 - 1e-13``;
it now runs (error 5.5e-3 of the range, the phase drift of that rtol over
100 s). The verdict is overruled only by a method's own factor (the
explicit Runge-Kutta methods, rk4, euler, the convolution method; not abm,
whose reported factor is RK4's) and up to 600 states (a dense
eigen-decomposition); the growth test is never overruled.

In addition any state that is non-finite or beyond ``BLOW_UP`` (1e100)
stops the run at once. Neither test judges a state whose every entry is
below ``QUIET`` (1e-12 in its SI unit): a model held at rest moves by
round-off, which is rough by nature and grows from exactly zero (fuzz seed
80337: two locked limited-slip differentials under an internal torque,
stopped as diverged by DOP853 at rtol 1e-10 when its speeds had "grown" from
0 to 2.5e-17 rad/s); a real instability passes that level within a few
steps and is judged from there.

A run too short for these tests (a fixed step h with fewer than
``FEW_STEPS = 20`` steps left at a segment start) is judged before it goes
on: with J the ODE Jacobian there and q the spectral radius of one step of
the method on ``u' = J u`` (rk4: ``max |R(h lambda)|``, the convolution
method's single pass: its two-step companion matrix), the run stops when
``q^n > max_growth`` over the n steps left. This can refuse a run that would
have come out right: an unstable mode that neither the start nor the forcing
excites grows from round-off only (1e-16 times q^n); in the drivetrain models
here every mode is excited.

What it cannot do: a numerical instability that stays bounded (the nonlinearity
of friction or backlash caps it) or grows by less than ``max_growth`` over
the run while changing by less than half its size per step is not detected.
Its error is then of the order of the solution, not astronomic; the accuracy
tables (benchmarks/results/solvers_ode.md) say which steps to use. An *undeclared*
jump of the forcing (a plain callable ``f(t)``, no breakpoint known) that
lifts a state by more than ``max_growth`` beyond everything of the first half
of the run would be mistaken for divergence; the solvers accept
``max_growth=None`` (only the non-finite / 1e100 check) or a larger factor
for such a model.
"""

from __future__ import annotations

import bisect
from collections import deque
from typing import NamedTuple

import numpy as np

#: default factor of growth beyond the explained scale that counts as divergence
MAX_GROWTH = 1e4
#: a state beyond this magnitude (or NaN) is a blow-up whatever the history
BLOW_UP = 1e100
#: a state whose entries all stay below this (SI units) is at rest to round-off: no growth or roughness verdict
QUIET = 1e-12
#: the roughness test: this many steps in a row with r_k above ROUGH and growth beyond ROUGH_GROWTH
ROUGH_STEPS = 10
ROUGH = 0.5
ROUGH_GROWTH = 4.0
#: a fixed-step run with fewer steps than this left is judged a priori (no history for the tests above)
FEW_STEPS = 2 * ROUGH_STEPS
#: ... when its ODE state is at most this large (a dense eigenvalue problem per segment)
FEW_STEPS_MAX_SIZE = 600
#: where the forcing of a segment is sampled (fractions of its length: ends and 3-point Gauss nodes)
_SAMPLES = (0.0, 0.5 - 0.5 * 0.6 ** 0.5, 0.5, 0.5 + 0.5 * 0.6 ** 0.5, 1.0)


def state_norm(u, scratch=None) -> float:
    """``max_j |u_j|`` (inf when a component is NaN, so NaN never passes a comparison as small).
    ``scratch``: an array of u's shape to hold ``|u|`` (on 2,000 states 2.0 us a norm against 3.1 us with a
    fresh array; the ODE driver checks every step)."""
    if u.size == 0:
        return 0.0
    if scratch is not None and scratch.shape == u.shape:
        n = float(np.abs(u, out=scratch).max())
    else:
        n = float(np.max(np.abs(u)))
    return n if n == n else np.inf


class Divergence(NamedTuple):
    """Why a run was stopped: ``kind`` "blow-up", "growth" or "rough"; N(u), and the scale it was compared with."""

    kind: str
    norm: float
    reference: float


class GrowthWatch:
    """The divergence criterion of the module docstring along one run (all segments)."""

    def __init__(self, t_start, u0, max_growth=MAX_GROWTH, compiled=False):
        self.max_growth = max_growth
        # ``compiled``: the per-step arithmetic in one numba pass (``_divergence_kernel``; a run whose right-hand
        # side is compiled, so numba is loaded), the same numbers as the numpy passes
        self._kernel = None
        if compiled:
            try:
                from ._divergence_kernel import step_check
                self._kernel = step_check
            except (ImportError, OSError, AttributeError):
                pass
        n0 = state_norm(u0)
        self.t_onset = float(t_start) if n0 > 0 else None
        self.times = [float(t_start)]
        self.prefix_max = [n0]           # max of N over the recorded times up to each entry (nondecreasing)
        self._forcing: deque = deque()   # (t_k, D_k), D_k decreasing: the window maximum is the first
        self.largest_ratio = 0.0         # max N / R over the run (how close a run came to the limit)
        self.largest_roughness = 0.0     # max over the run of min(r_k) over ROUGH_STEPS steps in a row
        # (t, u, N, r, u - the previous entry's u) of the last steps
        self._recent: list[tuple[float, np.ndarray, float, float, object]] = []
        self._scratch: np.ndarray | None = None      # |u| and the curvature d_k of a step's check, reused

    def segment_start(self, rhs, t, t_stop, size):
        """Record ``D_k`` of a segment [t, t_stop] started after a time event or a mode change
        (5 evaluations of g at the zero state with the segment's modes)."""
        span = t_stop - t
        if span <= 0:
            return
        rest = np.zeros(size)
        with np.errstate(all="ignore"):     # a law singular at zero only loses this (optional) scale
            rate = max(state_norm(rhs(t + f * span, rest)) for f in _SAMPLES)
        forcing = span * rate
        if not np.isfinite(forcing):
            return
        # sliding-window maximum: keep only entries not dominated by a later, larger one
        while self._forcing and self._forcing[-1][1] <= forcing:
            self._forcing.pop()
        self._forcing.append((float(t), forcing))

    def reference(self, t) -> float:
        """``R(t)``, or 0 (no test) while the state has been exactly zero or no step ended near half-way."""
        if self.t_onset is None:
            return 0.0
        elapsed = t - self.t_onset
        k = bisect.bisect_right(self.times, self.t_onset + 0.5 * elapsed) - 1
        if k < 0 or self.times[k] < self.t_onset + 0.4 * elapsed:
            return 0.0                   # no step ended near the half-way time: no bound to test against
        recent = self.t_onset + 0.25 * elapsed
        while self._forcing and self._forcing[0][0] <= recent:
            self._forcing.popleft()      # its response has entered the first half by now
        return max(self.prefix_max[k], self._forcing[0][1] if self._forcing else 0.0)

    def check(self, t, u):
        """Record the state at the end of a step; returns None, or a ``Divergence``."""
        recent = self._recent
        while recent and recent[-1][0] >= t:      # a restart at an event before the last step end
            recent.pop()
        if self._kernel is not None:
            n, entry = self._measure(t, u)
        else:
            if self._scratch is None or self._scratch.shape != np.shape(u):
                self._scratch = np.empty(np.shape(u))
            n, entry = state_norm(u, self._scratch), None
        if not n <= BLOW_UP:
            return Divergence("blow-up", n, self.reference(t))
        rough = self._roughness(t, u, n, entry)
        if self.max_growth is not None and n > QUIET:
            ref = self.reference(t)
            if ref > 0:
                ratio = n / ref
                self.largest_ratio = max(self.largest_ratio, ratio)
                if ratio > self.max_growth:
                    return Divergence("growth", n, ref)
            if rough is not None:
                return rough
        if self.t_onset is None and n > 0:
            self.t_onset = float(t)
        if t >= self.times[-1]:
            self.times.append(float(t))
            self.prefix_max.append(max(self.prefix_max[-1], n))
        return None

    def _measure(self, t, u):
        """``(N(u), the entry of u for _recent)`` in one compiled pass (``_divergence_kernel.step_check``)."""
        u = np.ascontiguousarray(u, dtype=np.float64)
        recent = self._recent
        size = u.shape[0]
        # fresh arrays: a pool of retired ones saved nothing (6.7 against 6.9 us on 2,000 states)
        u_copy, du = np.empty(size), np.empty(size)
        u1 = recent[-1][1] if recent else u
        curvature = len(recent) >= 2
        if curvature:       # d = (u - u1) - (t - t1) / (t1 - t0) * (u1 - u0), as in ``_roughness``
            t1 = recent[-1][0]
            du1, factor = recent[-1][4], (t - t1) / (t1 - recent[-2][0])
        else:
            du1, factor = u1, 0.0
        if self._scratch is None or self._scratch.shape != u.shape:
            self._scratch = np.empty(u.shape)
        n, dmax = self._kernel(u, u1, du1, factor, curvature, u_copy, du, self._scratch)
        r = dmax / n if curvature and n > 0 else 0.0
        return n, (float(t), u_copy, n, r, du if recent else None)

    def mode_change(self):
        """A friction mode change: the law of motion switched, so the curvature ``d_k`` of steps
        spanning it measures the jump of the acceleration, not an instability. The roughness history
        restarts (the growth test keeps its history). Found on a servo shaking a light inertia against
        a clutch to a heavy one at rest (fuzz seed 31): the clutch reverses every 0.019 s, two steps
        apart, the heavy inertia's tiny motion kinks at every reversal, and 10 steps in a row had
        ``r_k > 0.5`` while it grew from rest: a correct run was stopped as diverged."""
        self._recent.clear()

    def _roughness(self, t, u, n, entry=None):
        """Update r_k; a ``Divergence`` when the last ROUGH_STEPS steps were all rough and N grew. ``entry``: the
        step's ``(t, u, N, r, u - u1)`` when the compiled pass has made it (``_measure``)."""
        recent = self._recent
        if entry is None:
            r = 0.0
            du = None
            if recent:
                t1, u1 = recent[-1][0], recent[-1][1]
                du = u - u1
                if len(recent) >= 2 and n > 0:
                    # d = (u - u1) - (t - t1) / (t1 - t0) * (u1 - u0), with u1 - u0 kept from the step before
                    t0 = recent[-2][0]
                    d = np.multiply(recent[-1][4], (t - t1) / (t1 - t0), out=self._scratch)
                    np.subtract(du, d, out=d)
                    r = state_norm(d, self._scratch) / n
            entry = (float(t), u.copy(), n, r, du)
        recent.append(entry)
        if len(recent) > ROUGH_STEPS + 1:
            recent.pop(0)
        if len(recent) <= ROUGH_STEPS:
            return None
        sustained = min(entry[3] for entry in recent[1:])
        self.largest_roughness = max(self.largest_roughness, sustained)
        if sustained > ROUGH and n > ROUGH_GROWTH * recent[0][2]:
            return Divergence("rough", n, recent[0][2])
        return None
