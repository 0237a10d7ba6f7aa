"""What the accuracy contract costs: its state signals read from the stored rows, its first tolerance (issue
14/15, regmech.solvers.accuracy)."""

import numpy as np
import pytest

from regmech.bench.calibration import all_cases
from regmech.solvers.accuracy import result_state_labels, state_columns, state_matrix
from regmech.solvers.common import output_grid

CASES = {c.key: c for c in all_cases()}


@pytest.mark.parametrize("key, solver", [("coupled_clutches", "ida"), ("electric_car", "ida"), ("train_10", "ida"),
                                         ("gear_shift", "ida"), ("excavator_swing", "ida"), ("near_rigid_shaft", "ida"),
                                         ("coupled_clutches", "scipy:DOP853"), ("excavator_swing", "scipy:Radau"),
                                         ("train_10", "convolution")])
def test_state_columns_read_what_the_named_signals_hold(key, solver):
    """The contract reads its state signals from the trajectory's columns (``state_columns``); they must be
    exactly the named signals (positions and speeds of the masses, device states) the user reads, whichever
    adaptive solver made the run (ida reorders its unknowns for a band solver and puts them back)."""
    case = CASES[key]
    m = case.build()
    c = m.compile()
    t_end = min(case.t_end, 0.3)
    res = m.simulate(t_end, case.dt_out, solver=solver, rtol=1e-5)
    labels = result_state_labels(c)
    grid = output_grid(0.0, t_end, case.dt_out)
    fast = state_matrix(res, labels, grid, state_columns(c))
    named = state_matrix(res, labels, grid)
    assert fast.shape == named.shape == (len(grid), len(labels))
    np.testing.assert_array_equal(fast, named)


def test_idas_first_rtol_shrinks_faster_than_the_accuracy_on_its_native_path():
    """ida's global error grows faster than its tolerance shrinks (alpha ~ 0.85 over the calibration): on the
    native path, where a tighter run costs little more, its first rtol follows accuracy^(1 + RTOL_SLOPE) below
    the anchor; above it, on the Python path and for the other solvers, accuracy * RTOL_FACTOR."""
    from regmech.library import coupled_clutches, slip_control
    from regmech.solvers.accuracy import RTOL_ANCHOR, RTOL_FACTOR, first_rtol, native_served
    f = RTOL_FACTOR["ida"]
    assert first_rtol("ida", RTOL_ANCHOR, native=True) == pytest.approx(f * RTOL_ANCHOR)
    ratios = [first_rtol("ida", a, native=True) / a for a in (1e-4, 1e-5, 1e-6)]
    assert f > ratios[0] > ratios[1] > ratios[2]
    assert first_rtol("ida", 1e-2, native=True) == pytest.approx(f * 1e-2)       # never looser
    assert first_rtol("ida", 1e-6) == pytest.approx(f * 1e-6)
    assert first_rtol("scipy:DOP853", 1e-6, native=True) == pytest.approx(RTOL_FACTOR["scipy:DOP853"] * 1e-6)
    from regmech.solvers.ida_native import libraries
    if isinstance(libraries(), str):
        pytest.skip(f"no native path here: {libraries()}")
    cc = coupled_clutches().compile()
    assert native_served("ida", cc, {"native": True}) and not native_served("ida", cc, {})
    assert not native_served("ida", slip_control().compile(), {"native": True})   # a commanded clutch: Python path


def test_coupled_clutches_at_1e_6_needs_one_pair():
    """MSL CoupledClutches at accuracy 1e-6 (the peers' rtol 1e-9 row): the first pair at 0.03 a missed (its
    estimate 1.2e-6, a third run); the first rtol of ``first_rtol`` meets it with one pair, and the answer
    is within the accuracy of a tight reference."""
    from regmech.library import coupled_clutches
    case = CASES["coupled_clutches"]
    m = coupled_clutches()
    res = m.simulate(case.t_end, case.dt_out, accuracy=1e-6)
    st = res.stats
    assert st.solver == "ida" and st.extra["attempts"] == 1
    assert st.error_estimate <= 1e-6
    c = m.compile()
    labels, grid = result_state_labels(c), output_grid(0.0, case.t_end, case.dt_out)
    ref = m.simulate(case.t_end, case.dt_out, solver="scipy:DOP853", rtol=1e-11, atol=1e-13)
    from regmech.solvers.accuracy import compare_runs
    assert compare_runs(res, ref, labels, grid).value <= 1e-6


def test_auto_keeps_the_modal_traits_with_the_compiled_system_until_the_model_changes():
    """auto's modal traits (2-5 ms of linear form and eigenvalues on a small model) are computed once per
    compiled system; a parameter change drops the system and with it the kept traits."""
    import regmech.solvers.auto as auto
    from regmech.components import Fixed, Inertia, Spring
    import regmech as rm
    m = rm.Model("osc")
    m.add(Fixed("g"))
    m.add(Spring("k", c=100.0))
    m.add(Inertia("J", J=1.0, phi0=1.0))
    m.connect(m["k"].flange_a, m["g"].flange)
    m.connect(m["k"].flange_b, m["J"].flange_a)
    calls = []
    real = auto._modes

    def counting(*args):
        calls.append(args)
        return real(*args)
    auto._modes = counting
    try:
        tr = auto.traits(m, 0.0, 1.0, 1e-3)
        f1 = tr.modes[:, 1].copy()
        auto.traits(m, 0.0, 1.0, 1e-3).modes
        assert len(calls) == 1
        m["k"].c = 400.0                   # a change drops the compiled system and its kept traits
        f2 = auto.traits(m, 0.0, 1.0, 1e-3).modes[:, 1]
        assert len(calls) == 2
    finally:
        auto._modes = real
    np.testing.assert_allclose(f1, [10.0 / (2 * np.pi)], rtol=1e-9)
    np.testing.assert_allclose(f2, [20.0 / (2 * np.pi)], rtol=1e-9)
