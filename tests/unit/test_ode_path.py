"""The ODE-form path's fast pieces: the linear form of ``compile.odeform``, the spectral bound
of the explicit methods' up-front stiffness check, the signal list kept with the compiled model."""

import numpy as np
import pytest

import regmech as rm
from regmech.bench.hard_models import benchmark_chain
from regmech.bench.hard_models import stretched_chain
from regmech.compile.odeform import fast_operator, ode_form
from regmech.signals import Step
from regmech.solvers import ode_driver as od
from regmech.solvers.common import signal_breakpoints


def chain(n, c=1e4, d=1.0, drive=None):
    return benchmark_chain(n, tau=drive, c=c, d=d)


def start(c):
    modes = c.modes0
    y, _ = c.initial_y(0.0, modes)
    return od.OdeProblem(c, modes), c.ode_state(y)


@pytest.mark.parametrize("build", [lambda: chain(5), lambda: chain(1500),
                                   lambda: stretched_chain(1e5)[0].to_model(stretched_chain(1e5)[1])],
                         ids=["chain5", "chain1500", "stretched_1e5"])
def test_linear_form_gives_the_general_path_to_the_last_bit(build):
    # same sums in the same order (DIA only where it keeps the order): DOP853 at its stability limit moves
    # by far more than round-off when the last bits of g change, so the fast form must not change them
    c = build().compile()
    form = ode_form(c)
    assert form.linear
    rng = np.random.default_rng(3)
    for t in (0.0, 0.37, 1.9):
        u = rng.normal(size=c.ode_size()) * 10.0 ** rng.integers(-3, 3)
        assert np.array_equal(c.ode_rhs(t, u, c.modes0), c.ode_rhs_general(t, u, c.modes0))


def test_linear_form_jacobian_is_the_exact_dg_du():
    c = chain(6).compile()
    problem, u = start(c)
    A = od.ode_jacobian(problem, 0.1, u).toarray()
    fd = problem.jacobian(0.1, u).toarray()
    assert np.allclose(A, fd, rtol=1e-6, atol=1e-6 * np.abs(A).max())


@pytest.mark.parametrize("n", [5, 300])
def test_linear_form_jacobian_is_the_stacked_matrix_entry_for_entry(n):
    # the spectral bound sums |J| row by row in the stored order: the direct stacking must keep what sp.vstack
    # made (entries, their order, dtypes), or the radius, DOP853's step cap and its answers move by round-off
    import scipy.sparse as sp
    c = chain(n).compile()
    form = ode_form(c)
    if form.on_u:
        Tu = sp.csr_matrix(form.T)
    else:
        Tu = sp.csr_matrix(form.plan.T)[:, np.concatenate([c.ix, c.iv, c.iz]).astype(np.int64)]
    force = -(sp.diags(1.0 / c.mass) @ c.ScT)
    top = sp.hstack([sp.csr_matrix((c.n, c.n)), sp.identity(c.n, format="csr"), sp.csr_matrix((c.n, c.nz))])
    ref = sp.vstack([top, force @ Tu[:form.n_c], Tu[form.n_c:]]).tocsr()
    A = form.jacobian()
    assert A.shape == ref.shape and A.data.dtype == ref.data.dtype
    for a, b in ((A.indptr, ref.indptr), (A.indices, ref.indices), (A.data, ref.data)):
        assert np.array_equal(a, b)


def test_fast_operator_keeps_every_row_in_its_order():
    import scipy.sparse as sp
    rng = np.random.default_rng(0)
    n = 5000
    band = sp.diags([rng.normal(size=n - 1), rng.normal(size=n), rng.normal(size=n - 1)], [-1, 0, 1], format="csr")
    x = rng.normal(size=n) * 1e8
    op = fast_operator(band)
    assert sp.isspmatrix_dia(op) and np.array_equal(op @ x, band @ x)
    # rows stored out of column order: DIA only if one order of the diagonals serves every row
    shuffled = sp.csr_matrix((band.data.copy(), band.indices.copy(), band.indptr.copy()), shape=band.shape)
    for i in range(1, n - 1):
        lo = shuffled.indptr[i]
        shuffled.indices[lo:lo + 3] = shuffled.indices[lo:lo + 3][[2, 0, 1]]
        shuffled.data[lo:lo + 3] = shuffled.data[lo:lo + 3][[2, 0, 1]]
    shuffled.has_sorted_indices = False
    op = fast_operator(shuffled)
    assert np.array_equal(op @ x, shuffled @ x)
    scattered = sp.random(n, n, density=3e-4, random_state=1, format="csr")
    assert sp.isspmatrix_csr(fast_operator(scattered))        # entries on many diagonals: stays CSR


