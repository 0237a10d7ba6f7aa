"""Step caps of the adaptive ODE-form solvers, and DOP853's absolute tolerances.

A run that needs more than ``max_steps`` steps stops with a ``SimulationError``
naming the fastest link, the time reached and the remedies (``common.StepBudget``),
instead of crawling; small ``max_steps`` keep these tests fast and machine-independent.
"""

import numpy as np
import pytest

import regmech as rm
from regmech.bench.hard_models import inertia_ratio_chain, stretched_chain, undamped_chain
from regmech.solvers import scipy_ivp


def _stretched(ratio):
    chain, signal = stretched_chain(ratio)
    return chain.to_model(signal)


def test_explicit_method_at_its_stability_limit_is_stopped_by_the_step_count():
    # spectral radius 4.0e3 1/s: the up-front prediction at RK45's stability limit is 1,218 steps
    # for 1 s, so a cap of 1,400 lets the run start; it takes 1,595 steps, so the count stops it
    model = _stretched(1e4)
    with pytest.raises(rm.SimulationError) as err:
        model.simulate(1.0, dt_out=0.01, solver="scipy:RK45", rtol=1e-8, max_steps=1400)
    msg = str(err.value)
    assert "more than max_steps=1400 steps" in msg and "stopped at t=" in msg and "last step" in msg
    assert "stability limit" in msg and "stiff" in msg
    assert "'link5'" in msg                                  # the fastest link is named
    assert "'ida'" in msg and "band_hz" in msg and "raise max_steps" in msg


def test_explicit_method_held_by_the_tolerance_is_told_so():
    model, _ = undamped_chain()
    with pytest.raises(rm.SimulationError) as err:
        model.simulate(20.0, dt_out=0.1, solver="scipy:RK23", rtol=1e-8, max_steps=500)
    msg = str(err.value)
    assert "set by the tolerance" in msg and "'dop853'" in msg
    assert "fastest link is Spring 'spring" in msg and "periods in the run" in msg


@pytest.mark.parametrize("solver", ["scipy:DOP853", "dop853"])
def test_the_highest_order_method_is_not_sent_to_itself(solver):
    model, _ = undamped_chain()
    with pytest.raises(rm.SimulationError) as err:
        model.simulate(20.0, dt_out=0.1, solver=solver, rtol=1e-10, max_steps=1000)
    msg = str(err.value)
    assert "set by the tolerance" in msg and "higher-order method" not in msg and "raise max_steps" in msg


def test_implicit_method_is_capped_too():
    model, _ = undamped_chain()
    with pytest.raises(rm.SimulationError) as err:
        model.simulate(20.0, dt_out=0.1, solver="scipy:Radau", rtol=1e-8, max_steps=200)
    msg = str(err.value)
    assert "more than max_steps=200" in msg and "implicit method" in msg and "'spring" in msg


def test_cap_counts_the_whole_run_across_segments():
    # the ramp's breakpoint at t = 2 s cuts the run in two segments: the cap is on their sum
    model = _stretched(1e3)
    steps = model.simulate(4.0, dt_out=0.05, solver="scipy:RK45", rtol=1e-6).stats.steps
    assert steps > 100
    model.simulate(4.0, dt_out=0.05, solver="scipy:RK45", rtol=1e-6, max_steps=steps)   # exactly enough
    with pytest.raises(rm.SimulationError, match=f"more than max_steps={steps - 1} "):
        model.simulate(4.0, dt_out=0.05, solver="scipy:RK45", rtol=1e-6, max_steps=steps - 1)


def test_convolution_is_capped_with_the_same_message():
    model = _stretched(1e5)
    with pytest.raises(rm.SimulationError) as err:
        model.simulate(1.0, dt_out=0.01, solver="convolution", rtol=1e-8, max_steps=300)
    msg = str(err.value)
    assert "solver 'convolution' took more than max_steps=300" in msg and "'link5'" in msg


def test_convolution_fixed_steps_are_not_capped():
    model = _stretched(1e3)
    res = model.simulate(1.0, dt_out=0.01, solver="convolution", h=0.002, max_steps=10)
    assert res.stats.steps >= 500


@pytest.mark.parametrize("bad", [0, -5, 2.5, True])
def test_max_steps_must_be_a_positive_integer(bad):
    with pytest.raises(rm.ParameterError, match="max_steps"):
        _stretched(1e3).simulate(0.1, solver="scipy:RK45", max_steps=bad)


def test_default_caps_leave_the_benchmark_ladder_alone():
    # the longest runs of `regmech bench` (rtol down to 1e-9, DOP853 references at 1e-12), module docstring
    longest = {"RK23": 20_542, "RK45": 1_735, "DOP853": 871, "Radau": 4_744, "BDF": 3_737, "LSODA": 3_981}
    for method, steps in longest.items():
        assert scipy_ivp.DEFAULT_MAX_STEPS[method] > 1.5 * steps, method


