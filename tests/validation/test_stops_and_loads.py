"""End stops, ElastoGap, speed-dependent loads, the Stribeck law, VehicleLoad and LinearBrake
against closed forms or independent scipy models, with their energy books."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import regmech as rm
from regmech.bench.fuzz import energy_checks
from regmech.components import Brake, Clutch, Fixed, FrictionContact, Inertia, LinearSpeed, Mass, Speed, Torque, Force
from regmech.components.laws import Stribeck
from regmech.components.loads import (InverseSpeedDependentForce, InverseSpeedDependentTorque, LinearBrake,
                                      LinearSpeedDependentForce, LinearSpeedDependentTorque,
                                      QuadraticSpeedDependentForce, QuadraticSpeedDependentTorque, SignForce,
                                      SignTorque, VehicleLoad)
from regmech.components.stops import ElastoGap, EndStop, MassWithStopAndFriction
from regmech.errors import ParameterError
from regmech.signals import Ramp, Sine, Step, Table

TIGHT = dict(solver="ida", rtol=1e-10, atol=1e-12)


def contact_books(res, mod):
    """The energy books and loss signs at rel 1e-8; the pointwise power balance at 1e-3 only: IDA
    steps over the contact's kink without locating it (as for Backlash), and its interpolated
    acceleration just after the kink is off by ~1e-4 of the power scale, while the integrated books
    are not."""
    tight = [f for f in energy_checks(res, mod, rel=1e-8) if f.kind != "power-balance"]
    return tight + energy_checks(res, mod, rel=1e-3)


# ------------------------------------------------------------------ end stops

#: start position: the contact does not begin on an output instant (the acceleration has a kink there)
S0 = 0.00123


def _bounce(d, v0=1.0, m=2.0, c=1e5, domain="translational", t_end=0.36):
    mod = rm.Model("bounce")
    if domain == "translational":
        body = mod.add(Mass("body", m=m, s0=S0, v0=v0))
    else:
        body = mod.add(Inertia("body", J=m, phi0=S0, w0=v0))
    stop = mod.add(EndStop("stop", lower=-0.1, upper=0.1, c=c, d=d, domain=domain))
    mod.connect(body.flange_b, stop.flange)
    return mod, mod.simulate(t_end=t_end, dt_out=1e-5, **TIGHT)


@pytest.mark.slow
@pytest.mark.parametrize("domain", ["translational", "rotational"])
def test_elastic_stop_closed_form(domain):
    """d = 0: the contact is half a period of sqrt(c/m), the rebound speed is -v0, the penetration
    v0 sqrt(m/c); energy is conserved (books close, nothing dissipated)."""
    m, c, v0 = 2.0, 1e5, 1.0
    mod, res = _bounce(0.0, v0, m, c, domain)
    v = res["body.v" if domain == "translational" else "body.w"]
    s = res["body.s" if domain == "translational" else "body.phi"]
    t_hit = (0.1 - S0) / v0
    t_leave = t_hit + math.pi * math.sqrt(m / c)
    k = np.searchsorted(res.t, t_leave + 0.01)
    assert v[k] == pytest.approx(-v0, rel=1e-7)
    assert s.max() == pytest.approx(0.1 + v0 * math.sqrt(m / c), rel=1e-7)
    in_contact = res.t[s > 0.1]
    assert in_contact[0] == pytest.approx(t_hit, abs=2e-5) and in_contact[-1] == pytest.approx(t_leave, abs=2e-5)
    assert not contact_books(res, mod)
    # and the lower stop after the return: again -v0 -> +v0
    assert s.min() == pytest.approx(-0.1 - v0 * math.sqrt(m / c), rel=1e-6)


@pytest.mark.slow
def test_damped_stop_never_supplies_energy_and_never_pulls():
    mod, res = _bounce(200.0)
    f = res["stop.f"]
    s = res["body.s"]
    assert np.all(f[s > 0.1] >= 0) and np.all(f[s < -0.1] <= 0) and np.all(f[np.abs(s) <= 0.1] == 0)
    pot = res["stop.potential"]
    absorbed = np.concatenate([[0.0], np.cumsum(np.diff(res.t) * (res["stop.power"][1:] + res["stop.power"][:-1]) / 2)])
    dissipated = absorbed - (pot - pot[0])
    assert np.all(np.diff(dissipated) >= -1e-9)
    assert dissipated[-1] > 0.01
    assert abs(res["body.v"][-1]) < 1.0                   # it comes back slower
    assert not contact_books(res, mod)


def test_end_stop_parameter_errors():
    with pytest.raises(ParameterError, match="EndStop 's'.*lower < upper"):
        EndStop("s", lower=0.1, upper=0.1, c=1.0)
    with pytest.raises(ParameterError, match="EndStop 's'.*'c'"):
        EndStop("s", lower=0.0, upper=0.1, c=-1.0)
    with pytest.raises(ParameterError, match="'d'"):
        EndStop("s", lower=0.0, upper=0.1, c=1.0, d=-1.0)


@pytest.mark.slow
def test_elasto_gap_one_sided_contact():
    """A mass falls onto a gap (closed at s_rel < 0.05): half a period in contact, pushes only."""
    m, c, v0 = 1.0, 4e4, 0.5
    mod = rm.Model("gap")
    g = mod.add(Fixed("g", domain="translational"))
    body = mod.add(Mass("body", m=m, s0=0.20123, v0=-v0))
    gap = mod.add(ElastoGap("gap", c=c, d=0.0, phi_rel0=0.05))
    mod.connect(g.flange, gap.flange_a)
    mod.connect(gap.flange_b, body.flange_a)
    res = mod.simulate(t_end=0.6, dt_out=1e-5, **TIGHT)
    s, f = res["body.s"], res["gap.f"]
    assert np.all(f <= 0) and np.all(f[s >= 0.05] == 0)
    assert s.min() == pytest.approx(0.05 - v0 * math.sqrt(m / c), rel=1e-7)
    assert res["body.v"][-1] == pytest.approx(v0, rel=1e-7)
    contact = res.t[s < 0.05]
    assert contact[-1] - contact[0] == pytest.approx(math.pi * math.sqrt(m / c), abs=3e-5)
    assert not contact_books(res, mod)


def test_mass_with_stop_and_friction_books_and_rest():
    mod = rm.Model("mwsf")
    mw = mod.add(MassWithStopAndFriction("mw", m=1.0, s_min=-0.05, s_max=0.05, c=1e5, d=20.0, fn=10.0,
                                         mu_law=Stribeck(mu_s=0.5, mu_k=0.3, w_s=0.1), s0=0.0, v0=2.0))
    res = mod.simulate(t_end=1.5, dt_out=1e-4, **TIGHT)
    assert res["mw.mass.v"][-1] == 0.0 and res["mw.friction.mode"][-1] == 0
    assert -0.05 - 1e-3 < res["mw.mass.s"][-1] < 0.05 + 1e-3
    assert res["mw.stop.f"].max() > 0                     # it hit the stop
    assert not contact_books(res, mod)


# ------------------------------------------------------------------ speed-dependent loads

LOADS = [
    (LinearSpeedDependentTorque, lambda w: 3.0 * w / 20.0),
    (QuadraticSpeedDependentTorque, lambda w: 3.0 * w * abs(w) / 400.0),
    (SignTorque, lambda w: 3.0 * math.tanh(w / 1e-3)),
    (InverseSpeedDependentTorque, lambda w: 3.0 * 20.0 / w if abs(w) > 1e-3 else 3.0 * 20.0 * w / 1e-6),
]


@pytest.mark.parametrize("cls, law", LOADS)
@pytest.mark.parametrize("w", [-15.0, 7.0, 30.0])
def test_speed_dependent_torque_laws(cls, law, w):
    mod = rm.Model("load")
    sp = mod.add(Speed("sp", w_ref=w))
    J = mod.add(Inertia("J", J=1.0))
    load = mod.add(cls("load", tau_nominal=3.0, w_nominal=20.0))
    mod.connect(sp.flange, J.flange_a)
    mod.connect(J.flange_b, load.flange)
    res = mod.simulate(t_end=0.1, dt_out=0.05, **TIGHT)
    assert res["load.tau"][-1] == pytest.approx(law(w), rel=1e-9)
    assert res["load.power"][-1] >= 0.0           # a load with tau_nominal >= 0 only dissipates
    assert res["sp.tau"][-1] == pytest.approx(-law(w), rel=1e-9) or res["sp.tau"][-1] == pytest.approx(law(w), rel=1e-9)


@pytest.mark.parametrize("cls, closed", [
    (LinearSpeedDependentForce, lambda t: 10.0 * math.exp(-(50.0 / 10.0) / 5.0 * t)),
    (QuadraticSpeedDependentForce, lambda t: 10.0 / (1 + (50.0 / 100.0) / 5.0 * 10.0 * t)),
    (SignForce, lambda t: 10.0 - 50.0 / 5.0 * t),
    (InverseSpeedDependentForce, lambda t: math.sqrt(100.0 - 2 * 50.0 * 10.0 / 5.0 * t)),
])
def test_coast_down_closed_forms(cls, closed):
    """m dv/dt = -f(v) from v0 = 10 m/s: exponential, hyperbolic, linear and square-root decays."""
    mod = rm.Model("coast")
    body = mod.add(Mass("body", m=5.0, s0=0.0, v0=10.0))
    load = mod.add(cls("load", f_nominal=50.0, v_nominal=10.0))
    mod.connect(body.flange_b, load.flange)
    res = mod.simulate(t_end=0.45, dt_out=0.01, **TIGHT)     # the inverse law reaches v_eps at 0.5 s
    for k in range(0, len(res.t), 5):
        assert res["body.v"][k] == pytest.approx(closed(res.t[k]), rel=1e-7)
    assert not energy_checks(res, mod, rel=1e-8)


@pytest.mark.parametrize("cls", [InverseSpeedDependentTorque, InverseSpeedDependentForce])
def test_inverse_load_at_rest_evaluates_without_dividing_by_zero(cls):
    """Fuzz seed 80263: the inverse law was a Piecewise with ``w / w^2``; numpy evaluates both branches, so an
    output row at w = 0 (a load starting at rest) divided by zero inside the kernels (a RuntimeWarning to the
    user). Written as ``w / max(|w|, w_eps)^2`` it never divides by less than ``w_eps^2``."""
    import warnings
    translational = "Force" in cls.__name__
    mod = rm.Model("inverse_at_rest")
    body = mod.add(Mass("body", m=2.0) if translational else Inertia("body", J=2.0))
    load = mod.add(cls("load", **({"f_nominal": 3.0, "v_nominal": 4.0} if translational
                                  else {"tau_nominal": 3.0, "w_nominal": 4.0}), w_eps=0.5))
    mod.connect(body.flange_b, load.flange)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = mod.simulate(t_end=0.2, dt_out=0.01, **TIGHT)
        force = res["load.f" if translational else "load.tau"]
    assert np.all(force == 0.0)                      # at rest, no load: the body stays at rest
    speed = res["body.v" if translational else "body.w"]
    assert np.all(speed == 0.0)


def test_load_parameter_errors():
    with pytest.raises(ParameterError, match="LinearSpeedDependentTorque 'l'.*w_nominal"):
        LinearSpeedDependentTorque("l", tau_nominal=1.0, w_nominal=0.0)
    with pytest.raises(ParameterError, match="tau_nominal.*required"):
        QuadraticSpeedDependentTorque("l")
    with pytest.raises(ParameterError, match="SignForce 'l'.*w_eps"):
        SignForce("l", f_nominal=1.0, w_eps=-1.0)


# ------------------------------------------------------------------ Stribeck

def test_stribeck_spin_down_against_scipy():
    """A brake with a Stribeck law stops a flywheel: J dw/dt = -mu(w) cgeo fn, then sticks."""
    law = Stribeck(mu_s=0.5, mu_k=0.3, w_s=1.0, mu_v=0.01, delta=2.0)
    J, fn, cgeo = 1.0, 25.0, 0.2
    mod = rm.Model("spin")
    fly = mod.add(Inertia("fly", J=J, phi0=0.0, w0=10.0))
    br = mod.add(Brake("br", fn_max=fn, cgeo=cgeo, mu_law=law))
    mod.connect(fly.flange_b, br.flange)
    res = mod.simulate(t_end=8.0, dt_out=0.01, **TIGHT)

    def rhs(t, y):
        return [-law.mu(abs(y[0]))[0] * cgeo * fn * np.sign(y[0]) / J]
    stop = lambda t, y: y[0]
    stop.terminal = True
    sol = solve_ivp(rhs, (0, 8), [10.0], events=stop, rtol=1e-12, atol=1e-12, dense_output=True)
    t_stop = sol.t_events[0][0]
    assert res.events[0].t == pytest.approx(t_stop, abs=1e-7)
    assert res.events[0].new_mode == 0
    for k in range(0, np.searchsorted(res.t, t_stop), 40):
        assert res["fly.w"][k] == pytest.approx(sol.sol(res.t[k])[0], abs=1e-8)
    assert not energy_checks(res, mod, rel=1e-8)


def test_stribeck_breakaway_at_static_coefficient():
    """A ramp torque breaks a stuck clutch loose when it reaches mu_s * cgeo * fn (peak = 1)."""
    law = Stribeck(mu_s=0.6, mu_k=0.4, w_s=0.5)
    mod = rm.Model("break")
    g = mod.add(Fixed("g"))
    tq = mod.add(Torque("tq", tau=Ramp(height=10.0, duration=1.0)))
    J1 = mod.add(Inertia("J1", J=1.0, phi0=0.0, w0=0.0))
    cl = mod.add(Clutch("cl", fn_max=10.0, mu_law=law))
    mod.connect(tq.flange, J1.flange_a)
    mod.connect(J1.flange_b, cl.flange_a)
    mod.connect(cl.flange_b, g.flange)
    res = mod.simulate(t_end=1.0, dt_out=1e-3, **TIGHT)
    assert res.events[0].t == pytest.approx(0.6, abs=1e-8)
    assert res.events[0].new_mode == -1       # w_rel = w_b - w_a < 0: the inertia turns forward


def test_stribeck_law_values_and_errors():
    law = Stribeck(mu_s=0.5, mu_k=0.3, w_s=2.0, mu_v=0.01)
    mu, dmu = law.mu(0.0)
    assert mu == 0.5 and dmu == pytest.approx(-0.2 / 2.0 + 0.01)
    mu, _ = law.mu(2.0)
    assert mu == pytest.approx(0.3 + 0.2 / math.e + 0.02)
    h = 1e-6
    for w in (0.5, 3.0):
        assert law.mu(w)[1] == pytest.approx((law.mu(w + h)[0] - law.mu(w - h)[0]) / (2 * h), rel=1e-6)
    g2 = Stribeck(mu_s=0.5, mu_k=0.3, w_s=2.0, delta=2.0)
    assert g2.mu(1.0)[1] == pytest.approx((g2.mu(1.0 + h)[0] - g2.mu(1.0 - h)[0]) / (2 * h), rel=1e-6)
    with pytest.raises(ParameterError, match="Stribeck.*w_s"):
        Stribeck(mu_s=0.5, mu_k=0.3, w_s=0.0)
    with pytest.raises(ParameterError, match="Stribeck.*mu_k"):
        Stribeck(mu_s=0.5, mu_k=-0.3, w_s=1.0)
    with pytest.raises(ParameterError, match="Stribeck.*delta"):
        Stribeck(mu_s=0.5, mu_k=0.3, w_s=1.0, delta=0.5)
    with pytest.raises(ParameterError, match="Clutch 'c'.*mu_law"):
        Clutch("c", fn_max=1.0, mu_law=[(0, 0.5)])
    fc = FrictionContact("fc", fn=10.0, mu_law=law)
    assert fc.kinetic(2.0, 0.0)[0] == pytest.approx(10.0 * law.mu(2.0)[0])


# ------------------------------------------------------------------ vehicle load, linear brake

def test_vehicle_load_formula_with_grade_and_wind():
    m, c_r, c_drag = 1200.0, 0.012, 0.4
    grade = Table([(0.0, 0.0), (1.0, 0.08)])
    wind = Sine(amplitude=4.0, freq_hz=0.5)
    mod = rm.Model("vl")
    sp = mod.add(LinearSpeed("sp", v_ref=15.0))
    body = mod.add(Mass("body", m=m))
    vl = mod.add(VehicleLoad("vl", m=m, c_r=c_r, c_drag=c_drag, grade=grade, wind=wind))
    mod.connect(sp.flange, body.flange_a)
    mod.connect(body.flange_b, vl.flange)
    res = mod.simulate(t_end=2.0, dt_out=0.05, **TIGHT)
    g = 9.80665
    for k in range(len(res.t)):
        t = res.t[k]
        a, w = grade.value(t), wind.value(t)
        f = c_r * m * g * math.cos(a) * math.tanh(15.0 / 0.1) + c_drag * (15.0 - w) * abs(15.0 - w) + m * g * math.sin(a)
        assert res["vl.f"][k] == pytest.approx(f, rel=1e-9)


def test_vehicle_load_coasts_and_books_close():
    mod = rm.Model("coast")
    body = mod.add(Mass("body", m=1000.0, s0=0.0, v0=20.0))
    vl = mod.add(VehicleLoad.for_vehicle("vl", m=1000.0, c_r=0.01, c_d=0.3, area=2.0,
                                         grade=Table([(0, 0.0), (5, -0.03)]), wind=Step(height=-5.0, start_time=2.0)))
    mod.connect(body.flange_b, vl.flange)
    res = mod.simulate(t_end=10.0, dt_out=0.01, **TIGHT)
    assert not energy_checks(res, mod, rel=1e-8)
    with pytest.raises(ParameterError, match="VehicleLoad 'v'.*grade"):
        VehicleLoad("v", m=1000.0, grade=2.0)
    with pytest.raises(ParameterError, match="VehicleLoad 'v'.*area"):
        VehicleLoad.for_vehicle("v", m=1000.0, c_r=0.01, c_d=0.3, area=-2.0)


def test_linear_brake_stops_a_mass_and_holds():
    """Kinetic force mu fn: v(t) = v0 - mu fn t / m until it stops at m v0 / (mu fn), then Stuck;
    a force ramp later breaks it loose at peak * mu * fn."""
    m, v0, mu, fn = 10.0, 3.0, 0.4, 50.0
    mod = rm.Model("lb")
    body = mod.add(Mass("body", m=m, s0=0.0, v0=v0))
    push = mod.add(Force("push", f=Ramp(height=100.0, duration=1.0, start_time=3.0)))
    lb = mod.add(LinearBrake("lb", mu=mu, peak=1.5, fn_max=fn))
    mod.connect(body.flange_b, lb.flange)
    mod.connect(push.flange, body.flange_a)
    res = mod.simulate(t_end=4.0, dt_out=1e-3, **TIGHT)
    t_stop = m * v0 / (mu * fn)
    assert [(e.old_mode, e.new_mode) for e in res.events] == [(1, 0), (0, 1)]
    assert res.events[0].t == pytest.approx(t_stop, abs=1e-8)
    assert res.events[1].t == pytest.approx(3.0 + 1.5 * mu * fn / 100.0, abs=1e-8)
    k = np.searchsorted(res.t, 0.5)
    assert res["body.v"][k] == pytest.approx(v0 - mu * fn * res.t[k] / m, rel=1e-9)
    assert not energy_checks(res, mod, rel=1e-8)
    with pytest.raises(ParameterError, match="LinearBrake 'b'.*cgeo"):
        LinearBrake("b", fn_max=1.0, cgeo=2.0)


# ------------------------------------------------------------------ prescribed acceleration

def test_accelerate_follows_the_integral_and_needs_the_inertia_torque():
    from regmech.components import Accelerate, LinearAccelerate
    J = 0.5
    mod = rm.Model("acc")
    src = mod.add(Accelerate("src", a_ref=Step(height=-4.0, start_time=0.5, offset=2.0), w0=1.0))
    body = mod.add(Inertia("body", J=J))
    mod.connect(src.flange, body.flange_a)
    res = mod.simulate(1.0, dt_out=0.01, **TIGHT)
    expect = np.where(res.t <= 0.5, 1.0 + 2.0 * res.t, 2.0 - 2.0 * (res.t - 0.5))
    assert np.max(np.abs(res["body.w"] - expect)) < 1e-9
    k = np.searchsorted(res.t, 0.25)
    assert abs(res["src.tau"][k]) == pytest.approx(J * 2.0, rel=1e-9)
    assert not energy_checks(res, mod, rel=1e-8)
    lin = rm.Model("lin")
    s2 = lin.add(LinearAccelerate("s2", a_ref=Sine(amplitude=2.0, freq_hz=1.0), v0=0.5))
    M = lin.add(Mass("M", m=2.0))
    lin.connect(s2.flange, M.flange_a)
    r2 = lin.simulate(1.0, dt_out=0.01, **TIGHT)
    assert np.max(np.abs(r2["M.v"] - (0.5 + 2.0 / (2 * np.pi) * (1 - np.cos(2 * np.pi * r2.t))))) < 1e-9
    s2.v0 = 1.5                                  # the reference follows a changed start speed
    r3 = lin.simulate(0.5, dt_out=0.25, **TIGHT)
    assert r3["M.v"][0] == pytest.approx(1.5)
    with pytest.raises(ParameterError, match="Accelerate 'x'.*a_ref"):
        Accelerate("x")


def test_elastogap_rotational_units():
    """ElastoGap is written for translational flanges; a rotational one reads its parameters in rotational units
    (it showed N/m, N s/m and m before), and its docstring names the rotational units."""
    rot = ElastoGap("g", c=1.0e4, domain="rotational")
    assert (rot.param_unit("c"), rot.param_unit("d"), rot.param_unit("phi_rel0")) == ("N m/rad", "N m s/rad", "rad")
    lin = ElastoGap("g", c=1.0e4)
    assert (lin.param_unit("c"), lin.param_unit("d"), lin.param_unit("phi_rel0")) == ("N/m", "N s/m", "m")
    assert "[N m/rad] when rotational" in ElastoGap.__doc__
    with pytest.raises(rm.ParameterError, match=r"N m/rad"):
        ElastoGap("g", c=-1.0, domain="rotational")