def _models():
    from regmech.library import excavator_swing, first, gear_shift, train
    return {"chain30": chain(30), "chain300": chain(300), "train_100": train(100), "first": first(),
            "excavator": excavator_swing(), "gear_shift": gear_shift(),
            "stretched_1e5": stretched_chain(1e5)[0].to_model(stretched_chain(1e5)[1])}


@pytest.mark.slow
@pytest.mark.parametrize("name", ["chain30", "chain300", "train_100", "first", "excavator", "gear_shift",
                                  "stretched_1e5"])
def test_spectral_bound_is_an_upper_bound(name):
    c = _models()[name].compile()
    problem, u = start(c)
    J = od.ode_jacobian(problem, 0.0, u)
    exact = float(np.max(np.abs(np.linalg.eigvals(J.toarray()))))
    bound = od.spectral_bound(J, c)
    assert bound >= exact * (1 - 1e-9)
    if name.startswith("chain"):          # springs and dampers: the highest frequency plus the damping
        assert bound <= 1.05 * exact


def test_up_front_check_decides_by_the_exact_radius_near_its_line():
    # chain30: exact radius ~196 1/s, bound ~201; DOP853 steps up to its cap, h rho <= reach (2.28 at its default
    # rtol 1e-6: scipy_ivp.stability_cap), so over 1 s the check refuses when max_steps < rho / reach: with the
    # line between radius and bound the run must start (no up-front refusal), below the radius it is refused
    # before the first step
    import math
    from regmech.solvers.scipy_ivp import stability_cap
    c = chain(30).compile()
    problem, u = start(c)
    J = od.ode_jacobian(problem, 0.0, u)
    exact = float(np.max(np.abs(np.linalg.eigvals(J.toarray()))))
    bound = od.spectral_bound(J, c)
    reach = stability_cap("DOP853", 1.0, 1e-6)
    between = math.floor(bound / reach)
    assert exact < between * reach < bound
    m = chain(30)
    try:
        m.simulate(1.0, 0.01, solver="scipy:DOP853", max_steps=between)
    except rm.SimulationError as exc:
        assert f"took more than max_steps={between}" in str(exc)
    below = math.floor(exact / reach) - 3
    with pytest.raises(rm.SimulationError) as err:
        m.simulate(1.0, 0.01, solver="scipy:DOP853", max_steps=below)
    assert "limits this explicit method" in str(err.value) and "stiff for an explicit method" in str(err.value)
    assert "cap on DOP853" in str(err.value)


def test_spectral_radius_of_a_large_model_is_bounded_work():
    # beyond DENSE_EIG_MAX states only a refusal candidate asks ARPACK, with a bounded number of restarts
    c = chain(400).compile()
    problem, u = start(c)
    assert problem.size > od.DENSE_EIG_MAX
    J = od.ode_jacobian(problem, 0.0, u)
    bound = od.spectral_bound(J, c)
    assert od.spectral_radius(problem, 0.0, u, above=2 * bound) == bound      # settled by the bound
    rho = od.spectral_radius(problem, 0.0, u, above=1.0)                      # a refusal candidate
    assert rho is not None and 150.0 < rho <= bound * (1 + 1e-9)


