"""solver="auto" (regmech.solvers.auto): the choice from the model's structure, its reason, the default call."""

import math

import numpy as np
import pytest

import regmech as rm
from regmech.components import Fixed, Inertia, Spring
from regmech.solvers import auto
from regmech.solvers.accuracy import DEFAULT_ACCURACY


def undamped_chain(n=20, c=100.0, J=1.0, phi0=0.1):
    """n inertias on springs, the first one to the ground; the last one released from phi0."""
    m = rm.Model(f"undamped_chain_{n}")
    prev = m.add(Fixed("fixed")).flange
    for k in range(n):
        s = m.add(Spring(f"s{k}", c=c))
        b = m.add(Inertia(f"J{k}", J=J, phi0=phi0 if k == n - 1 else 0.0))
        m.connect(prev, s.flange_a)
        m.connect(s.flange_b, b.flange_a)
        prev = b.flange_b
    # slowest mode of the fixed-free chain of equal masses and springs
    w_min = 2.0 * math.sqrt(c / J) * math.sin(math.pi / (2 * (2 * n + 1)))
    return m, w_min


def energy(res, n):
    return sum(res[f"J{k}.kinetic"] for k in range(n)) + sum(res[f"s{k}.potential"] for k in range(n))


def test_undamped_chain_keeps_its_energy_under_the_default_call():
    """The issue's case: BDF at its default settings lost 3.3e-2 of the energy over 200 slowest periods."""
    m, w_min = undamped_chain()
    res = m.simulate(200 * 2 * math.pi / w_min)
    e = energy(res, 20)
    assert np.max(np.abs(e / e[0] - 1.0)) <= 1e-4
    assert res.stats.solver == "expm"
    assert "lightly damped" in res.stats.extra["auto_reason"]
    assert res.stats.extra["accuracy"] == DEFAULT_ACCURACY and res.stats.error_estimate <= DEFAULT_ACCURACY


def test_the_choice_and_its_reason_are_recorded():
    from regmech.library import coupled_clutches, train
    res = coupled_clutches().simulate(1.5, dt_out=1e-3)
    x = res.stats.extra
    assert res.stats.solver in rm.solvers.SOLVERS and x["auto_reason"].startswith(res.stats.solver)
    assert "3 friction devices" in x["auto_reason"] and x["auto_time"] >= 0.0
    assert "[auto: " in str(res.stats)
    big = train(150, c_r=0.0).simulate(5.0, dt_out=0.05, accuracy=1e-4)     # too large for the modal traits
    assert big.stats.solver == "expm" and "linear" in big.stats.extra["auto_reason"]


def test_a_nonlinear_model_never_goes_to_expm_and_a_stiff_one_never_to_an_explicit_method():
    from regmech.bench.hard_models import near_rigid_chain
    from regmech.library import vehicle_launch
    tr = auto.traits(vehicle_launch(), 0.0, 3.0, 5e-3)
    assert not tr.linear
    for acc in (1e-2, 1e-4, 1e-6):
        assert auto.choose(tr, acc)[0][0] != "expm"
    chain, sig = near_rigid_chain()
    tr = auto.traits(chain.to_model(sig), 0.0, 2.0, 4e-3)
    assert tr.spread >= auto.STIFF_SPREAD
    for acc in (1e-2, 1e-4, 1e-6):
        assert auto.choose(tr, acc)[0][0] in ("ida", "expm", "scipy:Radau", "scipy:BDF", "scipy:LSODA")


def test_settings_of_one_solver_are_refused_under_auto():
    m, _ = undamped_chain(3)
    for opt in ({"rtol": 1e-8}, {"atol": 1e-10}, {"h": 1e-3}, {"tol": 1e-4}):
        with pytest.raises(rm.ParameterError, match="solver='auto'"):
            m.simulate(1.0, **opt)
    with pytest.raises(rm.ParameterError, match="not options of"):
        m.simulate(1.0, linsolver="dense", order_p=2)


