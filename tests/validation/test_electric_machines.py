"""Electric machines: DCMotor and SeriesDCMotors against closed forms (steady state, electrical time
constant, the linear 2x2 system solved by the matrix exponential), their electrical energy books, and the
map-based ElectricMotor's envelope, quadrants and efficiency map."""

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid
from scipy.linalg import expm

import regmech as rm
from regmech.components import DCMotor, ElectricMotor, Fixed, Inertia, SeriesDCMotors, Speed, Torque
from regmech.errors import ParameterError
from regmech.signals import Ramp

U, R, L, K, J, TAU_L = 100.0, 0.5, 0.01, 0.8, 0.05, 10.0


def dc_model(u=U, tau_load=-TAU_L, w0=0.0, i0=0.0):
    m = rm.Model("dc")
    mot = m.add(DCMotor("motor", u=u, R=R, L=L, k=K, i0=i0))
    rotor = m.add(Inertia("rotor", J=J, phi0=0.0, w0=w0))
    load = m.add(Torque("load", tau=tau_load))
    m.connect(mot.flange, rotor.flange_a)
    m.connect(rotor.flange_b, load.flange)
    return m


@pytest.mark.slow
def test_dc_motor_follows_the_linear_closed_form_and_reaches_its_steady_state():
    """x = (i, w): x' = A x + b with A = [[-R/L, -k/L], [k/J, -0]], b = (u/L, tau_load/J): the exact
    solution x(t) = x_ss + expm(A t)(x0 - x_ss)."""
    res = dc_model().simulate(t_end=0.6, dt_out=1e-3, solver="ida", rtol=1e-9, atol=1e-10)
    A = np.array([[-R / L, -K / L], [K / J, 0.0]])
    b = np.array([U / L, -TAU_L / J])
    x_ss = np.linalg.solve(A, -b)
    assert x_ss == pytest.approx([TAU_L / K, (U - R * TAU_L / K) / K])       # i = tau_L/k, w = (u - R i)/k
    exact = np.array([x_ss + expm(A * t) @ (-x_ss) for t in res.t])
    assert np.max(np.abs(res["motor.i"] - exact[:, 0])) < 1e-4 * np.ptp(exact[:, 0])
    assert np.max(np.abs(res["rotor.w"] - exact[:, 1])) < 1e-5 * np.ptp(exact[:, 1])
    assert res["rotor.w"][-1] == pytest.approx(x_ss[1], rel=1e-5)
    assert res["motor.tau"] == pytest.approx(K * res["motor.i"])
    assert res.unit("motor.i") == "A" and res.unit("motor.p_el") == "W" and res.unit("motor.magnetic") == "J"


def test_dc_motor_with_the_rotor_held_rises_with_the_electrical_time_constant():
    m = rm.Model("dc_locked")
    mot = m.add(DCMotor("motor", u=U, R=R, L=L, k=K))
    ground = m.add(Fixed("ground"))
    m.connect(mot.flange, ground.flange)
    res = m.simulate(t_end=0.1, dt_out=1e-4, solver="ida", rtol=1e-9, atol=1e-10)
    exact = U / R * (1.0 - np.exp(-res.t * R / L))                       # time constant L/R = 20 ms
    assert np.max(np.abs(res["motor.i"] - exact)) < 1e-5 * U / R
    k63 = np.searchsorted(res["motor.i"], (1 - np.exp(-1)) * U / R)
    assert res.t[k63] == pytest.approx(L / R, abs=2e-4)


