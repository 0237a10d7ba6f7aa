"""Mode-logic findings of the fuzz run of seeds 10000-10499, each against a closed form or a tighter run.

A friction device whose zero slip is forced by a motion source through another stuck device.

A Speed source turns J1 through a stuck clutch (capacity 30 N m); a brake (12 N m) holds J1 to the
ground. When the source's speed passes zero the brake's slip passes zero too, but the brake cannot
stick: the clutch would have to slip (its kinetic torque 30 N m is beyond the brake's 12 N m), and
the clutch holds (its load |J1 a + 12| <= 19.5 N m < 30 N m). So the brake reverses and slides on
with its kinetic torque. Before the fix the ODE-form solvers kept the brake "Held" (no torque) while
J1 turned at up to 7 rad/s (a silently wrong run: fuzz seeds 10021 and 10059) and IDA refused the
run with a message about start velocities.

Closed form after the clutch sticks: J1.w = w_ref(t) = 2 + 5 sin(30 t + 0.4); brake torque 12 N m
against J1's motion; clutch torque J1 dw_ref/dt + 12 sign(w); brake reversals where w_ref = 0,
t = (pi + asin 0.4 - 0.4) / 30 and (2 pi - asin 0.4 - 0.4) / 30.

The second case gives the brake a static capacity (18 N m) above the clutch's kinetic torque (15 N m):
at the source's zero the brake sticks and the clutch slips (the device reaching zero slip sticks
first, as a compliance between them would decide and MSL's elements do); sliding both, also a
consistent set, is what the rules gave before (fuzz seed 10021 had this pattern on a limited-slip
differential). Closed form: J1 at rest from t1 = (pi + asin 0.4 - 1.4) / 30 on, brake holding 15 N m,
the clutch reversing at every zero of the source's speed.
"""

import math

import numpy as np
import pytest

import regmech as rm
from regmech.components import Brake, Clutch, Inertia, LimitedSlipDifferential, Speed

J, T_END = 0.05, 0.5


def w_ref(t):
    return 2.0 + 5.0 * np.sin(30.0 * t + 0.4)


def model(phase=0.4, lock_fn=2000.0, brake_peak=1.0, w0=0.0):
    m = rm.Model("dragged_brake")
    j1 = m.add(Inertia("J1", J=J, w0=w0))
    src = m.add(Speed("motor", w_ref=lambda t: 2.0 + 5.0 * math.sin(30.0 * t + phase)))
    lock = m.add(Clutch("lock", mu=0.3, cgeo=0.05, fn_max=lock_fn, f_normalized=1.0))
    brake = m.add(Brake("brake", mu=0.3, cgeo=0.4, fn_max=100.0, peak=brake_peak, f_normalized=1.0))
    m.connect(src.flange, lock.flange_a)
    m.connect(lock.flange_b, j1.flange_a)
    m.connect(brake.flange, j1.flange_b)
    return m


RUNS = [("ida", {"rtol": 1e-8}), ("scipy:DOP853", {"rtol": 1e-8}), ("scipy:Radau", {"rtol": 1e-8}),
        ("auto", {"accuracy": 1e-4})]


@pytest.mark.parametrize("solver,opts", RUNS, ids=[r[0] for r in RUNS])
def test_a_brake_dragged_through_zero_by_a_source_slides_with_its_kinetic_torque(solver, opts):
    res = model().simulate(T_END, dt_out=1e-3, solver=solver, **opts)
    t = res.t
    stuck_at = [e.t for e in res.events if e.component == "lock"]
    assert len(stuck_at) == 1                           # the clutch sticks once and then holds
    after = t > stuck_at[0] + 1e-3
    w = res["J1.w"][after]
    assert np.max(np.abs(w - w_ref(t[after]))) < 1e-4 * 7.0
    moving = np.abs(w) > 1e-2
    assert np.all(np.abs(np.abs(res["brake.tau"][after][moving]) - 12.0) < 1e-6 * 12.0)
    assert np.min(res["brake.power"]) > -1e-9 * 100.0     # a brake never supplies power
    a = 5.0 * 30.0 * np.cos(30.0 * t[after][moving] + 0.4)
    lock_tau = np.abs(J * a + 12.0 * np.sign(w[moving]))
    assert np.max(np.abs(np.abs(res["lock.tau"][after][moving]) - lock_tau)) < 1e-3 * 20.0
    # the brake reverses where the source's speed passes zero, and is never 'Held' while it turns
    brake_events = [e for e in res.events if e.component == "brake"]
    assert all(rm.modes.MODE_NAMES[e.new_mode] in ("Forward", "Backward") for e in brake_events)
    s = math.asin(0.4)
    expected = [(math.pi + s - 0.4) / 30.0, (2 * math.pi - s - 0.4) / 30.0]
    expected += [e + 2 * math.pi / 30.0 for e in expected]
    got = [e.t for e in brake_events]
    assert len(got) == len(expected)
    assert np.max(np.abs(np.array(got) - expected)) < 1e-6