def test_auto_falls_back_when_its_first_choice_refuses(monkeypatch):
    from regmech.library import vehicle_launch
    monkeypatch.setattr(auto, "choose", lambda tr, acc: [("expm", "forced for the test"), ("ida", "fallback")])
    res = vehicle_launch().simulate(0.3, dt_out=5e-3)         # nonlinear: expm refuses, naming components
    reason = res.stats.extra["auto_reason"]
    assert res.stats.solver == "ida" and "'expm' refused first" in reason
    # the reason says ida is a fallback and why expm was chosen, not ida's own reason as if it had been preferred
    assert reason.startswith("ida as a fallback: solver='auto' chose 'expm' (forced for the test)")
    assert "'ida' ran instead (variable-order BDF" in reason and "fallback)" not in reason


def test_periods_a_stepping_method_must_resolve():
    """periods(a) = max over the modes of min(span f, ln(1/a) / (2 pi zeta))."""
    tr = auto.Traits(True, [], 0.0, 1.0, np.array([[0.05, 10.0], [0.0, 0.1]]), 10.0, 500, 4, 0)
    assert tr.modes.shape == (2, 2)
    assert tr.periods(1e-4) == pytest.approx(math.log(1e4) / (2 * math.pi * 0.05))
    tr.span = 1.0
    assert tr.periods(1e-4) == pytest.approx(10.0)                     # the run ends first
    tr = auto.Traits(True, [], 0.0, 1.0, np.zeros((0, 2)), 1.0, 500, 4, 0)
    assert tr.periods(1e-4) == 0.0 and auto.choose(tr, 1e-4)[0][0] == "ida"


def test_choices_on_library_models():
    from regmech.library import first, vehicle_launch
    tr = auto.traits(first(), 0.0, 1.0, 1e-3)                          # 12 periods against 1000 output steps
    assert [s for s, _ in auto.choose(tr, 1e-4)] == ["ida", "expm", "dop853", "scipy:Radau"]
    tr = auto.traits(vehicle_launch(), 0.0, 3.0, 5e-3)
    assert not tr.linear and "nonlinear" in auto.choose(tr, 1e-3)[0][1]
    m, w_min = undamped_chain(6)
    tr = auto.traits(m, 0.0, 100 * 2 * math.pi / w_min, 1.0)
    assert [s for s, _ in auto.choose(tr, 1e-3)] == ["expm", "ida", "dop853", "scipy:Radau"]


def test_a_fast_sinusoidal_input_keeps_tight_accuracies_away_from_expm():
    """chain_drive_5 (425 Hz polygonal forcing): expm's contract took 540 steps per forcing period at 1e-6
    (968 ms against ida's 404 ms), 23 at 1e-3."""
    from regmech.library import chain_drive
    tr = auto.traits(chain_drive(n_links=5), 0.0, 0.02, 1e-4)
    assert tr.f_forcing == pytest.approx(17 * 25.0)
    assert auto.choose(tr, 1e-6)[0][0] == "ida" and auto.choose(tr, 1e-3)[0][0] == "expm"


def sine_driven_chain(n, freq_hz=5.0):
    """The benchmark chain (benchmarks/bench_foundation.chain, rebuilt here): a sine torque on the first of n
    inertias joined by spring-dampers, the last one grounded by a spring."""
    from regmech.components import SpringDamper, Torque
    from regmech.signals import Sine
    m = rm.Model(f"sine_chain_{n}")
    fixed = m.add(Fixed("fixed"))
    drive = m.add(Torque("drive", tau=Sine(amplitude=10.0, freq_hz=freq_hz)))
    J = [m.add(Inertia(f"J{i}", J=0.01 * (1.0 + 0.5 * math.sin(i)))) for i in range(n)]
    m.connect(drive.flange, J[0].flange_a)
    for i in range(n - 1):
        sd = m.add(SpringDamper(f"sd{i}", c=1e4, d=1.0))
        m.connect(J[i].flange_b, sd.flange_a)
        m.connect(sd.flange_b, J[i + 1].flange_a)
    end = m.add(Spring("ground", c=1e3))
    m.connect(J[-1].flange_b, end.flange_a)
    m.connect(end.flange_b, fixed.flange)
    return m


