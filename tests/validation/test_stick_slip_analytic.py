"""Stick/slip against hand calculations: belt oscillator, clutch lock-up, energy."""

import numpy as np
import pytest
from scipy.integrate import simpson

import regmech as rm
from regmech.components import (Brake, Clutch, Fixed, FrictionContact, Inertia, LinearSpeed, Mass, Spring,
                                 Torque)


def belt_oscillator(m=1.0, k=100.0, mu=0.3, peak=1.5, fn=10.0, v_belt=0.2):
    mod = rm.Model("belt")
    wall = mod.add(Fixed("wall", domain="translational"))
    belt = mod.add(LinearSpeed("belt", v_ref=v_belt))
    block = mod.add(Mass("block", m=m, s0=0.0, v0=v_belt))
    spring = mod.add(Spring("spring", c=k, domain="translational"))
    contact = mod.add(FrictionContact("contact", mu=mu, peak=peak, fn=fn))
    mod.connect(wall.flange, spring.flange_a)
    mod.connect(spring.flange_b, block.flange_a)
    mod.connect(block.flange_b, contact.flange_a)
    mod.connect(contact.flange_b, belt.flange)
    return mod


def test_belt_stick_slip_limit_cycle_phase_durations():
    m, k, mu, peak, fn, vb = 1.0, 100.0, 0.3, 1.5, 10.0, 0.2
    res = belt_oscillator(m, k, mu, peak, fn, vb).simulate(3.0, dt_out=1e-3, rtol=1e-9, solver="ida")
    Fk, Fs = mu * fn, peak * mu * fn
    om = np.sqrt(k / m)
    xk, xb = Fk / k, Fs / k
    delta = xb - xk
    alpha = np.arctan2(om * delta, vb)
    slip = (2 * np.pi - 2 * alpha) / om
    x_end = xk + delta * np.cos(2 * alpha) - vb / om * np.sin(2 * alpha)
    stick = (xb - x_end) / vb
    ev = [(e.t, e.new_mode) for e in res.events if e.component == "contact"]
    starts_slip = [t for t, mnew in ev if mnew != 0]
    starts_stick = [t for t, mnew in ev if mnew == 0]
    assert len(starts_slip) >= 3 and len(starts_stick) >= 3
    # first stick phase starts at x = 0 with the belt's speed: it lasts xb / vb
    assert starts_slip[0] == pytest.approx(xb / vb, abs=1e-7)
    slips = [b - a for a, b in zip(starts_slip, starts_stick)]
    sticks = [b - a for a, b in zip(starts_stick, starts_slip[1:])]
    assert np.allclose(slips, slip, atol=1e-7)
    assert np.allclose(sticks, stick, atol=1e-7)
    # while stuck the block moves with the belt (no drift)
    stuck = res["contact.mode"] == 0
    assert np.max(np.abs(res["block.v"][stuck] - vb)) < 1e-9


def clutch_lockup(T=2.0, fn=5.0, mu=1.0, peak=1.2):
    m = rm.Model("lockup")
    drive = m.add(Torque("drive", tau=T))
    J1 = m.add(Inertia("J1", J=1.0, phi0=0.0, w0=10.0))
    c = m.add(Clutch("clutch", mu=mu, peak=peak, cgeo=1.0, fn_max=fn))
    J2 = m.add(Inertia("J2", J=1.0, phi0=0.0, w0=0.0))
    m.connect(drive.flange, J1.flange_a)
    m.connect(J1.flange_b, c.flange_a)
    m.connect(c.flange_b, J2.flange_a)
    return m


def test_clutch_lock_time_holding_torque_and_slip_energy():
    T, tk = 2.0, 5.0
    res = clutch_lockup(T=T, fn=tk).simulate(3.0, dt_out=1e-3, rtol=1e-9, solver="ida")
    # slipping: J1' = T - tk = -3, J2' = tk = 5 -> w_rel closes at 8 rad/s^2 from -10
    t_lock = 10.0 / 8.0
    ev = res.events
    assert [(e.component, e.old_mode, e.new_mode) for e in ev] == [("clutch", -1, 0)]
    assert ev[0].t == pytest.approx(t_lock, abs=1e-9)
    after = res.t > t_lock + 1e-9
    # locked: both accelerate at T/2; the clutch holds J2: flange_b.tau = -J2 * a = -1
    assert np.allclose(res["clutch.tau"][after], -1.0, atol=1e-8)
    assert np.allclose(res["J1.w"][after], res["J2.w"][after], atol=1e-10)
    assert np.allclose(res["clutch.w_rel"][after], 0.0, atol=1e-10)
    # energy: work of the source = kinetic energy gained + slip energy (= tk * integral |w_rel|)
    slip_energy = simpson(res["clutch.power"], x=res.t)
    assert slip_energy == pytest.approx(tk * 10.0 * t_lock / 2, rel=1e-6)
    work = simpson(-res["drive.power"], x=res.t)
    dke = (res["J1.kinetic"] + res["J2.kinetic"])[-1] - 50.0
    assert work == pytest.approx(dke + slip_energy, rel=1e-7)


