"""IDA's absolute tolerances follow the size of the motion.

The defect: IDA weighs each unknown by ``rtol |y| + atol`` with the plain
``atol = rtol * 1e-2``. On a translational chain whose motion is small
(millimetres, mm/s) that makes the error test absolute, and at the default
rtol 1e-6 the 0.8 kg mass's speed came back up to 1e-2 of its range off
a tight reference while Radau was within 1e-5 (``_rescaled_atol`` in
``regmech.solvers.ida``). Neither the ElastoBacklash with b = 0 (it is a
plain spring-damper branch, no kink) nor the friction events were the
cause: the error is the same without them, and it vanishes when the same
model is driven 1e4 times harder.
"""

import numpy as np
import pytest

import regmech as rm
from regmech.components import ElastoBacklash, Fixed, Force, FrictionContact, Mass, Spring
from regmech.signals import Sine, Step
from regmech.solvers import ida
from regmech.solvers.common import StateScale

T = "translational"


def chain(force, friction=True, signal="step"):
    """0.8 kg -8e3- 15.6 kg -ElastoBacklash(1.6e4, d=10, b=0)- 267 kg -1.2e4- 27.3 kg, the 267 kg mass on a
    1e4 N/m spring to the ground (and on a FrictionContact with a mu table, normal force 1.2 F), a force of
    amplitude F on the 0.8 kg mass: a step at 0.05 s or a 1.5 Hz sine."""
    m = rm.Model("small_motion_chain")
    ground = m.add(Fixed("ground", domain=T))
    masses = [m.add(Mass(f"M{i}", m=mi, s0=0.0, v0=0.0)) for i, mi in enumerate((0.8, 15.6, 267.0, 27.3))]
    links = (Spring("k0", c=8e3, domain=T), ElastoBacklash("bl", c=1.6e4, d=10.0, b=0.0, domain=T),
             Spring("k2", c=1.2e4, domain=T))
    for i, link in enumerate(links):
        link = m.add(link)
        m.connect(masses[i].flange_b, link.flange_a)
        m.connect(link.flange_b, masses[i + 1].flange_a)
    f = Step(force, 0.05) if signal == "step" else Sine(amplitude=force, freq_hz=1.5)
    src = m.add(Force("F", f=f))
    m.connect(src.flange, masses[0].flange_a)
    k = m.add(Spring("kg", c=1e4, domain=T))
    m.connect(masses[2].flange_b, k.flange_a)
    m.connect(k.flange_b, ground.flange)
    if friction:
        fc = m.add(FrictionContact("fc", mu_table=[[0, 0.5], [0.05, 0.35], [0.5, 0.25]], peak=1.1, fn=1.2 * force))
        m.connect(masses[2].flange_b, fc.flange_a)
        m.connect(fc.flange_b, ground.flange)
    return m


def rel_err(ref, res, name):
    a = ref[name]
    return float(np.max(np.abs(np.interp(ref.t, res.t, res[name]) - a)) / np.ptp(a))


@pytest.mark.parametrize("friction, signal", [(False, "sine"), (True, "step")])
def test_ida_default_meets_the_tight_reference_on_a_chain_that_moves_little(friction, signal):
    """The 0.8 kg mass's speed at the defaults within 1e-4 of its range of DOP853 at rtol 1e-11.

    The bound: driven by 300 N, where the plain atol is nearly relative
    already, IDA's own global error at rtol 1e-6 over these 0.5 s is 4.1e-5
    (sine) and 4.9e-5 (step with friction); a tolerance that is relative
    gives as much at 0.03 N, and 1e-4 leaves twice that. Measured at 0.03 N: 3.9e-5 and 4.6e-5 now; 1.1e-2 and 1.7e-3 with
    the plain atol (Radau at the defaults: 1.0e-4 and 1.9e-5).
    """
    m = chain(0.03, friction, signal)
    ref = m.simulate(t_end=0.5, solver="scipy:DOP853", rtol=1e-11, atol=1e-14, max_steps=100_000)
    res = m.simulate(t_end=0.5, solver="ida")
    assert "atol_rescaled" in res.stats.extra
    assert len(res.events) == len(ref.events)
    assert rel_err(ref, res, "M0.v") < 1e-4


def test_ida_error_does_not_depend_on_the_size_of_the_motion():
    """The chain without friction is linear: its motion at 0.03 N is that at 300 N times 1e-4, and a relative
    tolerance must give the same answer up to the solver's own error (4.9e-5 at 300 N over 0.5 s). They differ
    by 2.3e-5 of the range; with the plain atol they differed by 3.2e-3."""
    big = chain(300.0, friction=False).simulate(t_end=0.5, solver="ida")
    small = chain(0.03, friction=False).simulate(t_end=0.5, solver="ida")
    assert "atol_rescaled" not in big.stats.extra
    v_big = big["M0.v"] / 300.0
    v_small = np.interp(big.t, small.t, small["M0.v"]) / 0.03
    assert np.max(np.abs(v_small - v_big)) / np.ptp(v_big) < 1e-4