@pytest.mark.slow
def test_a_large_linear_model_goes_to_expm_only_where_its_steps_repay_them():
    # regression: rule 3 sent every linear model above MODAL_MAX coordinates to expm at accuracy <= 1e-4, also
    # the 100-inertia chain driven at 5 Hz at 1e-6, where the forcing needs thousands of expm steps against a
    # few dozen periods of its fastest mode (expm 1.0 s, ida 0.25 s)
    # (measured with ida's Python callbacks: that path's weight; the native one, below)
    tr = auto.traits(sine_driven_chain(100), 0.0, 1.0, 1e-2)
    tr.ida_gain = 1.0
    tr.spectrum = None          # rule 3 alone (rule E takes this chain first: tests below)
    assert tr.modes is None and tr.linear          # too large for the modal traits
    assert tr.expm_steps_at(1e-6) > auto.large_model_bound(tr, 1e-6)
    first, reason = auto.choose(tr, 1e-6)[0]
    assert first == "ida" and "expm steps against at most" in reason
    # ... and no longer an accuracy threshold: at 1e-2 and 1e-4 one step per output interval repays the periods
    for acc in (1e-2, 1e-4):
        first, reason = auto.choose(tr, acc)[0]
        assert first == "expm" and "too many for the modal traits" in reason


def test_rule_3_weighs_the_size_of_the_model():
    # the same steps and periods: a ten times larger model makes each step of ida dearer, so expm repays more
    # (ida's Python callbacks: that path's weight)
    tr = auto.traits(sine_driven_chain(100), 0.0, 1.0, 1e-2)
    tr.ida_gain = 1.0
    tr.spectrum = None          # rule 3 alone
    big = auto.Traits(**{**{f: getattr(tr, f) for f in ("linear", "nonlinear", "floor", "spread", "modes_of", "span",
                                                       "expm_steps", "friction", "f_bound", "f_forcing")},
                         "states": 10 * tr.states})
    assert auto.large_model_bound(big, 1e-6) == pytest.approx(10 * auto.large_model_bound(tr, 1e-6))
    assert auto.choose(tr, 1e-6)[0][0] == "ida" and auto.choose(big, 1e-6)[0][0] == "expm"
    # a model of up to EXPM_STATES_REF states is never weighted below one
    small = auto.Traits(**{**big.__dict__, "states": 10, "_modes": False})
    assert auto.large_model_bound(small, 1e-4) == pytest.approx(
        auto.steps_per_period(1e-4) * small.periods_bound())


def test_native_ida_steps_count_where_the_periods_are_complete():
    """With ida's compiled callbacks (numba there) a step costs ``native_gain(states)`` times less, so expm needs
    fewer steps per period to be worth it -- but only where ``periods(a)`` counts every mode ida must resolve.
    Measured (CPU, accuracy 1e-3): the 10-inertia benchmark chain, modes all below the output grid's Nyquist
    frequency, native ida 8 ms against expm 25 ms; the undamped 6-inertia chain at dt_out 1 s, fast modes above
    it, native ida 238 ms (134,692 steps) against expm 33 ms."""
    from regmech.bench.hard_models import benchmark_chain
    tr = auto.traits(benchmark_chain(10), 0.0, 1.0, 1e-2)
    tr.ida_gain = 1.0
    python_choice = auto.choose(tr, 1e-3)[0][0]
    tr.ida_gain = auto.native_gain(tr.states)
    assert tr.modes is not None and tr.step_gain() == tr.ida_gain > 3.0
    assert auto.choose(tr, 1e-3)[0][0] == "ida"
    assert python_choice == "expm"
    m, w_min = undamped_chain(6)
    tr = auto.traits(m, 0.0, 100 * 2 * math.pi / w_min, 1.0)
    tr.ida_gain = auto.native_gain(tr.states)
    assert tr.step_gain() == 1.0 and auto.choose(tr, 1e-3)[0][0] == "expm"
    assert auto.native_gain(20) == pytest.approx(4.0) and auto.native_gain(2000) < 1.15


