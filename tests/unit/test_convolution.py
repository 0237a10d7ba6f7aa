"""The convolution method (REFERENCES.md [004]): its coefficients, limits, exactness and behaviour on models."""

import warnings

import numpy as np
import pytest
import sympy

import regmech as rm
from regmech.component import Param
from regmech.components import Backlash, Damper, Fixed, Inertia, Spring, Torque
from regmech.components.elastic import TwoFlangeCompliant
from regmech.library import SCENES, first
from regmech.signals import Sine, Step
from regmech.solvers.convolution import (ConvolutionStepper, corrector, lag_rates, phi_functions, predictor)
from regmech.solvers.ode_driver import OdeProblem

Z_VALUES = [0.0, 1e-14, 1e-9, 1e-6, 1e-3, 0.1, 0.3, 0.4999999, 0.5, 0.5000001, 0.9, 2.0, 10.0, 50.0, 1e3, 1e8]


def exact_phi(z):
    """phi1, phi2 at 40 significant digits (sympy)."""
    if z == 0:
        return 1.0, 0.5
    zz = sympy.Rational(repr(z))
    p1 = (1 - sympy.exp(-zz)) / zz
    p2 = (zz - 1 + sympy.exp(-zz)) / zz ** 2
    return float(sympy.N(p1, 40)), float(sympy.N(p2, 40))


def test_phi_functions_are_accurate_across_the_series_switch():
    p1, p2 = phi_functions(np.array(Z_VALUES))
    for z, a1, a2 in zip(Z_VALUES, p1, p2):
        e1, e2 = exact_phi(z)
        assert a1 == pytest.approx(e1, rel=4e-16, abs=0), z
        assert a2 == pytest.approx(e2, rel=4e-16, abs=0), z


def paper_predictor(y, y_prev, f, f_prev, h, T):
    E = np.exp(-h / T)
    return y * E + (1 - E) * f + (1 - (T / h) * (1 - E)) * (f - f_prev)


def paper_corrector(y, f, f_next, h, T):
    E = np.exp(-h / T)
    return y * E + f_next - f * E - (T / h) * (f_next - f) * (1 - E)


@pytest.mark.parametrize("T", [0.02, 0.1, 1.0, 7.0])
def test_rate_form_equals_the_papers_formulas(T):
    """u_P, u_C written with g = (f - u)/T agree with the paper's f-form (equal steps)."""
    rng = np.random.default_rng(3)
    h = 0.05
    u, u_prev, u_new = rng.normal(size=3)
    g, g_prev, g_new = rng.normal(size=3)
    f, f_prev, f_new = u + T * g, u_prev + T * g_prev, u_new + T * g_new
    r = np.array([1.0 / T])
    assert predictor(u, g, u_prev, g_prev, h, h, r)[0] == pytest.approx(paper_predictor(u, u_prev, f, f_prev, h, T),
                                                                        rel=1e-12, abs=1e-13)
    assert corrector(u, g, u_new, g_new, h, r)[0] == pytest.approx(paper_corrector(u, f, f_new, h, T),
                                                                   rel=1e-12, abs=1e-13)