@pytest.mark.slow
@pytest.mark.parametrize("solver,opts", RUNS, ids=[r[0] for r in RUNS])
def test_a_brake_reaching_zero_slip_sticks_when_it_can_hold_the_slipping_clutch(solver, opts):
    res = model(phase=1.4, lock_fn=1000.0, brake_peak=1.5, w0=2.0 + 5.0 * math.sin(1.4)).simulate(T_END, dt_out=1e-3, solver=solver, **opts)
    s = math.asin(0.4)
    zeros = [(math.pi + s - 1.4) / 30.0, (2 * math.pi - s - 1.4) / 30.0]
    zeros += [z + 2 * math.pi / 30.0 for z in zeros]
    zeros += [zeros[0] + 4 * math.pi / 30.0]
    t1 = zeros[0]
    brake = [e for e in res.events if e.component == "brake"]
    assert [rm.modes.MODE_NAMES[e.new_mode] for e in brake] == ["Stuck"]
    assert abs(brake[0].t - t1) < 1e-6
    after = res.t > t1 + 1e-3
    assert np.max(np.abs(res["J1.w"][after])) < 1e-6 * 7.0
    assert np.max(np.abs(np.abs(res["brake.tau"][after]) - 15.0)) < 1e-6 * 15.0
    assert np.max(np.abs(np.abs(res["lock.tau"][after]) - 15.0)) < 1e-6 * 15.0
    # the clutch reverses at every zero of the source's speed (one instant may record two changes)
    lock_times = sorted({round(e.t, 7) for e in res.events if e.component == "lock"})
    assert np.max(np.abs(np.array(lock_times) - zeros)) < 1e-6
    assert np.min(res["lock.power"]) > -1e-9 * 100.0 and np.min(res["brake.power"]) > -1e-9 * 100.0


def _planetary_and_clutch():
    """Fuzz seed 10135: a LossyPlanetary (large bearing friction) stuck until a clutch on the carrier
    reverses at t = 0.13919 s; in that event the gear's holding torque first passed its limit forward."""
    from regmech.components import EndStop, LossyPlanetary, Torque
    from regmech.signals import Constant, Ramp
    m = rm.Model("planetary_and_clutch")
    J1 = m.add(Inertia("J1", J=0.03383))
    gear = m.add(LossyPlanetary("gear", ratio=1.886, loss_table=[[0.0, 0.5742, 0.7787, 20.01, 0.1286]]))
    J2 = m.add(Inertia("J2", J=0.1066))
    J3 = m.add(Inertia("J3", J=3.841, w0=-10.32, phi0=-0.001564))
    clutch = m.add(Clutch("clutch", mu=0.1725, peak=1.443, cgeo=0.1615, fn_max=589.2,
                          f_normalized=Ramp(height=-0.1698, duration=0.02624, start_time=0.04858, offset=0.8694)))
    J4 = m.add(Inertia("J4", J=0.1814))
    stop = m.add(EndStop("stop", lower=-0.01257, upper=0.7226, c=59780.0, d=6.321, domain="rotational"))
    drive = m.add(Torque("drive", tau=Constant(-262.1)))
    m.connect(gear.carrier, J1.flange_b)
    m.connect(gear.ring, J2.flange_a)
    m.connect(gear.sun, J3.flange_a)
    m.connect(clutch.flange_a, J1.flange_a)
    m.connect(clutch.flange_b, J4.flange_a)
    m.connect(stop.flange, J4.flange_a)
    m.connect(drive.flange, J4.flange_b)
    m.connect(drive.support, J3.flange_b)
    return m