def test_rule_3_with_native_ida_weighs_its_cheap_steps():
    """Native ida against expm under the contract on the 5 Hz-driven chains (auto_rules.md): native ida was
    faster in every measured cell up to 100 inertias (the chain of 100 at 1e-2 and dt_out 1e-2: 29 ms against
    expm's 60 ms, which rule 3's Python-path weight chose; this file's chain of 100: 82 ms against 149 ms),
    expm in every cell at 1000 inertias."""
    tr = auto.traits(sine_driven_chain(100), 0.0, 1.0, 1e-2)
    tr.ida_gain = auto.native_gain(tr.states)
    tr.spectrum = None          # rule 3 alone
    assert tr.modes is None
    for acc in (1e-2, 1e-3, 1e-4, 1e-6):
        assert auto.choose(tr, acc)[0][0] == "ida"
    big = auto.traits(sine_driven_chain(1000), 0.0, 1.0, 1e-2)
    big.ida_gain = auto.native_gain(big.states)
    big.spectrum = None
    for acc in (1e-2, 1e-3, 1e-4, 1e-6):
        assert auto.choose(big, acc)[0][0] == "expm"
    # never weighted above the Python path's weight (a native step is not dearer than a Python one)
    for states in (100, 400, 2000, 20000):
        assert auto.native_size_weight(states) <= 1.0 or states > auto.EXPM_STATES_REF
    assert auto.native_size_weight(200) < 0.2 < 3.5 < auto.native_size_weight(2000) < 10.0


@pytest.mark.slow
def test_auto_falls_back_to_radau_when_expm_and_ida_meet_their_round_off_floor():
    """inertia_ratio_1e8 at accuracy 1e-6: expm's a-priori round-off bound (8.9e-7 against a/3) and ida's
    rtol floor (2.2e-9 for its 3e4 link spread) refuse it; auto used to stop there, although Radau meets it."""
    from regmech.bench.hard import CI, all_cases
    hc = [h for h in all_cases() if h.key == "inertia_ratio_1e8"][0]
    res = hc.build(CI)[0].simulate(hc.t_end[CI], dt_out=hc.dt_out[CI], accuracy=1e-6)
    assert res.stats.solver == "scipy:Radau"
    assert res.stats.error_estimate <= 1e-6
    assert "fallback" in res.stats.extra["auto_reason"]
    # and the answer is that accurate against the exact flow (the measure: error over the range of its kind)
    from regmech.bench.hard_models import inertia_ratio_chain
    chain, _ = inertia_ratio_chain()
    x, v = chain.exact(res.t, digits=30)
    err = max(np.max(np.abs(res[f"{nm}.w"] - v[:, i])) for i, nm in enumerate(chain.names))
    span = max(np.ptp(v[:, i]) for i in range(len(chain.names)))
    assert err <= 1e-6 * span, err / span


# ----------------------------------------------------------------------------------------------- rule E
def _explicit_first(tr, accuracy):
    """Rule E chose dop853: it runs before ida (after ida it is only the fallback of every model)."""
    order = [s for s, _ in auto.choose(tr, accuracy)]
    return order.index("dop853") < order.index("ida")


def damped_chain(n, d):
    from regmech.bench.hard_models import benchmark_chain
    return benchmark_chain(n, d=d)


@pytest.mark.slow
def test_the_split_bound_of_a_chain_is_its_top_frequency_and_its_damping():
    """``spectral_split`` on the benchmark chain (J about 1, c = 1e4, d): oscillation about 2 sqrt(c / J) = 200
    1/s, damping about 2 d / J, and their sum the spectral bound."""
    from regmech.compile.odeform import ode_form
    from regmech.solvers.ode_driver import spectral_bound, spectral_split
    for d in (1.0, 100.0, 3000.0):
        c = damped_chain(100, d).compile()
        J = ode_form(c).jacobian()
        osc, damp = spectral_split(J, c)
        assert osc == pytest.approx(200.0, rel=0.02) and damp == pytest.approx(4.0 * d, rel=0.02)
        rho = spectral_bound(J.tocsc(), c)
        assert max(osc, damp) <= rho * (1 + 1e-12) and rho <= (osc + damp) * (1 + 1e-12)
        lam = np.abs(np.linalg.eigvals(J.toarray())).max()
        assert lam <= rho * (1 + 1e-9)


