"""Fixed-step explicit methods on the ODE form: ``euler``, ``rk4``, ``abm``.

* ``euler``: ``u_{n+1} = u_n + h g_n`` (order 1, 1 evaluation per step).
* ``rk4``: the classical Runge-Kutta method (order 4, 4 evaluations per step).
* ``abm``: Adams-Bashforth-Moulton predictor-corrector of order 4 in PECE
  form (2 evaluations per step)::

      u_P = u_n + h/24 (55 g_n - 59 g_{n-1} + 37 g_{n-2} - 9 g_{n-3})
      u_{n+1} = u_n + h/24 (9 g(t_{n+1}, u_P) + 19 g_n - 5 g_{n-1} + g_{n-2})

  started (and restarted whenever the step length changes, after a time
  event or a mode change) by three RK4 steps.

Output times are hit exactly, not interpolated: the requested step ``h``
(option ``h`` [s], default ``dt_out``) is shortened on each output interval
to ``interval / ceil(interval / h)``, so that a whole number of equal steps
ends on every output instant, signal breakpoint and ``t_end``. Inside a
step (for locating a stick/slip crossing) the solution is the cubic Hermite
interpolant of the values and slopes at both ends.

These methods are only conditionally stable: a step larger than about
``bound/rho`` (``rho`` the spectral radius of the Jacobian, roughly the
highest natural frequency of the model; ``bound`` the method's stability
interval on the negative real axis: 2 for ``euler``, 2.785 for ``rk4``,
1.3 for ``abm`` in PECE form; ``rk4`` reaches 2.83 on the imaginary axis,
``euler`` is slightly unstable on undamped oscillations at any step) makes
the solution grow geometrically. The driver stops such a run as soon as the
state outgrows the scale its start and its forcing explain by more than
``max_growth`` (option, default 1e4; see ``regmech.solvers.divergence``)
with a ``SimulationError`` that gives ``rho`` and the largest stable step.

Error control (option ``tol``, default 1e-3): these methods do not control
their error step by step, so after the run a companion run at step 2h
estimates its global error by Richardson extrapolation
(``regmech.solvers.richardson``; order p = 1 for ``euler``, 4 for ``rk4``
and ``abm``). Every ODE-form state (positions, speeds, internal states)
must have an estimated error at most ``tol`` times the largest range of the
states of its kind; otherwise the run raises ``AccuracyError`` naming the
worst signal and component and a step that meets ``tol``. The estimate is
``res.stats.error_estimate``; the companion costs about half the main run.
``tol=None`` skips it (the bare method, as the benchmarks time it).
"""

from __future__ import annotations

import numpy as np

from . import register
from .divergence import MAX_GROWTH
from .ode_driver import KnotClock, Stepper, hermite
from .options import (FIXED_MAX_STEPS, OptionSet, chatter_options, fixed_max_steps_option, max_events_option,
                      max_growth_option, step_option, tol_option)
from .richardson import DEFAULT_TOL, simulate_fixed_step


class FixedStepper(Stepper):
    """Equal steps of at most ``h`` landing exactly on every knot; subclasses supply ``advance``.

    ``clock``: the step sequence (``KnotClock``; the error estimate's companion
    runs pass ``GroupedKnotClock`` for steps of exactly 2h).
    """

    #: convergence order p (for the error estimate)
    order = 4
    slope_at_end = True         # ``advance`` returns g(t + h, u_new)

    def __init__(self, problem, t0, u0, t_bound, knots, h, clock=KnotClock):
        self.problem = problem
        self.t = self.t_old = float(t0)
        self.u = np.array(u0, float)
        self.g = problem.rhs(self.t, self.u)
        self.u_old, self.g_old = self.u, self.g
        self.clock = clock(t0, knots, t_bound, h)
        self.fixed_step = float(h)
        self.nsteps = 0
        self.nrejected = 0
        self.njev = 0

    def step(self):
        h, t_new = self.clock.next_step(self.t)
        u_new, g_new = self.advance(self.t, self.u, self.g, h)
        self.t_old, self.u_old, self.g_old = self.t, self.u, self.g
        self.t, self.u, self.g = t_new, u_new, g_new
        self.nsteps += 1

    def interpolate(self, tq):
        if tq == self.t:
            return self.u
        return hermite(self.t_old, self.u_old, self.g_old, self.t, self.u, self.g, tq)

    def advance(self, t, u, g, h):  # pragma: no cover - abstract
        """One step from (t, u) with slope g = g(t, u); returns (u_new, g(t + h, u_new))."""
        raise NotImplementedError

    @staticmethod
    def stability_function(z):
        """Factor of one step on ``y' = lambda y``, ``z = h lambda`` (the classical RK4 polynomial)."""
        return 1 + z * (1 + z * (0.5 + z * (1.0 / 6.0 + z / 24.0)))

    amplification_exact = True

    def amplification(self, J, h, eigenvalues=None):
        if not J.size:
            return None
        lam = np.linalg.eigvals(J) if eigenvalues is None else eigenvalues
        return float(np.max(np.abs(self.stability_function(h * lam))))


