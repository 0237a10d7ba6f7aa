"""regmech's own Dormand-Prince integrators (``solvers.dopri``: ``dopri5``, ``dop853``) take scipy's steps
and give scipy's values up to round-off, compiled or not; their dense output, refusals and accuracy contract."""

import math

import numpy as np
import pytest
from scipy.integrate import DOP853, RK45

import regmech as rm
from regmech.bench.hard_models import benchmark_chain
from regmech.solvers import dopri

PAIRS = [(dopri.Dopri5, RK45), (dopri.Dop853, DOP853)]
SAME_METHOD = [("dopri5", "scipy:RK45"), ("dop853", "scipy:DOP853")]


def van_der_pol(t, y):
    """A forced nonlinear oscillator (mu = 5): steps that grow and shrink by orders of magnitude."""
    return np.array([y[1], 5.0 * (1.0 - y[0] ** 2) * y[1] - y[0] + math.sin(3.0 * t)])


def spring_chain(n):
    """A forced chain of n unit masses (springs 1e4, dampers 1): ``y = (x, v)``."""
    def rhs(t, y):
        x, v = y[:n], y[n:]
        f = 1e4 * (x[1:] - x[:-1]) + (v[1:] - v[:-1])
        a = np.zeros(n)
        a[:-1] += f
        a[1:] -= f
        a[0] += 10.0 * math.sin(31.4 * t)
        a[-1] -= 1e3 * x[-1]
        return np.concatenate((v, a))
    return rhs


CASES = [("van_der_pol", van_der_pol, np.array([2.0, 0.0]), 12.0),
         ("spring_chain", spring_chain(300), np.zeros(600), 0.5)]


def march(cls, fun, y0, t_end, rtol, instants):
    """Step ``cls`` to ``t_end``; the dense output at ``instants``, alternately as one array and one by one."""
    s = cls(fun, 0.0, y0, t_end, rtol=rtol, atol=rtol * 1e-2)
    cols, k, steps = [], 0, 0
    while s.status == "running":
        assert s.step() is None
        steps += 1
        inside = [t for t in instants[k:] if t <= s.t]
        if inside:
            d = s.dense_output()
            cols.append(d(np.array(inside)) if steps % 2 else np.column_stack([d(t) for t in inside]))
            k += len(inside)
    assert k == len(instants)
    return np.hstack(cols), steps, s.nfev


@pytest.fixture(params=["compiled", "numpy"])
def path(request, monkeypatch):
    """Both paths of the passes over the stages: numba's kernels, and numpy's when numba is not installed."""
    if request.param == "numpy":
        monkeypatch.setattr(dopri, "_kernels", None)
    elif dopri.compiled_passes(10 ** 6) is None:
        pytest.skip("numba not installed")
    else:
        monkeypatch.setattr(dopri, "COMPILED_MIN_STATES", 0)        # the small cases too
    return request.param


@pytest.mark.slow
@pytest.mark.parametrize("ours, theirs", PAIRS, ids=["dopri5", "dop853"])
@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
@pytest.mark.parametrize("rtol", [1e-4, 1e-8])
def test_same_steps_and_values_as_scipy(ours, theirs, case, rtol, path):
    _, fun, y0, t_end = case
    instants = np.linspace(0.0, t_end, 157)[1:]
    want, steps, nfev = march(theirs, fun, y0, t_end, rtol, instants)
    got, our_steps, our_nfev = march(ours, fun, y0, t_end, rtol, instants)
    half = len(y0) // 2
    assert_same_run(got, want, our_steps, steps, rtol, (slice(0, half), slice(half, None)))


def assert_same_run(got, want, our_steps, steps, rtol, kinds):
    """The same steps and values to round-off (relative to the range of the states of a kind: positions first,
    then speeds; ``kinds``: their slices of the rows). The sums run in another order, so a decision round-off
    can tip (an error norm within an ulp of 1, an event instant) may differ: then a step or two more or fewer,
    and values within the tolerance."""
    assert abs(our_steps - steps) <= 2, (our_steps, steps)
    bound = 1e-9 if our_steps == steps else 10 * rtol
    for kind in kinds:
        assert np.max(np.abs(got[kind] - want[kind])) <= bound * np.ptp(want[kind])


