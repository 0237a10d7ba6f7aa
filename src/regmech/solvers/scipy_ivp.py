"""scipy's ODE solvers on the ODE form: ``scipy:RK45``, ``scipy:RK23``, ``scipy:DOP853``,
``scipy:Radau``, ``scipy:BDF``, ``scipy:LSODA``.

Options: ``rtol`` (default 1e-6), ``atol`` (default ``rtol * 1e-2``, as for
IDA; see *Tolerances* below), ``first_step``, ``max_step`` [s], ``max_steps``
(see *Step cap* below), ``max_growth`` (divergence test, see
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

Tolerances. scipy accepts a step when ``rms(err_i / (atol_i + rtol |u_i|)) <= 1``;
every method gets the scalar ``atol`` except DOP853 (``SCALED_ATOL``),
whose scalar ``atol`` is the absolute tolerance of a motion of magnitude 1
or more and shrinks with a smaller one: ``atol_i = atol * clip(m_k,
ATOL_FLOOR, 1)`` with ``m_k`` the largest ``|u|`` so far in the run among
the states of the kind of ``u_i`` (positions, speeds, device states;
``StateScale``, updated after every step). Why: DOP853 held at its
stability limit by a fast mode lets errors of about ``atol`` per step
through its error estimate, and on ``inertia_ratio_1e8`` of the hard-case
suite (``regmech.bench.hard``: all states below 2e-3, so the plain
``atol = 1e-10`` is 100 times looser than ``rtol |u|``) it returned a speed
4.7e-4 of its range off at rtol 1e-8; with the scaling 2.2e-5, within the
case's 1e-4. RK45 (2.4e-6), RK23 and the implicit methods met the case
with the plain ``atol``, and scaling them too cost steps on the library
scenes (train_100 at rtol 1e-6, whose motion stays below 1 m/s: Radau
416 -> 555 steps, RK23 696 -> 1149), so they keep it. DOP853 with the
scaling at rtol 1e-6: coupled_clutches 31 -> 33 steps, train_100 141 ->
143, wall time unchanged within noise (medians of 5: 111 -> 110 ms and
188 -> 197 ms). The scaling never loosens a tolerance; an ``atol`` array
is used as given.

Stability cap. DOP853's error estimate (scipy's, as Hairer's: the 5th-order
estimate damped by the 3rd-order one, ``err5^2 / sqrt(err5^2 + 0.01 err3^2)``)
underestimates the error of a step at the edge of the stability interval, so
a run held there by a fast decaying mode returns noise in that mode far above
its tolerance: on fuzz seed 20025 (a mass held near rest by a RoadLoad's
regularised rolling resistance, a real eigenvalue of -6,400 1/s) the mass's
speed came out 14 % of its range off at rtol 1e-8 (1.2 % at 1e-6), with atol
no help (1.3e-3 at atol 1e-14). Each DOP853 segment therefore caps its step
at ``STABLE_CAP * 6.0 / rho`` (``stability_cap``; rho the spectral radius
of dg/du at the start of the run, the one the up-front refusal computes:
exact up to 40 states, above that the upper bound of
``ode_driver.spectral_bound`` unless near the refusal line): the error falls
to 4.0e-7 of the range at rtol 1e-8 and 1.7e-5 at 1e-6 for 16 % more steps
(464 -> 540 at 1e-6; CoupledClutches and First keep their 45 and 66 steps). A model that is not
stiff for the method never meets the cap. RK45 and RK23 keep their steps
(errors 3e-6 and 4e-4 of the range there, within their tolerances' reach).
On a nonlinear model the radius is taken again (``ode_driver.segment_radius``)
at a segment's start when its friction modes differ from those of the last
radius (not its contacts: ``_dynamics_key``), or ``RECAP_STEPS`` (64) steps
have passed since, and within a segment every ``RECAP_STEPS`` steps: fuzz
seed 92005's Magic Formula wheel made it 1,330-1,490 1/s where the start's was 303, and DOP853 at rtol 1e-8,
stepping at h rho = 5.7 after a Pulse edge, returned rows 6.9e-4 of the range
off (now 6.8e-9). The cap is never looser than the start's. The linear
form's radius is constant and taken once. (Taking it at every segment once
cost 70 % of a CoupledClutches run; this schedule costs nothing measurable
there: 61.8 against 61.9 ms.) Below ``rtol = CAP_RTOL`` (1e-3) the cap
shrinks as ``(rtol / CAP_RTOL)^(1/8)``, as DOP853's own steps do: at the
fixed cap the steps where it binds were the same at every rtol, and so was the error of
the output read from DOP853's continuous extension between them (on the
scalar test equation at ``h lambda = -5.4`` it is off by 2.5 times the
mode's amplitude at the step's start, while the step's end is within 0.15
of it and the damped error estimate passes it): random calibration seed 9
(a tyre's contact patch, a decaying mode near -520 1/s) read 1.9e-4 of
its range off at rtol 1e-5, 1e-6 and 1e-7 alike, so the accuracy
contract's pair agreed to 2.9e-6 at accuracy 1e-4. Scaled, the errors
are 2.8e-6, 4.4e-7 and 6.2e-8 (120, 148 and 185 steps instead of 91, 97
and 108).

Round-off. The implicit methods (Radau, BDF, LSODA) refuse up front a model
whose link spread puts round-off beyond the tolerance
(``common.check_link_spread``: ``eps (w_max/w_min)^2 > 100 rtol``, the same
test as IDA's); on the 1e7 chain of the hard cases they used to return errors
of 1.3e-4 of the range at rtol 1e-8. ``stiff_check=False`` runs anyway.

Step cap. A run stops with ``SimulationError`` when it has taken more than
``max_steps`` accepted steps (all segments together; ``common.StepBudget``).
The message gives the time reached, the last step, whether an explicit
method sat at its stability limit (``h rho`` against ``EXPLICIT_STABILITY``)
or was held by the tolerance, the fastest link of the model and the
remedies. Explicit methods are refused before the first step when the
spectral radius at the start already asks for more than ``max_steps``
steps at their stability limit. The check costs a bound
(``ode_driver.spectral_bound``: mass-scaled row and column sums of the
Jacobian, 1 ms at 1,000 inertias, 4 ms at 10,000; compiled when the
right-hand side is, 0.24 and 0.9 ms, ``_bound_kernel``) in the usual case
and the exact radius only when the bound reaches the limit, so it decides
as the exact radius does (it used to run ARPACK on every large model: 12 s
of a 12.6 s run on a 1,000-inertia chain). The default per method
(``DEFAULT_MAX_STEPS``) is chosen from the measured cost of a step so that
a refused run of a small model costs about 5 s on the development machine
(AMD EPYC, 2 cores shared): time per accepted step on 6- to 12-state chains
at rtol 1e-8, output recording included (stiff runs: ``stretched_1e5``,
``near_rigid_shaft``; smooth: ``stretched_1e3``, ``train_10``,
``long_horizon``):

    RK23 120-170 us, RK45 200-350 us, DOP853 380-890 us, Radau 250-610 us,
    BDF 125-240 us, LSODA 50-120 us.

Larger models cost more per step (train_100 about 5 times more), so the cap
bounds the work, not the time. The longest runs of the benchmark ladder
(``regmech bench``, rtol down to 1e-9, and the DOP853 references at rtol
1e-12) take at most: RK23 20,542 steps (vehicle_launch, rtol 1e-9), RK45
1,735, DOP853 871 (reference, rtol 1e-12), Radau 4,744, BDF 3,737, LSODA
3,981, all well below the caps; the passing hard cases (CI size) at most
RK23 22,667 (belt_limit_cycle), RK45 20,638 and LSODA 22,066 and BDF
37,995 (long_horizon), DOP853 6,527 (tiny_mass). Runs beyond the caps
that used to crawl for 15 to 60 s (RK23 on long_horizon: 310,000 steps;
Radau there: 61,000; RK45 and RK23 on stretched_1e5: 161,000 and 218,000)
are now refused within seconds (measured at CI size: RK23 on long_horizon
3.2 s, Radau there 3.8 s, RK23 on near_rigid_shaft 5.0 s; RK45, RK23 and
DOP853 on stretched_1e5 and RK45 and DOP853 on near_rigid_shaft up front,
0.01 s). The price: RK23 and DOP853 used to pass near_rigid_shaft in 7.0
and 6.4 s (52,583 and 16,424 steps, held at their stability limit by the
stiff shaft); they are refused now. Pass ``max_steps`` to let such runs go on.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, Radau

from ..errors import RegmechError, SimulationError
from . import common, dopri, register
from .common import ATOL_FLOOR, StepBudget, check_link_spread, scale_hint  # noqa: F401 (ATOL_FLOOR: re-exported)
from .divergence import MAX_GROWTH
from ..compile.odeform import ode_form
from .ode_driver import Stepper, ode_jacobian_pattern, segment_radius, simulate_ode
from .options import (Integer, OptionSet, atol_option, chatter_options, max_events_option, max_growth_option,
                      rtol_option, step_option, stiff_check_option)

METHODS = {"RK45": RK45, "RK23": RK23, "DOP853": DOP853, "Radau": Radau, "BDF": BDF, "LSODA": LSODA}

#: default ``max_steps`` per method: seconds of stepping on a small model (see the module docstring)
DEFAULT_MAX_STEPS = {"RK23": 40_000, "RK45": 25_000, "DOP853": 12_000, "Radau": 15_000, "BDF": 40_000,
                     "LSODA": 60_000}

#: the methods whose scalar atol is scaled to the magnitude of the motion (``StateScale``)
SCALED_ATOL = ("DOP853",)


class StateScale(common.StateScale):
    """``common.StateScale`` over the ODE state ``u = [x_K, v_K, z]``: kinds positions, speeds and
    device states."""

    def __init__(self, atol, c):
        nx, nv = len(c.Kx), len(c.Kv)
        bounds = [0, nx, nx + nv, c.ode_size()]
        super().__init__(atol, [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a], c.ode_size())


class ScipyStepper(Stepper):
    """One scipy ``OdeSolver`` per segment."""

    def __init__(self, method, problem, t0, u0, t_bound, budget=None, scale=None, cls=None, recap=None, **options):
        """``recap``: ``(t, u) -> max_step``, the step cap at a state (a capped method on a nonlinear model), asked
        every ``RECAP_STEPS`` steps."""
        self.label = f"scipy {method}" if cls is None else f"solver '{cls.solver_name}'"
        # the explicit methods' factor is their R(z) (``amplification``); the implicit ones give none
        self.amplification_exact = method in EXPLICIT_STABILITY
        cls = METHODS[method] if cls is None else cls
        if method in ("Radau", "BDF"):
            options["jac_sparsity"] = ode_jacobian_pattern(problem.c)
        elif method == "LSODA":
            options["jac"] = lambda t, u: problem.jacobian(t, u).toarray()
        self.method = method
        self._recap = recap
        self.problem = problem
        self.budget = budget
        self.scale = scale
        if scale is not None:
            scale.see(u0)
            options["atol"] = scale.tolerances()
        if cls in dopri.CLASSES.values():
            options["fun_into"] = problem.rhs_into          # stages written in place (``dopri``)
            options["stages"] = problem.stage_sweep()       # ... or all of a step's in one compiled call
        self.solver = cls(problem.rhs, t0, u0, t_bound, **options)
        f0 = getattr(self.solver, "f", None)
        if f0 is not None:
            # scipy's explicit methods would try steps forever: their first step estimate is NaN, and NaN < min_step
            # is False (a right-hand side non-finite at the start was a hang of scipy:RK45)
            self._refuse_nonfinite_rate(f0, t0, "cannot start")
        # RK, Radau and BDF read ``self.atol`` at every step; LSODA keeps its tolerances in Fortran
        self._retune = scale is not None and scale.scalar and method != "LSODA"
        self.t = self.t_old = float(t0)
        self.u = self.solver.y
        self.nsteps = 0
        self.nrejected = 0
        self._dense = None
        self._lu0 = getattr(self.solver, "nlu", 0)

    def _refuse_nonfinite_rate(self, g, t, what):
        """A ``SimulationError`` naming the first state whose rate ``g`` (at time t) is NaN or inf, if any."""
        if np.all(np.isfinite(g)):
            return
        from .ode_driver import ode_state_label
        raise SimulationError(
            f"{self.label} {what} at t={t:.6g} in model '{self.problem.c.model.name}': the rate of "
            f"{ode_state_label(self.problem.c, int(np.argmax(~np.isfinite(g))))} is NaN or inf there: a law or a "
            f"signal acting on it overflows. Check that component's parameters and signals, or try 'ida'.")

    @property
    def njev(self):
        # LSODA's Jacobians are counted by the problem (they are built there)
        return 0 if self.method == "LSODA" else int(getattr(self.solver, "njev", 0) or 0)

    def step(self):
        try:
            if self.method == "LSODA":
                # LSODA's Fortran failures arrive as a UserWarning before the failed status that is reported below
                # as a regmech error (the warning would only repeat it, pointing into scipy)
                with warnings.catch_warnings():
                    # LSODA's own message only (scipy's ode wrapper: "lsoda: ..."); a user's signal may warn too
                    warnings.filterwarnings("ignore", message="lsoda", category=UserWarning)
                    msg = self.solver.step()
            else:
                msg = self.solver.step()
        except RegmechError:
            raise
        except (RuntimeError, ArithmeticError, np.linalg.LinAlgError) as exc:
            # scipy's own failures inside a step (an LU that is exactly singular, an overflow) become ours
            raise SimulationError(
                f"{self.label} failed at t={self.solver.t:.6g} in model '{self.problem.c.model.name}': "
                f"{type(exc).__name__}: {exc}.{scale_hint(self.problem.c)} Try 'ida' or check the parameters."
            ) from exc
        if self.solver.status == "failed":
            # the explicit classes shrink the step on a NaN as on a large error until it is below their least step
            # (10 spacings of t), dividing it by 5 at most at each rejection: the stages that met the NaN lay up
            # to 5 least steps on. Look at the rate there, so that the cause is named rather than the step (one
            # least step on was not enough: whether the NaN was met within it depended on round-off of t)
            t, y = self.solver.t, self.solver.y
            least = 10.0 * abs(np.nextafter(t, np.inf) - t)
            for tq in t + least * np.array([0.0, 1.0, 2.0, 3.0, 5.0, 10.0]):
                self._refuse_nonfinite_rate(np.asarray(self.problem.rhs(tq, y)), t, "failed")
            raise SimulationError(f"{self.label} failed at t={self.solver.t:.6g} in model "
                                  f"'{self.problem_name}': {str(msg).rstrip('.')}. Try another rtol or a stiff "
                                  f"solver (ida)")
        self.t_old, self.t, self.u = self.solver.t_old, self.solver.t, self.solver.y
        self._dense = None
        self.nsteps += 1
        if self._recap is not None and self.nsteps % RECAP_STEPS == 0:
            self.solver.max_step = self._recap(self.t, self.u)
        if self._retune:
            if self.scale.see(self.u):      # the same tolerances are not rebuilt
                self.solver.atol = self.scale.tolerances()
        if self.budget is not None:
            self.budget.charge(self, self.problem)

    def interpolate(self, tq):
        if tq == self.t:
            return self.u
        if self._dense is None:
            self._dense = self.solver.dense_output()
        return self._dense(tq)

    def interpolate_many(self, tqs):
        """The states at ``tqs``: a list of rows, or from three instants on an ``(m, n)`` array (its rows).
        """
        # scipy's dense output evaluates many instants at once, element by element as for one (DOP853, Radau,
        # BDF) or by one matrix product (RK45, RK23): one call per step instead of one per output instant
        if len(tqs) <= 2:          # a large model's one or two outputs per step: no batch to gain, a copy to pay
            return [self.interpolate(tq) for tq in tqs]
        if self._dense is None:
            self._dense = self.solver.dense_output()
        rows = getattr(self._dense, "rows", None)      # regmech's Dormand-Prince: (m, n) at once
        if rows is not None:
            return rows(tqs)
        return np.ascontiguousarray(self._dense(np.asarray(tqs, float)).T)

    def stats(self):
        return {"lu_decompositions": int(getattr(self.solver, "nlu", 0) or 0) - self._lu0}


    def amplification(self, J, h, eigenvalues=None):
        """``max |R(h lambda)|`` over the eigenvalues of J for the explicit Runge-Kutta methods, with ``R(z) = 1 +
        z b^T (I - z A)^-1 1`` of the method's tableau (``stability_function``); None for the implicit ones."""
        if self.method not in EXPLICIT_STABILITY or not J.size:
            return None
        lam = np.linalg.eigvals(J) if eigenvalues is None else eigenvalues
        cls = type(self.solver)
        return float(np.max(np.abs(stability_function(cls.A, cls.B, h * np.asarray(lam)))))