def test_rule_e_sends_a_large_lightly_damped_linear_model_to_the_explicit_method():
    """The 5 Hz-driven chain of 100 inertias at accuracy 1e-6: dop853's pair 20 ms against native ida's 51 ms and
    expm's 235 ms on 1000 inertias (auto_rules.md, rule E); ida and expm stay as fallbacks."""
    tr = auto.traits(damped_chain(100, 1.0), 0.0, 1.0, 1e-2)
    assert tr.spectrum is not None
    order = [s for s, _ in auto.choose(tr, 1e-6)]
    assert order[0] == "dop853" and order[1:] == ["ida", "expm", "scipy:Radau"]
    assert "lightly damped oscillation" in auto.choose(tr, 1e-6)[0][1]
    # the pair's stable steps: the cap at the two tolerances over the span
    from regmech.solvers.scipy_ivp import stability_cap
    rho = tr.spectrum[0]
    assert tr.explicit_steps(1e-6) == pytest.approx(1.0 / stability_cap("DOP853", rho, 1e-7)
                                                    + 1.0 / stability_cap("DOP853", rho, 1e-8))


def test_rule_e_steps_aside_for_damped_small_frictional_or_long_runs():
    # the fastest rates are decays (dampers of 100 N m s/rad: damping 400 1/s against oscillation 200 1/s)
    tr = auto.traits(damped_chain(100, 100.0), 0.0, 1.0, 1e-2)
    assert tr.spectrum[2] > auto.EXPLICIT_DAMPING * tr.spectrum[1]
    assert not _explicit_first(tr, 1e-6)
    # too small: native ida's steps are cheaper there (at a loose accuracy below 200 states)
    tr = auto.traits(damped_chain(30, 1.0), 0.0, 1.0, 1e-2)
    assert tr.spectrum is None and not _explicit_first(tr, 1e-6)
    tr = auto.traits(damped_chain(75, 1.0), 0.0, 1.0, 1e-2)
    assert tr.states < auto.EXPLICIT_STATES_MIN_LOOSE
    assert auto.choose(tr, 1e-3)[0][0] != "dop853" and auto.choose(tr, 1e-6)[0][0] == "dop853"
    assert auto.choose(tr, auto.EXPLICIT_TIGHT)[0][0] == "dop853" != auto.choose(tr, 2 * auto.EXPLICIT_TIGHT)[0][0]
    tr = auto.traits(damped_chain(100, 1.0), 0.0, 1.0, 1e-2)
    assert auto.choose(tr, 1e-3)[0][0] == "dop853"
    # more stable steps than DOP853's step budget (a run of 200 s)
    tr = auto.traits(damped_chain(100, 1.0), 0.0, 200.0, 1.0)
    assert tr.explicit_steps(1e-6) > 12_000 and not _explicit_first(tr, 1e-6)
    # a friction device: events (ida's root finding)
    import regmech as rm
    from regmech.components import Clutch
    from regmech.signals import Constant
    m = damped_chain(100, 1.0)
    cl = m.add(Clutch("clutch", mu=0.3, peak=1.1, fn_max=1.0, f_normalized=Constant(1.0)))
    ground = m.add(rm.components.Fixed("g2"))
    m.connect(m.components["J50"].flange_b, cl.flange_a)
    m.connect(cl.flange_b, ground.flange)
    tr = auto.traits(m, 0.0, 1.0, 1e-2)
    assert tr.spectrum is None and not _explicit_first(tr, 1e-3)


@pytest.mark.slow
@pytest.mark.parametrize("accuracy", [1e-3, 1e-6])
def test_the_default_call_on_a_large_chain_keeps_its_promise(accuracy):
    """auto's dop853 under the contract against the exact flow (expm at a tight accuracy, its Richardson estimate
    near round-off): the error over the range of each kind within the accuracy asked."""
    n = 100 if accuracy <= auto.EXPLICIT_TIGHT else 200        # 200 / 400 states: rule E's sizes at each
    m = damped_chain(n, 1.0)
    res = m.simulate(1.0, 1e-2, accuracy=accuracy)
    assert res.stats.solver == "dop853" and res.stats.error_estimate <= accuracy
    ref = m.simulate(1.0, 1e-2, solver="expm", accuracy=1e-9)
    for kind in ("phi", "w"):
        names = [f"J{i}.{kind}" for i in range(n)]
        err = max(np.max(np.abs(res[nm] - ref[nm])) for nm in names)
        span = max(np.ptp(ref[nm]) for nm in names)
        assert err <= accuracy * span, (kind, err / span)


