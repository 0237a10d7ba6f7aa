"""The first-order state space of a model (``Model.linearize`` -> ``compile.statespace.StateSpace``)."""

import numpy as np
import pytest
import scipy.signal

import regmech as rm
from regmech.components import Damper, Fixed, Inertia, SpringDamper, Torque
from regmech.errors import ParameterError
from regmech.signals import Step

from test_blocks import motor_loop

# the loop of ``motor_loop``: inertia J, viscous load d, motor R, L, k_m, PI gain k and integral time T_i
J, D, R, L, KM, K, TI = 0.01, 0.001, 1.0, 1e-3, 0.1, 1.0, 0.1


def analytic_matrix():
    """States (phi, w, x, i): J w' = k_m i - d w + tau_L; L i' = u - R i - k_m w; u = k (ref - w) + x;
    x' = (k / T_i) (ref - w)."""
    return np.array([[0.0, 1.0, 0.0, 0.0],
                     [0.0, -D / J, 0.0, KM / J],
                     [0.0, -K / TI, 0.0, 0.0],
                     [0.0, -(KM + K) / L, 1.0 / L, -R / L]])


def sorted_poles(p):
    return p[np.lexsort((p.imag, p.real))]


@pytest.fixture(scope="module")
def run():
    m = motor_loop()
    return m, m.simulate(4.0)


def test_closed_loop_poles_match_the_analytic_ones(run):
    m, res = run
    lin = m.linearize(at=res, t=3.5)
    assert lin.states == ["J.phi", "J.w", "pi.x", "mot.i"]
    expect = sorted_poles(np.linalg.eigvals(analytic_matrix()))
    got = lin.poles()
    assert len(got) == 4
    for p, q in zip(got, expect):
        assert abs(p - q) <= 1e-6 * max(1.0, abs(q))
    np.testing.assert_allclose(lin.A, analytic_matrix(), rtol=1e-9, atol=1e-9)
    # damping and natural frequency of the complex pair
    pair = got[np.abs(got.imag) > 0][0]
    k = list(got).index(pair)
    assert lin.natural_frequencies()[k] == pytest.approx(abs(pair))
    assert lin.damping()[k] == pytest.approx(-pair.real / abs(pair))


def test_named_inputs_and_outputs(run):
    m, res = run
    lin = m.linearize(at=res, t=3.5, inputs=["load.tau", "pi.ref"], outputs=["J.w", "pi.y", "mot.i"])
    assert lin.inputs == ["load.tau", "pi.ref"] and lin.outputs == ["J.w", "pi.y", "mot.i"]
    # B: the load torque accelerates J by 1/J; the reference moves the integrator by k/T_i and the voltage
    # (so L i') by k
    np.testing.assert_allclose(lin.B, [[0, 0], [1 / J, 0], [0, K / TI], [0, K / L]], rtol=1e-12, atol=1e-12)
    # the PI output is an algebraic unknown: y = k (ref - w) + x, its D entry k from the reference
    np.testing.assert_allclose(lin.C, [[0, 1, 0, 0], [0, -K, 1, 0], [0, 0, 0, 1]], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(lin.D, [[0, 0], [0, K], [0, 0]], atol=1e-12)
    ss = lin.to_scipy()
    assert isinstance(ss, scipy.signal.StateSpace)
    w, mag, phase = lin.bode(input="pi.ref", output="J.w")
    assert mag[0] == pytest.approx(1.0, rel=1e-3)        # integral action: unit gain at low frequency


def test_step_response_matches_scipy_on_the_linearised_model(run):
    m, res = run
    lin = m.linearize(at=res, t=3.5, inputs=["pi.ref"], outputs=["J.w"])
    t0, dt, step = 3.5, 1.0, 0.1
    m2 = motor_loop(ref=Step(height=step, start_time=t0, offset=100.0))
    res2 = m2.simulate(t0 + dt, dt_out=1e-3, solver="ida", rtol=1e-10, atol=1e-12)
    after = res2.t > t0                 # (the row at t0 itself is there twice: before and after the step)
    tt = np.linspace(0.0, dt, 1001)
    w = np.interp(tt, np.r_[0.0, res2.t[after] - t0], np.r_[0.0, res2["J.w"][after] - res2.at("J.w", t0)])
    _, y = scipy.signal.step(lin.to_scipy(), T=tt)
    y = step * np.ravel(y)
    span = np.ptp(y)
    assert span > 0.5 * step
    assert np.max(np.abs(w - y)) <= 1e-4 * span


def test_mechanics_only_model_both_forms_agree():
    m = rm.Model("two_mass")
    J1 = m.add(Inertia("J1", J=1.0))
    J2 = m.add(Inertia("J2", J=2.0))
    sd = m.add(SpringDamper("sd", c=1e4, d=5.0))
    vd = m.add(Damper("vd", d=0.3))
    g = m.add(Fixed("g"))
    tq = m.add(Torque("tq", tau=1.0))
    m.connect(J1.flange_b, sd.flange_a)
    m.connect(sd.flange_b, J2.flange_a)
    m.connect(J2.flange_b, vd.flange_a)
    m.connect(vd.flange_b, g.flange)
    m.connect(tq.flange, J1.flange_a)
    structural = m.linearize()
    M, B, C = (np.asarray(a) for a in (structural.M, structural.B, structural.C))
    n = len(M)
    companion = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, C), -np.linalg.solve(M, B)]])
    first = m.linearize(form="state_space", inputs=["tq.tau"], outputs=["J2.w"])
    np.testing.assert_allclose(sorted_poles(np.linalg.eigvals(companion)), first.poles(), rtol=1e-9, atol=1e-9)
    # the input enters both alike: W u in the structural form, B u here
    w_struct = np.linalg.solve(M, np.asarray(structural.W)[:, 0])
    assert np.allclose(np.sort(np.abs(first.B[:, 0]))[-n:], np.sort(np.abs(w_struct)), rtol=1e-12)


def test_unknown_input_and_output_are_named(run):
    m, res = run
    with pytest.raises(ParameterError, match=r"no input 'nope.tau'.*load.tau"):
        m.linearize(at=res, t=3.5, inputs=["nope.tau"])
    with pytest.raises(ParameterError, match=r"input 'mot.u' reads pi.y, a value of the model itself"):
        m.linearize(at=res, t=3.5, inputs=["mot.u"])
    with pytest.raises(ParameterError, match=r"no linear output 'J.nope'"):
        m.linearize(at=res, t=3.5, outputs=["J.nope"])


def test_to_control_when_installed(run):
    control = pytest.importorskip("control")
    m, res = run
    lin = m.linearize(at=res, t=3.5, inputs=["pi.ref"], outputs=["J.w"])
    sys = lin.to_control()
    assert list(sys.input_labels) == ["pi_ref"] and list(sys.output_labels) == ["J_w"]
    np.testing.assert_allclose(sorted_poles(np.asarray(control.poles(sys))), lin.poles(), rtol=1e-9, atol=1e-9)
