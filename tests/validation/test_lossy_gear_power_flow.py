"""LossyGear against an independent calculation: driving-side switches (the power flow changing
direction), negative and positive ratios, loss power never negative, solvers and tolerances agreeing.

The reference is a hand-written scipy model of two inertias joined by the gear. It has no quadrant
state and no events: at each instant it solves the scalar equation of the loss law for the
acceleration with ``brentq``. Written by power flow for a gear without bearing friction (the
driven side receives ``eta`` times the power the driving side gives), and as MSL's V-shaped
(forward) / roof-shaped (backward) law in ``tau_a`` when bearing friction is present. The loss
torque is continuous across a driving-side switch, so a tight ``solve_ivp`` run is accurate there.
"""

import functools
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import regmech as rm
from regmech.components import Brake, Damper, Inertia, LossyGear, Shaft, Torque
from regmech.signals import Constant, Sine

J_A, J_B = 2.58, 5.2


def two_inertias(ratio, table, tau_a, tau_b, w0):
    """``torque_a -> J_a -> LossyGear -> J_b <- torque_b``; J_a starts at ``w0``."""
    m = rm.Model("lossy_two_inertias")
    ja = m.add(Inertia("Ja", J=J_A, phi0=0.0, w0=w0))
    jb = m.add(Inertia("Jb", J=J_B))
    gear = m.add(LossyGear("gear", ratio=ratio, loss_table=table))
    ta = m.add(Torque("torque_a", tau=tau_a))
    tb = m.add(Torque("torque_b", tau=tau_b))
    m.connect(ta.flange, ja.flange_a)
    m.connect(ja.flange_b, gear.flange_a)
    m.connect(gear.flange_b, jb.flange_a)
    m.connect(jb.flange_b, tb.flange)
    return m


def _sine(amp, f, phase=0.0):
    return lambda t: amp * math.sin(2 * math.pi * f * t + phase)


def reference_run(ratio, table, Ta, Tb, w0, t_end, t_out):
    """Independent solution: (w_a on t_out, loss power on t_out, driving-side switches [(t, side)]).

    Unknown: ``alpha = dw_a/dt``. The torques flowing into the gear are ``tau_a = Ta - J_a alpha``
    and ``tau_b = Tb - J_b alpha / ratio``; the loss torque at flange_a is ``tau_a + tau_b / ratio``
    (the torque balance of the gear, ``tau_b = -ratio (tau_a - tau_loss)``)."""
    eta1, eta2, bf1, bf2 = table[1:]
    frictionless = bf1 == 0 and bf2 == 0

    def law(tau_a, w):
        """Loss torque [N m] at flange_a for torque tau_a into flange_a, speed w != 0."""
        if frictionless:
            # power flow: flange_a drives (tau_a w > 0): flange_b gives eta1 tau_a w;
            # flange_b drives: flange_a gives eta2 times what flange_b puts in
            return (1 - eta1) * tau_a if tau_a * w > 0 else (1 - 1 / eta2) * tau_a
        if w > 0:
            return max((1 - eta1) * tau_a + bf1, (1 - 1 / eta2) * tau_a + bf2)
        return min((1 - eta1) * tau_a - bf1, (1 - 1 / eta2) * tau_a - bf2)

    def alpha(t, w):
        ta, tb = Ta(t), Tb(t)
        g = lambda a: (ta - J_A * a) + (tb - J_B * a / ratio) / ratio - law(ta - J_A * a, w)
        span = 10.0 * (abs(ta) + abs(tb) / abs(ratio) + bf1 + bf2 + 1.0) / J_A
        return brentq(g, -span, span, xtol=1e-14, rtol=1e-15)      # g decreases strictly: one root

    bf_a = 0.0 if frictionless else (bf1 - bf2) / (eta1 - 1 / eta2)

    def tau_eta(t, y):
        w = y[0]
        tau_a = Ta(t) - J_A * alpha(t, w)
        return tau_a - bf_a if w > 0 else tau_a + bf_a

    sol = solve_ivp(lambda t, y: [alpha(t, y[0])], (0.0, t_end), [w0], method="DOP853", rtol=1e-12,
                    atol=1e-12, dense_output=True, events=tau_eta)
    assert sol.success and np.all(np.sign(sol.y[0]) == np.sign(w0))     # rolling one way throughout
    w = sol.sol(t_out)[0]
    loss = np.array([(Ta(t) - J_A * alpha(t, wi) + (Tb(t) - J_B * alpha(t, wi) / ratio) / ratio) * wi
                     for t, wi in zip(t_out, w)])
    # driving flange after each switch: +1 flange_a (forward: tau_eta > 0; backward: tau_eta < 0)
    switches = [(float(t), int(np.sign(w0)) * (1 if tau_eta(t + 1e-7, sol.sol(t + 1e-7)) > 0 else -1))
                for t in sol.t_events[0] if 1e-9 < t < t_end - 1e-7]
    return w, loss, switches


