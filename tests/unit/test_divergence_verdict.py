"""The roughness verdict of the divergence test is checked against the method's own amplification
(``ode_driver.RoughVerdict``): a growing oscillation that an explicit method cannot resolve is still stopped, a
resolved one whose beating grows while a high-order method crosses it in a few steps per period is not."""

import numpy as np
import pytest
from scipy.integrate import DOP853, RK23, RK45

import regmech as rm
from regmech.bench.hard_models import undamped_chain
from regmech.components import Fixed, Inertia, Spring, SpringDamper, Torque
from regmech.signals import Sine
from regmech.solvers.explicit import ABMStepper, RK4Stepper
from regmech.solvers.scipy_ivp import stability_function


@pytest.mark.parametrize("cls, order, limit", [(RK23, 3, 2.51), (RK45, 5, 3.31), (DOP853, 8, 6.39)])
def test_stability_function_of_the_tableau(cls, order, limit):
    # R(z) agrees with exp(z) to the method's order, and its interval on the negative real axis is the known one
    z = np.array([0.05, -0.03 + 0.04j])
    assert np.all(np.abs(stability_function(cls.A, cls.B, z) - np.exp(z)) <= 10 * np.abs(z) ** (order + 1))
    x = np.linspace(-7.0, 0.0, 7001)
    stable = np.abs(stability_function(cls.A, cls.B, x)) <= 1.0
    assert abs(x[np.argmax(stable)] - (-limit)) < 0.01


def _pair(name, tau, J1, link, soft, w0=0.0):
    """A torque ``tau`` on inertia J1 (start speed w0), a spring-damper ``link = (c, d)`` to a unit inertia J2 (J1
    given as ``J1``), and J2 grounded by a spring of stiffness ``soft``."""
    m = rm.Model(name)
    ground = m.add(Fixed("ground"))
    drive = m.add(Torque("drive", tau=tau))
    j1, j2 = m.add(Inertia("J1", J=J1, w0=w0)), m.add(Inertia("J2", J=1.0))
    sd, spring = m.add(SpringDamper("link", c=link[0], d=link[1])), m.add(Spring("soft", c=soft))
    m.connect(drive.flange, j1.flange_a)
    m.connect(j1.flange_b, sd.flange_a)
    m.connect(sd.flange_b, j2.flange_a)
    m.connect(j2.flange_b, spring.flange_a)
    m.connect(spring.flange_b, ground.flange)
    return m


def _stiff_pair(theta):
    """A light spring-damper pair whose mode turns ``theta`` radians per step of 0.01 s, driven slowly."""
    return _pair("pair", Sine(amplitude=1.0, freq_hz=1.0), 1.0, ((theta / 0.01) ** 2 / 2, 0.01), 10.0, w0=1.0)


def test_a_growing_oscillation_beyond_rk4s_limit_is_still_stopped_as_rough():
    # h omega = 3 > 2.83 (RK4's reach on the imaginary axis): |R| = 1.5 a step, the verdict stands
    with pytest.raises(rm.SimulationError) as err:
        _stiff_pair(3.0).simulate(2.0, 0.01, solver="rk4", tol=None)
    msg = str(err.value)
    assert "diverged" in msg and "while changing at every step by more than 0.5 times its size" in msg


@pytest.mark.slow
@pytest.mark.parametrize("solver", ["scipy:DOP853", "dop853"])
@pytest.mark.parametrize("rtol", [3e-4, 1e-4])
def test_a_resolved_beating_oscillation_is_not_stopped_as_diverged(solver, rtol):
    # the undamped 4-inertia chain over 100 s: DOP853 at a loose rtol takes 6 to 8 steps per period of its
    # fastest mode, so every step changes the state by more than half its size, and the beating of the modes
    # grows it fourfold within ten steps (t = 7.3 s at rtol 1e-4); it was stopped as diverged while the method's
    # factor on every mode is 1 - 1e-13. The answer's error is that of the rtol over 100 s of undamped motion
    model, _ = undamped_chain()
    ref = model.simulate(100.0, 0.1, solver="scipy:DOP853", rtol=1e-11, atol=1e-13)
    res = model.simulate(100.0, 0.1, solver=solver, rtol=rtol)
    assert res.stats.extra["roughness"] > 0.5 and res.stats.extra["rough_verdicts_overruled"] >= 1
    names = ["J0.w", "J1.w", "J2.w", "J3.w"]
    err = max(np.max(np.abs(res[k] - ref[k])) for k in names) / max(np.ptp(ref[k]) for k in names)
    assert err < 100 * rtol, err          # measured: 1.6e-2 at 3e-4, 5.5e-3 at 1e-4 (phase drift over 100 s)


