"""The compiled spectral bound (``solvers._bound_kernel``: the explicit methods' up-front check)
gives the numpy path's bound to the last bit, so DOP853's step cap, which it sets, is the same; it is the
path a run with a compiled right-hand side takes."""

import math
import warnings

import numpy as np
import pytest
import scipy.sparse as sp

from regmech.bench.fuzz import generate_seed
from regmech.bench.hard_models import benchmark_chain, stretched_chain
from regmech.compile import odeform
from regmech.solvers import ode_driver as od

pytest.importorskip("numba")
from regmech.solvers import _bound_kernel as K  # noqa: E402  (numba)


def start(c):
    y, _ = c.initial_y(0.0, c.modes0)
    return od.OdeProblem(c, c.modes0), c.ode_state(y)


def jacobian(model):
    c = model.compile()
    problem, u = start(c)
    return od.ode_jacobian(problem, 0.0, u), c


def models():
    from regmech.library import excavator_swing, first, gear_shift, train
    from test_odeform_native import tree
    out = {"chain30": benchmark_chain(30), "chain300": benchmark_chain(300), "train_100": train(100),
           "first": first(), "excavator": excavator_swing(), "gear_shift": gear_shift(), "tree": tree(3, 20)}
    scene, spec = stretched_chain(1e5)
    out["stretched_1e5"] = scene.to_model(spec)
    return out


@pytest.mark.parametrize("name", ["chain30", "chain300", "train_100", "first", "excavator", "gear_shift", "tree",
                                  "stretched_1e5"])
def test_compiled_bound_is_the_numpy_bound(name):
    J, c = jacobian(models()[name])
    for M in (J, sp.csr_matrix(J), sp.csc_matrix(J)[:, ::-1][:, ::-1]):     # CSC, CSR, CSC in another order
        assert od.spectral_bound(M, c, compiled=True) == od.spectral_bound(M, c)


def test_compiled_bound_is_the_numpy_bound_on_random_drivetrains():
    checked = 0
    for seed in range(25):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                J, c = jacobian(generate_seed(seed).build())
            except Exception:         # a drivetrain whose start cannot be assembled: not this test's subject
                continue
        assert od.spectral_bound(J, c, compiled=True) == od.spectral_bound(J, c), seed
        checked += 1
    assert checked >= 20


def test_rows_that_tie_on_one_key_still_give_an_upper_bound():
    # a chain whose interior rows tie on p (equal masses and stiffness) but differ in their damping (q):
    # which of the tied rows each selection keeps may differ, the bound stays above the exact radius and
    # next to the numpy path's
    import regmech as rm
    from regmech.components import Fixed, Inertia, SpringDamper, Torque
    m = rm.Model("ties")
    fixed = m.add(Fixed("fixed"))
    drive = m.add(Torque("drive", tau=1.0))
    prev = fixed.flange
    for i in range(120):
        J = m.add(Inertia(f"J{i}", J=1.0))
        sd = m.add(SpringDamper(f"sd{i}", c=1e4, d=0.1 + 0.01 * ((7 * i) % 13)))
        m.connect(prev, sd.flange_a)
        m.connect(sd.flange_b, J.flange_a)
        prev = J.flange_b
    m.connect(drive.flange, prev)
    J, c = jacobian(m)
    exact = float(np.max(np.abs(np.linalg.eigvals(J.toarray()))))
    compiled, plain = od.spectral_bound(J, c, compiled=True), od.spectral_bound(J, c)
    assert compiled >= exact * (1 - 1e-12)
    assert compiled == pytest.approx(plain, rel=1e-3)


def test_a_non_finite_entry_gives_no_finite_bound():
    # NaN: a NaN bound; inf: a scale of 0 in the search, ValueError (in both paths; the up-front check then
    # has no radius, ``_spectral_radius_of``)
    J, c = jacobian(benchmark_chain(30))

    def outcome(M, compiled):
        try:
            with np.errstate(all="ignore"):        # the numpy path's arithmetic on inf and NaN
                bound = od.spectral_bound(M, c, compiled=compiled)
            return "finite" if math.isfinite(bound) else "not finite"
        except ValueError:
            return "ValueError"
    for bad in (np.nan, np.inf, -np.inf):
        M = J.copy()
        M.data[len(M.data) // 2] = bad
        assert outcome(M, True) == outcome(M, False) != "finite"
    empty = sp.csc_matrix(J.shape)
    assert od.spectral_bound(empty, c, compiled=True) == od.spectral_bound(empty, c) == 0.0


def test_the_k_largest_are_marked_with_ties_to_the_lower_row():
    rng = np.random.default_rng(3)
    for n, k in ((1, 1), (5, 33), (200, 33), (1000, 7)):
        key = rng.integers(0, 6, n).astype(float)          # many ties
        key[rng.integers(0, n, max(1, n // 50))] = np.nan   # never marked
        mark = np.zeros(n, np.bool_)
        K._mark_largest.py_func(key, min(k, n), mark)
        order = sorted((i for i in range(n) if not np.isnan(key[i])), key=lambda i: (-key[i], i))
        assert set(np.nonzero(mark)[0]) == set(order[:min(k, n)])


def test_the_up_front_check_takes_the_compiled_bound_when_the_form_is_compiled(monkeypatch):
    calls = []
    compiled = od._compiled_spectral_bound
    monkeypatch.setattr(od, "_compiled_spectral_bound", lambda J, c: calls.append(1) or compiled(J, c))
    m = benchmark_chain(300)
    res = m.simulate(0.05, 0.01, solver="scipy:DOP853", rtol=1e-6)
    assert calls == [1]
    monkeypatch.setattr(odeform, "NATIVE", False)
    plain = benchmark_chain(300).simulate(0.05, 0.01, solver="scipy:DOP853", rtol=1e-6)
    assert calls == [1]                                      # the numpy path: the same bound, the same run
    np.testing.assert_array_equal(res["J299.w"], plain["J299.w"])
    assert (res.stats.steps, res.stats.rhs_calls) == (plain.stats.steps, plain.stats.rhs_calls)
