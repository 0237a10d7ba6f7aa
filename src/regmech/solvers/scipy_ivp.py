"""scipy's ODE solvers on the ODE form: ``scipy:RK45``, ``scipy:RK23``, ``scipy:DOP853``,
``scipy:Radau``, ``scipy:BDF``, ``scipy:LSODA``.

Options: ``rtol`` (default 1e-6), ``atol`` (default ``rtol * 1e-2``, as for
IDA), ``first_step``, ``max_step`` [s], ``max_growth`` (divergence test, see
``regmech.solvers.divergence``). The implicit methods get the
structure: Radau and BDF the sparsity pattern of ``dg/du``
(``jac_sparsity``, so scipy builds a sparse finite-difference Jacobian with
grouped columns and factorises it sparsely); LSODA, which takes no pattern,
a Jacobian built from the same grouped finite differences.

The ``OdeSolver`` classes are stepped directly (rather than through
``solve_ivp``) so that every ODE-form solver shares one driver
(``ode_driver``): output values come from scipy's dense output; a
stick/slip event is a downward zero crossing of a friction event function,
checked after every step and located on the dense output, i.e. what
``solve_ivp(events=...)`` with ``terminal=True, direction=-1`` does, except
that the restart point is taken on the crossed side of the zero.
"""

from __future__ import annotations

from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, Radau

from ..errors import ParameterError, SimulationError
from . import register
from .divergence import MAX_GROWTH, check_max_growth
from .ode_driver import Stepper, ode_jacobian_pattern, simulate_ode

METHODS = {"RK45": RK45, "RK23": RK23, "DOP853": DOP853, "Radau": Radau, "BDF": BDF, "LSODA": LSODA}


class ScipyStepper(Stepper):
    """One scipy ``OdeSolver`` per segment."""

    def __init__(self, method, problem, t0, u0, t_bound, **options):
        cls = METHODS[method]
        if method in ("Radau", "BDF"):
            options["jac_sparsity"] = ode_jacobian_pattern(problem.c)
        elif method == "LSODA":
            options["jac"] = lambda t, u: problem.jacobian(t, u).toarray()
        self.method = method
        self.solver = cls(problem.rhs, t0, u0, t_bound, **options)
        self.t = self.t_old = float(t0)
        self.u = self.solver.y
        self.nsteps = 0
        self.nrejected = 0
        self._dense = None
        self._lu0 = getattr(self.solver, "nlu", 0)

    @property
    def njev(self):
        # LSODA's Jacobians are counted by the problem (they are built there)
        return 0 if self.method == "LSODA" else int(getattr(self.solver, "njev", 0) or 0)

    def step(self):
        msg = self.solver.step()
        if self.solver.status == "failed":
            raise SimulationError(f"scipy {self.method} failed at t={self.solver.t:.6g} in model "
                                  f"'{self.problem_name}': {msg}. Try another rtol or a stiff solver (ida)")
        self.t_old, self.t, self.u = self.solver.t_old, self.solver.t, self.solver.y
        self._dense = None
        self.nsteps += 1

    def interpolate(self, tq):
        if tq == self.t:
            return self.u
        if self._dense is None:
            self._dense = self.solver.dense_output()
        return self._dense(tq)

    def stats(self):
        return {"lu_decompositions": int(getattr(self.solver, "nlu", 0) or 0) - self._lu0}


#: stability interval of the explicit methods on the negative real axis (h * rho up to about this)
EXPLICIT_STABILITY = {"RK23": 2.5, "RK45": 3.3, "DOP853": 6.0}


def _refuse_if_stiff(name, method, problem, t0, u0, t_end, max_steps):
    """An explicit method needs h <= bound / rho: refuse up front when that takes more than max_steps."""
    from .ode_driver import _spectral_radius
    rho = _spectral_radius(problem, t0, u0)
    if not rho:
        return
    needed = (t_end - t0) * rho / EXPLICIT_STABILITY[method]
    if needed > max_steps:
        raise SimulationError(
            f"solver '{name}' on model '{problem.c.model.name}': the Jacobian's spectral radius {rho:.3g} 1/s limits "
            f"this explicit method to steps below {EXPLICIT_STABILITY[method] / rho:.3g} s, about {needed:.3g} steps "
            f"for the run, more than max_steps={max_steps}: the model is stiff for an explicit method. Use 'ida', "
            f"'scipy:Radau', 'scipy:BDF' or 'convolution', or raise max_steps.{problem.c.stiffness_hint(always=True)}")


def _scipy_solver(method):
    name = f"scipy:{method}"

    @register(name)
    def simulate_scipy(model, t_start=0.0, t_end=1.0, dt_out=None, rtol=1e-6, atol=None, first_step=None,
                       max_step=None, max_events=100000, chatter_window=None, chatter_count=50,
                       max_growth=MAX_GROWTH, max_steps=200_000, **unused):
        if unused:
            raise ParameterError(f"solver '{name}' takes rtol, atol, first_step, max_step, max_events, "
                                 f"chatter_window, chatter_count, max_growth, max_steps; got unknown "
                                 f"{sorted(unused)}")
        max_growth = check_max_growth(name, max_growth)
        if not (isinstance(rtol, (int, float)) and rtol > 0):
            raise ParameterError(f"solver '{name}': rtol must be a positive number, got {rtol!r}")
        options = {"rtol": rtol, "atol": rtol * 1e-2 if atol is None else atol}
        if first_step is not None:
            options["first_step"] = first_step
        if max_step is not None:
            options["max_step"] = max_step

        checked = []

        def make(problem, t0, u0, t_bound, knots):
            if method in EXPLICIT_STABILITY and not checked:
                checked.append(True)
                _refuse_if_stiff(name, method, problem, t0, u0, t_end, max_steps)
            step_opts = dict(options)
            if "first_step" in step_opts:
                step_opts["first_step"] = min(step_opts["first_step"], t_bound - t0)
            stepper = ScipyStepper(method, problem, t0, u0, t_bound, **step_opts)
            stepper.problem_name = model.name
            return stepper

        return simulate_ode(model, name, make, t_start, t_end, dt_out, max_events=max_events,
                            chatter_window=chatter_window, chatter_count=chatter_count, max_growth=max_growth)

    simulate_scipy.__doc__ = f"scipy.integrate.{method} on the ODE form (see regmech.solvers.scipy_ivp)."
    simulate_scipy.__name__ = f"simulate_scipy_{method}"
    return simulate_scipy


for _method in METHODS:
    _scipy_solver(_method)