@pytest.mark.parametrize("ours, theirs", SAME_METHOD)
@pytest.mark.parametrize("model", ["chain", "coupled_clutches"])
def test_through_regmech_same_steps_and_answer_as_the_scipy_solver(ours, theirs, model):
    # the chain runs the compiled linear form (stages written in place, ``rhs_into``), under DOP853's step cap
    # at rtol 1e-9; CoupledClutches the friction modes, events located on the dense output
    if model == "chain":
        m, t_end, dt, rtol, names = benchmark_chain(300), 0.5, 1e-2, 1e-9, ["J0.w", "J150.w", "J299.w"]
    else:
        m, t_end, dt, rtol, names = rm.library.coupled_clutches(), 1.5, 1e-3, 1e-6, ["J1.w", "J2.w", "J3.w", "J4.w"]
    a = m.simulate(t_end, dt, solver=theirs, rtol=rtol)
    b = m.simulate(t_end, dt, solver=ours, rtol=rtol)
    assert b.stats.solver == ours and b.stats.events == a.stats.events
    assert len(a.t) == len(b.t) and np.allclose(a.t, b.t, rtol=0, atol=1e-9)    # event rows at the same instants
    got, want = np.array([b[k] for k in names]), np.array([a[k] for k in names])
    assert_same_run(got, want, b.stats.steps, a.stats.steps, rtol, (slice(None),))     # speeds only


def test_dense_output_holds_only_until_the_next_step():
    s = dopri.Dop853(van_der_pol, 0.0, np.array([2.0, 0.0]), 1.0, rtol=1e-6, atol=1e-8)
    s.step()
    d = s.dense_output()
    mid = 0.5 * (s.t_old + s.t)
    y = d(mid)
    assert y.shape == (2,) and d(np.array([mid, s.t])).shape == (2, 2)
    assert np.allclose(d(s.t), s.y, rtol=1e-12, atol=1e-14)          # the interpolant ends on the step's end
    assert np.allclose(d(s.t_old), s.y_old, rtol=1e-12, atol=1e-14)
    s.step()
    with pytest.raises(RuntimeError, match="after its integrator began another step"):
        d(mid)


def test_dense_output_before_a_step_or_after_a_failed_one_raises():
    s = dopri.Dopri5(van_der_pol, 0.0, np.array([2.0, 0.0]), 1.0, rtol=1e-6, atol=1e-8)
    with pytest.raises(RuntimeError, match="only after a step"):
        s.dense_output()
    s.step()
    d = s.dense_output()
    s.fun = lambda t, y: np.full(2, np.nan)       # the next step fails, having overwritten the stages
    assert s.step() is not None and s.status == "failed"
    with pytest.raises(RuntimeError, match="another step"):
        d(s.t)


@pytest.mark.parametrize("solver", ["dopri5", "dop853", "scipy:RK45", "scipy:DOP853"])
def test_a_model_without_states_fills_the_grid(solver):
    # a prescribed motion leaves nothing to integrate: one empty step, the outputs from the motion itself
    from regmech.components import Inertia, Position
    from regmech.signals import Sine
    m = rm.Model("prescribed")
    src = m.add(Position("src", phi_ref=Sine(amplitude=1.0, freq_hz=1.0)))
    J = m.add(Inertia("J1", J=2.0))
    m.connect(src.flange, J.flange_a)
    res = m.simulate(1.0, dt_out=0.01, solver=solver)
    assert len(res.t) == 101 and np.allclose(res["J1.phi"], np.sin(2 * np.pi * res.t), atol=1e-12)


@pytest.mark.parametrize("solver", ["dopri5", "dop853", "scipy:RK45", "scipy:DOP853", "scipy:Radau"])
@pytest.mark.parametrize("when", ["start", "later", "later_elsewhere"])
def test_a_right_hand_side_that_is_nan_ends_in_an_error_naming_the_state(solver, when):
    # not reachable through the library's components (signals and start values are checked first): a subclass's
    # law that returns NaN. scipy's explicit methods looped forever on a NaN at the start (their first step is NaN)
    m = rm.library.coupled_clutches()
    c = m.compile()
    law = c.ode_rhs
    # two instants later: where the shrinking steps stop short of the NaN depends on round-off of t (a least step
    # on from there found it on one machine and missed it on another, for scipy:DOP853 and dop853 alike)
    t_bad = {"start": 0.0, "later": 0.5, "later_elsewhere": 0.3711}[when]

    def broken(t, u, modes):
        g = law(t, u, modes)
        if t >= t_bad:
            g = g.copy()
            g[-1] = np.nan
        return g
    c.ode_rhs = broken
    # a loop inside scipy's step never reaches regmech's timeout_s: an alarm makes a hang a failure, not a stall
    import signal

    def stalled(*_):
        raise TimeoutError("the run did not end within 60 s (a NaN that loops inside a step)")
    previous = signal.signal(signal.SIGALRM, stalled)
    signal.alarm(60)
    try:
        with pytest.raises(rm.SimulationError) as err:
            m.simulate(1.0, 1e-2, solver=solver)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    msg = str(err.value)
    assert "NaN or inf" in msg and "the speed of 'J4'" in msg, msg
    assert f"t={t_bad:g}" in msg


