"""Causal blocks inside the DAE (regmech.blocks): closed loops, events, sampling and the refusals."""

import math
import pickle

import numpy as np
import pytest

import regmech as rm
from regmech.blocks import (PI, PID, Compare, Constant, Feedback, Gain, Integrator, Lag, Max, Min, Product,
                            SampleHold, Saturation, SpeedSensor, Sum, Switch, Table1D)
from regmech.components import Clutch, DCMotor, Damper, Fixed, Inertia, Torque
from regmech.errors import ModelError, ParameterError
from regmech.signals import Ramp, Step

W_REF = 100.0


def motor_loop(limits=True, ref=W_REF, J=0.01, d=0.001):
    """SpeedSensor -> PI on the voltage of a DC motor driving an inertia with a viscous load."""
    m = rm.Model("speed_loop")
    inertia = m.add(Inertia("J", J=J))
    visc = m.add(Damper("visc", d=d))
    g = m.add(Fixed("g"))
    m.connect(visc.flange_a, inertia.flange_b)
    m.connect(visc.flange_b, g.flange)
    load = m.add(Torque("load", tau=0.0))          # a load torque on the inertia (an input to linearise by)
    m.connect(load.flange, inertia.flange_b)
    ws = m.add(SpeedSensor("ws"))
    m.connect(ws.flange, inertia.flange_b)
    kw = dict(y_min=-24.0, y_max=24.0) if limits else {}
    pi = m.add(PI("pi", u=ws.y, ref=ref, k=1.0, T_i=0.1, **kw))
    mot = m.add(DCMotor("mot", u=pi.y, R=1.0, L=1e-3, k=0.1))
    m.connect(mot.flange, inertia.flange_a)
    return m


def test_closed_loop_dc_motor_reaches_its_reference():
    res = motor_loop().simulate(4.0)
    w = res["J.w"][-1]
    assert abs(w - W_REF) <= 1e-6 * W_REF
    # the block outputs are result signals; the loop's voltage is the motor's: R d w / k + k w at rest
    assert res["pi.y"][-1] == pytest.approx(1.0 * 0.001 * W_REF / 0.1 + 0.1 * W_REF, rel=1e-6)
    assert res["ws.y"][-1] == pytest.approx(w, rel=1e-12)
    assert res["mot.u"][-1] == pytest.approx(res["pi.y"][-1], rel=1e-12)
    # the start saturates the voltage: reaching and leaving the limit are events of kind "limit"
    assert res["pi.y"][1] == pytest.approx(24.0)
    assert any(e.component == "pi" and e.kind == "limit" for e in res.events)
    assert np.all(res["pi.y"] <= 24.0 + 1e-9)


def test_blocks_refuse_the_native_path_with_a_reason():
    from regmech.solvers.ida_native import eligible
    c = motor_loop().compile()
    why = eligible(c, "dense")
    assert why is not None and "causal blocks" in why


def test_explicit_solver_refuses_block_outputs_by_name():
    with pytest.raises(ModelError, match="causal blocks.*pi.*solver='ida'"):
        motor_loop().simulate(0.1, solver="dop853")


def _driven(tau_block_builder, t_end=1.0, **sim):
    m = rm.Model("driven")
    J = m.add(Inertia("J", J=1.0))
    blk = tau_block_builder(m, J)
    tq = m.add(Torque("tq", tau=blk.y))
    m.connect(tq.flange, J.flange_a)
    return m, m.simulate(t_end, **sim)