def _check_against_reference(res, ref_w, ref_loss, ref_switches, t_out, tol_w, tol_t):
    w = np.interp(t_out, res.t, res["Ja.w"])
    rng = np.ptp(ref_w)
    assert np.max(np.abs(w - ref_w)) < tol_w * rng, np.max(np.abs(w - ref_w)) / rng
    loss = np.interp(t_out, res.t, res["gear.power"])
    p_scale = np.max(np.abs(ref_loss))
    assert np.max(np.abs(loss - ref_loss)) < 100 * tol_w * p_scale, np.max(np.abs(loss - ref_loss)) / p_scale
    sides = [(e.t, e.new_mode) for e in res.events if e.kind == "driving side"]
    assert [s for _, s in sides] == [s for _, s in ref_switches]
    assert np.allclose([t for t, _ in sides], [t for t, _ in ref_switches], rtol=0, atol=tol_t)
    assert not [e for e in res.events if e.kind == "mode"]          # rolling throughout


CASES = {
    # ratio, loss table row, w0: negative and positive ratios, reductions and step-ups, both directions
    "neg_ratio_fwd": (-2.995, (0.0, 0.72, 0.659, 0.0, 0.0), 39.2),
    "pos_ratio_fwd": (2.995, (0.0, 0.72, 0.659, 0.0, 0.0), 39.2),
    "neg_ratio_bwd": (-2.995, (0.0, 0.72, 0.659, 0.0, 0.0), -39.2),
    "neg_stepup_fwd": (-0.4, (0.0, 0.8, 0.6, 0.0, 0.0), 20.0),
    "neg_ratio_bearing_fwd": (-2.995, (0.0, 0.72, 0.659, 0.0, 0.3663), 39.2),
    "pos_ratio_bearing_bwd": (2.995, (0.0, 0.72, 0.659, 0.2, 0.3663), -39.2),
}


@functools.lru_cache(maxsize=None)
def _case_reference(case, t_end):
    ratio, row, w0 = CASES[case]
    t_out = np.linspace(0.0, t_end, 401)
    return (t_out,) + reference_run(ratio, row, _sine(30.0, 1.3), _sine(60.0, 0.7, 0.4), w0, t_end, t_out)


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("solver, rtol", [("ida", 1e-10), ("scipy:DOP853", 1e-10)])
def test_driving_side_switches_match_independent_model(case, solver, rtol):
    ratio, row, w0 = CASES[case]
    t_end = 2.0
    t_out, ref_w, ref_loss, ref_switches = _case_reference(case, t_end)
    assert len(ref_switches) >= 2          # the power flow changes direction, both ways
    m = two_inertias(ratio, [list(row)], Sine(amplitude=30.0, freq_hz=1.3),
                     Sine(amplitude=60.0, freq_hz=0.7, phase=0.4), w0)
    res = m.simulate(t_end, dt_out=5e-3, solver=solver, rtol=rtol, atol=rtol * 1e-2)
    _check_against_reference(res, ref_w, ref_loss, ref_switches, t_out, 1e-7, 1e-6)