def test_caller_start_is_not_written_and_atol_arrays_are_taken():
    y0 = np.array([2.0, 0.0])
    s = dopri.Dopri5(van_der_pol, 0.0, y0, 1.0, rtol=1e-6, atol=np.array([1e-8, 1e-6]))
    while s.status == "running":
        s.step()
    assert np.array_equal(y0, [2.0, 0.0]) and s.t == 1.0
    assert s.atol.shape == (2,) and s.atol[1] == 1e-6


def test_a_step_below_the_spacing_of_numbers_fails_with_scipy_message():
    # a right-hand side that blows up in finite time: the steps shrink until they cannot
    s = dopri.Dopri5(lambda t, y: y * y, 0.0, np.array([1.0]), 2.0, rtol=1e-8, atol=1e-10)
    msg = None
    for _ in range(10_000):
        msg = s.step()
        if s.status != "running":
            break
    assert s.status == "failed" and "less than spacing" in msg and s.t < 1.001      # y = 1 / (1 - t)


@pytest.mark.parametrize("solver", ["dopri5", "dop853"])
@pytest.mark.parametrize("bad", [float("nan"), math.inf])
def test_a_signal_that_turns_non_finite_is_a_regmech_error_naming_it(solver, bad):
    from regmech.components import Torque
    from test_input_errors import _at, _driven, _late
    with pytest.raises(rm.SimulationError) as err:
        _driven(Torque("src", tau=_late(bad))).simulate(1.5, solver=solver)
    msg = str(err.value)
    assert "Torque 'src'" in msg and "tau" in msg and "finite" in msg and 0.7 <= _at(msg) < 0.8


@pytest.mark.parametrize("solver", ["dopri5", "dop853"])
def test_the_step_budget_stops_a_run_and_names_the_solver(solver):
    with pytest.raises(rm.SimulationError) as err:
        rm.library.first().simulate(1.0, 1e-3, solver=solver, rtol=1e-8, max_steps=20)
    msg = str(err.value)
    assert f"solver '{solver}'" in msg and "more than max_steps=20" in msg


def test_the_accuracy_contract_holds_with_dop853():
    m = rm.library.first()
    ref = m.simulate(1.0, 1e-3, solver="dop853", rtol=1e-12, atol=1e-14)
    res = m.simulate(1.0, 1e-3, solver="dop853", accuracy=1e-5)
    assert res.stats.error_estimate <= 1e-5
    for k in ("inertia1.w", "inertia2.w", "inertia3.w"):
        assert np.max(np.abs(res[k] - ref[k])) <= 1e-5 * np.ptp(ref[k]), k


@pytest.mark.parametrize("solver", ["dop853", "dopri5"])
def test_a_model_too_stiff_for_max_steps_is_refused_up_front_as_by_scipy_methods(solver):
    # chain30's spectral radius ~196 1/s: over 1 s at the stability limit (6 / rho for DOP853, 3.3 / rho for RK45)
    # more than 30 steps, so the shared up-front check refuses before the first step
    with pytest.raises(rm.SimulationError) as err:
        benchmark_chain(30).simulate(1.0, 0.01, solver=solver, max_steps=30)
    msg = str(err.value)
    assert f"solver '{solver}'" in msg and "stiff for an explicit method" in msg and "'ida'" in msg