@pytest.mark.slow
def test_dop853_on_a_motion_far_below_one_keeps_its_accuracy_promise():
    """inertia_ratio_1e8 (all states below 2e-3): with the plain atol DOP853 at its stability limit let a
    speed drift 4.7e-4 of its range unnoticed. With atol scaled to the motion (``StateScale``) a bare run
    at rtol 1e-8 ends 4e-6 to 1.5e-4 off depending on the summation order of the right-hand side (measured
    over four orders of the same sums), so a bare run's error is round-off's choice and not asserted here.
    What must hold on every machine: under ``accuracy=`` the answer meets it, or the run is refused."""
    from regmech.bench.hard import CI, get_case
    case = get_case("inertia_ratio_1e8")
    model, check = case.build(CI)
    try:
        res = model.simulate(case.t_end[CI], dt_out=case.dt_out[CI], solver="scipy:DOP853", accuracy=1e-4)
    except rm.AccuracyError as exc:
        assert any(name in str(exc) for name in model.components), exc    # refused, naming the component
        return
    got = check(res)
    assert got.value <= 1e-4, got                                   # the promise, against the reference
    assert res.stats.error_estimate <= 1e-4


def test_state_scale_never_loosens_and_keeps_an_array_atol():
    model = inertia_ratio_chain()[0].to_model(inertia_ratio_chain()[1])
    c = model.compile()
    scale = scipy_ivp.StateScale(1e-8, c)
    scale.see(np.zeros(c.ode_size()))
    assert np.allclose(scale.tolerances(), 1e-8 * scipy_ivp.ATOL_FLOOR)
    u = np.full(c.ode_size(), 5.0)
    scale.see(u)
    assert np.allclose(scale.tolerances(), 1e-8)                # magnitude above 1: the plain atol
    vec = np.linspace(1e-9, 1e-8, c.ode_size())
    assert scipy_ivp.StateScale(vec, c).tolerances() is vec


@pytest.mark.slow
def test_convolution_stops_when_newton_keeps_failing_and_names_the_stiff_link():
    # stretched_1e7: once the chain settles the round-off of link5's force exceeds the speeds' atol;
    # Newton then fails at almost every attempt (deterministic: no wall clock involved, ~15,000 steps).
    # The up-front round-off refusal (check_link_spread) is switched off to reach that watch.
    from regmech.bench.hard import CI, get_case
    case = get_case("stretched_1e7")
    model, _ = case.build(CI)
    with pytest.raises(rm.SimulationError, match="round-off"):
        model.simulate(case.t_end[CI], dt_out=case.dt_out[CI], solver="convolution", rtol=case.rtol)
    with pytest.raises(rm.SimulationError) as err:
        model.simulate(case.t_end[CI], dt_out=case.dt_out[CI], solver="convolution", rtol=case.rtol,
                       stiff_check=False)
    msg = str(err.value)
    assert "failed to converge" in msg and "'link5'" in msg and "round-off" in msg


def test_dop853_cap_shrinks_with_rtol_as_its_steps_do():
    """The cap is STABLE_CAP of the stability interval at rtol 1e-3 and above, and shrinks as rtol^(1/8) below
    (as DOP853's own steps do), so that the accuracy contract's pair differs where steps are capped."""
    cap = scipy_ivp.stability_cap("DOP853", 100.0, 1e-3)
    assert cap == pytest.approx(scipy_ivp.STABLE_CAP * 6.0 / 100.0)
    assert scipy_ivp.stability_cap("DOP853", 100.0, 1e-1) == cap
    assert scipy_ivp.stability_cap("DOP853", 100.0, 1e-11) == pytest.approx(0.1 * cap)
    assert scipy_ivp.stability_cap("DOP853", 100.0) == cap
    assert scipy_ivp.stability_cap("RK45", 100.0, 1e-6) is None


def test_a_stiffness_no_link_explains_is_named_by_its_mass_and_devices():
    """Random calibration seed 78: a load regularised over 0.03 m/s on a 0.109 kg mass (a rate of 3e6 1/s) was
    refused for DOP853 with no component named; the message names the mass and what acts on it."""
    from regmech.components import Force, InverseSpeedDependentForce, Mass
    m = rm.Model("regularised_load")
    M1 = m.add(Mass("M1", m=0.109, v0=0.0))
    load = m.add(InverseSpeedDependentForce("load1", f_nominal=228.0, v_nominal=1.566, w_eps=0.03208))
    push = m.add(Force("push1", f=-447.1))
    m.connect(load.flange, M1.flange_b)
    m.connect(push.flange, M1.flange_a)
    with pytest.raises(rm.SimulationError) as info:
        m.simulate(0.5, 1e-3, solver="scipy:DOP853", rtol=1e-4)
    text = str(info.value)
    assert "'M1'" in text and "'load1'" in text and "spectral radius" in text


