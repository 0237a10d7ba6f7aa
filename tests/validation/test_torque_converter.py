"""TorqueConverter / ConverterFluid against the closed forms of the K-factor description:
stall point, coupling point, traction and overrun torques, lock-up, energy books."""

import math

import numpy as np
import pytest

import regmech as rm
from regmech.bench.fuzz import energy_checks
from regmech.components import Damper, Fixed, Inertia, Speed, Torque
from regmech.components.converter import K_TABLE, TR_TABLE, ConverterFluid, TorqueConverter
from regmech.errors import ParameterError
from regmech.signals import Ramp, Table

K = np.array(K_TABLE)
TR = np.array(TR_TABLE)


def c_of(nu):
    """1/K^2 interpolated linearly, falling to 0 at nu = 1 (the documented convention), held below 0."""
    xs = np.append(K[:, 0], 1.0)
    ys = np.append(1.0 / K[:, 1] ** 2, 0.0)
    return float(np.interp(nu, xs, ys))


def test_stall_point_closed_form():
    """Turbine held: a constant engine torque T settles where T = (w/K(0))^2, i.e. w = K(0) sqrt(T); the
    turbine receives TR(0) T."""
    T = 150.0
    m = rm.Model("stall")
    eng = m.add(Torque("engine", tau=T))
    J_e = m.add(Inertia("J_e", J=0.15, phi0=0.0, w0=30.0))
    tc = m.add(TorqueConverter("tc"))
    g = m.add(Fixed("g"))
    m.connect(eng.flange, J_e.flange_a)
    m.connect(J_e.flange_b, tc.pump)
    m.connect(tc.turbine, g.flange)
    res = m.simulate(t_end=4.0, dt_out=1e-2, solver="ida", rtol=1e-9, atol=1e-9)
    w_stall = K[0, 1] * math.sqrt(T)
    assert res["J_e.w"][-1] == pytest.approx(w_stall, rel=1e-6)
    assert res["tc.fluid.tau"][-1] == pytest.approx(T, rel=1e-6)
    assert -res["tc.fluid.turbine.tau"][-1] == pytest.approx(TR[0, 1] * T, rel=1e-6)
    # the engine speed rises monotonically to the stall speed (first-order lag, no overshoot)
    assert np.all(np.diff(res["J_e.w"]) >= -1e-9)
    assert not energy_checks(res, m, rel=1e-6)


def _two_speeds(w_p, w_t):
    m = rm.Model("speeds")
    sp = m.add(Speed("sp", w_ref=w_p))
    st = m.add(Speed("st", w_ref=w_t))
    Jp = m.add(Inertia("Jp", J=0.1))
    Jt = m.add(Inertia("Jt", J=0.1))
    fl = m.add(ConverterFluid("fluid"))
    m.connect(sp.flange, Jp.flange_a)
    m.connect(st.flange, Jt.flange_a)
    m.connect(Jp.flange_b, fl.pump)
    m.connect(fl.turbine, Jt.flange_b)
    res = m.simulate(t_end=0.1, dt_out=0.05, solver="ida", rtol=1e-10, atol=1e-10)
    return res["fluid.tau"][-1], -res["fluid.turbine.tau"][-1], res["fluid.power"][-1]


@pytest.mark.parametrize("nu", [0.0, 0.3, 0.5, 0.7, 0.9])
def test_traction_torques_follow_the_tables(nu):
    w_p = 220.0
    tau_p, tau_t, power = _two_speeds(w_p, nu * w_p)
    assert tau_p == pytest.approx(w_p ** 2 * c_of(nu), rel=1e-9)
    assert tau_t == pytest.approx(np.interp(nu, TR[:, 0], TR[:, 1]) * tau_p, rel=1e-9)
    assert power == pytest.approx(tau_p * w_p - tau_t * nu * w_p, rel=1e-9)
    assert power >= 0.0


def test_coupling_point_equal_torques():
    """At the coupling point (TR = 1, nu_c = 0.85) pump and turbine torques are equal: (w_p/K(nu_c))^2."""
    w_p = 300.0
    tau_p, tau_t, _ = _two_speeds(w_p, 0.85 * w_p)
    assert tau_p == pytest.approx((w_p / 19.0) ** 2, rel=1e-9)
    assert tau_t == pytest.approx(tau_p, rel=1e-9)     # nu is regularised by (w_eps/w_p)^2 ~ 1e-11


