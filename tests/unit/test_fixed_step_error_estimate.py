"""The Richardson error estimate of the fixed-step solvers (regmech.solvers.richardson): option ``tol``."""

import math
import re

import numpy as np
import pytest

import regmech as rm
from regmech.components import Fixed, Inertia, SpringDamper, Torque
from regmech.errors import AccuracyError, ParameterError
from regmech.signals import Ramp
from regmech.solvers.ode_driver import GroupedKnotClock, KnotClock

# round-off-sensitive: .ci/run runs these again under other OpenBLAS kernels (see the README)
pytestmark = pytest.mark.roundoff

J, C, D = 1.0, 100.0, 1.0                 # omega_0 = 10 rad/s, zeta = 0.05
PHI0, W0 = 0.1, -0.5
T_END, DT_OUT = 2.0, 0.01


def oscillator():
    m = rm.Model("oscillator")
    fixed = m.add(Fixed("fixed"))
    body = m.add(Inertia("J", J=J, phi0=PHI0, w0=W0))
    link = m.add(SpringDamper("link", c=C, d=D))
    m.connect(body.flange_b, link.flange_a)
    m.connect(link.flange_b, fixed.flange)
    return m


def exact(t):
    """Free damped vibration: phi = e^(-zeta w0 t) (A cos wd t + B sin wd t), and its derivative."""
    w0 = math.sqrt(C / J)
    zeta = D / (2 * math.sqrt(C * J))
    wd = w0 * math.sqrt(1 - zeta ** 2)
    a, b = PHI0, (W0 + zeta * w0 * PHI0) / wd
    decay = np.exp(-zeta * w0 * t)
    phi = decay * (a * np.cos(wd * t) + b * np.sin(wd * t))
    w = decay * ((b * wd - zeta * w0 * a) * np.cos(wd * t) - (a * wd + zeta * w0 * b) * np.sin(wd * t))
    return phi, w


def true_error(res):
    """max |error| of the angle and the speed, each relative to its range (the estimate's measure)."""
    phi, w = exact(res.t)
    return max(np.max(np.abs(res["J.phi"] - phi)) / np.ptp(phi), np.max(np.abs(res["J.w"] - w)) / np.ptp(w))


def test_the_exact_solution_is_right():
    res = oscillator().simulate(T_END, DT_OUT, solver="scipy:DOP853", rtol=1e-12, atol=1e-14)
    assert true_error(res) < 1e-9


@pytest.mark.parametrize("solver, steps, t_end", [
    ("euler", [2e-4, 1e-4], 0.5),
    ("rk4", [1e-2, 5e-3], T_END),
    ("abm", [5e-3, 2.5e-3], T_END),
])
def test_the_estimate_tracks_the_true_error_in_the_asymptotic_range(solver, steps, t_end):
    m = oscillator()
    for h in steps:
        res = m.simulate(t_end, DT_OUT, solver=solver, h=h, tol=0.5)
        est, err = res.stats.error_estimate, true_error(res)
        assert err / 3 <= est <= 3 * err, (solver, h, est, err)
        assert res.stats.extra["error_signal"] in ("J.phi", "J.w")
        assert res.stats.extra["companion_ratio"] == 2.0          # the companion took exactly 2h


@pytest.mark.parametrize("solver, h, tol, t_end", [("euler", 1e-3, 1e-3, 0.5), ("rk4", 0.05, 1e-6, T_END)])
def test_refusal_names_the_component_and_its_step_meets_tol(solver, h, tol, t_end):
    m = oscillator()
    with pytest.raises(AccuracyError) as info:
        m.simulate(t_end, DT_OUT, solver=solver, h=h, tol=tol)
    msg = str(info.value)
    assert isinstance(info.value, rm.SimulationError)              # a regmech error like any other failure
    assert "'J'" in msg and ("J.phi" in msg or "J.w" in msg)
    assert f"tol = {tol:g}" in msg and "tol=None" in msg
    h_new = float(re.search(r"Use a step h <= ([0-9.e+-]+) s", msg).group(1))
    assert h_new < h
    res = m.simulate(t_end, DT_OUT, solver=solver, h=h_new, tol=tol)      # no AccuracyError now
    assert res.stats.error_estimate <= tol
    assert true_error(res) <= 3 * tol


def _counting(model):
    """Count the evaluations of the ODE right-hand side of the model's compiled system."""
    c = model.compile()
    inner = c.ode_rhs
    calls = [0]

    def counted(*args, **kw):
        calls[0] += 1
        return inner(*args, **kw)
    c.ode_rhs = counted
    return calls