@pytest.mark.slow
@pytest.mark.parametrize("solver", ["scipy:DOP853", "dop853"])
def test_dop853_error_falls_with_rtol_on_a_forced_stiff_lightly_damped_pair(solver):
    # the step cap scales with rtol on the spectral radius for every model: a lightly damped, stiff link forced
    # slowly sits near DOP853's stability limit, where its global error stops following rtol if the steps may
    # grow to that limit (a cap on the damping alone was tried for symmetric mechanical systems: 1.2e-6
    # of the range at rtol 1e-5 to 1e-8 here, 5.2e-8 at 1e-9; reverted). Errors with the cap: 0.13-0.16 rtol.
    from regmech.components import Fixed, Inertia, Spring, SpringDamper, Torque
    from regmech.signals import Sine
    m = rm.Model("stiff_pair")
    ground = m.add(Fixed("ground"))
    drive = m.add(Torque("drive", tau=Sine(amplitude=1.0, freq_hz=0.5)))
    J1, J2 = m.add(Inertia("J1", J=1.0)), m.add(Inertia("J2", J=1.0))
    link, soft = m.add(SpringDamper("link", c=1e6, d=0.05)), m.add(Spring("soft", c=10.0))
    m.connect(drive.flange, J1.flange_a)
    m.connect(J1.flange_b, link.flange_a)
    m.connect(link.flange_b, J2.flange_a)
    m.connect(J2.flange_b, soft.flange_a)
    m.connect(soft.flange_b, ground.flange)
    ref = m.simulate(2.0, 1e-3, solver="scipy:DOP853", rtol=1e-13, atol=1e-15)
    for rtol in (1e-7, 1e-9):
        res = m.simulate(2.0, 1e-3, solver=solver, rtol=rtol)           # regmech's dop853 has the same cap
        err = np.max(np.abs(res["J1.w"] - ref["J1.w"])) / np.ptp(ref["J1.w"])
        assert err <= 2 * rtol, (rtol, err)


@pytest.mark.parametrize("solver", ["scipy:DOP853", "dop853"])
def test_dop853_is_refused_up_front_by_its_cap_not_after_its_steps(solver):
    # a fuzz model at rest on a 4e8 N m/rad spring (rho 2e4 1/s): at rtol 1e-8 DOP853's cap is h rho <= 1.28, so the
    # run needs 15,600 steps; the up-front check counted at the stability limit 6 (3,300 steps) and let it take
    # its 12,000 steps before the step count stopped it
    m = rm.Model("at_rest")
    J, s, f = m.add(rm.components.Inertia("J", J=1.0)), m.add(rm.components.Spring("s", c=4e8)), \
        m.add(rm.components.Fixed("fixed"))
    m.connect(s.flange_a, J.flange_a)
    m.connect(s.flange_b, f.flange)
    with pytest.raises(rm.SimulationError) as err:
        m.simulate(1.0, dt_out=1e-3, solver=solver, rtol=1e-8)
    msg = str(err.value)
    assert "limits this explicit method" in msg and "cap on DOP853" in msg and "took more than" not in msg
    assert "Spring 's'" in msg


def test_a_step_held_at_dop853s_cap_is_not_called_tolerance_bound(monkeypatch):
    # DOP853's steps never exceed regmech's cap (h rho <= 0.9 * 6 * (rtol / 1e-3)^(1/8), 1.28 at rtol 1e-8): a
    # run stopped by its step count with its last step at the cap was told "the steps are set by the tolerance"
    from types import SimpleNamespace

    from regmech.solvers import common, ode_driver
    cap = scipy_ivp.stability_cap("DOP853", 1.0, 1e-8)
    budget = common.StepBudget("dop853", 10, 1.0, scipy_ivp.EXPLICIT_STABILITY["DOP853"], cap)
    monkeypatch.setattr(ode_driver, "_spectral_radius", lambda problem, t, u: 2e4)
    stepper = SimpleNamespace(t=0.5, t_old=0.5 - 0.99 * cap / 2e4, u=None)
    why, stiff = budget._diagnosis(stepper, None, stepper.t - stepper.t_old)
    assert stiff and "regmech's cap" in why and "set by the tolerance" not in why
    why, stiff = budget._diagnosis(stepper, None, 0.3 * cap / 2e4)
    assert not stiff and "set by the tolerance" in why