def test_static_blocks_compute_their_laws():
    def build(m, J):
        ws = m.add(SpeedSensor("ws"))
        m.connect(ws.flange, J.flange_a)
        c = m.add(Constant("c", k=2.0))
        fb = m.add(Feedback("fb", u1=c.y, u2=ws.y))                 # 2 - w
        s = m.add(Sum("s", u1=fb.y, u2=1.0, k2=-0.5))             # 1.5 - w
        p = m.add(Product("p", u1=s.y, u2=2.0))                   # 3 - 2 w
        mn = m.add(Min("mn", u1=p.y, u2=1.0))
        mx = m.add(Max("mx", u1=mn.y, u2=-1.0))
        return m.add(Gain("gain", u=mx.y, k=1.0))
    m, res = _driven(build, t_end=3.0, dt_out=0.01)
    w = res["J.w"]
    assert np.allclose(res["p.y"], 3 - 2 * w, atol=1e-12)
    assert np.allclose(res["mn.y"], np.minimum(3 - 2 * w, 1.0), atol=1e-12)
    assert np.allclose(res["mx.y"], np.maximum(np.minimum(3 - 2 * w, 1.0), -1.0), atol=1e-12)
    # w' = min(3 - 2w, 1): w = t until w = 1, then w -> 1.5 with the time constant 0.5 s
    t = res.t
    expect = np.where(t <= 1.0, t, 1.5 - 0.5 * np.exp(-2.0 * (t - 1.0)))
    assert np.max(np.abs(w - expect)) < 1e-4
    assert any(e.component == "mn" for e in res.events)


def test_saturation_switch_compare_and_table():
    def build(m, J):
        ws = m.add(SpeedSensor("ws"))
        m.connect(ws.flange, J.flange_a)
        tab = m.add(Table1D("tab", u=ws.y, table=[[0.0, 1.0], [1.0, 3.0], [2.0, 0.0]]))
        cmp_ = m.add(Compare("cmp", u=ws.y, ref=1.5))
        sw = m.add(Switch("sw", u1=2.5, u2=cmp_.y, u3=tab.y, threshold=0.5))
        return m.add(Saturation("sat", u=sw.y, y_min=-0.5, y_max=2.0))
    m, res = _driven(build, t_end=3.0, dt_out=0.01)
    w = res["J.w"]
    table = np.interp(w, [0.0, 1.0, 2.0], [1.0, 3.0, 0.0])
    assert np.allclose(res["tab.y"], table, atol=1e-12)
    assert np.allclose(res["sat.y"], np.clip(np.where(w > 1.5, 2.5, table), -0.5, 2.0), atol=1e-9)
    # past w = 1.5 the switch drives with the upper limit 2 (the table alone would settle at w = 2)
    t_switch = next(e.t for e in res.events if e.component == "cmp")
    assert w[-1] == pytest.approx(1.5 + 2.0 * (3.0 - t_switch), rel=1e-5)
    assert any(e.component == "sat" for e in res.events)


def test_lag_and_integrator():
    def build(m, J):
        lag = m.add(Lag("lag", u=Step(2.0, 0.0), T=0.2))
        integ = m.add(Integrator("int", u=lag.y, k=1.0, y_max=1.0))
        return integ
    m, res = _driven(build, t_end=2.0, dt_out=0.01)
    t = res.t
    assert np.max(np.abs(res["lag.y"] - 2.0 * (1 - np.exp(-t / 0.2)))) < 1e-4
    integral = 2.0 * (t - 0.2 * (1 - np.exp(-t / 0.2)))
    assert np.max(np.abs(res["int.y"] - np.minimum(integral, 1.0))) < 1e-4
    assert any(e.component == "int" and e.kind == "limit" for e in res.events)


def test_sample_and_hold_holds_the_input_of_the_last_sample_instant():
    T = 0.1

    def build(m, J):
        return m.add(SampleHold("sh", u=Ramp(height=1.0, duration=1.0), T=T))
    m, res = _driven(build, t_end=1.0, dt_out=0.025)
    t, y = res.t, res["sh.y"]
    between = np.abs(t / T - np.round(t / T)) > 1e-6
    assert np.allclose(y[between], np.floor(t[between] / T) * T, atol=1e-12)
    # at each sample instant two rows: the value held until then, and the new sample
    for k in range(1, 10):
        rows = np.nonzero(np.abs(t - k * T) < 1e-12)[0]
        assert len(rows) == 2
        assert y[rows[0]] == pytest.approx((k - 1) * T, abs=1e-12)
        assert y[rows[1]] == pytest.approx(k * T, abs=1e-12)
    # the torque is a staircase, so the speed is the sum of the held values times the time
    assert res["J.w"][-1] == pytest.approx(sum(T * k * T for k in range(10)), rel=1e-6)


