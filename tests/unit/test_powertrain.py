"""Engine (torque map x throttle) and RoadLoad (rolling, drag, grade) against closed forms."""

import math
import pickle

import numpy as np
import pytest

import regmech as rm
from regmech.components import Damper, Fixed, Force, Inertia, Mass, Position, Speed
from regmech.components.powertrain import STANDARD_GRAVITY, Engine, RoadLoad
from regmech.signals import Ramp, Step

TORQUE_MAP = [[0.0, 50.0], [100.0, 150.0], [400.0, 200.0], [600.0, 120.0]]   # rad/s, N m
TIGHT = dict(rtol=1e-10, atol=1e-10)


def _engine_on_load(throttle, d_load=0.6, J=0.2, w0=50.0, torque_map=TORQUE_MAP):
    m = rm.Model("engine_load")
    fixed = m.add(Fixed("fixed"))
    engine = m.add(Engine("engine", torque_map=torque_map, throttle=throttle))
    crank = m.add(Inertia("crank", J=J, phi0=0.0, w0=w0))
    load = m.add(Damper("load", d=d_load))
    m.connect(engine.flange, crank.flange_a)
    m.connect(crank.flange_b, load.flange_a)
    m.connect(load.flange_b, fixed.flange)
    return m


def test_engine_torque_follows_the_map_times_throttle():
    # drive the crank along a speed ramp through every segment and beyond both ends
    m = rm.Model("engine_sweep")
    engine = m.add(Engine("engine", torque_map=TORQUE_MAP, throttle=0.7))
    crank = m.add(Inertia("crank", J=0.2))
    drive = m.add(Speed("speed_sweep", w_ref=Ramp(height=700.0, duration=1.0, offset=-50.0)))  # -50 .. 650 rad/s
    m.connect(engine.flange, crank.flange_a)
    m.connect(drive.flange, crank.flange_b)
    res = m.simulate(1.0, dt_out=1e-3, rtol=1e-8, solver="ida")
    w = res["crank.w"]
    xs, ys = np.array(TORQUE_MAP).T
    np.testing.assert_allclose(res["engine.tau"], 0.7 * np.interp(w, xs, ys), rtol=1e-10, atol=1e-9)
    assert w.min() < 0 and w.max() > 600      # held at the end values outside the table
    # the engine acts on its flange with +tau: flange.tau = -tau (MSL Torque)
    np.testing.assert_allclose(res["engine.flange.tau"], -res["engine.tau"])


def test_engine_settles_where_torque_meets_load():
    # on the segment 100..400 rad/s: 0.8 (150 + (w - 100)/6) = 0.6 w
    res = _engine_on_load(throttle=0.8).simulate(20.0, dt_out=0.1, **TIGHT, solver="ida")
    w_eq = (0.8 * (150.0 - 100.0 / 6.0)) / (0.6 - 0.8 / 6.0)
    assert res["crank.w"][-1] == pytest.approx(w_eq, rel=1e-8)
    assert res["engine.tau"][-1] == pytest.approx(0.6 * w_eq, rel=1e-8)


def test_engine_throttle_step_is_a_time_event():
    # throttle 0 -> 1 at t = 0.5: before it the crank coasts down on the damper alone
    res = _engine_on_load(throttle=Step(height=1.0, start_time=0.5)).simulate(1.0, dt_out=0.01, **TIGHT, solver="ida")
    before = res.t <= 0.5
    np.testing.assert_allclose(res["crank.w"][before], 50.0 * np.exp(-0.6 / 0.2 * res.t[before]), rtol=1e-8)
    assert res["crank.w"][-1] > res["crank.w"][before][-1]
    # work of the engine = change of kinetic energy + dissipated in the load
    t = res.t
    trap = lambda y: float(np.sum(np.diff(t) * (y[1:] + y[:-1]) / 2))   # noqa: E731
    work = -trap(res["engine.power"])
    dissipated = trap(res["load.power"])
    d_kin = res["crank.kinetic"][-1] - res["crank.kinetic"][0]
    assert work == pytest.approx(d_kin + dissipated, rel=1e-4)


def test_engines_with_one_map_share_a_class_and_maps_can_change():
    a = Engine("a", torque_map=TORQUE_MAP)
    b = Engine("b", torque_map=np.array(TORQUE_MAP))
    c = Engine("c", torque_map=[[0.0, 10.0], [1.0, 20.0]])
    assert type(a) is type(b) and type(a) is not type(c)
    assert all(isinstance(e, Engine) for e in (a, b, c))
    c.torque_map = TORQUE_MAP
    assert type(c) is type(a)
    res = _engine_on_load(throttle=0.8, torque_map=[[0.0, 10.0], [1.0, 20.0]])
    res["engine"].torque_map = TORQUE_MAP        # the model is rebuilt with the new map
    out = res.simulate(20.0, dt_out=1.0, **TIGHT, solver="ida")
    w_eq = (0.8 * (150.0 - 100.0 / 6.0)) / (0.6 - 0.8 / 6.0)
    assert out["crank.w"][-1] == pytest.approx(w_eq, rel=1e-8)