@pytest.mark.parametrize("solver", ["dop853", "dopri5"])
def test_the_compiled_stage_sweep_gives_the_loops_numbers(solver, monkeypatch):
    """``OdeProblem.stage_sweep`` (a step's stages in one compiled call, ``_dopri_kernels.linear_stages``) makes the
    same passes in the same order as the Python loop over the stages: the same steps, evaluations and numbers,
    dense output included (a chain with a step input whose breakpoint falls inside a step)."""
    pytest.importorskip("numba")
    from regmech.bench.hard_models import benchmark_chain
    from regmech.signals import Step
    from regmech.solvers import ode_driver
    m = benchmark_chain(120, tau=Step(height=5.0, start_time=0.0123))
    m.compile()
    used = []
    sweep = ode_driver.OdeProblem.stage_sweep

    def spy(self):
        got = sweep(self)
        used.append(got is not None)
        return got
    monkeypatch.setattr(ode_driver.OdeProblem, "stage_sweep", spy)
    a = m.simulate(0.2, 1e-3, solver=solver, rtol=1e-7)
    assert used and all(used)
    monkeypatch.setattr(ode_driver.OdeProblem, "stage_sweep", lambda self: None)
    b = m.simulate(0.2, 1e-3, solver=solver, rtol=1e-7)
    assert a.stats.steps == b.stats.steps and a.stats.rhs_calls == b.stats.rhs_calls
    np.testing.assert_array_equal(a._traj.Y, b._traj.Y)


def test_the_compiled_passes_leave_out_terms_of_zero_weight_and_keep_the_sums():
    """``_dopri_kernels._combine`` skips the zero weights of the tables (a third of DOP853's: each would read a row
    of stages from memory): the sums are the plain ones in stage order to the last bit, a zero first weight or
    zero weights only included, and a non-finite row of zero weight does not reach them."""
    pytest.importorskip("numba")
    from regmech.solvers import _dopri_kernels as k
    rng = np.random.default_rng(7)
    n = 3 * k.BLOCK + 17                                # whole blocks and a partial one
    K = rng.standard_normal((6, n))
    y0, y1 = rng.standard_normal(n), rng.standard_normal(n)
    for w in ([0.0, 0.5, 0.0, -1.25, 2.0, 0.0], [0.3, 0.0, 0.0, 0.0, 0.0, 0.7], [0.0] * 6):
        w = np.array(w)
        out = np.empty(n)
        k.blend(y0, y1, 0.25, K, w, 6, 0.01, out)
        acc = np.zeros(n)                              # the plain sum in stage order, zero terms included
        first = True
        for j in range(6):
            if first:
                acc, first = w[j] * K[j], False
            else:
                acc = acc + w[j] * K[j]
        want = y0 + 0.25 * (y1 - y0) + 0.01 * acc
        np.testing.assert_array_equal(out, want)
    K[2, 5] = np.nan                                   # in a row of zero weight: not in the sums
    w = np.array([0.0, 0.5, 0.0, -1.25, 2.0, 0.0])
    k.blend(y0, y0, 0.0, K, w, 6, 0.01, out)
    assert np.all(np.isfinite(out))
    e5, e3 = k.blended_sums(K, w, w[::-1].copy(), 6, y0, y1, np.full(n, 1e-6), 1e-3)
    assert math.isfinite(e5) and math.isnan(e3)        # the reversed weights give row 2 the weight -1.25


@pytest.mark.parametrize("cls", [dopri.Dop853, dopri.Dopri5], ids=["dop853", "dopri5"])
def test_a_non_finite_rate_at_the_step_end_rejects_the_step(cls, path):
    """DOP853's error weights give the step end's rate ``f_new`` none, and the compiled sums leave out terms of zero
    weight: a NaN there kept the norm finite and the step was taken, its NaN the next step's first stage. Now the step is rejected and shrunk, as for any non-finite stage."""
    s = cls(spring_chain(3), 0.0, np.r_[0.01, 0.0, 0.0, 0.0, 0.0, 0.0], 1.0, rtol=1e-6, atol=1e-8)
    real, calls = s._eval, []

    def once_nan(t, y):                         # the first f_new of the run is NaN, the others as they are
        calls.append(t)
        f = real(t, y)
        return np.full_like(f, np.nan) if len(calls) == 1 else f
    s._eval = once_nan
    h_first = s.h_abs
    assert s.step() is None
    assert len(calls) >= 2                      # the NaN step was tried again
    assert np.all(np.isfinite(s.f)) and np.all(np.isfinite(s.y))
    assert s.t < h_first                        # shrunk: the rejected trial was the first guess
