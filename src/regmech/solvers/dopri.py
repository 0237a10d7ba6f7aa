"""regmech's own Dormand-Prince integrators: ``dopri5`` (order 5(4)) and ``dop853`` (order 8(5,3)).

The same methods as ``scipy:RK45`` and ``scipy:DOP853`` (Dormand and Prince's tableaus, read from scipy's
classes; Hairer, Norsett and Wanner, *Solving Ordinary Differential Equations I*, sec. II.4-II.6), with the
same step control, so that on the same model and tolerances they take scipy's steps and return scipy's values
up to round-off (``tests/unit/test_dopri.py``). Only a decision that round-off can tip differs: the sums are
taken in another order, so a step's error norm, or a stick/slip instant located on the dense output, can
differ in its last bits (measured: CoupledClutches over 1 s, 33 steps against scipy's 32; the answers within
1e-14 of the range).

* a step ``h`` from ``(t, y)`` with ``f = g(t, y)``: stages ``K_0 = f``,
  ``K_s = g(t + c_s h, y + h sum_{j<s} a_sj K_j)``; ``y_new = y + h sum_j b_j K_j``; ``K_S = g(t + h, y_new)``
  is the next step's ``f`` (first same as last);
* the error, measured in ``scale_i = atol_i + rtol max(|y_i|, |y_new_i|)``: for ``dopri5`` the RMS of
  ``h sum_j e_j K_j / scale``; for ``dop853`` ``|h| E5^2 / sqrt(n (E5^2 + 0.01 E3^2))`` with ``E5``, ``E3``
  the 2-norms of the 5th- and 3rd-order estimates over ``scale`` (Hairer's blend);
* accepted when that norm is below 1; the next step is ``h * min(10, 0.9 norm^(-1/(q+1)))`` (q = 4 or 7; no
  growth right after a rejection), a rejected one is retried at ``h * max(0.2, 0.9 norm^(-1/(q+1)))``;
  every step at most ``max_step``, never below ten ulps of ``t`` (a run that needs less fails);
* the first step from Hairer's estimate (sec. II.4) unless ``first_step`` is given;
* dense output: ``dopri5`` the quartic of the stages (``P``); ``dop853`` the 7th-degree interpolant of three
  extra stages, made for a step whose interpolant the driver reads (an output instant falls in it, or a
  friction device's event guard is armed: then every step).

Why a second implementation: scipy forms each stage's argument by a matrix product into a new array, scales
it into another and adds the state into a third, and its error norms make three more; on a chain of 10,000
inertias (20,000 states) that bookkeeping was two thirds of a scipy RK45 run, the right-hand side one third.
Here one pass per stage writes ``y + h sum a_sj K_j`` into a buffer the integrator keeps, and one pass gives
the error norm (compiled when numba is installed, ``_dopri_kernels``; else numpy into the same buffers, three
passes per stage; ``compiled_passes``). On small models the gain is the Python around each stage.

The classes follow scipy's ``OdeSolver`` protocol as far as ``scipy_ivp.ScipyStepper`` uses it (``step``,
``dense_output``, ``t``, ``t_old``, ``y``, ``status``, a settable ``atol``), so both families share one
driver, one stiffness check, one step cap and one scaled atol (``scipy_ivp``).
"""

from __future__ import annotations

import math
import sys

import numpy as np
from scipy.integrate import DOP853 as _ScipyDOP853
from scipy.integrate import RK45 as _ScipyRK45

#: the compiled passes (``_dopri_kernels``) once loaded; None when numba is not installed (or cannot load)
_UNLOADED = object()
_kernels = _UNLOADED
#: a model of fewer states takes the compiled passes only when numba is loaded already: they save 10-30 % of a
#: small run (a chain of 10 inertias, 20 states: 23 against 27 ms by RK45), which would not repay numba's
#: import (about 0.3 s) in a process that makes one such run; from this size on the form's own right-hand side
#: is compiled (``compile.odeform``), which loads numba anyway
COMPILED_MIN_STATES = 100