@pytest.mark.parametrize("solver", ["ida", "scipy:DOP853", "scipy:RK45"])
def test_driving_side_at_a_tie_is_decided_by_where_the_torque_goes(solver):
    """At t = 0 no torque acts, so both laws give zero loss; the drive torque then decelerates J_a
    and flange_b drives. Deciding the side by the sign of tau_eta (zero) kept flange_a driving, with
    the event function negative from the start and never armed: the gear supplied power for the
    whole first half period."""
    ratio, row, w0 = -2.995, (0.0, 0.72, 0.659, 0.0, 0.0), 39.2
    Ta, Tb = _sine(-30.0, 1.3), (lambda t: 0.0)
    t_end = 1.0
    t_out = np.linspace(0.0, t_end, 201)
    ref_w, ref_loss, ref_switches = reference_run(ratio, row, Ta, Tb, w0, t_end, t_out)
    m = two_inertias(ratio, [list(row)], Sine(amplitude=-30.0, freq_hz=1.3), Constant(0.0), w0)
    res = m.simulate(t_end, dt_out=5e-3, solver=solver, rtol=1e-6)
    assert res["gear.power"].min() >= -1e-9 * np.abs(res["gear.power"]).max()
    _check_against_reference(res, ref_w, ref_loss, ref_switches, t_out, 1e-4, 1e-4)


@pytest.mark.parametrize("ratio", [-2.995, 2.995, -0.4])
@pytest.mark.parametrize("solver", ["ida", "scipy:DOP853", "rk4"])
def test_constant_torques_closed_form(ratio, solver):
    """Constant torques, flange_b driving (the load overhauls the gear): the acceleration is
    constant, ``alpha = (T_a + eta2 T_b / ratio) / (J_a + eta2 J_b / ratio^2)`` (flange_a gets eta2 of
    the power flange_b puts in), the loss is ``(1 - eta2) * P_b``."""
    eta2 = 0.659
    w0, Ta, Tb = 10.0, -2.0, 30.0 * np.sign(ratio)          # T_b pushes J_b the way it turns
    alpha = (Ta + eta2 * Tb / ratio) / (J_A + eta2 * J_B / ratio ** 2)
    m = two_inertias(ratio, [[0.0, 0.72, eta2, 0.0, 0.0]], Ta, Tb, w0)
    opts = {"h": 1e-2, "tol": None} if solver == "rk4" else {"rtol": 1e-8}
    res = m.simulate(1.0, dt_out=1e-2, solver=solver, **opts)
    assert np.allclose(res["Ja.w"], w0 + alpha * res.t, rtol=1e-9, atol=1e-9)
    tau_b = Tb - J_B * alpha / ratio
    p_b = tau_b * (w0 + alpha * res.t) / ratio           # power flange_b puts into the gear, > 0
    assert np.all(p_b > 0)
    assert np.allclose(res["gear.power"], (1 - eta2) * p_b, rtol=1e-7, atol=1e-9)
    assert not res.events


# --------------------------------------------------------------- a model found by fuzzing
def fuzz_model(tau1=(1.96, 1.82), tau2=(89.5, 1.07), fn_max=1.32, f_brake=1.46, mu=0.4, peak=1.19, d=0.0294):
    """The issue-13 model: LossyGear(ratio -2.995) between a 2.58 kg m^2 inertia (w0 39.2, with a
    0.033 kg m^2 inertia on a rigid Shaft and a 0.0105 kg m^2 one, w0 -10.2, on a Damper) and a
    5.2 kg m^2 inertia held by a Brake with a sine normal force; two sine torques ((amplitude, Hz)
    on the 0.033 and the 5.2 kg m^2 inertias). The values the issue leaves open come from a
    random search over them: before the fix 27 of 120 such models had ida at rtol 1e-10 more than
    1e-4, or DOP853 at 1e-6 more than 1e-3 of the range off DOP853 at 1e-11, or the gear supplying
    power in one of these runs."""
    m = rm.Model("lossy_fuzz")
    j1 = m.add(Inertia("J1", J=2.58, w0=39.2))
    j3 = m.add(Inertia("J3", J=0.033))
    j4 = m.add(Inertia("J4", J=0.0105, w0=-10.2))
    j2 = m.add(Inertia("J2", J=5.2))
    shaft = m.add(Shaft("shaft"))
    damper = m.add(Damper("damper", d=d))
    gear = m.add(LossyGear("gear", ratio=-2.995, loss_table=[[0, 0.72, 0.659, 0, 0.3663]]))
    brake = m.add(Brake("brake", mu=mu, peak=peak, fn_max=fn_max, f_normalized=Sine(amplitude=1.0, freq_hz=f_brake)))
    t1 = m.add(Torque("t1", tau=Sine(amplitude=tau1[0], freq_hz=tau1[1])))
    t2 = m.add(Torque("t2", tau=Sine(amplitude=tau2[0], freq_hz=tau2[1])))
    m.connect(j1.flange_b, shaft.flange_a)
    m.connect(shaft.flange_b, j3.flange_a)
    m.connect(j1.flange_b, damper.flange_a)
    m.connect(damper.flange_b, j4.flange_a)
    m.connect(j1.flange_a, gear.flange_a)
    m.connect(gear.flange_b, j2.flange_a)
    m.connect(j2.flange_b, brake.flange)
    m.connect(t1.flange, j3.flange_b)
    m.connect(t2.flange, j2.flange_b)
    return m