def test_only_a_methods_own_factor_may_overrule_the_verdict():
    # abm reports RK4's factor for its start-up steps, a larger region than its own: it never overrules
    assert RK4Stepper.amplification_exact and not ABMStepper.amplification_exact


def test_a_nonlinear_models_jacobian_is_taken_again_once_the_run_has_moved_on(monkeypatch):
    # the verdict at t judges the window of the last ROUGH_STEPS steps: a nonlinear model's dg/du older than that
    # window is not used (found by fuzzing: a verdict reused a Jacobian from far earlier in the run)
    from regmech.components import QuadraticSpeedDependentTorque
    from regmech.solvers import ode_driver as od
    m = _stiff_pair(0.5)
    load = m.add(QuadraticSpeedDependentTorque("drag", tau_nominal=-1.0, w_nominal=1.0))
    m.connect(m["J2"].flange_b, load.flange)
    c = m.compile()
    problem, u = od.OdeProblem(c, c.modes0), c.ode_state(c.initial_y(0.0, c.modes0)[0])
    taken = []
    monkeypatch.setattr(od, "ode_jacobian", lambda p, t, x: taken.append(t) or od.grouped_fd_jacobian(
        p.rhs, t, x, p.rhs(t, x), od.ode_jacobian_pattern(p.c)))

    class Step:                        # a stepper's end of step: t, its length and the state
        amplification_exact = True

        def __init__(self, t, h):
            self.t, self.t_old, self.u = t, t - h, u

        def amplification(self, J, h, eigenvalues=None):
            return 0.5                 # stable: the verdict is overruled

    verdict = od.RoughVerdict()
    for t in (0.10, 0.15, 0.19, 0.35, 0.40):
        assert verdict.overruled(problem, Step(t, 0.01))
    assert taken == [0.10, 0.35] and verdict.overruled_count == 5


def _stepped_pair(start):
    """A light inertia on a stiff, nearly undamped link to a grounded one (a 503 Hz mode), a step torque on it."""
    from regmech.signals import Step
    return _pair("stepped_pair", Step(height=10.0, start_time=start), 1e-2, (1e5, 1e-3), 100.0)


@pytest.mark.slow
@pytest.mark.parametrize("start", [0.0, 0.1234])
def test_exact_flow_is_never_judged_rough(start):
    # read every millisecond, the 503 Hz mode changes completely from one output step to the next while the step
    # drives the state up from rest: the roughness test stopped expm's exact flow as diverged (t = 0.012 s and
    # 0.133 s). The answer against the closed form x(t) = A^-1 (e^{A (t - t_s)} - I) b of the state-space model
    from scipy.linalg import expm as dense_expm
    res = _stepped_pair(start).simulate(1.0, 1e-3, solver="expm", h=1e-3)
    J, c, d, c0 = np.array([1e-2, 1.0]), 1e5, 1e-3, 100.0
    K = np.array([[c, -c], [-c, c + c0]])
    D = np.array([[d, -d], [-d, d]])
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-K / J[:, None], -D / J[:, None]]])
    b = np.array([0.0, 0.0, 10.0 / J[0], 0.0])
    t = np.asarray(res.t)
    exact = np.array([np.linalg.solve(A, (dense_expm(A * (tk - start)) - np.eye(4)) @ b) if tk > start
                      else np.zeros(4) for tk in t])
    for k, name in enumerate(["J1.phi", "J2.phi", "J1.w", "J2.w"]):
        got = np.asarray(res[name])
        assert np.max(np.abs(got - exact[:, k])) <= 1e-6 * np.ptp(exact[:, k]), name