def test_rule_e_falls_back_when_the_explicit_method_refuses(monkeypatch):
    from regmech.solvers import SOLVERS
    from regmech.errors import SimulationError

    def refuses(*args, **kwargs):
        raise SimulationError("refused for the test")
    refuses.options = SOLVERS["dop853"].options
    monkeypatch.setitem(SOLVERS, "dop853", refuses)
    res = damped_chain(100, 1.0).simulate(1.0, 1e-2, accuracy=1e-6)
    reason = res.stats.extra["auto_reason"]
    assert res.stats.solver == "ida" and "'dop853' refused first: refused for the test" in reason


def test_rule_e_steps_aside_for_options_of_ida():
    # an option of ida's that dop853 does not take: ida runs instead of a refusal naming dop853
    assert auto.choose(auto.traits(damped_chain(100, 1.0), 0.0, 1.0, 1e-2), 1e-6)[0][0] == "dop853"
    res = damped_chain(100, 1.0).simulate(1.0, 1e-2, accuracy=1e-6, max_order=3)
    assert res.stats.solver == "ida"


def test_the_candidates_are_each_named_once():
    """A linear model whose round-off bound is near the accuracy (rule 2: expm) and too large for the modal traits
    (rule 3 would add expm again): expm ran twice before it refused (the review's model: chain of 1000 inertias
    with one link of 1e11 N m/rad, accuracy 1e-6)."""
    from regmech.bench.hard_models import benchmark_chain
    m = benchmark_chain(1000)
    m.components["sd500"].c = 1e11
    tr = auto.traits(m, 0.0, 1.0, 1e-2)
    for acc in (1e-2, 1e-4, 1e-6):
        names = [s for s, _ in auto.choose(tr, acc)]
        assert len(names) == len(set(names)), (acc, names)
    for n, d in ((100, 1.0), (100, 3000.0), (30, 1.0)):
        tr = auto.traits(damped_chain(n, d), 0.0, 1.0, 1e-2)
        for acc in (1e-2, 1e-4, 1e-6):
            names = [s for s, _ in auto.choose(tr, acc)]
            assert len(names) == len(set(names)), (n, d, acc, names)


def test_a_fallback_that_cannot_take_the_options_says_why_the_first_choice_refused(monkeypatch):
    # first_step is dop853's, not ida's: when dop853 refuses, the refusal is what the user reads, with a note
    from regmech.solvers import SOLVERS
    from regmech.errors import SimulationError
    real = SOLVERS["dop853"]

    def refuses(model, t_start=0.0, t_end=1.0, dt_out=None, rtol=1e-6, atol=None, first_step=None, **kw):
        raise SimulationError("refused for the test")
    refuses.options = real.options
    monkeypatch.setitem(SOLVERS, "dop853", refuses)
    auto._accepted.cache_clear()
    try:
        with pytest.raises(SimulationError) as err:
            damped_chain(100, 1.0).simulate(1.0, 1e-2, accuracy=1e-6, first_step=1e-4)
    finally:
        auto._accepted.cache_clear()
    msg = str(err.value)
    assert "refused for the test" in msg and "could not fall back to 'ida'" in msg and "first_step" in msg


def test_rule_e_prime_runs_expm_first_where_its_steps_are_fewer_on_a_fine_grid():
    """A stiff lightly damped chain (links of 1e6 N m/rad: rho about 2000 1/s) driven by a step at accuracy 1e-6:
    DOP853's cap takes about 2,700 steps for the pair against expm's 1,000 output steps at dt_out 1e-3 (the fuzz
    models' cells of that kind: expm 1.1-8.5x faster), so expm runs first and dop853 next; at dt_out 1e-2 expm's
    first step would be 20 times the fastest time scale (its first run refused and retried at a tiny step on the
    random trees), and at 2,000 states an expm step costs more: dop853 first."""
    from regmech.bench.hard_models import benchmark_chain
    from regmech.signals import Step
    m = benchmark_chain(100, tau=Step(height=10.0, start_time=0.1), c=1e6)
    tr = auto.traits(m, 0.0, 1.0, 1e-3)
    assert tr.explicit_steps(1e-6) > auto.EXPM_FIRST_RATIO * tr.expm_steps_at(1e-6)
    order = [s for s, _ in auto.choose(tr, 1e-6)]
    assert order == ["expm", "dop853", "ida", "scipy:Radau"]
    assert "fewer than the about" in auto.choose(tr, 1e-6)[0][1]
    coarse = auto.traits(m, 0.0, 1.0, 1e-2)
    assert [s for s, _ in auto.choose(coarse, 1e-6)][:2] == ["dop853", "ida"]
    big = auto.traits(benchmark_chain(700, tau=Step(height=10.0, start_time=0.1), c=1e6), 0.0, 1.0, 1e-3)
    assert big.states > auto.EXPM_FIRST_STATES and auto.choose(big, 1e-6)[0][0] == "dop853"