def compiled_passes(n: int):
    """The module of compiled passes for an integrator of ``n`` states, or None (numpy's passes)."""
    global _kernels
    if _kernels is None or (_kernels is _UNLOADED and n < COMPILED_MIN_STATES and "numba" not in sys.modules):
        return None
    if _kernels is _UNLOADED:
        try:
            from . import _dopri_kernels
            _kernels = _dopri_kernels
        except (ImportError, OSError, AttributeError):    # no numba, or one that cannot load (as ida_native)
            _kernels = None
    return _kernels


SAFETY = 0.9          # the step factor's safety margin
MIN_FACTOR = 0.2      # the most a rejected step shrinks at once
MAX_FACTOR = 10.0     # the most an accepted step grows at once


def _rms(x) -> float:
    return float(np.linalg.norm(x)) / math.sqrt(x.size) if x.size else 0.0


def initial_step(fun, t0, y0, f0, t_bound, max_step, order, rtol, atol) -> float:
    """Hairer's starting step (sec. II.4) [s]: ``h0 = 0.01 d0 / d1`` from the sizes ``d0`` of ``y0`` and ``d1``
    of ``f0`` in the tolerance's scale (1e-6 s when either is below 1e-5), then ``h1 = (0.01 / max(d1, d2))^(1 /
    (order + 1))`` with ``d2`` the change of ``f`` over an Euler step of ``h0``; the smallest of ``100 h0``,
    ``h1``, the interval and ``max_step``. One extra evaluation of ``fun``."""
    span = abs(t_bound - t0)
    if y0.size == 0:
        return math.inf
    if span == 0.0:
        return 0.0
    direction = 1.0 if t_bound >= t0 else -1.0
    scale = atol + np.abs(y0) * rtol
    d0, d1 = _rms(y0 / scale), _rms(f0 / scale)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, span)
    f1 = fun(t0 + h0 * direction, y0 + h0 * direction * f0)
    d2 = _rms((f1 - f0) / scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1))
    return min(100.0 * h0, h1, span, max_step)


def _all_finite(v) -> bool:
    """Whether every entry of ``v`` is finite: one summing pass (a NaN or inf makes the sum non-finite), the
    entries tested one by one only when the sum is not finite (it may overflow on finite entries)."""
    return math.isfinite(float(np.add.reduce(v))) or bool(np.all(np.isfinite(v)))


def _stage_numpy(y, K, coef, s, h, out, work):
    """``out = y + h sum_{j<s} coef_j K_j`` without new arrays (``work``: length-n scratch)."""
    np.dot(coef[:s], K[:s], out=work)
    work *= h
    np.add(y, work, out=out)