class EulerStepper(FixedStepper):
    stability_bound = 2.0
    order = 1

    @staticmethod
    def stability_function(z):
        return 1 + z

    def advance(self, t, u, g, h):
        u1 = u + h * g
        return u1, self.problem.rhs(t + h, u1)


def rk4_step(rhs, t, u, g, h):
    k2 = rhs(t + 0.5 * h, u + 0.5 * h * g)
    k3 = rhs(t + 0.5 * h, u + 0.5 * h * k2)
    k4 = rhs(t + h, u + h * k3)
    return u + (h / 6.0) * (g + 2.0 * k2 + 2.0 * k3 + k4)


class RK4Stepper(FixedStepper):
    stability_bound = 2.785

    def advance(self, t, u, g, h):
        u1 = rk4_step(self.problem.rhs, t, u, g, h)
        return u1, self.problem.rhs(t + h, u1)


class ABMStepper(FixedStepper):
    """Adams-Bashforth-Moulton 4 (PECE); the history holds g_n, g_{n-1}, g_{n-2}, g_{n-3} at spacing h."""

    stability_bound = 1.3      # measured: y' = lambda y stays bounded for h lambda in [-1.3, 0)
    # amplification: the RK4 factor of the start-up steps (a short run is mostly those; ABM's own region is
    # smaller, so this errs on the side of letting a short run go); not exact, so it never overrules a
    # roughness verdict (``ode_driver.RoughVerdict``)
    amplification_exact = False

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.history = [self.g]
        self.h_hist = None
        self.starts = 1

    def advance(self, t, u, g, h):
        rhs = self.problem.rhs
        if self.h_hist is None or abs(h - self.h_hist) > 1e-10 * h:
            if self.h_hist is not None:
                self.starts += 1
            self.history, self.h_hist = [g], h          # a new spacing: restart with RK4
        if len(self.history) < 4:
            u1 = rk4_step(rhs, t, u, g, h)
            g1 = rhs(t + h, u1)
        else:
            g0, gm1, gm2, gm3 = self.history
            u_p = u + (h / 24.0) * (55.0 * g0 - 59.0 * gm1 + 37.0 * gm2 - 9.0 * gm3)
            g_p = rhs(t + h, u_p)
            u1 = u + (h / 24.0) * (9.0 * g_p + 19.0 * g0 - 5.0 * gm1 + gm2)
            g1 = rhs(t + h, u1)
        self.history = [g1] + self.history[:3]
        return u1, g1

    def stats(self):
        return {"abm_starts": self.starts}


def _fixed_step_solver(name, stepper_cls):
    options = OptionSet(
        f"a fixed-step method of order {stepper_cls.order}: it takes a step h and a bound tol of its estimated "
        f"global error instead of rtol/atol",
        h=step_option("step [s] (default dt_out)"),
        tol=tol_option(),
        max_steps=fixed_max_steps_option(),
        max_events=max_events_option(),
        max_growth=max_growth_option(),
        **chatter_options(),
    )

    @register(name, options)
    def simulate_fixed(model, t_start=0.0, t_end=1.0, dt_out=None, h=None, tol=DEFAULT_TOL, max_steps=FIXED_MAX_STEPS,
                       max_events=100000, chatter_window=None, chatter_count=50, max_growth=MAX_GROWTH):
        step = dt_out if h is None else h

        def make_stepper(clock, companion):
            def make(problem, t0, u0, t_bound, knots):
                return stepper_cls(problem, t0, u0, t_bound, knots, step, clock=clock)
            return make

        def after_main(res):
            res.stats.extra["h"] = float(step)

        return simulate_fixed_step(model, name, make_stepper, h=float(step), order=stepper_cls.order, tol=tol,
                                   t_start=t_start, t_end=t_end, dt_out=dt_out, after_main=after_main,
                                   max_steps=max_steps, max_events=max_events, chatter_window=chatter_window,
                                   chatter_count=chatter_count, explicit=True, max_growth=max_growth)

    simulate_fixed.__doc__ = (f"Fixed-step '{name}' on the ODE form (see regmech.solvers.explicit); options h [s] "
                              f"(default dt_out), tol (default {DEFAULT_TOL:g}: bound of the Richardson estimate of "
                              f"the global error relative to the range of each kind of state, AccuracyError beyond "
                              f"it; None: no estimate, see regmech.solvers.richardson), max_steps, max_events, chatter_window, "
                              f"chatter_count, max_growth.")
    simulate_fixed.__name__ = f"simulate_{name}"
    return simulate_fixed


simulate_euler = _fixed_step_solver("euler", EulerStepper)
simulate_rk4 = _fixed_step_solver("rk4", RK4Stepper)
simulate_abm = _fixed_step_solver("abm", ABMStepper)
