"""A friction element's lumped thermal mass inside the DAE: ``C dT/dt = lam w_rel -
G (T - T_amb)`` with the temperature a state and fade ``mu * fade(T)``; closed forms, an independent scipy
model of a fading brake stop (slip, then stuck), the heat books, and the solvers that decline it."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import regmech as rm
from regmech.components import Brake, Clutch, Fixed, Inertia, Speed, Torque
from regmech.components.heat import ThermalMass
from regmech.errors import ParameterError, SimulationError

# long-running (over 2 s on 2 cores): left out of the fast lane, pytest -m 'not slow'
pytestmark = pytest.mark.slow

MU, CGEO, FN = 0.4, 0.1, 1000.0


def _driven_brake(w, thermal, f_normalized=1.0):
    """A brake on an inertia turned at the constant speed ``w`` by a Speed source: constant slip power
    ``mu cgeo fn w`` while engaged."""
    m = rm.Model("slip_power")
    src = m.add(Speed("src", w_ref=w))
    J = m.add(Inertia("J", J=1.0, w0=w))
    b = m.add(Brake("b", mu=MU, cgeo=CGEO, fn_max=FN, f_normalized=f_normalized, thermal=thermal))
    m.connect(src.flange, J.flange_a)
    m.connect(J.flange_b, b.flange)
    return m


@pytest.mark.parametrize("solver", ["ida", "scipy:Radau"])
@pytest.mark.parametrize("G", [0.0, 4.0])
def test_constant_power_slip_closed_form(solver, G):
    """T(t) = T_amb + (T0 - T_amb) e^{-t/tau} + (P/G)(1 - e^{-t/tau}), tau = C/G (G = 0: T0 + P t / C)."""
    w, C, T_amb, T0 = 50.0, 800.0, 300.0, 320.0
    P = MU * CGEO * FN * w
    res = _driven_brake(w, ThermalMass(C=C, G=G, T_amb=T_amb, T0=T0)).simulate(
        t_end=200.0, dt_out=0.5, solver=solver, rtol=1e-9, atol=1e-9)
    t = res.t
    if G == 0.0:
        exact = T0 + P * t / C
    else:
        decay = np.exp(-G * t / C)
        exact = T_amb + (T0 - T_amb) * decay + P / G * (1.0 - decay)
    assert res.unit("b.T") == "K"
    np.testing.assert_allclose(res["b.T"], exact, rtol=1e-7, atol=0)
    # books: heat stored in the mass + heat to ambient = the dissipated work (exact here: P is constant)
    np.testing.assert_allclose(res["b.heat"], P * t, rtol=1e-9, atol=1e-6)
    # heat_to_ambient is integrated from the laws between the rows like heat (the trapezoid over the rows, before:
    # 3.2e-7 of the heat off at G = 4), so the books close to the run's tolerance
    np.testing.assert_allclose(res["b.heat_flow_to_ambient"], G * (res["b.T"] - T_amb), rtol=1e-12, atol=1e-12)
    books = res["b.heat_stored"] + res["b.heat_to_ambient"]
    np.testing.assert_allclose(books, res["b.heat"], rtol=0, atol=2e-8 * res["b.heat"][-1])


def test_free_and_stuck_modes_exchange_heat_with_ambient_only():
    """Disengaged (mode Free) and locked (mode Stuck) the element absorbs no power: a hot one cools along
    T_amb + (T0 - T_amb) e^{-G t / C}."""
    C, G, T_amb, T0 = 500.0, 5.0, 293.15, 450.0
    th = ThermalMass(C=C, G=G, T_amb=T_amb, T0=T0)
    free = _driven_brake(10.0, th, f_normalized=0.0).simulate(t_end=300.0, dt_out=1.0, rtol=1e-9, atol=1e-9,
                                                               solver="ida")
    assert set(free["b.mode"]) == {2.0}
    # stuck: a brake holding an inertia at rest under a torque below its capacity
    m = rm.Model("held")
    J = m.add(Inertia("J", J=1.0, w0=0.0))
    tq = m.add(Torque("tq", tau=10.0))
    b = m.add(Brake("b", mu=MU, cgeo=CGEO, fn_max=FN, thermal=th))
    m.connect(tq.flange, J.flange_a)
    m.connect(J.flange_b, b.flange)
    held = m.simulate(t_end=300.0, dt_out=1.0, rtol=1e-9, atol=1e-9, solver="ida")
    assert set(held["b.mode"]) == {0.0}
    for res in (free, held):
        exact = T_amb + (T0 - T_amb) * np.exp(-G * res.t / C)
        np.testing.assert_allclose(res["b.T"], exact, rtol=1e-8)
        assert abs(res["b.heat"][-1]) < 1e-9


def _fade_stop_by_hand(J, w0, C, G, T_amb, T0, fade, t_end):
    """The same brake stop written by hand: sliding until w = 0 (an event), then held at rest (the torque
    needed is zero) while the mass cools."""
    Ts, fs = np.asarray(fade, float).T

    def tk(T):
        return MU * float(np.interp(T, Ts, fs)) * CGEO * FN

    def sliding(t, s):
        w, T = s
        return [-tk(T) / J, (tk(T) * w - G * (T - T_amb)) / C]

    def stop(t, s):
        return s[0]
    stop.terminal, stop.direction = True, -1
    a = solve_ivp(sliding, (0.0, t_end), [w0, T0], events=stop, rtol=1e-11, atol=1e-11, dense_output=True)
    t_stop = float(a.t_events[0][0])
    T_stop = float(a.y_events[0][0][1])

    def at(t):
        if t <= t_stop:
            w, T = a.sol(t)
            return max(w, 0.0), T
        return 0.0, T_amb + (T_stop - T_amb) * math.exp(-G * (t - t_stop) / C)
    return t_stop, at


def _fade_stop(J, w0, thermal):
    m = rm.Model("fade_stop")
    Jm = m.add(Inertia("J", J=J, w0=w0))
    b = m.add(Brake("b", mu=MU, cgeo=CGEO, fn_max=FN, thermal=thermal))
    m.connect(Jm.flange_b, b.flange)
    return m


@pytest.mark.parametrize("solver", ["ida", "scipy:DOP853"])
def test_fading_brake_stop_against_hand_model(solver):
    """A flywheel braked to rest with fade (mu falls to 60 % between 300 and 400 K), then cooling while
    stuck: regmech against the hand-written scipy model, and the books against the kinetic energy."""
    J, w0, C, G, T_amb = 2.0, 100.0, 100.0, 2.0, 300.0
    fade = [(300.0, 1.0), (400.0, 0.6)]
    m = _fade_stop(J, w0, ThermalMass(C=C, G=G, T_amb=T_amb, fade=fade))
    res = m.simulate(t_end=20.0, dt_out=0.01, solver=solver, rtol=1e-9, atol=1e-10)
    t_stop, hand = _fade_stop_by_hand(J, w0, C, G, T_amb, T_amb, fade, 20.0)
    # without fade the stop takes J w0 / (mu cgeo fn) = 5 s
    assert t_stop > 5.5
    assert [e.t for e in res.events] == pytest.approx([t_stop], abs=1e-6)
    expected = np.array([hand(t) for t in res.t])
    np.testing.assert_allclose(res["J.w"], expected[:, 0], atol=1e-6 * w0)
    np.testing.assert_allclose(res["b.T"], expected[:, 1], atol=1e-6 * 100.0)
    assert res["b.T"].max() > 360.0          # hot enough for the fade to matter
    # the work done on the brake is the flywheel's kinetic energy: all of it in the mass or in the air
    e_kin = 0.5 * J * w0 ** 2
    assert res["b.heat"][-1] == pytest.approx(e_kin, rel=1e-4)
    assert res["b.heat_stored"][-1] + res["b.heat_to_ambient"][-1] == pytest.approx(e_kin, rel=1e-4)


def test_hot_clutch_breaks_away_earlier():
    """Fade lowers the static capacity too: a stuck clutch whose mass starts hot slips under a load the cold
    one holds (the holding-torque check reads the temperature state)."""
    def run(T0):
        m = rm.Model("hot")
        tq = m.add(Torque("tq", tau=30.0))
        J1 = m.add(Inertia("J1", J=1.0))
        c = m.add(Clutch("c", mu=MU, cgeo=CGEO, fn_max=FN, peak=1.0,
                         thermal=ThermalMass(C=1e6, G=0.0, T0=T0, fade=[(300.0, 1.0), (500.0, 0.5)])))
        J2 = m.add(Inertia("J2", J=1.0))
        ground = m.add(Fixed("ground"))
        m.connect(tq.flange, J1.flange_a)
        m.connect(J1.flange_b, c.flange_a)
        m.connect(c.flange_b, J2.flange_a)
        m.connect(J2.flange_b, ground.flange)
        return m.simulate(t_end=0.5, dt_out=0.01, solver="ida")
    cold, hot = run(300.0), run(500.0)      # capacity 40 N m cold, 20 N m hot; the load is 30 N m
    assert set(cold["c.mode"]) == {0.0} and cold["J1.w"][-1] == pytest.approx(0.0, abs=1e-9)
    assert hot["c.mode"][-1] != 0.0 and hot["J1.w"][-1] > 0.0
    # sliding on the hot mass: J1 w' = 30 - 0.5 * 40 = 10 (the heat of 0.5 s barely warms a 1 MJ/K mass)
    assert hot["J1.w"][-1] == pytest.approx(10.0 * 0.5, rel=1e-4)


def test_solvers_that_cannot_hold_the_state_decline_by_name():
    m = _driven_brake(20.0, ThermalMass(C=100.0, G=1.0))
    with pytest.raises(SimulationError, match=r"Brake 'b'.*internal states \(a thermal mass"):
        m.simulate(t_end=1.0, solver="expm")
    # the first-order state space holds it: the temperature's pole is -G / C
    lin = m.linearize()
    assert "b.T" in lin.states
    assert np.sort(lin.poles().real)[0] == pytest.approx(-1.0 / 100.0, rel=1e-9)
    from regmech.solvers.ida_native import friction_laws
    reason = friction_laws(_fade_stop(1.0, 10.0, ThermalMass(C=100.0)).compile().friction)
    assert isinstance(reason, str) and "Brake 'b' reads inputs from the state" in reason
    res = m.simulate(t_end=1.0, dt_out=0.1)          # auto picks a method that holds it
    assert res.stats.solver != "expm" and np.all(np.isfinite(res["b.T"]))


def test_thermal_mass_parameters_are_checked():
    with pytest.raises(ParameterError, match="C must be"):
        ThermalMass(C=0.0)
    with pytest.raises(ParameterError, match="G must be"):
        ThermalMass(C=1.0, G=-1.0)
    with pytest.raises(ParameterError, match="fade must be"):
        ThermalMass(C=1.0, fade=[(400.0, 1.0), (300.0, 0.5)])
    with pytest.raises(ParameterError, match="fade must be"):
        ThermalMass(C=1.0, fade=[(300.0, -0.1)])
    with pytest.raises(ParameterError, match="thermal must be"):
        Brake("b", fn_max=1.0, thermal=500.0)
    th = ThermalMass(C=1.0, fade=[(300.0, 1.0), (400.0, 0.5)])
    assert th.factor(350.0) == pytest.approx((0.75, -0.005))
    assert th.factor(200.0) == (1.0, 0.0) and th.factor(500.0) == (0.5, 0.0)


@pytest.mark.parametrize("solver, options", [("convolution", {}), ("rk4", {"h": 1e-3}), ("scipy:LSODA", {})])
def test_ode_form_solvers_hold_the_thermal_state(solver, options):
    """The ODE-form solvers integrate the temperature too (its rate is filled in after the KKT solve, where the
    friction force is known): the fading stop's temperature and stop time agree with IDA's at their accuracy."""
    fade = [(300.0, 1.0), (400.0, 0.6)]
    build = (lambda: _fade_stop(2.0, 100.0, ThermalMass(C=100.0, G=2.0, T_amb=300.0, fade=fade)))
    ref = build().simulate(t_end=8.0, dt_out=0.01, solver="ida", rtol=1e-9, atol=1e-10)
    res = build().simulate(t_end=8.0, dt_out=0.01, solver=solver, **options)
    assert res.events[0].t == pytest.approx(ref.events[0].t, abs=1e-3)
    np.testing.assert_allclose(res["b.T"], ref["b.T"], atol=1e-3 * np.ptp(ref["b.T"]))


def test_temperature_is_integrated_as_its_rise_over_ambient():
    """The solvers hold a thermal mass's state as ``T - T_amb`` (``friction_state_datum``) and the result
    shows ``T``: at 293 K a rise of 2 mK weighed by ``rtol |T|`` was a tolerance 1e5 times the motion's, and
    the accuracy contract capped the pair's rtol for it (random drivetrain seed 30: 22 s, now 10 s)."""
    w, C, T_amb = 50.0, 1e6, 293.15
    P = MU * CGEO * FN * w
    m = _driven_brake(w, ThermalMass(C=C, G=0.0, T_amb=T_amb))
    c = m.compile()
    j = c.state_names.index("b.T")
    assert c.state_datum[j] == T_amb and c.state_start[j] == 0.0
    res = m.simulate(t_end=1.0, dt_out=0.01)
    assert "rtol_cap" not in res.stats.extra
    exact = T_amb + P * res.t / C
    assert res["b.T"][0] == T_amb
    assert np.max(np.abs(res["b.T"] - exact)) <= 1e-3 * np.ptp(exact)
    np.testing.assert_allclose(res["b.heat_stored"], C * (res["b.T"] - T_amb), rtol=1e-12, atol=1e-9)