@pytest.mark.parametrize("ratio", [1.05, 1.2, 2.0])
def test_overrun_turbine_drives_the_pump(ratio):
    """Overrun: tau_t = w_t^2 c(w_p/w_t), torque ratio 1; the pump is driven (negative absorbed torque)."""
    w_p = 150.0
    w_t = ratio * w_p
    tau_p, tau_t, power = _two_speeds(w_p, w_t)
    expect = w_t ** 2 * c_of(1.0 / ratio)
    assert tau_p == pytest.approx(-expect, rel=1e-9)
    assert tau_t == pytest.approx(-expect, rel=1e-9)
    assert power == pytest.approx(expect * (w_t - w_p), rel=1e-9)
    assert power > 0.0


def test_continuous_at_speed_ratio_one():
    w = 200.0
    below = _two_speeds(w, w * (1 - 1e-7))[0]
    above = _two_speeds(w, w * (1 + 1e-7))[0]
    # both sides tend to zero at nu = 1, linearly in the distance to it (no jump between traction and overrun)
    assert 0 < below == pytest.approx(w ** 2 * c_of(1 - 1e-7), rel=1e-2)   # w_rel of 2e-5 rad/s: the speed error matters
    assert 0 > above == pytest.approx(-(w * (1 + 1e-7)) ** 2 * c_of(1 / (1 + 1e-7)), rel=1e-2)
    assert abs(below) < 1e-3 and abs(above) < 1e-3


def _launch(lockup, t_end=4.0, engine=None, drag=0.0):
    m = rm.Model("tc_launch")
    eng = m.add(Torque("engine", tau=engine if engine is not None else 180.0))
    J_e = m.add(Inertia("J_e", J=0.15, phi0=0.0, w0=80.0))
    tc = m.add(TorqueConverter("tc", lockup=lockup, lockup_capacity=500.0))
    veh = m.add(Inertia("veh", J=8.0, phi0=0.0, w0=0.0))
    load = m.add(Damper("load", d=1.0))
    g = m.add(Fixed("g"))
    m.connect(eng.flange, J_e.flange_a)
    m.connect(J_e.flange_b, tc.pump)
    m.connect(tc.turbine, veh.flange_a)
    m.connect(veh.flange_b, load.flange_a)
    m.connect(load.flange_b, g.flange)
    if drag:
        fr = m.add(Damper("engine_drag", d=drag))
        m.connect(J_e.flange_b, fr.flange_a)
        m.connect(fr.flange_b, g.flange)
    return m


def test_lockup_engages_slips_and_locks():
    m = _launch(Ramp(height=1.0, duration=0.5, start_time=2.0))
    res = m.simulate(t_end=4.0, dt_out=2e-3, solver="ida", rtol=1e-8, atol=1e-8)
    modes = res["tc.lockup.mode"]
    t = res.t
    assert np.all(modes[t < 2.0] == 2)                   # open: the fluid carries everything
    assert set(np.unique(modes[(t > 2.0)])) >= {0}       # locks in the end
    kinds = [(e.component, e.new_mode) for e in res.events]
    assert ("tc.lockup", -1) in [(c, int(n)) for c, n in kinds]   # slipping first (turbine slower)
    k = np.searchsorted(t, 3.9)
    assert res["tc.pump.w"][k] == pytest.approx(res["tc.turbine.w"][k], rel=1e-9)
    assert not energy_checks(res, m, rel=1e-6)
    # with the clutch locked the fluid transmits nothing (nu = 1)
    assert abs(res["tc.fluid.tau"][k]) < 1e-6


def test_overrun_in_a_coast_down_and_books():
    """Engine torque cut at 2 s: the vehicle drives the engine through the fluid (overrun, negative pump torque)."""
    m = _launch(0.0, engine=Table([(0.0, 180.0), (2.0, 180.0), (2.0, 0.0)]), drag=0.5)
    res = m.simulate(t_end=4.0, dt_out=2e-3, solver="ida", rtol=1e-8, atol=1e-8)
    late = res.t > 2.5
    assert np.all(res["tc.turbine.w"][late] > res["tc.pump.w"][late])
    assert np.all(res["tc.fluid.tau"][late] < 0)
    assert np.all(res["tc.fluid.power"] >= -1e-6)
    assert not energy_checks(res, m, rel=1e-6)