class DormandPrince:
    """One explicit embedded Runge-Kutta integrator of ``y' = fun(t, y)`` (module docstring); subclasses give
    the tableau. ``fun(t, y)`` returns a new array each call (the state's derivative at a step's end is kept);
    ``fun_into(t, y, out)``, when given, writes the same values into ``out`` (a row of the stages: no copy).
    ``atol``: scalar or array of length n; ``rtol`` scalar."""

    order: int
    error_estimator_order: int
    n_stages: int
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray

    TOO_SMALL_STEP = "Required step size is less than spacing between numbers."

    def __init__(self, fun, t0, y0, t_bound, max_step=np.inf, rtol=1e-3, atol=1e-6, first_step=None,
                 fun_into=None, stages=None):
        self.fun = fun
        self.fun_into = fun_into
        self.t = float(t0)
        self.t_old = None
        self.t_bound = float(t_bound)
        self.direction = 1.0 if self.t_bound >= self.t else -1.0
        self.y = np.array(y0, dtype=np.float64)          # a copy: the caller's start is never written
        self.n = self.y.size
        self.max_step = float(max_step)
        self.rtol = float(rtol)
        self.atol = atol
        self.nfev = 0
        self.njev = 0
        self.nlu = 0
        self.status = "running"
        self.steps_begun = 0             # attempts started: a dense output holds until the next one
        self._k = compiled_passes(self.n)
        # a compiled sweep over a step's stages (``OdeProblem.stage_sweep``): the same passes as the loop below
        self._sweep = stages if self._k is not None else None
        self.f = self._eval(self.t, self.y)
        S = self.n_stages
        self.K = np.empty((self.K_rows(), self.n))
        self._work = np.empty(self.n)                    # stage arguments are built here
        self._sum = np.empty(self.n)                     # numpy path's scratch
        self._a_rows = [np.ascontiguousarray(self.A[s, :s]) for s in range(S)]
        self._b = np.ascontiguousarray(self.B)
        self.error_exponent = -1.0 / (self.error_estimator_order + 1)
        self.y_old = None
        self.h_previous = None
        if first_step is None:
            self.h_abs = initial_step(self._eval, self.t, self.y, self.f, self.t_bound, self.max_step,
                                      self.error_estimator_order, self.rtol, self._atol)
            if not math.isfinite(self.h_abs) and self.n:
                # a non-finite f at the start makes the estimate NaN, and NaN < min_step never ends the loop of
                # ``_step_impl``: try the longest step, whose attempts then shrink to the spacing of numbers and fail
                self.h_abs = min(self.max_step, abs(self.t_bound - self.t))
        else:
            self.h_abs = float(first_step)

    # ------------------------------------------------------------------ tolerances
    @property
    def atol(self):
        return self._atol

    @atol.setter
    def atol(self, value):
        # one array of length n, whatever was given (the compiled norm reads one entry per state)
        self._atol = np.ascontiguousarray(np.broadcast_to(np.asarray(value, np.float64), (self.n,)))

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        # every stage's row of A and node c in one square table, the extra stages of a dense output included (rows
        # S + 1 on; row S, the step's end, is made from B): what the compiled sweep reads (``_sweep``)
        extra_a, extra_c = getattr(cls, "A_EXTRA", ()), getattr(cls, "C_EXTRA", ())
        S = cls.n_stages
        rows = S + 1 + len(extra_c)
        cls._A_ALL, cls._C_ALL = np.zeros((rows, rows)), np.zeros(rows)
        cls._A_ALL[:S, :cls.A.shape[1]], cls._C_ALL[:S] = cls.A, cls.C
        for i, (a, c) in enumerate(zip(extra_a, extra_c)):
            cls._A_ALL[S + 1 + i, :S + 1 + i], cls._C_ALL[S + 1 + i] = a[:S + 1 + i], c

    def K_rows(self) -> int:
        return self.n_stages + 1

    def _eval(self, t, y):
        self.nfev += 1
        return self.fun(t, y)

    def _eval_into(self, t, y, row):
        """``K[row] = fun(t, y)``, written there by ``fun_into`` when given (no copy)."""
        self.nfev += 1
        if self.fun_into is not None:
            self.fun_into(t, y, self.K[row])
        else:
            self.K[row] = self.fun(t, y)

    def _stage(self, y, coef, s, h, out):
        if self._k is not None:
            self._k.blend(y, y, 0.0, self.K, coef, s, h, out)
        else:
            _stage_numpy(y, self.K, coef, s, h, out, self._sum)

    # ------------------------------------------------------------------ stepping
    def step(self):
        """One accepted step (retrying rejected ones); returns None, or the failure's message (``status``
        becomes ``"failed"``); ``"finished"`` once ``t_bound`` is reached."""
        if self.status != "running":
            raise RuntimeError("attempt to step on a failed or finished solver")
        if self.n == 0 or self.t == self.t_bound:
            # nothing to integrate (no state, or an empty span): the end at once, as scipy's solvers do
            self.t_old, self.y_old, self.h_previous = self.t, self.y, 0.0
            self.t = self.t_bound
            self.steps_begun += 1
            self.status = "finished"
            return None
        if not self._step_impl():
            self.status = "failed"          # the caller names a non-finite rate (``scipy_ivp.ScipyStepper``)
            return self.TOO_SMALL_STEP
        if self.direction * (self.t - self.t_bound) >= 0:
            self.status = "finished"
        return None

    def _step_impl(self) -> bool:
        t, y, f = self.t, self.y, self.f
        min_step = 10.0 * abs(np.nextafter(t, self.direction * np.inf) - t)
        h_abs = min(max(self.h_abs, min_step), self.max_step)
        rejected = False
        K, S = self.K, self.n_stages
        self.steps_begun += 1
        while True:
            if h_abs < min_step:
                return False
            t_new = t + h_abs * self.direction
            if self.direction * (t_new - self.t_bound) > 0:
                t_new = self.t_bound
            h = t_new - t
            h_abs = abs(h)
            K[0] = f
            if self._sweep is not None:
                self.nfev += S - 1
                self._sweep(y, K, self._A_ALL, self._C_ALL, 1, S, t, h, self._work)
            else:
                for s in range(1, S):
                    self._stage(y, self._a_rows[s], s, h, self._work)
                    self._eval_into(t + self.C[s] * h, self._work, s)
            y_new = np.empty(self.n)
            self._stage(y, self._b, S, h, y_new)
            f_new = self._eval(t + h, y_new)
            K[S] = f_new
            norm = self._error_norm(y, y_new, h)
            if not (math.isfinite(norm) and _all_finite(f_new)):
                # NaN or inf in a stage: shrink as for a large error (as scipy), which recovers from an overflow of
                # a too long trial step; one that persists fails at the spacing of numbers. The end's rate f_new
                # is tested apart: DOP853's error weights give it none (and the compiled sums leave out the terms
                # of zero weight), so a non-finite f_new kept the norm finite and the step was taken
                norm = math.inf
            if norm < 1.0:
                factor = MAX_FACTOR if norm == 0.0 else min(MAX_FACTOR, SAFETY * norm ** self.error_exponent)
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                break
            h_abs *= max(MIN_FACTOR, SAFETY * norm ** self.error_exponent)
            rejected = True
        self.h_previous = h
        self.y_old = y
        self.t_old = t
        self.t = t_new
        self.y = y_new
        self.h_abs = h_abs
        self.f = f_new
        return True

    def _check_stepped(self):
        if self.t_old is None:
            raise RuntimeError("a Dormand-Prince dense output exists only after a step")

    def _error_norm(self, y, y_new, h) -> float:  # pragma: no cover - interface
        raise NotImplementedError

    def dense_output(self):  # pragma: no cover - interface
        raise NotImplementedError