def test_brake_holds_without_drift_and_breaks_away_above_peak():
    m = rm.Model("brake")
    load = m.add(Torque("load", tau=rm.signals.Ramp(height=12.0, duration=1.0)))
    J = m.add(Inertia("J", J=2.0, phi0=0.0, w0=0.0))
    b = m.add(Brake("brake", mu=0.5, peak=1.2, cgeo=1.0, fn_max=15.0))   # holds up to 9 N m
    m.connect(load.flange, J.flange_a)
    m.connect(J.flange_b, b.flange)
    res = m.simulate(1.0, dt_out=1e-3, rtol=1e-9, solver="ida")
    assert [(e.old_mode, e.new_mode) for e in res.events] == [(0, 1)]
    assert res.events[0].t == pytest.approx(9.0 / 12.0, abs=1e-8)
    before = res.t < 0.75
    assert np.max(np.abs(res["J.phi"][before])) == 0.0 or np.max(np.abs(res["J.phi"][before])) < 1e-14
    assert np.allclose(res["brake.tau"][before], res["load.tau"][before], atol=1e-9)


def _double_brake(load_signal):
    m = rm.Model("double_brake")
    load = m.add(Torque("load", tau=load_signal))
    J = m.add(Inertia("J", J=1.0, phi0=0.0, w0=0.0))
    m.add(Brake("b1", mu=0.5, peak=1.2, fn_max=10.0))      # static 6, kinetic 5
    m.add(Brake("b2", mu=0.5, peak=1.2, fn_max=10.0))
    m.connect(load.flange, J.flange_a)
    m.connect(J.flange_b, m["b1"].flange)
    m.connect(J.flange_b, m["b2"].flange)
    return m


def test_two_lockable_devices_on_one_rigid_group_hold_in_turn():
    # two brakes lock the same inertia: the split of the holding torque would not be unique.
    # Rule ("holding in turn"): b1 (first in model order) holds alone while b2 is Held (mode 3,
    # no torque); past b1's static capacity 6 N m, b1 acts with its kinetic 5 N m at zero speed
    # and b2 holds the rest; the inertia breaks away at kinetic(b1) + static(b2) = 11 N m.
    res = _double_brake(rm.signals.Ramp(height=15.0, duration=1.0)).simulate(1.0, dt_out=1e-3, rtol=1e-9, solver="ida")
    changes = [(round(e.t, 6), e.component, e.old_mode, e.new_mode) for e in res.events]
    assert changes[:2] == [(0.4, "b1", 0, 1), (0.4, "b2", 3, 0)]
    assert str(res.events[1]) == "t=0.4: b2 Held -> Stuck"
    assert ("b2", 0, 1) in [c[1:] for c in changes]
    first_motion = res.t[np.argmax(np.abs(res["J.w"]) > 1e-9)]
    assert first_motion == pytest.approx(11.0 / 15.0, abs=2e-3)     # 5 + 6 N m
    alone = res.t < 0.39
    assert np.allclose(res["b2.tau"][alone], 0.0, atol=1e-12) and np.all(res["b2.mode"][alone] == 3)
    turn = (res.t > 0.41) & (res.t < 0.72)
    assert np.allclose(res["b1.tau"][turn], 5.0, atol=1e-9)
    held = res.t < 0.72
    assert np.allclose(res["b1.tau"][held] + res["b2.tau"][held], res["load.tau"][held], atol=1e-8)