def stability_function(A, B, z):
    """``R(z)`` of the explicit Runge-Kutta method with tableau ``A`` (strictly lower triangular) and weights
    ``B``: one step's factor on ``y' = lambda y``, ``z = h lambda`` (array). The stages of that equation,
    ``k_s = lambda (y + h sum_j a_sj k_j)``, in units of ``lambda y``: ``g_s = 1 + z sum_{j<s} a_sj g_j``; then
    ``R = 1 + z sum_s b_s g_s``."""
    z = np.asarray(z, dtype=complex)
    g = []
    for s in range(len(B)):
        acc = np.zeros_like(z)
        for j in range(s):
            if A[s, j]:
                acc += A[s, j] * g[j]
        g.append(1.0 + z * acc)
    return 1.0 + z * sum(b * gs for b, gs in zip(B, g))


#: stability interval of the explicit methods on the negative real axis (h * rho up to about this)
EXPLICIT_STABILITY = {"RK23": 2.5, "RK45": 3.3, "DOP853": 6.0}

#: the methods whose step is capped below their stability limit (module docstring, *Stability cap*)
CAPPED = ("DOP853",)

#: the cap: ``h <= STABLE_CAP * EXPLICIT_STABILITY / rho`` at ``rtol >= CAP_RTOL``, and below it that times
#: ``(rtol / CAP_RTOL) ** (1 / CAP_ORDER)`` (module docstring, *Stability cap*)
STABLE_CAP = 0.9
CAP_RTOL = 1e-3
CAP_ORDER = 8