def test_repeated_run_is_reported_and_counted():
    m = chain(0.3, friction=False)
    res = m.simulate(t_end=0.2, solver="ida")
    info = res.stats.extra["atol_rescaled"]
    # positions peak near 1e-4 m and speeds near 4e-3 m/s here: atol scaled by those (s = 1 for the default)
    x_max = max(np.abs(res[f"M{i}.s"]).max() for i in range(4))
    v_max = max(np.abs(res[f"M{i}.v"]).max() for i in range(4))
    assert info["positions"] == pytest.approx(x_max, rel=0.05)
    assert info["speeds"] == pytest.approx(v_max, rel=0.05)
    assert res.stats.rhs_calls > info["first_run_rhs_calls"] > 0
    assert res.stats.wall_time >= info["first_run_wall_time"]
    # an array atol is used as given: one run
    c = m.compile()
    once = m.simulate(t_end=0.2, solver="ida", atol=np.full(c.N, 1e-8))
    assert "atol_rescaled" not in once.stats.extra
    # atol_rescale=False: one run with the scalar atol as given
    plain = m.simulate(t_end=0.2, solver="ida", atol_rescale=False)
    assert "atol_rescaled" not in plain.stats.extra
    assert plain.stats.rhs_calls == info["first_run_rhs_calls"]


def test_the_contract_makes_each_ida_run_once():
    """The accuracy contract scales a small motion's atol itself (``accuracy.motion_scale``): ida repeats none of
    its runs (``atol_rescale=False``; once the contract has scaled, ida's repeat could only resolve a kind the
    estimate leaves out as at rest, calibration seed 9001); the returned run still meets the accuracy."""
    from regmech.solvers import SOLVERS, _load
    from regmech.solvers.accuracy import simulate_with_accuracy
    _load()
    m = chain(0.3, friction=False)
    ref = m.simulate(t_end=0.2, solver="scipy:DOP853", rtol=1e-11, atol=1e-14, max_steps=100_000)
    flags = []

    def ida(model, **kw):
        flags.append(kw.get("atol_rescale", True))
        return SOLVERS["ida"](model, **kw)
    res = simulate_with_accuracy(m, "ida", ida, 0.0, 0.2, None, 1e-4, {})
    assert len(flags) >= 2 and not any(flags)
    assert rel_err(ref, res, "M0.v") <= res.stats.error_estimate <= 1e-4


def _compiled_chain():
    return chain(1.0, friction=False).compile()


def test_rescaled_atol_rule():
    c = _compiled_chain()
    rtol, atol = 1e-6, 1e-8
    Y = np.zeros((3, c.N))
    Y[1, c.ix] = 2e-3              # positions up to 2e-3 (below s / 30, s = 1: rescaled)
    Y[2, c.iv] = -0.5              # speeds up to 0.5 (above s / 30: as they are)
    Y[1, c.ilam] = 1e3             # forces are not a kind: they keep _atol_vector's scaling
    tol, factors = ida._rescaled_atol(c, Y, rtol, atol)
    assert factors["positions"] == pytest.approx(2e-3) and factors["speeds"] == pytest.approx(0.5)
    assert np.allclose(tol[c.ix], ida.KAPPA * rtol * 2e-3)
    assert np.allclose(tol[c.iv], ida.KAPPA * rtol * 0.5)
    assert np.all(tol[c.ilam] == atol)
    # the default atol is rtol * 1e-2
    assert np.allclose(ida._rescaled_atol(c, Y, rtol, None)[0], tol)
    # every kind at or above s / 30: no second run; nor for an array atol
    Y[1, c.ix] = 0.04
    assert ida._rescaled_atol(c, Y, rtol, atol) is None
    Y[1, c.ix] = 2e-3
    assert ida._rescaled_atol(c, Y, rtol, np.full(c.N, atol)) is None
    # a kind that did not move at all keeps atol (nothing to resolve)
    Y[2, c.iv] = 0.0
    tol, factors = ida._rescaled_atol(c, Y, rtol, atol)
    assert np.all(tol[c.iv] == atol) and factors["speeds"] == 1.0
    # never below what round-off leaves of the kind's magnitude (a very tight rtol)
    tol, _ = ida._rescaled_atol(c, Y, 1e-13, 1e-14)
    assert np.allclose(tol[c.ix], 1e3 * np.finfo(float).eps * 2e-3)
    # and never below RERUN_FLOOR times atol
    Y[1, c.ix] = 1e-11
    tol, _ = ida._rescaled_atol(c, Y, rtol, atol)
    assert np.allclose(tol[c.ix], ida.RERUN_FLOOR * atol)
    # a kind within the measure's floor of no motion (ABSOLUTE_FLOOR, 1e-12 SI units) did not move: its values are
    # round-off (calibration seed 9001: a stuck clutch's temperature rise of 1.5e-14 K had the device states'
    # atol scaled by RERUN_FLOOR, and the repeat crawled)
    Y[1, c.ix] = 1.5e-14
    assert ida._rescaled_atol(c, Y, rtol, atol) is None