def test_friction_never_drives_the_motion_it_holds_when_the_load_reverses():
    # load 0 -> 9 -> -9 -> 0 N m: within kinetic(b1) + static(b2) = 11, so J never moves. When the
    # load falls below b1's kinetic 5 N m, b1 sticks again (relief event) instead of pushing
    # against b2; the same in the reverse direction.
    load = rm.signals.Table([(0, 0), (1, 9), (2, -9), (3, 0)])
    res = _double_brake(load).simulate(3.0, dt_out=1e-3, rtol=1e-9, solver="ida")
    assert np.abs(res["J.w"]).max() == 0.0
    assert np.allclose(res["b1.tau"] + res["b2.tau"], res["load.tau"], atol=1e-8)
    assert (res["b1.tau"] * res["b2.tau"]).min() > -1e-6          # never opposing each other
    got = [(round(e.t, 6), e.component, e.old_mode, e.new_mode) for e in res.events]
    t6, t5 = 6.0 / 9.0, 1.0 + 4.0 / 18.0                          # b1 past 6; load back below 5
    assert got == [(round(t6, 6), "b1", 0, 1), (round(t6, 6), "b2", 3, 0),
                   (round(t5, 6), "b1", 1, 0), (round(t5, 6), "b2", 0, 3),
                   (round(1 + 15 / 18, 6), "b1", 0, -1), (round(1 + 15 / 18, 6), "b2", 3, 0),
                   (round(2 + 4 / 9, 6), "b1", -1, 0), (round(2 + 4 / 9, 6), "b2", 0, 3)]


def test_chattering_guard_names_device_time_and_remedy():
    from regmech.library import coupled_clutches
    with pytest.raises(rm.ChatteringError) as err:
        coupled_clutches().simulate(1.5, dt_out=1e-3, rtol=1e-8, chatter_window=1.0, chatter_count=3, solver="ida")
    msg = str(err.value)
    assert "clutch1" in msg and "t=" in msg and "damping" in msg


def test_friction_device_needs_masses_on_both_sides():
    m = rm.Model("bad")
    J = m.add(Inertia("J", J=1.0))
    c = m.add(Clutch("clutch", fn_max=1.0))
    d = m.add(rm.components.Damper("d", d=1.0))
    f = m.add(Fixed("f"))
    m.connect(J.flange_b, c.flange_a)
    m.connect(c.flange_b, d.flange_a)
    m.connect(d.flange_b, f.flange)
    with pytest.raises(rm.RegularityError, match="'clutch' has no mass on one side"):
        m.check()


def test_clutch_engaging_at_exactly_zero_relative_speed_sticks():
    m = rm.Model("zero_engage")
    drive = m.add(Torque("drive", tau=1.0))
    J1 = m.add(Inertia("J1", J=1.0, phi0=0.0, w0=0.0))
    c = m.add(Clutch("clutch", fn_max=10.0, f_normalized=rm.signals.Step(start_time=0.5)))
    J2 = m.add(Inertia("J2", J=1.0, phi0=0.0, w0=0.0))
    m.connect(drive.flange, J1.flange_a)
    m.connect(J1.flange_b, c.flange_a)
    m.connect(c.flange_b, J2.flange_a)
    # J2 gets a torque so that both have the same speed at 0.5
    d2 = m.add(Torque("drive2", tau=1.0))
    m.connect(d2.flange, J2.flange_b)
    res = m.simulate(1.0, dt_out=1e-2, rtol=1e-9, solver="ida")
    assert [(e.t, e.old_mode, e.new_mode) for e in res.events] == [(0.5, 2, 0)]
    assert np.allclose(res["J1.w"], res["J2.w"], atol=1e-12)


def test_bearing_friction_spins_down_and_stays_stopped():
    # constant bearing torque 2 N m (table), J = 0.5, w0 = 8: stops at t = J w0 / 2 = 2 s, then stays
    m = rm.Model("spin_down")
    J = m.add(Inertia("J", J=0.5, phi0=0.0, w0=8.0))
    b = m.add(rm.components.BearingFriction("bearing", tau_table=[(0.0, 2.0), (100.0, 2.0)], peak=1.5))
    m.connect(J.flange_b, b.flange)
    res = m.simulate(3.0, dt_out=1e-2, rtol=1e-9, solver="ida")
    assert [(e.old_mode, e.new_mode) for e in res.events] == [(1, 0)]
    assert res.events[0].t == pytest.approx(2.0, abs=1e-9)
    assert np.allclose(res["J.w"], np.maximum(8.0 - 4.0 * res.t, 0.0), atol=1e-9)
    assert np.all(res["J.w"][res.t > 2.0 + 1e-9] == 0.0)          # after the event rows: exactly at rest