#: a capped method on a nonlinear model takes the spectral radius again every this many steps (``ScipyStepper``):
#: about n + 1 right-hand sides and a dense eigen-decomposition up to 40 states, against 12 right-hand sides a step
RECAP_STEPS = 64


def stability_cap(method, rho, rtol=None):
    """The largest step [s] a capped method may take on a model whose dg/du has spectral radius ``rho``
    [1/s] at tolerance ``rtol`` (None: the cap of ``CAP_RTOL``), or None (no cap: the method is not capped,
    or rho is zero or unknown)."""
    if method not in CAPPED or not rho or not np.isfinite(rho):
        return None
    scale = 1.0 if rtol is None else min(1.0, (float(rtol) / CAP_RTOL) ** (1.0 / CAP_ORDER))
    return STABLE_CAP * scale * EXPLICIT_STABILITY[method] / rho


def _refuse_if_stiff(name, method, problem, t0, u0, t_end, max_steps, rtol=None):
    """An explicit method needs h <= bound / rho (a capped one ``stability_cap``, the step it will take at most):
    refuse up front when that takes more than max_steps (rho exact near the line, an upper bound far below it:
    ``ode_driver.spectral_radius``)."""
    from .ode_driver import spectral_radius, stiff_equation_hint
    # h rho allowed: the stability limit, or for DOP853 its cap at this rtol, which it never steps beyond (counting
    # at the limit let a run take its 12,000 steps, 10 s, before the step count stopped it: a 4e8 N m/rad spring)
    reach = stability_cap(method, 1.0, rtol) or EXPLICIT_STABILITY[method]
    # only rho > limit matters: a cheap upper bound settles the usual case (see ode_driver.spectral_radius)
    limit = max_steps * reach / (t_end - t0)
    rho = spectral_radius(problem, t0, u0, above=limit)
    if not rho:
        return rho
    needed = (t_end - t0) * rho / reach
    if needed > max_steps:
        capped = (f" (regmech's cap on {method}, {reach / EXPLICIT_STABILITY[method]:.2g} of its stability limit at this "
                  f"rtol: scipy_ivp.stability_cap)" if method in CAPPED else "")
        raise SimulationError(
            f"solver '{name}' on model '{problem.c.model.name}': the Jacobian's spectral radius {rho:.3g} 1/s limits "
            f"this explicit method to steps below {reach / rho:.3g} s{capped}, about {needed:.3g} steps "
            f"for the run, more than max_steps={max_steps}: the model is stiff for an explicit method (or the run "
            f"is long: {(t_end - t0) * rho / (2 * np.pi):.3g} periods of its fastest motion). Use 'ida', "
            f"'scipy:Radau', 'scipy:BDF' or 'convolution' for a stiff model, or raise max_steps for a long run."
            f"{problem.c.stiffness_hint(always=True) or stiff_equation_hint(problem, t0, u0)}")
    return rho