def test_tol_none_skips_the_companion_and_the_companion_leaves_the_result_alone():
    m = oscillator()
    calls = _counting(m)
    bare = m.simulate(T_END, DT_OUT, solver="rk4", h=5e-3, tol=None)
    n_bare = calls[0]
    calls[0] = 0
    checked = m.simulate(T_END, DT_OUT, solver="rk4", h=5e-3)
    n_checked = calls[0]
    assert bare.stats.error_estimate is None and "companion_steps" not in bare.stats.extra
    assert checked.stats.error_estimate is not None
    # the companion at 2h: half the steps, about half the evaluations
    assert checked.stats.extra["companion_steps"] * 2 == checked.stats.steps == bare.stats.steps
    assert 1.4 * n_bare < n_checked < 1.6 * n_bare
    assert checked.stats.rhs_calls == bare.stats.rhs_calls         # the result counts the main run only
    np.testing.assert_array_equal(checked.t, bare.t)
    for name in ("J.phi", "J.w", "J.a", "link.tau"):
        np.testing.assert_array_equal(checked[name], bare[name])


@pytest.mark.slow
def test_stick_slip_scene_at_a_sensible_step_is_not_refused_and_not_changed():
    from regmech.library import coupled_clutches
    m = coupled_clutches()
    res = m.simulate(1.5, 0.01, solver="rk4", h=1e-3)
    assert res.stats.error_estimate < 1e-6
    bare = m.simulate(1.5, 0.01, solver="rk4", h=1e-3, tol=None)
    assert [(e.t, e.component, e.new_mode) for e in res.events] == \
        [(e.t, e.component, e.new_mode) for e in bare.events]
    np.testing.assert_array_equal(res["J4.w"], bare["J4.w"])
    ref = m.simulate(1.5, 0.01, solver="ida", rtol=1e-10, atol=1e-12)
    grid = np.linspace(0.0, 1.5, 301)
    for name in ("J1.w", "J2.w", "J3.w", "J4.w"):
        err = np.max(np.abs(np.interp(grid, res.t, res[name]) - np.interp(grid, ref.t, ref[name])))
        assert err < 1e-5 * np.ptp(ref[name]), name


def _chain3(c=1e5):
    m = rm.Model("chain3")
    fixed = m.add(Fixed("fixed"))
    drive = m.add(Torque("drive", tau=Ramp(height=10.0, duration=0.1)))
    masses = [m.add(Inertia(f"J{k}", J=1.0, phi0=0.0, w0=0.0)) for k in range(3)]
    m.connect(drive.support, fixed.flange)
    m.connect(drive.flange, masses[0].flange_a)
    for k in range(2):
        link = m.add(SpringDamper(f"link{k}", c=c, d=1.0))
        m.connect(masses[k].flange_b, link.flange_a)
        m.connect(link.flange_b, masses[k + 1].flange_a)
    anchor = m.add(SpringDamper("anchor", c=c, d=1.0))
    m.connect(masses[-1].flange_b, anchor.flange_a)
    m.connect(anchor.flange_b, fixed.flange)
    return m


def test_a_companion_that_diverges_falls_back_to_half_steps():
    # rk4 is stable up to h ~ 2.785 / 570 = 4.9e-3 s here: h = 3e-3 runs, its companion at 6e-3 diverges;
    # the error is then estimated against a run at h/2 (measured: 0.038, true 0.0377) and refused
    m = _chain3()
    res = m.simulate(0.5, 0.05, solver="rk4", h=3e-3, tol=None)
    assert np.all(np.isfinite(res["J2.w"]))
    ref = m.simulate(0.5, 0.05, rtol=1e-11, solver="ida")
    names = ["J0.w", "J1.w", "J2.w"]
    scale = max(np.ptp(ref[n]) for n in names)
    true = max(np.max(np.abs(np.interp(ref.t, res.t, res[n]) - ref[n])) for n in names) / scale
    with pytest.raises(AccuracyError, match=r"estimate against a run at h/2 \(the run at 2h failed") as info:
        m.simulate(0.5, 0.05, solver="rk4", h=3e-3)
    est = float(re.search(r"estimated error ([0-9.e+-]+)", str(info.value)).group(1))
    assert true / 1.5 < est < true * 1.5
    # a looser tol accepts the run with the h/2 estimate recorded
    ok = m.simulate(0.5, 0.05, solver="rk4", h=3e-3, tol=0.1)
    assert ok.stats.extra["error_companion"].startswith("h/2") and ok.stats.error_estimate == pytest.approx(est, rel=0.1)


@pytest.mark.slow
def test_a_2h_estimate_outside_the_asymptotic_range_is_checked_at_h_over_2():
    # abm on the vehicle launch at h = 1e-3: the run at 2h puts the tyre's contact mode near abm's
    # stability limit and over-estimates (0.013) an error that is 2.2e-4; the run at h/2 decides
    from regmech.library import vehicle_launch
    res = vehicle_launch().simulate(2.0, dt_out=0.01, solver="abm", h=1e-3)
    assert res.stats.error_estimate <= 1e-3
    assert res.stats.extra["error_companion"].startswith("h/2") and res.stats.extra["error_estimate_2h"] > 1e-3