def test_signal_list_follows_a_changed_parameter():
    m = chain(3, drive=Step(height=1.0, start_time=0.5))
    m.compile()
    assert signal_breakpoints(m, 0.0, 1.0) == [0.5]
    assert signal_breakpoints(m, 0.0, 1.0) == [0.5]          # kept with the compiled model
    m["drive"].tau = Step(height=1.0, start_time=0.3)
    assert signal_breakpoints(m, 0.0, 1.0) == [0.3]
    m.compile()
    assert signal_breakpoints(m, 0.0, 1.0) == [0.3]
    res = m.simulate(1.0, 0.1, solver="rk4", tol=None, h=0.005)
    # the run stops at the new breakpoint (its left and right limits beside the grid point), not the old one
    assert np.count_nonzero(np.isclose(res.t, 0.3)) == 3 and np.count_nonzero(np.isclose(res.t, 0.5)) == 1


def test_fixed_step_rows_with_the_step_slope_match_recomputed_rows():
    # the output row at a step end takes y' from the stepper's slope g(t, u) instead of a new evaluation
    m = chain(4)
    res = m.simulate(0.5, 0.01, solver="rk4", tol=None)
    c = m.compile()
    names = c.structure.coord_names
    for k in (1, 17, len(res.t) - 1):
        u = np.array([res[f"{nm}.phi"][k] for nm in names] + [res[f"{nm}.w"][k] for nm in names])
        a = c.ode_rhs_general(res.t[k], u, c.modes0)[len(names):]
        assert np.array_equal([res[f"{nm}.a"][k] for nm in names], a)


def test_deferred_accelerations_are_the_rows_recomputed_on_their_side_of_a_breakpoint():
    # an adaptive run's interpolated rows get y' = g(t, u) only when an output reads it; at the breakpoint of a
    # Step input the row before it (left limit) and the row after it (right limit) must read the input on their
    # own sides, as at once: the left row's acceleration without the step, the right row's with it
    m = chain(4, drive=Step(height=2.0, start_time=0.25))
    res = m.simulate(0.5, 0.01, solver="scipy:DOP853", rtol=1e-8)
    traj = res._traj
    assert traj._yp_fill is not None                       # nothing read y' yet
    c = m.compile()
    names = c.structure.coord_names
    for k in range(len(res.t)):
        u = np.array([traj.Y[k, c.ix[j]] for j in range(c.n)] + [traj.Y[k, c.iv[j]] for j in range(c.n)])
        left = bool(traj.left[k])
        g = ode_form(c).rhs(res.t[k], u, left)
        assert np.array_equal([res[f"{nm}.a"][k] for nm in names], g[c.n:2 * c.n]), (k, res.t[k], left)
    at = np.nonzero(np.isclose(res.t, 0.25))[0]
    assert len(at) == 2 and traj.left[at[0]] and not traj.left[at[1]]
    # the drive's torque acts on the first inertia: its acceleration jumps by the step over its inertia
    J0 = float(m[names[0]].J)
    assert res[f"{names[0]}.a"][at[1]] - res[f"{names[0]}.a"][at[0]] == pytest.approx(2.0 / J0, rel=1e-6)


def test_rows_with_given_rates_allocate_no_rates_until_read(monkeypatch):
    """The start and the breakpoint rows of a linear run come with y' (``_Sink.row``); they must not allocate the
    rates of every row (on a chain of 10,000 inertias 17.8 MB of fresh memory a run that nobody read): the
    recorder's y' array stays unallocated, and reading an acceleration gives the given rows' rates."""
    from regmech.solvers import pages
    sizes = []
    zeros = pages.zeros
    monkeypatch.setattr(pages, "zeros", lambda shape, dtype=float: sizes.append(shape) or zeros(shape, dtype))
    m = chain(4, drive=Step(height=2.0, start_time=0.25))
    res = m.simulate(0.5, 0.01, solver="scipy:DOP853", rtol=1e-8)
    c = m.compile()
    assert len(sizes) == 1 and sizes[0][1] == c.N and sizes[0][0] >= len(res.t)     # y of the rows only
    traj = res._traj
    assert traj._yp_fill is not None
    names = c.structure.coord_names
    at = np.nonzero(np.isclose(res.t, 0.25))[0]
    y0, yp0 = c.initial_y(0.0, c.modes0)
    assert np.array_equal(traj.YPv[0], yp0[c.iv])            # the starting row's given rates, as they were given
    assert len(sizes) == 2 and sizes[1] == (len(res.t), len(yp0))
    # the right-hand row at the breakpoint (given by the driver) reads the step, the left one (interpolated) not
    J0 = float(m[names[0]].J)
    assert res[f"{names[0]}.a"][at[1]] - res[f"{names[0]}.a"][at[0]] == pytest.approx(2.0 / J0, rel=1e-6)