def test_table_errors_name_the_converter():
    with pytest.raises(ParameterError, match="ConverterFluid 'f'.*K_table"):
        ConverterFluid("f", K_table=[(0.1, 14.0), (0.5, 15.0)])
    with pytest.raises(ParameterError, match="K_table"):
        ConverterFluid("f", K_table=[(0.0, 14.0), (1.0, 15.0)])
    with pytest.raises(ParameterError, match="efficiency"):
        ConverterFluid("f", TR_table=[(0.0, 2.0), (0.9, 1.5)])
    with pytest.raises(ParameterError, match="K_table"):
        TorqueConverter("tc", K_table=[(0.0, -1.0)])
    f = ConverterFluid("f")
    with pytest.raises(ParameterError, match="cannot be changed"):
        f.K_table = [(0.0, 10.0)]
    with pytest.raises(ParameterError, match="lockup"):
        TorqueConverter("tc", lockup=2.0)


def test_fluid_classes_shared_per_table_and_picklable():
    import pickle
    a, b = ConverterFluid("a"), ConverterFluid("b")
    c = ConverterFluid("c", K_table=[(0.0, 12.0), (0.8, 18.0)])
    assert type(a) is type(b) and type(a) is not type(c)
    assert isinstance(c, ConverterFluid)
    d = pickle.loads(pickle.dumps(c))
    assert type(d) is type(c) and np.array_equal(d.K_table, c.K_table)


@pytest.mark.parametrize("w_p, w_t", [(100.0, -100.0 * (1 - 1e-7)), (100.0, -100.0 * (1 + 1e-7))])
def test_counter_rotation_is_continuous_and_dissipative(w_p, w_t):
    """Turbine backwards (nu < 0): TR goes from TR(0) to 1 at nu = -1, where the overrun law takes over
    (|w_t| = |w_p|): both torques continuous there (a fuzz model crossed it with the old held TR(0), a
    jump of the turbine torque by TR(0) - 1, and IDA failed)."""
    tau_p, tau_t, power = _two_speeds(w_p, w_t)
    expect = w_p ** 2 * c_of(0.0)
    assert tau_p == pytest.approx(expect, rel=1e-5)
    assert tau_t == pytest.approx(expect, rel=1e-5)       # TR = 1 on both sides of nu = -1
    assert power > 0
    mid = _two_speeds(100.0, -50.0)
    tr = TR[0, 1] + (TR[0, 1] - 1.0) * (-0.5)
    assert mid[1] == pytest.approx(tr * mid[0], rel=1e-9)


@pytest.mark.parametrize("w", [1.0, 50.0])
def test_no_jump_between_traction_and_overrun_at_equal_speeds(w):
    """At w_t = w_p the speed ratio is exactly 1 in both branches, so traction and overrun both give zero torque
    with the same slope. The former regularisation nu = w_t w_p / (w_p^2 + w_eps^2) made nu = 1 - w_eps^2 / w^2
    at equal speeds: +-7.9e-8 N m on either side of a slip of 1e-12 (any speed), which a locked lock-up clutch
    flipped at every Newton iterate (fuzz seed 10034: IDA failed at rtol 1e-8)."""
    d = 1e-12 * w
    below, above = _two_speeds(w, w - d)[0], _two_speeds(w, w + d)[0]
    slope = w * (1.0 / K[-1, 1] ** 2) / (1.0 - K[-1, 0])        # |d tau_p / d w_t| at nu = 1: c's slope times w
    assert below == pytest.approx(slope * d, rel=1e-3)           # linear in the slip, the same on both sides
    assert above == pytest.approx(-slope * d, rel=1e-3)


@pytest.mark.parametrize("w", [2.3886, 50.0, 0.01])
def test_no_jump_between_traction_and_overrun_in_counter_rotation(w):
    """At w_t = -w_p the turbine torque is continuous to round-off: the regularised speed ratio is -1 + 2 w_eps^2 /
    (w_p^2 + w_eps^2) there, and the deep-stall torque ratio, a line in it, reached 1 + (TR(0) - 1) 2 w_eps^2 /
    w_p^2 only: a jump of the turbine torque by (TR(0) - 1) 2 w_eps^2 c(0) (7e-8 N m on fuzz seed 60009, at
    any speed) that IDA could not step over at rtol 1e-10. Either side of the crossing, the slopes differ (a kink,
    a switching surface), the values do not; both torques stay within the slope times the distance."""
    d = 1e-9 * w
    inside, beyond = _two_speeds(w, -w + d), _two_speeds(w, -w - d)
    scale = w * w * c_of(0.0)
    for k in (0, 1):
        assert abs(inside[k] - beyond[k]) < 20 * d * w * c_of(0.0) + 1e-15 * scale, k
    assert inside[2] > 0 and beyond[2] > 0