def test_expm_round_off_floor_is_refused_up_front_naming_the_stiff_link():
    # the floor comes from the set-up, not the steps: every run shares it, so it is decided from the
    # spectrum before the run (4 eps * 4.1e6^2 = 1.5e-2 > tol, link spread 4.1e6), the same on every BLAS build
    from regmech.bench.hard_models import stretched_chain
    chain, signal = stretched_chain(1e7)
    m = chain.to_model(signal)
    with pytest.raises(AccuracyError) as info:
        m.simulate(10.0, dt_out=0.02, solver="expm", h=0.01)
    msg = str(info.value)
    assert "round-off floor" in msg and "'link5'" in msg and "at any step" in msg and "rm.Scene(band_hz" in msg
    # the same chain at a frequency ratio of 1e3 is exact to round-off: a tiny estimate, no refusal
    chain, signal = stretched_chain(1e3)
    res = chain.to_model(signal).simulate(10.0, dt_out=0.02, solver="expm", h=0.01)
    assert res.stats.error_estimate < 1e-9
    assert res.stats.error_estimate >= res.stats.extra["error_floor"] > 0


@pytest.mark.slow
@pytest.mark.parametrize("ratio", [1e4, 1e6, 1e7])
def test_expm_round_off_bound_covers_the_error_against_a_30_digit_answer(ratio):
    # the a-priori bound must lie above the true error at any step (measured 0.08..0.23 of it); the error is
    # the same at every step (a set-up floor), so the bound is checked at a coarse and a fine step
    import numpy as np
    from regmech.bench.hard_models import stretched_chain
    chain, signal = stretched_chain(ratio)
    m = chain.to_model(signal)
    for h in (0.1, 0.005):
        res = m.simulate(4.0, dt_out=0.1, solver="expm", h=h, tol=0.5)
        x, _ = chain.exact(res.t, digits=30)
        err = max(np.max(np.abs(res[f"{nm}.phi"] - x[:, i])) for i, nm in enumerate(chain.names)) / np.ptp(x)
        assert err <= res.stats.extra["error_floor"] <= res.stats.error_estimate


def test_expm_estimate_follows_the_input_hold_error():
    # a sine torque held by its midpoint value (order_p = 1): the estimate assumes the guaranteed order 1, the
    # midpoint rule reaches order 2 on smooth forcing, so the estimate is (2^2 - 1) / (2^1 - 1) = 3 times the
    # error: on the safe side, never below it (a user's function: a Sine would be taken exactly by its particular
    # solution, with no hold error at all)
    import math
    m = oscillator()
    drive = m.add(Torque("drive", tau=lambda t: 50.0 * math.sin(2 * math.pi * 3.0 * t)))
    m.connect(drive.support, m["fixed"].flange)
    m.connect(drive.flange, m["J"].flange_a)
    ref = m.simulate(T_END, DT_OUT, solver="scipy:DOP853", rtol=1e-12, atol=1e-14)
    res = m.simulate(T_END, DT_OUT, solver="expm", h=0.01, order_p=1, tol=0.5)
    err = max(np.max(np.abs(res[n] - ref[n])) / np.ptp(ref[n]) for n in ("J.phi", "J.w"))
    assert err <= res.stats.error_estimate <= 4 * err, (res.stats.error_estimate, err)


def test_grouped_clock_takes_exactly_double_steps_on_every_other_knot():
    knots = np.arange(1, 11) * 0.01                  # h = dt_out: one main step per output interval
    main, comp = KnotClock(0.0, knots, 0.1, 0.01), GroupedKnotClock(0.0, knots, 0.1, 0.01, factor=2)
    t_main, t_comp, t = [], [], 0.0
    while t < 0.1:
        _, t = main.next_step(t)
        t_main.append(t)
    t = 0.0
    while t < 0.1:
        h, t = comp.next_step(t)
        assert h == pytest.approx(0.02, rel=1e-12)
        t_comp.append(t)
    assert t_comp == t_main[1::2] and comp.main_steps == len(t_main)
    # three main steps per interval (dt_out / h = 2.5): pairs of intervals, 3 steps of 2h each
    comp = GroupedKnotClock(0.0, [0.005, 0.01], 0.01, 0.002, factor=2)
    assert comp.plan == [(0.01, 3)]


@pytest.mark.parametrize("solver", ["euler", "rk4", "abm", "expm"])
@pytest.mark.parametrize("bad", [0.0, 1.0, -1e-3, "1e-3", True])
def test_bad_tol_is_refused(solver, bad):
    with pytest.raises(ParameterError, match="tol"):
        oscillator().simulate(0.1, 0.01, solver=solver, tol=bad)