def _dynamics_key(problem):
    """The friction modes of the current segment: what changes the ODE form's dg/du from one segment to the next,
    besides the state of a nonlinear law.

    Not the sides of the piecewise laws' surfaces (contacts), although a contact's stiffness moves the radius too:
    with them, fuzz seed 95096 (an end stop's 5.7 ms contacts, radius 9 -> 535-757 1/s) came out 2.1e-6 of the range
    off at rtol 1e-10 where it was 1.4e-7 with the start's cap, and 1.1e-8 to 1.1e-7 with this key (every
    ``RECAP_STEPS`` steps inside a contact still sees its stiffness). Why the contacts' own radius made it worse is
    not understood (its segments went from 118 to 120)."""
    return np.asarray(problem.modes).tobytes()


def _scipy_options(method) -> OptionSet:
    return OptionSet(
        f"scipy.integrate.{method} on the ODE form (local error control by rtol/atol)",
        rtol=rtol_option(1e-6),
        atol=atol_option(lambda c: c.ode_size(), "state of the ODE form"),
        first_step=step_option("first step [s] (default: scipy's estimate)"),
        max_step=step_option("largest step [s] (default: no limit)"),
        max_events=max_events_option(),
        max_growth=max_growth_option(),
        max_steps=Integer(f"most accepted steps over the whole run (default {DEFAULT_MAX_STEPS[method]})", 1,
                          optional=True),
        stiff_check=stiff_check_option(),
        **chatter_options(),
    )