@pytest.mark.slow
@pytest.mark.parametrize("solver,opts", [("ida", {"rtol": 1e-8}), ("scipy:DOP853", {"rtol": 1e-8})],
                         ids=["ida", "DOP853"])
def test_a_lossy_gear_breaking_away_in_a_clutch_event_rolls_the_way_it_moves(solver, opts):
    """The gear broke away Forward (its loss torque beyond the forward limit under the clutch's old mode) and
    rolled backward at once under the clutch's new mode: its event function (mode * w_rel) started at zero and
    fell, the gear then supplied up to 238 W (2 % of the power scale) on every solver to the end of the run.
    The rule that re-sticks a device leaving zero slip against its own direction now covers lossy gears."""
    res = _planetary_and_clutch().simulate(0.4465, dt_out=1.7414e-4, solver=solver, **opts)
    w_a = res["gear.sun.w"] - res["gear.carrier.w"]
    mode = res["gear.mode"]
    rolling = (mode == 1) | (mode == -1)
    assert np.all(mode[rolling] * w_a[rolling] >= -1e-6 * np.abs(w_a).max())
    p = res["gear.power"]
    assert p.min() >= -1e-6 * np.abs(res["drive.power"]).max(), (p.min(), res.t[np.argmin(p)])


def _two_bearings_on_a_locked_differential():
    """Fuzz seed 10169 (its unconnected mass on an ElastoGap left out): two BearingFriction on one
    rigid motion (the carrier and one side of a limited-slip differential whose lock is stuck), driven by a DC
    motor on a Sine voltage."""
    from regmech.components import BearingFriction, DCMotor
    from regmech.signals import Sine
    m = rm.Model("two_bearings")
    J1 = m.add(Inertia("J1", J=0.06508, w0=0.0, phi0=-0.1074))
    b1 = m.add(BearingFriction("bearing1", tau_table=[(0.0, 1.844), (0.119, 0.1733)], peak=1.277))
    lsd = m.add(LimitedSlipDifferential("lsd", ratio=1.0, preload=1601.0, mu=0.1524, cgeo=0.05, peak=1.298,
                                        J_side=0.0008907))
    motor = m.add(DCMotor("motor", u=Sine(amplitude=26.04, freq_hz=8.005, phase=2.613, offset=3.368,
                                          start_time=0.1791), R=0.587, L=0.001222, k=0.114))
    b2 = m.add(BearingFriction("bearing2", tau_table=[(0.0, 0.5458), (7.474, 0.1921)], peak=1.345))
    m.connect(b1.flange, J1.flange_a)
    m.connect(lsd.carrier, J1.flange_a)
    m.connect(motor.flange, lsd.left)
    m.connect(b2.flange, lsd.left)
    return m


def test_holding_in_turn_does_not_depend_on_a_round_off_event():
    """At t = 0.20556 s the second holder (bearing2) passed its capacity while bearing1 slid at zero speed
    (holding in turn). The logic re-stuck bearing1 with its static capacity; at the next event it would
    re-stick bearing2 instead and break the motion away. IDA got that next event at once (a round-off crossing
    of a slip of 1e-97), DOP853 1.7 ms later at bearing1's capacity: the runs ended 1 % of J1.phi's range
    apart, each converged in its tolerance. ``settle`` now runs to a fixed point, so both break away at once."""
    runs = {s: _two_bearings_on_a_locked_differential().simulate(0.6, dt_out=1e-3, solver=s, rtol=1e-8)
            for s in ("ida", "scipy:DOP853")}
    paths = {s: [(e.component, e.old_mode, e.new_mode) for e in r.events] for s, r in runs.items()}
    assert paths["ida"] == paths["scipy:DOP853"]
    a, b = runs["ida"], runs["scipy:DOP853"]
    assert np.max(np.abs(a["J1.phi"] - b["J1.phi"])) < 1e-5 * np.ptp(b["J1.phi"])