class Dopri5(DormandPrince):
    """Dormand-Prince 5(4) with its quartic dense output (the method of ``scipy:RK45``)."""

    solver_name, method = "dopri5", "RK45"

    order = _ScipyRK45.order
    error_estimator_order = _ScipyRK45.error_estimator_order
    n_stages = _ScipyRK45.n_stages
    A, B, C = _ScipyRK45.A, _ScipyRK45.B, _ScipyRK45.C
    E = np.ascontiguousarray(_ScipyRK45.E)
    P = np.ascontiguousarray(_ScipyRK45.P)

    def _error_norm(self, y, y_new, h) -> float:
        if self._k is not None:
            return self._k.rms_error(self.K, self.E, h, y, y_new, self._atol, self.rtol)
        scale = self._atol + np.maximum(np.abs(y), np.abs(y_new)) * self.rtol
        err = np.dot(self.E, self.K, out=self._sum)
        err *= h
        err /= scale
        return _rms(err)

    def dense_output(self):
        """The step's quartic ``y(t_old + x h) = y_old + h sum_j (sum_k P_jk x^(k+1)) K_j`` (``StepOutput``)."""
        self._check_stepped()
        P = self.P

        powers = np.arange(1, P.shape[1] + 1)

        def weights(x):
            # x: (m,) instants as fractions of the step -> c (m,), w (m, rows)
            return np.zeros(x.shape), (x[:, None] ** powers) @ P.T

        def weight_row(x):
            # one instant (a float): c, w (rows,)
            return 0.0, P @ (x ** powers)
        return StepOutput(self, weights, P.shape[0], weight_row)