def _scipy_solver(method, name=None, cls=None):
    """Register ``scipy:<method>`` (scipy's class), or ``name`` run by ``cls``, an integrator of the same method
    (``dopri``), which then shares the method's step cap, scaled atol, stiffness check and step budget."""
    name = f"scipy:{method}" if name is None else name

    @register(name, _scipy_options(method) if cls is None else _own_options(name, method, cls))
    def simulate_scipy(model, t_start=0.0, t_end=1.0, dt_out=None, rtol=1e-6, atol=None, first_step=None,
                       max_step=None, max_events=100000, chatter_window=None, chatter_count=50,
                       max_growth=MAX_GROWTH, max_steps=None, stiff_check=True):
        if method not in EXPLICIT_STABILITY:
            # an implicit method would step through a spread whose round-off exceeds rtol and return an
            # answer off by far more than rtol (explicit ones are refused by their stability limit first)
            check_link_spread(model.compile(), rtol, name, stiff_check)
        if max_steps is None:
            max_steps = DEFAULT_MAX_STEPS[method]
        budget = StepBudget(name, max_steps, t_end, EXPLICIT_STABILITY.get(method), stability_cap(method, 1.0, rtol))
        atol = rtol * 1e-2 if atol is None else atol
        scales = []         # the StateScale of the run, made with the first segment (it needs the compiled model)
        options = {"rtol": rtol}
        if first_step is not None:
            options["first_step"] = first_step
        if max_step is not None:
            options["max_step"] = max_step

        start_radius = []   # the spectral radius at the run's start, once (``_refuse_if_stiff``)
        last = dict(key=None, rho=None, steps=0)    # the latest radius, its friction modes and the run's steps then

        def make(problem, t0, u0, t_bound, knots):
            if method in EXPLICIT_STABILITY and not start_radius:
                # the radius at the start (exact up to 40 states, else an upper bound unless near the limit)
                # serves both the refusal and the step cap of every segment
                start_radius.append(_refuse_if_stiff(name, method, problem, t0, u0, t_end, max_steps, rtol))
            step_opts = dict(options)
            if "first_step" in step_opts:
                step_opts["first_step"] = min(step_opts["first_step"], t_bound - t0)
            rho = start_radius[0] if start_radius else None
            recap = None
            if method in CAPPED and rho is not None and not ode_form(problem.c).linear:
                # a nonlinear law's stiffness moves with the state, a mode with the segment: the radius again at a
                # segment's start when its friction modes differ from the last radius's (``_dynamics_key``) or when
                # ``RECAP_STEPS`` steps have passed since, and within a segment every ``RECAP_STEPS`` steps; never
                # below the start's (the cap only tightens: calibration seed 9's tyre, whose later radius was lower,
                # was interpolated 10 times further off at rtol 1e-6 with the looser cap)
                rho0 = rho
                key = _dynamics_key(problem)
                if last["key"] is None:
                    last.update(key=key, rho=rho0, steps=budget.steps)
                elif key != last["key"] or budget.steps - last["steps"] >= RECAP_STEPS:
                    last.update(key=key, rho=max(rho0, segment_radius(problem, t0, u0) or 0.0), steps=budget.steps)
                rho = last["rho"]
                limit = step_opts.get("max_step", np.inf)

                def recap(t, u):
                    last.update(rho=max(rho0, segment_radius(problem, t, u) or 0.0), steps=budget.steps)
                    now = stability_cap(method, last["rho"], rtol)       # None: no stiffness, no cap
                    return limit if now is None else min(limit, now)
            cap = stability_cap(method, rho, rtol)
            if cap is not None:
                step_opts["max_step"] = min(step_opts.get("max_step", np.inf), cap)
            if method not in SCALED_ATOL:
                step_opts["atol"] = atol
            elif not scales:
                scales.append(StateScale(atol, problem.c))
            stepper = ScipyStepper(method, problem, t0, u0, t_bound, budget=budget,
                                   scale=scales[0] if scales else None, cls=cls, recap=recap, **step_opts)
            stepper.problem_name = model.name
            return stepper

        return simulate_ode(model, name, make, t_start, t_end, dt_out, max_events=max_events,
                            chatter_window=chatter_window, chatter_count=chatter_count, max_growth=max_growth)

    simulate_scipy.__doc__ = (f"scipy.integrate.{method} on the ODE form (see regmech.solvers.scipy_ivp)."
                              if cls is None else
                              f"{cls.__doc__} (see regmech.solvers.dopri and regmech.solvers.scipy_ivp)")
    simulate_scipy.__name__ = f"simulate_scipy_{method}" if cls is None else f"simulate_{name}"
    return simulate_scipy


def _own_options(name, method, cls) -> OptionSet:
    opts = _scipy_options(method)
    opts.options["first_step"] = step_option("first step [s] (default: Hairer's estimate, as scipy's)")
    opts.about = (f"regmech's Dormand-Prince integrator '{name}' on the ODE form: the method and step control of "
                  f"scipy's {method}, its stages summed in place (local error control by rtol/atol; see "
                  f"regmech.solvers.dopri)")
    return opts


for _method in METHODS:
    _scipy_solver(_method)

#: regmech's own integrators of scipy's explicit Dormand-Prince methods (``dopri``): ``dopri5`` and ``dop853``
for _cls in dopri.CLASSES.values():
    _scipy_solver(_cls.method, _cls.solver_name, _cls)