def _stiff_random_chain(n, seed, d_scale):
    """n inertias of 1e-3 to 10 kg m^2 on spring-dampers of 1e2 to 1e6 N m/rad (d_scale x 0.1-10 N m s/rad), a step
    torque on the first, the last grounded: local modes of light inertias on stiff links, kHz above the rest."""
    from regmech.components import SpringDamper, Torque
    from regmech.signals import Step
    rng = np.random.default_rng(seed)
    m = rm.Model(f"stiff_random_chain_{n}_{seed}")
    fixed = m.add(Fixed("fixed"))
    J = [m.add(Inertia(f"J{i}", J=float(10 ** rng.uniform(-3, 1)))) for i in range(n)]
    drive = m.add(Torque("drive", tau=Step(height=10.0, start_time=0.1)))
    m.connect(drive.flange, J[0].flange_a)
    for i in range(1, n):
        sd = m.add(SpringDamper(f"sd{i}", c=float(10 ** rng.uniform(2, 6)), d=d_scale * float(10 ** rng.uniform(-1, 1))))
        m.connect(J[i - 1].flange_b, sd.flange_a)
        m.connect(sd.flange_b, J[i].flange_a)
    end = m.add(Spring("ground", c=1e3))
    m.connect(J[-1].flange_b, end.flange_a)
    m.connect(end.flange_b, fixed.flange)
    return m


def test_rule3_counts_ringing_modes_above_the_output_grid():
    # found by fuzzing: rule 3 capped the periods a stepping method must resolve at the output grid's Nyquist
    # frequency and chose ida, which resolved the lightly damped kHz modes of the stiff links for 2 s where expm
    # took 0.06 s (a chain of 117 inertias). Ringing on top (damping <= EXPLICIT_DAMPING x oscillation) and a
    # stiff spread lift the cap
    m = _stiff_random_chain(117, 115, d_scale=0.013)
    tr = auto.traits(m, 0.0, 1.0, 1e-2)
    assert tr.modes is None and tr.spectrum is not None and auto.ringing(tr.spectrum, tr.spread)
    assert tr.f_bound > 10 * tr.f_nyquist
    first, reason = auto.choose(tr, 1e-3)[0]
    assert first == "expm" and "while they ring" in reason
    res = m.simulate(1.0, 1e-2)
    assert res.stats.solver == "expm" and res.stats.error_estimate <= DEFAULT_ACCURACY
    # heavy dampers on the same links: the top of the spectrum decays, the cap stays (ida steps over such modes)
    heavy = auto.traits(_stiff_random_chain(117, 115, d_scale=30.0), 0.0, 1.0, 1e-2)
    assert not auto.ringing(heavy.spectrum, heavy.spread) and heavy.f_bound == heavy.f_nyquist


def test_rule3_keeps_the_cap_on_the_uniform_benchmark_chain():
    # the benchmark chain rings on top too, but its links are alike (spread 1): no local modes far above the rest
    # (the bound on its frequencies, 45 Hz, is below the output grid's Nyquist frequency); rule 3 would not send it
    # to expm (rule E takes it first: dop853)
    from regmech.bench.hard_models import benchmark_chain
    tr = auto.traits(benchmark_chain(100), 0.0, 1.0, 1e-2)
    assert tr.spectrum is not None and not auto.ringing(tr.spectrum, tr.spread)
    assert tr.f_bound <= tr.f_nyquist
    if tr.ida_gain > 1.0:
        assert tr.expm_steps_at(DEFAULT_ACCURACY) > auto.large_model_bound(tr, DEFAULT_ACCURACY)
        assert [s for s, _ in auto.choose(tr, DEFAULT_ACCURACY)][:2] == ["dop853", "ida"]