def test_sampled_pi_loop_runs_and_holds_the_reference():
    m = motor_loop(limits=True)
    pi = m["pi"]
    sh = m.add(SampleHold("sh", u=pi.y, T=0.002))
    m["mot"].u = sh.y
    res = m.simulate(3.0)
    assert abs(res["J.w"][-1] - W_REF) <= 1e-6 * W_REF


def test_clutch_normal_force_from_a_block():
    m = rm.Model("clutch")
    J1 = m.add(Inertia("J1", J=1.0, w0=10.0))
    J2 = m.add(Inertia("J2", J=1.0))
    lag = m.add(Lag("lag", u=Step(0.9, 0.2), T=0.1))
    cl = m.add(Clutch("cl", f_normalized=lag.y, mu=0.3, fn_max=100.0, cgeo=1.0))
    m.connect(cl.flange_a, J1.flange_b)
    m.connect(cl.flange_b, J2.flange_a)
    res = m.simulate(2.0)
    # it engages, then sticks once the speeds meet (momentum conserved: both at 5 rad/s)
    assert res["J1.w"][-1] == pytest.approx(5.0, rel=1e-6)
    assert res["J2.w"][-1] == pytest.approx(5.0, rel=1e-6)
    assert res["lag.y"][-1] == pytest.approx(0.9 * (1 - math.exp(-1.8 / 0.1)), rel=1e-4)


def test_pid_with_filtered_derivative_reaches_the_reference():
    m = motor_loop(limits=True)
    ws = m["ws"]
    pid = m.add(PID("pid", u=ws.y, ref=50.0, k=0.5, T_i=0.1, T_d=0.01, N=10.0, y_min=-24.0, y_max=24.0))
    m["mot"].u = pid.y
    res = m.simulate(8.0)
    assert abs(res["J.w"][-1] - 50.0) <= 1e-6 * 50.0


def test_compiled_model_with_blocks_pickles():
    m = motor_loop()
    c = m.compile()
    c2 = pickle.loads(pickle.dumps(c))
    y, yp = c.initial_y(0.0)
    r1, r2 = np.zeros(c.N), np.zeros(c.N)
    c.residual(0.0, y, yp, r1)
    c2.residual(0.0, y, yp, r2)
    assert np.array_equal(r1, r2)


# -- bad input: each a named error with the block and the fix -----------------------------------------------
def test_unconnected_input_is_named():
    with pytest.raises(ParameterError, match=r"PI 'pi': input 'u' is not connected; give it u=<block>.y"):
        PI("pi", ref=1.0, k=1.0, T_i=1.0)


def test_algebraic_loop_is_refused_naming_the_blocks():
    m = rm.Model("loop")
    J = m.add(Inertia("J", J=1.0))
    a = m.add(Gain("a", u=0.0, k=0.5))
    b = m.add(Gain("b", u=a.y, k=0.5))
    a.u = b.y
    tq = m.add(Torque("tq", tau=b.y))
    m.connect(tq.flange, J.flange_a)
    with pytest.raises(ModelError, match=r"algebraic loop.*Gain 'a'.*Gain 'b'.*Lag"):
        m.simulate(1.0)


def test_loop_through_a_lag_is_no_algebraic_loop():
    m = rm.Model("loop")
    J = m.add(Inertia("J", J=1.0))
    a = m.add(Gain("a", u=0.0, k=-1.0))
    lag = m.add(Lag("lag", u=a.y, T=0.1))
    s = m.add(Sum("s", u1=lag.y, u2=1.0))
    a.u = s.y                       # y_lag' = (-(y_lag + 1) - y_lag) / T: y_lag -> -0.5
    tq = m.add(Torque("tq", tau=s.y))
    m.connect(tq.flange, J.flange_a)
    res = m.simulate(2.0)
    assert res["lag.y"][-1] == pytest.approx(-0.5, rel=1e-6)


@pytest.mark.parametrize("period", [0.0, -0.01])
def test_sample_period_must_be_positive(period):
    with pytest.raises(ParameterError, match=r"SampleHold 'sh': the sample period T must be > 0"):
        SampleHold("sh", u=1.0, T=period)


def test_table_with_unsorted_breakpoints_is_named():
    with pytest.raises(ParameterError, match=r"Table1D 'tab': the breakpoints x must be strictly increasing.*sort"):
        Table1D("tab", u=1.0, table=[[0, 0], [2, 1], [1, 3]])