class Dop853(DormandPrince):
    """Dormand-Prince 8(5,3) with its 7th-degree dense output (the method of ``scipy:DOP853``)."""

    solver_name, method = "dop853", "DOP853"

    order = _ScipyDOP853.order
    error_estimator_order = _ScipyDOP853.error_estimator_order
    n_stages = _ScipyDOP853.n_stages
    A, B, C = _ScipyDOP853.A, _ScipyDOP853.B, _ScipyDOP853.C
    E3 = np.ascontiguousarray(_ScipyDOP853.E3)
    E5 = np.ascontiguousarray(_ScipyDOP853.E5)
    D = np.ascontiguousarray(_ScipyDOP853.D)
    A_EXTRA = _ScipyDOP853.A_EXTRA
    C_EXTRA = _ScipyDOP853.C_EXTRA

    #: the rows of A of the three extra stages, each to its stage (13, 14, 15)
    _A_EXTRA_ROWS = [np.ascontiguousarray(a[:_ScipyDOP853.n_stages + 1 + i]) for i, a in enumerate(A_EXTRA)]

    def K_rows(self) -> int:
        # the 13 stages of a step and the three more of its dense output (rows 13-15)
        return self.n_stages + 1 + len(self.C_EXTRA)

    def _error_norm(self, y, y_new, h) -> float:
        S1 = self.n_stages + 1
        if self._k is not None:
            e5, e3 = self._k.blended_sums(self.K, self.E5, self.E3, S1, y, y_new, self._atol, self.rtol)
        else:
            scale = self._atol + np.maximum(np.abs(y), np.abs(y_new)) * self.rtol
            err = np.dot(self.E5, self.K[:S1], out=self._sum)
            err /= scale
            e5 = float(np.dot(err, err))
            err = np.dot(self.E3, self.K[:S1], out=self._sum)
            err /= scale
            e3 = float(np.dot(err, err))
        if e5 == 0.0 and e3 == 0.0:
            return 0.0
        return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * self.n)

    def dense_output(self):
        """The step's 7th-degree interpolant (Hairer's contd8; ``StepOutput``) from three extra stages, made
        here once per step asked.

        Hairer's form ``y_old + x (F_0 + (1 - x)(F_1 + x (F_2 + (1 - x)(... F_6))))`` with ``F_0 = dy = y - y_old``,
        ``F_1 = h K_0 - dy``, ``F_2 = 2 dy - h (f + K_0)`` (``f = K_12``, the step's end) and ``F_3+k = h sum_j
        D_kj K_j`` is, with ``b_k(x)`` the product of the factors in front of ``F_k`` (``x``, ``x (1 - x)``,
        ``x^2 (1 - x)``, ...), ``y_old + c dy + h sum_j w_j K_j`` with ``c = b_0 - b_1 + 2 b_2`` and ``w_j = sum_k
        b_3+k D_kj``, plus ``b_1 - b_2`` at ``j = 0`` and ``-b_2`` at ``j = 12``: one pass over the stages per
        instant instead of seven vectors made and summed."""
        self._check_stepped()
        K, h, t0, y0 = self.K, self.h_previous, self.t_old, self.y_old
        S1 = self.n_stages + 1
        if h and self._sweep is not None:
            self.nfev += len(self.C_EXTRA)
            self._sweep(y0, K, self._A_ALL, self._C_ALL, S1, S1 + len(self.C_EXTRA), t0, h, self._work)
        elif h:
            for i, (a, c) in enumerate(zip(self._A_EXTRA_ROWS, self.C_EXTRA)):
                s = S1 + i
                self._stage(y0, a, s, h, self._work)
                self._eval_into(t0 + c * h, self._work, s)
        D, last = self.D, self.n_stages

        def weights(x):
            # x: (m,) instants as fractions of the step -> c (m,), w (m, rows)
            u = 1.0 - x
            b = np.array([x, x * u, x * x * u, (x * u) ** 2, x ** 3 * u * u, (x * u) ** 3, x ** 4 * u ** 3])
            w = b[3:].T @ D
            w[:, 0] += b[1] - b[2]
            w[:, last] -= b[2]
            return b[0] - b[1] + 2.0 * b[2], w

        def weight_row(x):
            # one instant (a float): the same b_k in Python floats, w (rows,) from one product (the array form
            # above made a dozen arrays of one entry, 30 us an output instant on the chain of 100 inertias)
            u = 1.0 - x
            xu = x * u
            b = (x, xu, x * x * u, xu * xu, x ** 3 * u * u, xu ** 3, x ** 4 * u ** 3)
            w = np.array(b[3:]) @ D
            w[0] += b[1] - b[2]
            w[last] -= b[2]
            return b[0] - b[1] + 2.0 * b[2], w
        return StepOutput(self, weights, D.shape[1], weight_row)