# Before the fix: ida at rtol 1e-6 15 % of the range off and the gear supplying 332 W. Its first
# driving-side switch (t = 3.6 ms) was decided by the round-off sign of tau_eta at the event; which
# solver lost that draw depended on round-off (with 4-digit values it was DOP853 at 1e-6), so the
# deterministic regression test for it is the tie test above; this one checks the agreement.
TIE = {}
# Before the fix: DOP853 at rtol 1e-6 9 % off, the gear supplying 17 W, 23 of 45 mode changes. In
# single 0.27 s steps the sine normal force engaged and released the brake, the gear's speed
# reversed and came back, and its driving side switched and came back: the step ends saw none of it.
DIPS = dict(tau1=(812.0, 0.754), tau2=(2.23, 1.15), fn_max=523.0, f_brake=3.63, mu=0.529, peak=1.26, d=0.0131)

# Before the fix: every solver had the gear supplying 840 W after t = 0.81 s, where the gear and
# the brake reach zero speed together (one motion) and roll back: in the mode iteration the gear's
# side was flipped once while the brake was still stuck, and a second flip, needed after the brake
# broke away, was refused (one flip per gear and event).
REVERSAL = dict(tau1=(82.8, 2.34), tau2=(778.0, 0.18), fn_max=48.7, f_brake=0.523, mu=0.726, peak=1.012, d=0.587)

RUNS = [("REVERSAL", "scipy:DOP853", 1e-8, 1e-5), ("REVERSAL", "ida", 1e-8, 1e-5),
        ("TIE", "scipy:DOP853", 1e-6, 1e-3), ("TIE", "scipy:DOP853", 1e-9, 1e-6), ("TIE", "ida", 1e-6, 1e-3),
        ("TIE", "ida", 1e-10, 1e-6), ("TIE", "scipy:Radau", 1e-8, 1e-4), ("TIE", "rk4", None, 1e-3),
        ("DIPS", "scipy:DOP853", 1e-6, 1e-3), ("DIPS", "scipy:RK45", 1e-6, 1e-3), ("DIPS", "ida", 1e-6, 1e-3)]
T_FUZZ = {"TIE": 1.5, "DIPS": 3.0, "REVERSAL": 1.5}


@functools.lru_cache(maxsize=None)
def _fuzz_reference(which):
    return fuzz_model(**globals()[which]).simulate(T_FUZZ[which], dt_out=1e-3, solver="scipy:DOP853",
                                                        rtol=1e-11, atol=1e-13)


@pytest.mark.slow
@pytest.mark.parametrize("which, solver, rtol, tol", RUNS)
def test_fuzz_model_agrees_across_solvers_and_tolerances(which, solver, rtol, tol):
    ref = _fuzz_reference(which)
    t_end = T_FUZZ[which]
    opts = {"h": 5e-3, "tol": None} if rtol is None else {"rtol": rtol, "atol": rtol * 1e-2}
    res = fuzz_model(**globals()[which]).simulate(t_end, dt_out=1e-3, solver=solver, **opts)
    grid = np.linspace(0.0, t_end, 1501)
    for name in ("J1.w", "J2.w"):
        err = np.max(np.abs(np.interp(grid, res.t, res[name]) - np.interp(grid, ref.t, ref[name])))
        assert err < tol * np.ptp(ref[name]), (name, err / np.ptp(ref[name]))
    # the loss element never supplies power, at any output point
    assert res["gear.power"].min() >= -1e-9 * np.abs(res["gear.power"]).max()
    # every mode change and driving-side switch is an event, the same in every run
    got = [(e.t, e.component, e.old_mode, e.new_mode, e.kind) for e in res.events]
    want = [(e.t, e.component, e.old_mode, e.new_mode, e.kind) for e in ref.events]
    assert sum(e[4] == "driving side" for e in want) >= 2
    assert [g[1:] for g in got] == [w[1:] for w in want]
    assert np.allclose([g[0] for g in got], [w[0] for w in want], rtol=0, atol=1e-3 if tol >= 1e-3 else 1e-6)