def test_block_output_of_the_wrong_unit_is_named():
    ws = SpeedSensor("ws")
    with pytest.raises(ParameterError, match=r"DCMotor 'mot': parameter 'u' is in \[V\] but ws.y is in \[rad/s\]"):
        DCMotor("mot", u=ws.y, R=1.0, L=1e-3, k=0.1)


def test_block_not_in_the_model_is_named():
    m = rm.Model("m")
    J = m.add(Inertia("J", J=1.0))
    g = Gain("g", u=1.0, k=1.0)
    tq = m.add(Torque("tq", tau=g.y))
    m.connect(tq.flange, J.flange_a)
    with pytest.raises(ModelError, match=r"Gain 'g' is not part of this model"):
        m.simulate(1.0)


def test_limits_in_the_wrong_order_are_named():
    with pytest.raises(ParameterError, match=r"Saturation 'sat': needs y_min < y_max"):
        Saturation("sat", u=1.0, y_min=1.0, y_max=0.0)
    with pytest.raises(ParameterError, match=r"PI 'pi': needs y_min < y_max"):
        PI("pi", u=1.0, ref=0.0, k=1.0, T_i=1.0, y_min=2.0, y_max=1.0)


def test_engine_idle_speed_loop_through_a_throttle_actuator_lag():
    from regmech.components import Engine
    m = rm.Model("idle")
    J = m.add(Inertia("J", J=0.2, w0=80.0))
    ws = m.add(SpeedSensor("ws"))
    m.connect(ws.flange, J.flange_b)
    pi = m.add(PI("idle", u=ws.y, ref=85.0, k=0.05, T_i=0.5, y_min=0.0, y_max=1.0))
    act = m.add(Lag("act", u=pi.y, T=0.05))
    eng = m.add(Engine("eng", torque_map=[[0, 100], [300, 150], [600, 100]], drag_map=[[0, -10], [600, -40]],
                       throttle=act.y))
    load, g = m.add(Damper("load", d=0.5)), m.add(Fixed("g"))
    m.connect(eng.flange, J.flange_a)
    m.connect(J.flange_b, load.flange_a)
    m.connect(load.flange_b, g.flange)
    res = m.simulate(10.0)
    assert abs(res["J.w"][-1] - 85.0) <= 1e-6 * 85.0
    # at rest the engine's torque carries the load: thr T_full(w) + (1 - thr) T_drag(w) = d w
    w, thr = 85.0, res["act.y"][-1]
    full, drag = np.interp(w, [0, 300, 600], [100, 150, 100]), np.interp(w, [0, 600], [-10, -40])
    assert thr * full + (1 - thr) * drag == pytest.approx(0.5 * w, rel=1e-6)


def test_relay_with_hysteresis_holds_the_speed_between_its_levels():
    from regmech.blocks import Hysteresis
    m = rm.Model("relay")
    J = m.add(Inertia("J", J=1.0))
    d, g = m.add(Damper("d", d=1.0)), m.add(Fixed("g"))
    m.connect(J.flange_b, d.flange_a)
    m.connect(d.flange_b, g.flange)
    ws = m.add(SpeedSensor("ws"))
    m.connect(ws.flange, J.flange_b)
    rel = m.add(Hysteresis("rel", u=ws.y, u_low=4.0, u_high=6.0, y_on=0.0, y_off=10.0))
    tq = m.add(Torque("tq", tau=rel.y))
    m.connect(tq.flange, J.flange_a)
    res = m.simulate(10.0, dt_out=0.01)
    w = res["J.w"]
    # w' = 10 - w while off (from 0 up to 6), w' = -w while on (down to 4): a limit cycle between the levels
    assert w.max() == pytest.approx(6.0, abs=1e-6)
    assert w[res.t > 1.0].min() == pytest.approx(4.0, abs=1e-6)
    t_on = math.log(10.0 / 4.0)                 # first switch: 10 (1 - exp(-t)) = 6
    ups = [e.t for e in res.events if e.kind == "latch" and e.new_mode > 0]
    downs = [e.t for e in res.events if e.kind == "latch" and e.new_mode < 0]
    assert ups[0] == pytest.approx(t_on, abs=1e-6)
    # each half cycle: down from 6 to 4 takes ln(6/4), up from 4 to 6 takes ln(6/4) (10 - w from 6 to 4)
    assert downs[0] - ups[0] == pytest.approx(math.log(1.5), abs=1e-6)
    assert ups[1] - downs[0] == pytest.approx(math.log(1.5), abs=1e-6)