class StepOutput:
    """The last step's dense output, ``y(t_old + x h) = y_old + c(x) (y - y_old) + h sum_j w_j(x) K_j``: one
    pass over the integrator's stages per instant (``_dopri_kernels.blend``), for ``t`` a number (an array of
    n) or an array of m instants (``(n, m)``, as scipy's dense output; ``rows`` gives them as ``(m, n)``, the
    output rows of a step: their weights made together and the sum over the stages one matrix product). It
    reads the stages in place, so it holds only until the integrator's next step (a later call raises)."""

    def __init__(self, solver, weights, rows, weight_row=None):
        self.solver, self.weights, self.n_stages = solver, weights, rows
        self.weight_row = weight_row          # one instant's (c, w), cheaper than ``weights`` on an array of one
        self.t_old, self.h, self.y_old, self.y = solver.t_old, solver.h_previous, solver.y_old, solver.y
        self.K = solver.K
        self.step = solver.steps_begun

    def _check(self):
        if self.solver.steps_begun != self.step:
            raise RuntimeError("a Dormand-Prince dense output read after its integrator began another step")

    def _at(self, t):
        self._check()
        if self.h == 0.0:                    # an empty step (no state, or an empty span): the state itself
            return self.y.copy()
        x = (float(t) - self.t_old) / self.h
        if self.weight_row is not None:
            c, w = self.weight_row(x)
        else:
            c, w = self.weights(np.array([x]))
            c, w = float(c[0]), w[0]
        w = np.ascontiguousarray(w, dtype=np.float64)
        out = np.empty(self.y_old.size)
        if self.solver._k is not None:
            self.solver._k.blend(self.y_old, self.y, c, self.K, w, self.n_stages, self.h, out)
        else:
            np.dot(w, self.K[:self.n_stages], out=out)
            out *= self.h
            out += self.y_old + c * (self.y - self.y_old)
        return out

    def rows(self, ts):
        """The states at the instants ``ts`` as the rows of an ``(m, n)`` array: the m instants' weights in one
        pass, ``h W K`` one matrix product (a step's output instants: 10 us each through ``_at`` on a train of
        100 cars, 20,000 instants a pair of runs, where the product costs about the copy of the rows)."""
        self._check()
        ts = np.asarray(ts, float)
        if self.h == 0.0:
            return np.tile(self.y, (ts.size, 1))
        c, w = self.weights((ts - self.t_old) / self.h)
        out = w @ self.K[:self.n_stages]
        out *= self.h
        out += self.y_old
        out += c[:, None] * (self.y - self.y_old)
        return out

    def __call__(self, t):
        if np.ndim(t) == 0:
            return self._at(t)
        return self.rows(t).T


#: the classes by their solver name (``simulate(solver=...)``)
CLASSES = {cls.solver_name: cls for cls in (Dopri5, Dop853)}