def test_state_scale_saturation_and_floor():
    scale = StateScale(1e-8, [np.array([0, 1]), np.array([2])], 4, saturation=0.1, floor=1e-2)
    scale.see(np.array([[1e-3, -2e-3, 5.0, 7.0], [0.0, 1e-3, 0.0, 9.0]]))
    assert np.allclose(scale.factors(), [2e-2, 1.0])
    tol = scale.tolerances()
    assert np.allclose(tol, [2e-10, 2e-10, 1e-8, 1e-8])          # index 3 belongs to no kind: plain atol
    scale.see(np.array([1e-5, 0.0, 0.0, 0.0]))                    # smaller later: the largest so far stays
    assert np.allclose(scale.tolerances(), tol)
    tiny = StateScale(1e-8, [np.array([0])], 1, saturation=0.1, floor=1e-2)
    tiny.see(np.array([1e-9]))
    assert tiny.tolerances()[0] == pytest.approx(1e-10)           # floor: 1e-2 times atol


def test_a_failing_repeated_run_says_what_was_repeated_and_the_remedy(monkeypatch):
    runs = []
    real = ida._run_ida

    def run(**call):
        runs.append(call.get("kind_atol") is not None)
        if runs[-1]:
            raise rm.SimulationError("IDA failed at t=0.1 in model 'small_motion_chain': error test failed")
        return real(**call)

    monkeypatch.setattr(ida, "_run_ida", run)
    with pytest.raises(rm.SimulationError) as err:
        chain(0.3, friction=False).simulate(t_end=0.2, solver="ida")
    assert runs == [False, True]
    msg = str(err.value)
    assert "error test failed" in msg and "repeated run" in msg and "'small_motion_chain'" in msg
    assert "positions" in msg and "pass atol=" in msg
    # the atol suggested makes one run: its first run is not repeated
    suggested = float(msg.split("pass atol=")[1].split()[0])
    monkeypatch.setattr(ida, "_run_ida", real)
    res = chain(0.3, friction=False).simulate(t_end=0.2, solver="ida", atol=suggested)
    assert "atol_rescaled" not in res.stats.extra


def test_abs_max_agrees_with_numpy_for_short_and_long_arrays_nan_included():
    """``_numbers.abs_max`` (the tolerances' and the mode logic's short-array shortcut) gives numpy's value:
    the largest magnitude, 0 for an empty array, NaN wherever a NaN stands (Python's max alone would drop a NaN
    that is not first)."""
    import math
    from regmech._numbers import abs_max
    rng = np.random.default_rng(3)
    for n in (0, 1, 5, 32, 33, 200):
        x = rng.standard_normal(n) * 10.0 ** rng.integers(-5, 5, n)
        assert abs_max(x) == float(np.abs(x).max(initial=0.0))
        if n:
            for k in {0, n // 2, n - 1}:
                y = x.copy()
                y[k] = np.nan
                assert math.isnan(abs_max(y))


def test_an_ida_failure_after_an_event_names_the_devices_that_changed_there():
    """Calibration seed 6023: IDA failed right after a brake's reversal, and the message named the masses with the
    largest accelerations and the servo, not the brake. A segment that began at an event now says which."""
    from regmech.result import Event
    from regmech.solvers.ida import _restart_note
    assert _restart_note([], 0.1) == ""
    earlier = Event(0.05, "brake2", 0, 1, "mode")
    assert _restart_note([earlier], 0.100285582) == ""          # a segment that began at a time event
    note = _restart_note([earlier, Event(0.100285582, "lbrake1", -1, 1, "mode"),
                          Event(0.100285582, "hstop1", 0, 1, "contact")], 0.100285582)
    assert "t=0.100285582" in note and "lbrake1 Backward -> Forward" in note and "hstop1" in note
    assert "solver='dop853'" in note and "brake2" not in note


def test_an_explicit_run_announces_its_repeat():
    """A repeat with rescaled tolerances is said (a RuntimeWarning naming atol) and counted in the stats."""
    m = chain(0.3, friction=False)
    with pytest.warns(RuntimeWarning, match="made again"):
        res = m.simulate(t_end=0.2, solver="ida")
    assert res.stats.extra["atol_rescaled"]["first_run_rhs_calls"] > 0


def test_a_repeat_beyond_its_budget_returns_the_first_run(monkeypatch):
    """The repeat may cost what the first run cost: beyond that it is stopped, the first run is returned as it
    was (its step attempts and residual calls, nothing of the repeat), the stats say so and a warning too."""
    from regmech.solvers import ida
    m = chain(0.3, friction=False)
    plain = m.simulate(t_end=0.2, solver="ida", atol_rescale=False, native=False)
    monkeypatch.setattr(ida, "REPEAT_BUDGET", 0.5)
    with pytest.warns(RuntimeWarning, match="was stopped"):
        res = m.simulate(t_end=0.2, solver="ida", native=False)
    info = res.stats.extra["atol_rescaled"]
    assert info["stopped"] is True and info["repeat_budget_calls"] == int(0.5 * plain.stats.rhs_calls)
    assert res.stats.steps == plain.stats.steps and res.stats.rhs_calls == plain.stats.rhs_calls
    assert np.array_equal(res["M0.v"], plain["M0.v"])