def test_shift_schedule_shifts_on_its_lines_without_hunting():
    from regmech.blocks import ShiftSchedule, VelocitySensor
    from regmech.components import Force, Mass
    from regmech.signals import Sine
    m = rm.Model("schedule")
    car = m.add(Mass("car", m=1.0))
    vs = m.add(VelocitySensor("vs"))
    m.connect(vs.flange, car.flange_a)
    sch = m.add(ShiftSchedule("sch", v=vs.y, thr=0.5, up=[[5, 10], [10, 20]], down=[[3, 6], [6, 12]]))
    f = m.add(Force("f", f=Sine(amplitude=5.0, freq_hz=0.05)))
    m.connect(f.flange, car.flange_b)
    res = m.simulate(20.0, dt_out=0.05, accuracy=1e-8)
    # v = (5 / omega) (1 - cos(omega t)): up lines at thr 0.5: 7.5 and 15, down lines 4.5 and 9
    omega = 2 * math.pi * 0.05
    shifts = [(e.t, e.new_mode) for e in res.events if e.component == "sch"]
    assert [s for _, s in shifts] == [1, 1, -1, -1]
    for (t, _), level in zip(shifts, (7.5, 15.0, 9.0, 4.5)):
        assert 5.0 / omega * (1 - math.cos(omega * t)) == pytest.approx(level, abs=1e-6)
    assert res["sch.y"].max() == 3.0 and res["sch.y"][-1] == 1.0


def test_shift_schedule_refuses_overlapping_lines_and_hysteresis_levels():
    from regmech.blocks import Hysteresis, ShiftSchedule
    with pytest.raises(ParameterError, match=r"ShiftSchedule 'sch': the down line of gear 2 .* below the up line"):
        ShiftSchedule("sch", v=1.0, up=[[5, 10]], down=[[6, 8]])
    with pytest.raises(ParameterError, match=r"Hysteresis 'h': needs u_low < u_high"):
        Hysteresis("h", u=1.0, u_low=2.0, u_high=1.0)


def test_gearbox_follows_a_shift_schedule_block():
    from regmech.blocks import ShiftSchedule
    from regmech.components import Gearbox
    m = rm.Model("car")
    eng = m.add(Inertia("eng", J=0.2))
    drive = m.add(Torque("drive", tau=30.0))
    m.connect(drive.flange, eng.flange_a)
    car = m.add(Inertia("car", J=5.0))
    drag, g = m.add(Damper("drag", d=0.5)), m.add(Fixed("g"))
    m.connect(car.flange_b, drag.flange_a)
    m.connect(drag.flange_b, g.flange)
    ws = m.add(SpeedSensor("ws"))
    m.connect(ws.flange, car.flange_a)
    sch = m.add(ShiftSchedule("sch", v=ws.y, thr=0.5, up=[[5, 10], [10, 20]], down=[[3, 6], [6, 12]]))
    box = m.add(Gearbox("box", ratios=[3.0, 2.0, 1.0], capacity=400.0, gear=sch.y, gear0=1))
    m.connect(eng.flange_b, box.flange_a)
    m.connect(box.flange_b, car.flange_a)
    assert box.schedule is None
    res = m.simulate(10.0, dt_out=0.05)
    ups = [e.t for e in res.events if e.component == "sch"]
    assert len(ups) == 2                      # 1 -> 2 at 7.5 rad/s, 2 -> 3 at 15 rad/s, no hunting after
    assert res.at("car.w", ups[0]) == pytest.approx(7.5, rel=1e-6)
    assert res.at("car.w", ups[1]) == pytest.approx(15.0, rel=1e-6)
    # in third gear (ratio 1) the engine turns with the car once the element has locked
    assert res["eng.w"][-1] == pytest.approx(res["car.w"][-1], rel=1e-6)
    assert any(e.component == "box.shift3" and e.new_mode == 0 for e in res.events)