def test_pure_integrator_limit_is_adams_of_order_two():
    rng = np.random.default_rng(4)
    u, u_prev, u_new, g, g_prev, g_new = (rng.normal(size=5) for _ in range(6))
    h, h_prev = 0.01, 0.008
    zero = np.zeros(5)
    ab2 = u + h * g + 0.5 * h * (h / h_prev) * (g - g_prev)          # variable-step Adams-Bashforth 2
    trap = u + 0.5 * h * (g + g_new)                                  # Adams-Moulton 2 (trapezoid)
    np.testing.assert_array_equal(predictor(u, g, u_prev, g_prev, h, h_prev, zero), ab2)
    np.testing.assert_allclose(corrector(u, g, u_new, g_new, h, zero), trap, rtol=1e-15, atol=1e-16)
    # T large but finite: continuous in 1/T (no cancellation of the large T g terms)
    tiny = np.full(5, 1e-10)
    np.testing.assert_allclose(predictor(u, g, u_prev, g_prev, h, h_prev, tiny), ab2, rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(corrector(u, g, u_new, g_new, h, tiny), trap, rtol=1e-11, atol=1e-12)
    # and the paper's f-form loses everything there: f = u + T g with T = 1e10 keeps ~6 digits of u
    fT = 1e10
    paper = paper_corrector(u, u + fT * g, u_new + fT * g_new, h, fT)
    assert np.max(np.abs(paper - trap)) > 1e-9


@pytest.mark.parametrize("h_over_T", [0.01, 1.0, 100.0])
def test_linear_lag_with_linear_input_is_integrated_exactly(h_over_T):
    """T y' + y = a + b t: a straight-line input is what the method assumes, so it is exact at any step."""
    T, a, b, y0 = 0.05, 1.5, -4.0, 3.0
    h = h_over_T * T
    rate = np.array([1.0 / T])

    def g(t, y):
        return (a + b * t - y) / T

    def exact(t):
        return a + b * (t - T) + (y0 - a + b * T) * np.exp(-t / T)

    t, y = 0.0, np.array([y0])
    gy = g(t, y)
    y_prev = g_prev = None
    for _ in range(20):
        yp = predictor(y, gy, y_prev, g_prev, h, h, rate)
        yc = corrector(y, gy, yp, g(t + h, yp), h, rate)
        y_prev, g_prev = y, gy
        t, y = t + h, yc
        gy = g(t, y)
        assert y[0] == pytest.approx(exact(t), rel=1e-12, abs=1e-12)


def test_time_constants_come_from_the_jacobian_diagonal():
    m = first()                      # damper d = 10 on inertia2, which carries J2 + ratio^2 J1 = 2 + 100*0.1
    c = m.compile()
    y, yp = c.initial_y(0.0)
    u = c.ode_state(y)
    st = ConvolutionStepper(OdeProblem(c, c.modes0), 0.0, u, 1.0, np.array([1.0]))
    np.testing.assert_allclose(st.rate, [0.0, 0.0, 10.0 / 12.0, 0.0], rtol=1e-6)
    assert np.all(lag_rates([-2.0, 0.0, 3.0]) == [2.0, 0.0, 0.0])


class Maxwell(TwoFlangeCompliant):
    """Spring ``c`` in series with a damper ``d``: ``tau = c (phi_rel - z)``, ``z' = tau / d`` (a device state)."""

    c = Param(check="positive", unit="N m/rad")
    d = Param(check="positive", unit="N m s/rad")
    states = {"z": None}

    def law(self, rel, rel_dot):
        return self.c * (rel - self.z)

    def derivatives(self, e, de):
        return [self.c * (e[0] - self.z) / self.d]


def maxwell_model(c=1e4, d=1.0):
    m = rm.Model("maxwell")
    fixed = m.add(Fixed("fixed"))
    drive = m.add(Torque("drive", tau=Sine(amplitude=1.0, freq_hz=1.0)))
    body = m.add(Inertia("J", J=1.0, phi0=0.0, w0=0.0))
    relax = m.add(Maxwell("mx", c=c, d=d))
    spring = m.add(Spring("spring", c=10.0))
    m.connect(drive.support, fixed.flange)
    m.connect(drive.flange, body.flange_a)
    m.connect(body.flange_b, relax.flange_a)
    m.connect(relax.flange_b, fixed.flange)
    m.connect(body.flange_a, spring.flange_a)
    m.connect(spring.flange_b, fixed.flange)
    return m


@pytest.mark.parametrize("corrector", ["implicit", "pece"])
def test_device_states_with_a_fast_lag(corrector):
    """The whole ODE state (x, v and device states z) is integrated; z has T = d/c = 1e-4 s, far below the step."""
    m = maxwell_model()
    ref = m.simulate(1.0, 0.02, solver="ida", rtol=1e-10, atol=1e-12)
    res = m.simulate(1.0, 0.02, solver="convolution", rtol=1e-6, corrector=corrector)
    for n in ("J.w", "mx.z", "mx.tau"):
        assert np.max(np.abs(res[n] - ref[n])) < 5e-3 * np.max(np.abs(ref[n])), n
    # the fixed step is 10x the lag's time constant: explicit RK4 would blow up (h rho ~ 10), this stays bounded
    res = m.simulate(1.0, 0.02, solver="convolution", h=1e-3, corrector=corrector)
    assert np.max(np.abs(res["J.w"] - ref["J.w"])) < 0.02 * np.max(np.abs(ref["J.w"]))
    with pytest.raises(rm.SimulationError):
        m.simulate(1.0, 0.02, solver="rk4", h=1e-3)


@pytest.mark.parametrize("corrector", ["implicit", "pece"])
def test_error_follows_the_tolerance(corrector):
    m = first()
    ref = m.simulate(1.0, 0.01, solver="ida", rtol=1e-11, atol=1e-13)
    errs = []
    for rtol in (1e-4, 1e-6):
        res = m.simulate(1.0, 0.01, solver="convolution", rtol=rtol, corrector=corrector)
        errs.append(np.max(np.abs(res["inertia3.w"] - ref["inertia3.w"])))
        assert res.stats.extra["rejected"] < res.stats.steps
    # second order: the error per unit step ~ rtol^(2/3); two decades of rtol give ~20x
    assert errs[1] < errs[0] / 10, errs


def test_tolerates_a_jump_that_is_not_declared_as_an_event():
    """A torque given as a plain callable with a jump (no breakpoint known): step control shrinks the
    step at the jump and passes it; the result matches the run where the jump is a time event."""
    t_on = 0.3037

    def build(tau):
        m = rm.Model("jump")
        fixed = m.add(Fixed("fixed"))
        drive = m.add(Torque("drive", tau=tau))
        body = m.add(Inertia("J", J=2.0, phi0=0.0, w0=0.0))
        spring = m.add(Spring("spring", c=100.0))
        m.connect(drive.support, fixed.flange)
        m.connect(drive.flange, body.flange_a)
        m.connect(body.flange_b, spring.flange_a)
        m.connect(spring.flange_b, fixed.flange)
        return m

    ref = build(Step(height=4.0, start_time=t_on)).simulate(1.0, 0.01, solver="ida", rtol=1e-10, atol=1e-12)
    res = build(lambda t: 4.0 if t >= t_on else 0.0).simulate(1.0, 0.01, solver="convolution", rtol=1e-7)
    on_grid = ref.t != t_on                       # the reference also has the breakpoint's two rows
    np.testing.assert_array_equal(res.t, ref.t[on_grid])
    err = np.max(np.abs(res["J.w"] - ref["J.w"][on_grid]))
    assert err < 1e-4 * np.max(np.abs(ref["J.w"])), err
    assert res.stats.extra["rejected"] > 0        # the jump was felt and handled by step control


def backlash_pair():
    """Two inertias joined by a dead-zone spring in parallel with a damper, the second anchored by a spring:
    a kink of the right-hand side at every contact change."""
    m = rm.Model("backlash_pair")
    fixed = m.add(Fixed("fixed"))
    drive = m.add(Torque("drive", tau=Sine(amplitude=50.0, freq_hz=1.5)))
    j1 = m.add(Inertia("J1", J=1.0, phi0=0.0, w0=0.0))
    j2 = m.add(Inertia("J2", J=4.0, phi0=0.0, w0=0.0))
    play = m.add(Backlash("play", c=2e3, b=0.05))
    damper = m.add(Damper("damper", d=5.0))
    anchor = m.add(Spring("anchor", c=200.0))
    m.connect(drive.support, fixed.flange)
    m.connect(drive.flange, j1.flange_a)
    for dev in (play, damper):
        m.connect(j1.flange_b, dev.flange_a)
        m.connect(dev.flange_b, j2.flange_a)
    m.connect(j2.flange_b, anchor.flange_a)
    m.connect(anchor.flange_b, fixed.flange)
    return m


def test_implicit_corrector_satisfies_the_papers_corrector_equation():
    """After every fixed step (h = 0.05 s, ~3 steps per period of the contact mode, across backlash kinks)
    the new state solves y_{i+1} = y_i E + f_{i+1} - f_i E - (T/h)(f_{i+1} - f_i)(1 - E) to the Newton
    tolerance, with f = y + T g and T = 1/rate (rate-form, checked against the f-form above)."""
    c = backlash_pair().compile()
    y, yp = c.initial_y(0.0)
    h, n_steps = 0.05, 40
    c._t_right = n_steps * h
    problem = OdeProblem(c, c.modes0)
    st = ConvolutionStepper(problem, 0.0, c.ode_state(y), n_steps * h, np.arange(1, n_steps + 1) * h, h=h,
                            rtol=1e-10, atol=1e-12)
    checked = 0
    for _ in range(n_steps):
        u0, g0, subdivided = st.u, st.g, st.counts["subdivided"]
        st.step()
        if st.counts["subdivided"] != subdivided:
            continue                    # taken in parts: the equation holds for the last part only
        g1 = problem.rhs(st.t, st.u)
        residual = st.u - corrector(u0, g0, st.u, g1, h, st.rate)
        assert np.max(np.abs(residual) / (1e-12 + 1e-10 * np.abs(st.u))) < 1.0, st.t
        checked += 1
    assert checked >= 35
    assert st.counts["newton_failures"] > 0          # the kinks were felt (and handled by a fresh Jacobian)


def test_newton_keeps_its_lu_across_steps_on_a_smooth_model():
    m = maxwell_model()
    res = m.simulate(1.0, 0.02, solver="convolution", h=1e-3)
    ex = res.stats.extra
    assert ex["newton_failures"] == 0 and ex["subdivided"] == 0
    # one LU per segment (here one): the matrix depends only on h and the Jacobian, both kept
    assert ex["lu_decompositions"] == res.stats.segments == 1
    assert ex["newton_iterations"] <= 2 * res.stats.steps


@pytest.fixture(scope="module")
def excavator():
    m = SCENES["excavator_swing"]()
    return m, m.simulate(3.0, dt_out=0.1, solver="ida", rtol=1e-9)


def test_stable_where_rk4_diverges_on_the_excavator(excavator):
    """The issue: 'on the excavator scene the convolution method stays stable at steps where explicit RK4
    diverges'. At h = 0.1 s (rk4 and the paper's single-pass corrector are stable up to 0.057 s and 0.026 s,
    benchmarks/results/solvers_ode.md) the implicit corrector completes within 5 % of the speed reached."""
    m, ref = excavator
    # (refused as it diverges, or before a short segment's steps as it would: which test sees it first depends
    # on where rk4 locates the backlashes' contacts)
    with pytest.raises(rm.SimulationError, match="solver 'rk4' (diverged|would diverge)"):
        m.simulate(3.0, dt_out=0.1, solver="rk4", h=0.1)
    with pytest.raises(rm.SimulationError, match="corrector='implicit'"):
        m.simulate(3.0, dt_out=0.1, solver="convolution", h=0.1, corrector="pece")
    res = m.simulate(3.0, dt_out=0.1, solver="convolution", h=0.1)
    # the events' rows (mode changes, and the backlash's contacts, located by each run at its own times) lie
    # between the output instants: compare the rows on the grid
    on_grid = np.abs(ref.t / 0.1 - np.round(ref.t / 0.1)) < 1e-9
    on_grid_res = np.abs(res.t / 0.1 - np.round(res.t / 0.1)) < 1e-9
    assert on_grid.sum() == on_grid_res.sum()
    w, w_ref = res["turntable.w"][on_grid_res], ref["turntable.w"][on_grid]
    assert np.all(np.abs(res.t[on_grid_res] - ref.t[on_grid]) < 1e-12)
    err = np.max(np.abs(w - w_ref))
    assert err < 0.05 * np.max(np.abs(w_ref)), err                  # measured 0.24 rad/s of 7.85 (3 %)
    assert abs(w[-1] - w_ref[-1]) < 0.005 * w_ref[-1]                # measured 0.013 rad/s at 3 s
    # the turntable breaks away (the one stick/slip event) within a step of the reference; each device's
    # sequence of changes (the backlashes' contacts too) is the reference's (two symmetric backlashes touch
    # at one instant, in either order)
    def per_device(r):
        seq = {}
        for e in r.events:
            seq.setdefault(e.component, []).append((e.kind, e.old_mode, e.new_mode))
        return seq
    assert per_device(res) == per_device(ref)
    mode_res = [e for e in res.events if e.kind == "mode"]
    mode_ref = [e for e in ref.events if e.kind == "mode"]
    assert abs(mode_res[0].t - mode_ref[0].t) < 0.01             # measured 0.0042 s


def test_an_event_on_a_breakpoint_leaves_no_empty_segment():
    """gear_shift: the brake becomes free exactly where its release ramp ends (0.4 s); the zero-length
    segment after that event is skipped (it gave 0/0 in the starting-step estimate)."""
    m = SCENES["gear_shift"]()
    ref = m.simulate(1.0, dt_out=0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = m.simulate(1.0, dt_out=0.01, solver="convolution")
    assert [(e.component, e.old_mode, e.new_mode) for e in res.events] == \
        [(e.component, e.old_mode, e.new_mode) for e in ref.events]
    assert any(abs(e.t - 0.4) < 1e-9 for e in res.events)