def test_locked_lockup_runs_under_ida_at_tight_tolerance():
    """Fuzz seed 10034's converter part: the lock-up clutch holds pump and turbine from the start while a
    Gearbox in neutral idles behind it; IDA refused it ('corrector convergence failed', at t = 6e-4 s at rtol
    1e-8) because of the jump above. Now it runs, with DOP853's answer."""
    def build():
        m = rm.Model("locked")
        J1 = m.add(Inertia("J1", J=5.223))
        tc = m.add(TorqueConverter("tc", K_table=[(0.0, 7.019), (0.5, 7.721), (0.9, 11.23)],
                                   TR_table=[(0.0, 1.754), (0.85, 1.0), (1.0, 1.0)], J_pump=0.5276,
                                   J_turbine=0.08671, lockup=0.9166, lockup_capacity=27.74))
        J2 = m.add(Inertia("J2", J=0.05149))
        drive = m.add(Torque("drive", tau=0.8156))
        from regmech.components import Gearbox
        gb = m.add(Gearbox("gb", ratios=[2.722, 2.154], gear=[(0.0, 0), (0.2318, 2)], capacity=32.54,
                           efficiency=None, J_in=0.01709, J_out=0.2902, J_gear=0.0009531, release_time=0.07005,
                           engage_time=0.04691, shift_delay=0.05935))
        J3 = m.add(Inertia("J3", J=0.01347, w0=4.424))
        m.connect(tc.pump, J1.flange_a)
        m.connect(tc.turbine, J2.flange_b)
        m.connect(drive.flange, J1.flange_b)
        m.connect(gb.flange_a, tc.turbine)
        m.connect(gb.flange_b, J3.flange_b)
        return m
    ida = build().simulate(t_end=0.6, dt_out=2e-3, solver="ida", rtol=1e-8, atol=1e-10)
    dop = build().simulate(t_end=0.6, dt_out=2e-3, solver="scipy:DOP853", rtol=1e-10, atol=1e-12)
    assert set(ida["tc.lockup.mode"]) == {0.0}
    assert [(e.component, e.new_mode) for e in ida.events] == [(e.component, e.new_mode) for e in dop.events]
    np.testing.assert_allclose(ida["J1.w"], dop["J1.w"], atol=1e-6 * np.ptp(dop["J1.w"]))


def test_counter_rotation_kink_is_an_event_and_ida_crosses_it_at_tight_tolerance():
    """Fuzz seed 60009: the turbine, pulled backwards, overtakes the pump's speed (``w_t = -w_p``), where the
    law's slope jumps. Unwatched, IDA at rtol 1e-10 took a step of 1.3e-22 s there and failed; the crossing is
    now a switching surface: an Event of kind "flow" at the instant the speeds meet, and DOP853's answer."""
    def build():
        m = rm.Model("counter_rotation")
        m.add(Inertia("Jp", J=1.148))
        m.add(Speed("engine", w_ref=2.3886))
        m.add(ConverterFluid("fluid", K_table=[(0.0, 4.725), (0.5, 5.197), (0.9, 7.559)],
                             TR_table=[(0.0, 1.835), (0.85, 1.0), (1.0, 1.0)]))
        m.add(Inertia("Jt", J=0.3, w0=-1.0))
        m.add(Torque("pull", tau=Ramp(height=-2.0, duration=1.0)))
        m.connect("engine.flange", "Jp.flange_a")
        m.connect("fluid.pump", "Jp.flange_b")
        m.connect("fluid.turbine", "Jt.flange_a")
        m.connect("pull.flange", "Jt.flange_b")
        return m
    ida = build().simulate(t_end=2.0, dt_out=2e-3, solver="ida", rtol=1e-10)
    dop = build().simulate(t_end=2.0, dt_out=2e-3, solver="scipy:DOP853", rtol=1e-11)
    flows = [e for e in ida.events if e.kind == "flow"]
    assert [(e.component, e.old_mode, e.new_mode) for e in flows] == [("fluid", 1, 0)]
    # the event sits where w_t + w_p changes sign in the reference
    s = dop["Jt.w"] + dop["Jp.w"]
    k = int(np.nonzero(np.diff(np.sign(s)))[0][0])
    t_cross = dop.t[k] - s[k] * (dop.t[k + 1] - dop.t[k]) / (s[k + 1] - s[k])
    assert abs(flows[0].t - t_cross) < 1e-5
    assert "w_p + w_t > 0 -> w_p + w_t < 0" in str(flows[0])
    np.testing.assert_allclose(ida["Jt.w"], dop["Jt.w"], atol=1e-7 * np.ptp(dop["Jt.w"]))