def test_a_long_horizon_at_a_coarse_step_asks_for_a_much_smaller_step_not_another_solver():
    # 320 periods at h omega = 0.5: the runs at h, 2h, 4h all carry phase errors of the size of the
    # motion, so the differences do not shrink; that is not a round-off floor
    from regmech.components import Fixed, Inertia, Spring
    m = rm.Model("osc")
    J = m.add(Inertia("J", J=1.0, phi0=1.0, w0=0.0))
    k = m.add(Spring("k", c=100.0))
    g = m.add(Fixed("g"))
    m.connect(J.flange_b, k.flange_a)
    m.connect(k.flange_b, g.flange)
    with pytest.raises(rm.AccuracyError) as err:
        m.simulate(200.0, dt_out=0.1, solver="rk4", h=0.05)
    msg = str(err.value)
    assert "far from resolving the motion" in msg and "'J'" in msg
    assert "a smaller step will not help" not in msg


@pytest.mark.slow
def test_the_half_step_check_is_skipped_on_long_runs(monkeypatch):
    # beyond HALF_STEP_MAX_STEPS main steps the 2h estimate decides alone (the h/2 run would cost twice
    # the main run): the same abm run as above is then refused on its 2h estimate
    from regmech.library import vehicle_launch
    from regmech.solvers import richardson
    monkeypatch.setattr(richardson, "HALF_STEP_MAX_STEPS", 100)
    with pytest.raises(AccuracyError, match="estimated error"):
        vehicle_launch().simulate(2.0, dt_out=0.01, solver="abm", h=1e-3)


@pytest.mark.parametrize("solver", ["euler", "rk4", "abm", "expm"])
def test_a_step_that_needs_more_than_max_steps_is_refused_before_the_run(solver):
    # h = 1e-12 over 10 s would be 1e13 steps: a hang, refused up front with the count and the remedies
    m = oscillator()
    with pytest.raises(rm.SimulationError, match=r"takes 10,000,000,000,000 steps, more than max_steps=2,000,000"):
        m.simulate(10.0, dt_out=0.1, solver=solver, h=1e-12)
    with pytest.raises(rm.SimulationError, match="more than max_steps=50"):
        m.simulate(1.0, dt_out=0.1, solver=solver, h=0.01, max_steps=50)
    assert m.simulate(1.0, dt_out=0.1, solver=solver, h=0.01, max_steps=100, tol=None).stats.steps == 100


@pytest.mark.parametrize("h, tol", [(0.1, 1e-6), (0.1, 1e-8), (0.05, 1e-8)])
def test_expm_suggests_its_step_with_the_order_it_shows(h, tol):
    """expm's guaranteed order is order_p = 2 (holding the inputs by a line over a step); under forcing slow
    against the step its error goes as h^4. The step suggested after a refusal used the order 2 and overshot:
    the default call on a 1,000-inertia chain at accuracy 1e-6 ended at an estimate of 2.9e-10 (2,500 steps
    where 600 do); here the estimates were 2.4e-3 to 2.9e-5 of tol. With the order observed between the
    runs at h, 2h and 4h (at most 2 order_p) the suggested step meets tol with its estimate above tol / 100 (a
    user's function: a Sine would be exact)."""
    import math
    m = oscillator()
    drive = m.add(Torque("drive", tau=lambda t: 5.0 * math.sin(math.pi * t)))
    m.connect(drive.flange, m["J"].flange_a)
    with pytest.raises(AccuracyError) as info:
        m.simulate(4.0, 0.1, solver="expm", h=h, tol=tol)
    h_new = float(re.search(r"Use a step h <= ([0-9.e+-]+) s", str(info.value)).group(1))
    assert "faster than the guaranteed order 2" in str(info.value)
    res = m.simulate(4.0, 0.1, solver="expm", h=h_new, tol=tol)
    assert tol / 100 <= res.stats.error_estimate <= tol


def test_a_pair_that_agrees_everywhere_names_no_worst_signal():
    """A model at rest (no load, no start motion): both runs of the pair are exactly zero, the estimate is 0 and
    no signal is named the worst (the first state's name came back before)."""
    m = rm.Model("at rest")
    fixed = m.add(Fixed("fixed"))
    body = m.add(Inertia("J", J=J))
    link = m.add(SpringDamper("link", c=C, d=D))
    m.connect(body.flange_b, link.flange_a)
    m.connect(link.flange_b, fixed.flange)
    res = m.simulate(0.5, DT_OUT, solver="rk4", h=1e-2, tol=0.5)
    assert res.stats.error_estimate == 0.0
    assert res.stats.extra["error_signal"] == "" and res.stats.extra["error_component"] == ""
    assert "worst" not in str(res.stats)