def test_dc_motor_energy_book_electrical_and_mechanical():
    """int u i = int R i^2 + L i^2/2 + int k i w, and int k i w = kinetic + work against the load."""
    res = dc_model(u=Ramp(height=U, duration=0.1)).simulate(t_end=0.5, dt_out=1e-4, solver="ida", rtol=1e-9, atol=1e-10)
    t = res.t

    def integral(p):
        return cumulative_trapezoid(p, t, initial=0.0)
    e_in = integral(res["motor.p_el"])
    e_mech = integral(res["motor.p_mech"])
    book_el = e_in - integral(res["motor.p_loss"]) - (res["motor.magnetic"] - res["motor.magnetic"][0]) - e_mech
    book_mech = e_mech - (res["rotor.kinetic"] - res["rotor.kinetic"][0]) - integral(res["load.power"])
    assert e_in[-1] > 1e3
    assert np.max(np.abs(book_el)) < 1e-6 * e_in[-1]
    assert np.max(np.abs(book_mech)) < 1e-6 * e_in[-1]
    assert np.allclose(res["motor.p_mech"], -res["motor.power"], atol=1e-9 * np.abs(res["motor.p_mech"]).max())
    # the copper losses as heat (integrated from the laws between the rows; the trapezoid agrees on this grid)
    assert np.max(np.abs(res["motor.heat"] - integral(res["motor.p_loss"]))) < 1e-6 * e_in[-1]
    # generator quadrant: a spinning rotor on a short-circuited armature (u = 0) is braked by its current;
    # its kinetic energy ends in the resistance (and the inductance)
    gen = dc_model(u=0.0, tau_load=0.0, w0=100.0).simulate(t_end=0.5, dt_out=1e-4, solver="ida", rtol=1e-9,
                                                             atol=1e-10)
    assert gen["motor.p_mech"][1:200].max() < 0 and gen["rotor.w"][-1] < 1e-3 * 100.0
    heat = cumulative_trapezoid(gen["motor.p_loss"], gen.t, initial=0.0) + gen["motor.magnetic"]
    lost = gen["rotor.kinetic"][0] - gen["rotor.kinetic"]
    assert np.max(np.abs(heat - lost)) < 1e-6 * lost[-1]


def test_series_dc_motors_share_one_current():
    """Rigidly coupled rotors (one inertia) on both flanges: the steady state of the two-motor circuit
    i = tau_L / (k1 + k2), w = (u - R i) / (k1 + k2), and both motor torques k_j i."""
    m = rm.Model("series")
    arm = m.add(SeriesDCMotors("armature", u=U, R=R, L=L, k_1=0.5, k_2=0.3))
    r1 = m.add(Inertia("r1", J=J, phi0=0.0, w0=0.0))
    r2 = m.add(Inertia("r2", J=J, phi0=0.0, w0=0.0))
    from regmech.components import IdealGear
    link = m.add(IdealGear("link", ratio=1.0))
    load = m.add(Torque("load", tau=-TAU_L))
    m.connect(arm.flange_1, r1.flange_a)
    m.connect(arm.flange_2, r2.flange_a)
    m.connect(r1.flange_b, link.flange_a)
    m.connect(link.flange_b, r2.flange_b)
    m.connect(r1.flange_b, load.flange)
    res = m.simulate(t_end=1.0, dt_out=1e-3, solver="ida", rtol=1e-9, atol=1e-10)
    i_ss = TAU_L / 0.8
    assert res["armature.i"][-1] == pytest.approx(i_ss, rel=1e-5)
    assert res["r1.w"][-1] == pytest.approx((U - R * i_ss) / 0.8, rel=1e-5)
    assert res["armature.tau_1"][-1] == pytest.approx(0.5 * i_ss, rel=1e-5)
    assert res["armature.tau_2"][-1] == pytest.approx(0.3 * i_ss, rel=1e-5)


@pytest.mark.parametrize("bad", [dict(R=0.0), dict(L=-1.0), dict(k=float("nan")), dict(u="volts")])
def test_dc_motor_parameters_are_checked(bad):
    params = dict(u=U, R=R, L=L, k=K) | bad
    with pytest.raises(ParameterError, match="DCMotor 'm'"):
        DCMotor("m", **params)


# --- map-based ElectricMotor ----------------------------------------------------------------------
TAU_MAX, P_MAX = 300.0, 60e3            # base speed 200 rad/s


def em_run(command, w_ref, **kw):
    """The rotor driven at a prescribed speed ramp: the machine's torque is read against the envelope."""
    m = rm.Model("em")
    em = m.add(ElectricMotor("em", command=command, tau_max=TAU_MAX, p_max=P_MAX, **kw))
    rotor = m.add(Inertia("rotor", J=0.1))
    drive = m.add(Speed("drive", w_ref=w_ref))
    m.connect(em.flange, rotor.flange_a)
    m.connect(rotor.flange_b, drive.flange)
    return em, m.simulate(t_end=1.0, dt_out=1e-3, solver="ida", rtol=1e-8, atol=1e-9)


