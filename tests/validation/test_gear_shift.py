"""Planetary 1-2 upshift: brake released while the clutch is applied (library/gearshift.py)."""

import warnings

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

from regmech.library import SCENES
from regmech.library.gearshift import gear_shift

T_END = 1.0
T_E, R, T_SHIFT, BRAKE_TIME, BRAKE_CAP, PEAK = 200.0, 2.0, 0.2, 0.2, 500.0, 1.2
BACKWARD, STUCK, FORWARD, FREE = -1, 0, 1, 2


@pytest.fixture(scope="module")
def res():
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # default IDA settings must run without any warning
        return gear_shift().simulate(T_END, dt_out=1e-3, solver="ida")


def events_of(res, name):
    return [(e.t, e.old_mode, e.new_mode) for e in res.events if e.component == name]


def test_registered_as_scene():
    assert SCENES["gear_shift"] is gear_shift


def test_first_gear_before_direct_drive_after(res):
    t = res.t
    ratio = res["input.w"] / res["output.w"]
    (t_lock, old, new), = [ev for ev in events_of(res, "clutch") if ev[2] == STUCK]
    assert np.allclose(ratio[t < T_SHIFT], 1.0 + R, rtol=1e-9, atol=0)
    assert np.max(np.abs(res["ring.w"][t < T_SHIFT])) < 1e-12           # held by the brake
    after = t > t_lock
    assert np.allclose(ratio[after], 1.0, rtol=1e-6, atol=0)
    assert np.allclose(res["ring.w"][after], res["output.w"][after], rtol=1e-6, atol=0)
    assert res["input.w"][-1] < 0.5 * res["input.w"].max()                # the engine was pulled down


def test_clutch_slips_then_locks_and_brake_sticks_slides_and_frees(res):
    t = res.t
    clutch, brake = events_of(res, "clutch"), events_of(res, "brake")
    # the clutch engages at the start of the shift, slipping (ring slower than the input), then locks for good
    assert [(o, n) for _, o, n in clutch] == [(FREE, BACKWARD), (BACKWARD, STUCK)]
    assert clutch[0][0] == pytest.approx(T_SHIFT)
    t_lock = clutch[1][0]
    slipping = (t > T_SHIFT) & (t < t_lock)
    assert np.all(res["clutch.w_rel"][slipping] < 0) and np.all(res["clutch.mode"][t > t_lock] == STUCK)
    # the brake holds, breaks away forward (the clutch drags the ring along), and is free when released
    assert [(o, n) for _, o, n in brake] == [(STUCK, FORWARD), (FORWARD, FREE)]
    t_break, t_free = brake[0][0], brake[1][0]
    assert T_SHIFT < t_break < t_free == pytest.approx(T_SHIFT + BRAKE_TIME)
    assert t_free < t_lock                                               # inertia phase after the brake is off
    # break-away when the holding torque reaches the static capacity of the falling pressure
    capacity = PEAK * BRAKE_CAP * (1.0 - (t_break - T_SHIFT) / BRAKE_TIME)
    k = np.searchsorted(t, t_break)                                      # the row before the event
    assert abs(res["brake.tau"][k]) == pytest.approx(capacity, rel=1e-4)
    assert np.all(res["ring.w"][(t > t_break) & (t < t_lock)] > 0)


def test_torque_phase_dip_and_inertia_phase_hump(res):
    t = res.t
    out = -res["output_shaft.tau"]                  # MSL sign: tau = c (phi_vehicle - phi_output)
    (t_break, _, _), (t_free, _, _) = events_of(res, "brake")
    t_lock = events_of(res, "clutch")[1][0]
    first = out[t < T_SHIFT]
    second = out[-1]                                # direct drive, the vehicle's share of T_e
    assert np.ptp(first) < 1e-6 * first[0]           # pre-twisted shaft: no jerk before the shift
    # quasi-static shares of the vehicle (J 11) in the accelerating drive: 1st (ring held) and direct
    assert first[0] == pytest.approx(11.0 * (1 + R) * T_E / (0.25 * (1 + R) ** 2 + 0.05 + 11.0), rel=1e-9)
    assert second == pytest.approx(11.0 * T_E / (0.25 + 0.03 + 0.05 + 11.0), rel=1e-3)
    torque_phase = (t > T_SHIFT) & (t < t_break + 0.02)
    inertia_phase = (t > t_free) & (t < t_lock)
    assert out[torque_phase].min() < 0.85 * second   # the dip below the 2nd-gear level
    assert out[inertia_phase].max() > 1.8 * second   # the engine's inertia pushes the output
    # the lock ends the inertia phase abruptly (the shift shock); the shaft oscillation then dies out
    assert np.ptp(out[t > T_END - 0.1]) < 0.01 * second


def test_energy_balance(res):
    t = res.t

    def integral(p):
        return cumulative_trapezoid(p, t, initial=0.0)
    work = integral(-res["engine.power"])
    kinetic = sum(res[f"{n}.kinetic"] for n in ("input", "ring", "output", "vehicle"))
    elastic = res["output_shaft.potential"]
    damping = 20.0 * res["output_shaft.w_rel"] ** 2
    # friction only dissipates, to where its events are located: the lock-up row lies on the clutch's root, which
    # IDA places within 100 eps (|t| + |h|) of the crossing, and w_rel moves by a_rel times that (measured:
    # 1.6e-11 rad/s against -300 N m, -4.7e-9 W; the bound below is 2.0e-8 W for the clutch)
    t_tol = 100 * np.finfo(float).eps * 2 * t[-1]
    for dev in ("clutch", "brake"):
        slack = t_tol * np.abs(res[f"{dev}.tau"] * res[f"{dev}.a_rel"]).max()
        assert np.all(res[f"{dev}.power"] >= -slack), dev
    dissipated = integral(damping + res["clutch.power"] + res["brake.power"])
    balance = work - (kinetic - kinetic[0]) - (elastic - elastic[0]) - dissipated
    assert np.max(np.abs(balance)) < 1e-5 * work[-1]
    assert integral(res["clutch.power"])[-1] > 0.3 * work[-1]     # the shift costs heat in the clutch