@pytest.mark.parametrize("column", ["position", "speed"])
def test_a_non_finite_given_rate_is_refused(monkeypatch, column):
    m = chain(3)
    c = m.compile()
    real = c.initial_y
    bad = 0 if column == "position" else int(c.iv[1])

    def bad_start(t, modes):
        y, yp = real(t, modes)
        yp = yp.copy()
        yp[bad] = np.nan
        return y, yp
    monkeypatch.setattr(c, "initial_y", bad_start)
    with pytest.raises(rm.SimulationError, match="non-finite .* at t=0") as err:
        m.simulate(0.1, 0.01, solver="scipy:DOP853")
    if column == "speed":                   # a speed's rate: the coordinate is named
        assert f"acceleration of '{c.structure.coord_names[1]}'" in str(err.value)


def test_deferred_accelerations_survive_pickling():
    import pickle
    m = chain(3, drive=Step(height=1.0, start_time=0.1))
    res = m.simulate(0.3, 0.01, solver="scipy:RK45", rtol=1e-8)
    again = pickle.loads(pickle.dumps(res))               # computes them first: the function is not pickled
    assert np.array_equal(again["J0.a"], res["J0.a"])
    assert np.any(res["J0.a"] != 0.0)


def test_state_scale_says_when_its_tolerances_change():
    from regmech.solvers import scipy_ivp
    c = chain(3).compile()
    scale = scipy_ivp.StateScale(1e-8, c)
    size = c.ode_size()
    assert not scale.see(np.zeros(size))                  # at the floor: nothing moves
    assert not scale.see(np.full(size, 1e-4))             # still below the floor (1e-3 of a motion of 1)
    before = scale.tolerances()
    assert scale.see(np.full(size, 0.2))                  # a kind grew below saturation: new tolerances
    assert not np.array_equal(scale.tolerances(), before)
    assert not scale.see(np.full(size, 0.1))              # nothing grew
    assert scale.see(np.full(size, 3.0))                  # saturated now (factor 0.2 -> 1)
    assert not scale.see(np.full(size, 7.0))              # beyond saturation: unchanged
    assert np.allclose(scale.tolerances(), 1e-8)


def test_spectral_radius_of_the_linear_form_is_kept_with_the_compiled_model(monkeypatch):
    m = chain(30)
    c = m.compile()
    problem, u = start(c)
    calls = []
    bound = od.spectral_bound
    monkeypatch.setattr(od, "spectral_bound", lambda J, c, **kw: calls.append(1) or bound(J, c, **kw))
    rho = od.spectral_radius(problem, 0.0, u, above=1e9)
    assert od.spectral_radius(problem, 0.0, u, above=1e9) == rho and len(calls) == 1
    m["sd3"].c = 4e4                                       # a stiffer link: a new compiled model, a new radius
    c2 = m.compile()
    problem2, u2 = start(c2)
    assert od.spectral_radius(problem2, 0.0, u2, above=1e9) > rho and len(calls) == 2


def test_a_non_finite_deferred_acceleration_is_refused_naming_its_coordinate(monkeypatch):
    m = chain(3, drive=Step(height=1.0, start_time=0.1))
    res = m.simulate(0.3, 0.01, solver="scipy:DOP853", rtol=1e-8)
    form = ode_form(m.compile())
    n = form.n
    name = m.compile().structure.coord_names[1]

    def overflowing(t, u, left=None):
        g = np.zeros(form.size)
        g[n + 1] = np.inf
        return g
    monkeypatch.setattr(form, "rhs", overflowing)
    with pytest.raises(rm.SimulationError, match=f"acceleration of '{name}' became non-finite"):
        res[f"{name}.a"]