def test_electric_motor_envelope_constant_torque_then_constant_power():
    em, res = em_run(1.0, Ramp(height=600.0, duration=1.0))
    w = res["rotor.w"]
    expected = np.where(w <= 200.0, TAU_MAX, P_MAX / np.maximum(w, 1e-12))
    assert em.w_base == pytest.approx(200.0)
    assert np.max(np.abs(res["em.tau"] - expected)) < 1e-6 * TAU_MAX
    assert np.max(res["em.p_mech"]) == pytest.approx(P_MAX, rel=1e-6)
    assert np.allclose(res["em.p_el"], res["em.p_mech"])                 # no map: lossless


def test_electric_motor_efficiency_map_in_motor_and_generator_quadrants():
    speeds, torques = [0.0, 200.0, 600.0], [0.0, 150.0, 300.0]
    eta = [[0.80, 0.85, 0.88], [0.90, 0.94, 0.92], [0.86, 0.90, 0.90]]
    eta_gen = [[0.75, 0.80, 0.85], [0.88, 0.92, 0.90], [0.84, 0.88, 0.88]]
    kw = dict(eta_speeds=speeds, eta_torques=torques, eta=eta, eta_gen=eta_gen)
    for command in (0.5, -0.5):
        em, res = em_run(command, Ramp(height=600.0, duration=1.0), **kw)
        w, tau = res["rotor.w"], res["em.tau"]
        # independent bilinear interpolation of the grid by hand
        table = np.array(eta if command > 0 else eta_gen)
        exp_eta = np.empty_like(w)
        for n, (wk, tk) in enumerate(zip(np.abs(w), np.abs(tau))):
            i = min(int(np.searchsorted(speeds, wk, side="right")) - 1, len(speeds) - 2)
            j = min(int(np.searchsorted(torques, tk, side="right")) - 1, len(torques) - 2)
            a = (wk - speeds[i]) / (speeds[i + 1] - speeds[i])
            b = (tk - torques[j]) / (torques[j + 1] - torques[j])
            exp_eta[n] = ((1 - a) * (1 - b) * table[i, j] + a * (1 - b) * table[i + 1, j]
                          + (1 - a) * b * table[i, j + 1] + a * b * table[i + 1, j + 1])
        moving = w > 0         # at rest p_mech = 0 and either map gives p_el = 0
        assert np.allclose(res["em.efficiency"][moving], exp_eta[moving], rtol=1e-12)
        p_mech = tau * w
        if command > 0:      # motor: draws more than it delivers
            assert np.allclose(res["em.p_el"][moving], p_mech[moving] / exp_eta[moving])
            assert np.all(res["em.p_loss"] >= 0)
        else:                # generator: returns less than it absorbs
            assert np.all(p_mech[1:] < 0)
            assert np.allclose(res["em.p_el"][moving], p_mech[moving] * exp_eta[moving])
            assert np.all(res["em.p_loss"][1:] > 0)


@pytest.mark.parametrize("bad, match", [
    (dict(tau_max=-1.0), "tau_max"),
    (dict(eta_speeds=[0, 100]), "needs eta_speeds, eta_torques and eta together"),
    (dict(eta_speeds=[0, 100], eta_torques=[0, 10], eta=[[0.9, 0.9], [0.9, 1.2]]), "efficiencies in"),
    (dict(eta_speeds=[100, 0], eta_torques=[0, 10], eta=[[0.9, 0.9], [0.9, 0.9]]), "strictly increasing"),
    (dict(command=2.0), "command"),
])
def test_electric_motor_parameters_are_checked(bad, match):
    params = dict(tau_max=TAU_MAX, p_max=P_MAX) | bad
    with pytest.raises((ParameterError, rm.errors.RegmechError), match=match):
        em = ElectricMotor("em", **params)
        em_run(em.command, 10.0)