def two_lossy_gears():
    """Two lossy gears in series (ratios -2 and 3, bearing friction on both sides), a brake with a
    sine normal force between them, sine torques at both ends."""
    m = rm.Model("two_lossy_gears")
    j1 = m.add(Inertia("J1", J=1.0, w0=20.0))
    j2 = m.add(Inertia("J2", J=0.5))
    j3 = m.add(Inertia("J3", J=3.0))
    g1 = m.add(LossyGear("g1", ratio=-2.0, loss_table=[[0, 0.8, 0.7, 0.1, 0.2]]))
    g2 = m.add(LossyGear("g2", ratio=3.0, loss_table=[[0, 0.9, 0.6, 0.0, 0.05]]))
    t1 = m.add(Torque("t1", tau=Sine(amplitude=20.0, freq_hz=1.1)))
    t3 = m.add(Torque("t3", tau=Sine(amplitude=50.0, freq_hz=0.6, phase=1.0)))
    brake = m.add(Brake("brake", mu=0.3, fn_max=30.0, f_normalized=Sine(amplitude=1.0, freq_hz=0.4)))
    m.connect(t1.flange, j1.flange_a)
    m.connect(j1.flange_b, g1.flange_a)
    m.connect(g1.flange_b, j2.flange_a)
    m.connect(j2.flange_b, g2.flange_a)
    m.connect(g2.flange_b, j3.flange_a)
    m.connect(j3.flange_b, t3.flange)
    m.connect(j2.flange_b, brake.flange)
    return m


@functools.lru_cache(maxsize=None)
def _two_gears_reference():
    return two_lossy_gears().simulate(4.0, dt_out=1e-3, solver="scipy:DOP853", rtol=1e-11, atol=1e-13)


@pytest.mark.slow
@pytest.mark.parametrize("solver, rtol", [("scipy:DOP853", 1e-6), ("ida", 1e-6), ("ida", 1e-10)])
def test_two_lossy_gears_in_series(solver, rtol):
    """Before the fix DOP853 at rtol 1e-6 was 1.7e-3 off with g1 supplying 0.14 W: its driving side
    switched and came back inside one 0.2 s step (none of the 12 switches appeared as events).
    IDA at 1e-10 checks that the restart after a switch decided at a tie is consistent with the
    residual (an inconsistency of 1e-9 of the torques failed IDA's error test there)."""
    ref = _two_gears_reference()
    res = two_lossy_gears().simulate(4.0, dt_out=1e-3, solver=solver, rtol=rtol, atol=rtol * 1e-2)
    grid = np.linspace(0.0, 4.0, 2001)
    for name in ("J1.w", "J3.w"):
        err = np.max(np.abs(np.interp(grid, res.t, res[name]) - np.interp(grid, ref.t, ref[name])))
        assert err < 100 * rtol * np.ptp(ref[name]), (name, err / np.ptp(ref[name]))
    for g in ("g1", "g2"):
        assert res[f"{g}.power"].min() >= -1e-9 * np.abs(res[f"{g}.power"]).max()
    want = [(e.component, e.old_mode, e.new_mode, e.kind) for e in ref.events]
    assert sum(w[3] == "driving side" for w in want) >= 10
    assert [(e.component, e.old_mode, e.new_mode, e.kind) for e in res.events] == want


def test_driving_side_event_reads_as_such():
    ev = rm.Event(0.25, "gear", 1, -1, "driving side")
    assert str(ev) == "t=0.25: gear driving side: flange_a drives -> flange_b drives"
    assert rm.Event(0.25, "gear", 1, 0).kind == "mode"