def test_engine_pickles_with_its_map():
    m = _engine_on_load(throttle=0.5)
    m2 = pickle.loads(pickle.dumps(m))
    e2 = m2["engine"]
    assert type(e2) is type(m["engine"]) and e2.model is m2
    np.testing.assert_array_equal(e2.torque_map, np.array(TORQUE_MAP))


def test_engine_map_errors():
    with pytest.raises(rm.ParameterError, match="Engine 'e'.*increasing"):
        Engine("e", torque_map=[[100.0, 1.0], [50.0, 2.0]])
    with pytest.raises(rm.ParameterError, match="Engine 'e'.*torque_map"):
        Engine("e", torque_map="full load")
    with pytest.raises(rm.ParameterError, match="torque_map.*required"):
        Engine("e")


def _car(force, road: RoadLoad, v0=1.0, m=1500.0):
    model = rm.Model("car")
    car = model.add(Mass("car", m=m, s0=0.0, v0=v0))
    drive = model.add(Force("drive", f=force))
    model.add(road)
    model.connect(drive.flange, car.flange_a)
    model.connect(car.flange_b, road.flange)
    return model


def test_vehicle_reaches_the_speed_where_drive_equals_resistance():
    # m v' = F - f_roll - c v^2 (tanh(v/v_eps) = 1 to 1e-8 for v >= 1 m/s, v_eps = 0.1):
    # v(t) = V tanh(c V t / m + atanh(v0 / V)),  V = sqrt((F - f_roll)/c)
    m, F = 1500.0, 800.0
    road = RoadLoad.for_vehicle("road", m=m, c_r=0.012, c_d=0.3, area=2.2)
    assert road.f_roll == pytest.approx(0.012 * m * STANDARD_GRAVITY)
    assert road.c_drag == pytest.approx(0.5 * 1.2 * 0.3 * 2.2)
    res = _car(F, road).simulate(1200.0, dt_out=2.0, **TIGHT, solver="ida")
    V = math.sqrt((F - road.f_roll) / road.c_drag)
    v_exact = V * np.tanh(road.c_drag * V * res.t / m + math.atanh(1.0 / V))
    np.testing.assert_allclose(res["car.v"], v_exact, rtol=1e-7)
    assert res["car.v"][-1] == pytest.approx(V, rel=1e-6)
    np.testing.assert_allclose(res["road.f"][-1], F, rtol=1e-6)


def test_grade_force_is_conservative_and_rolls_the_car_back():
    # uphill without drive: the car slows, stops, rolls back; height energy is the device's potential
    m = 1000.0
    road = RoadLoad("road", grade=0.05, m=m, f_roll=0.0, c_drag=0.0)
    res = _car(0.0, road, v0=5.0, m=m).simulate(30.0, dt_out=0.01, **TIGHT, solver="ida")
    a = -m * STANDARD_GRAVITY * math.sin(0.05) / m
    np.testing.assert_allclose(res["car.v"], 5.0 + a * res.t, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(res["road.potential"], m * STANDARD_GRAVITY * math.sin(0.05) * res["car.s"],
                               rtol=1e-12, atol=1e-9)
    total = res["car.kinetic"] + res["road.potential"]
    np.testing.assert_allclose(total, total[0], rtol=1e-8)
    assert res["car.v"][-1] < 0


def test_rolling_resistance_smoothing_near_zero_speed():
    # f_roll tanh(v/v_eps): half a percent of the speed scale gives about half a percent of f_roll
    road = RoadLoad("road", f_roll=100.0, v_eps=0.1)
    m = rm.Model("creep")
    car = m.add(Mass("car", m=10.0))
    drive = m.add(Position("push", phi_ref=Ramp(height=0.01, duration=1.0), domain="translational"))
    m.add(road)
    m.connect(drive.flange, car.flange_a)
    m.connect(car.flange_b, road.flange)
    res = m.simulate(0.9, dt_out=0.1, rtol=1e-8, solver="ida")
    np.testing.assert_allclose(res["road.f"][1:], 100.0 * np.tanh(0.01 / 0.1), rtol=1e-10)


def test_road_load_parameter_errors():
    with pytest.raises(rm.ParameterError, match="RoadLoad 'r'.*mass m"):
        RoadLoad("r", grade=0.1)
    with pytest.raises(rm.ParameterError, match="RoadLoad 'r'.*grade"):
        RoadLoad("r", grade=2.0, m=1000.0)
    with pytest.raises(rm.ParameterError, match="RoadLoad 'r'.*v_eps"):
        RoadLoad("r", v_eps=0.0)
    with pytest.raises(rm.ParameterError, match="RoadLoad 'r'.*c_d"):
        RoadLoad.for_vehicle("r", m=1000.0, c_r=0.01, c_d=-0.3, area=2.0)

