"""DOP853's step cap (``scipy_ivp.stability_cap``) on the linear form of a mechanical system: the eigenvalues
near the negative real axis, where DOP853's error estimate misses a step's error, are bounded by the damping
(``ode_driver.damping_radius``); the cap scales with the tolerance on that bound only, so a lightly damped
chain takes the steps its tolerance asks for, and any other model keeps the cap on its spectral radius."""

import math

import numpy as np
import pytest
import scipy.sparse as sp

import regmech as rm
from regmech.bench.hard_models import benchmark_chain
from regmech.components import Fixed, Inertia, LinearSpeedDependentTorque, SpringDamper, Torque
from regmech.solvers import ode_driver as od
from regmech.solvers import scipy_ivp
from regmech.signals import Sine


def start(c):
    y, _ = c.initial_y(0.0, c.modes0)
    return od.OdeProblem(c, c.modes0), c.ode_state(y)


def loaded_chain(n=12, d=1.0, load=-0.5):
    """A sine-driven chain with a speed-dependent load at its end (a diagonal damping entry of either sign)."""
    m = benchmark_chain(n, tau=Sine(amplitude=1.0, freq_hz=5.0), d=d)
    last = m[f"J{n - 1}"]
    drag = m.add(LinearSpeedDependentTorque("drag", tau_nominal=load, w_nominal=1.0))
    m.connect(last.flange_b, drag.flange)
    return m


def models():
    return {"chain20": benchmark_chain(20), "overdamped": benchmark_chain(15, c=1e3, d=400.0),
            "loaded": loaded_chain(), "feeding": loaded_chain(load=0.5)}


@pytest.mark.parametrize("name", ["chain20", "overdamped", "loaded", "feeding"])
def test_damping_radius_bounds_the_eigenvalues_near_the_negative_real_axis(name):
    c = models()[name].compile()
    problem, u = start(c)
    b = od.damping_radius(problem)
    assert b is not None
    lam = np.linalg.eigvals(od.ode_jacobian(problem, 0.0, u).toarray())
    real = np.abs(lam.imag) <= 1e-9 * np.abs(lam)
    assert np.all(np.abs(lam[real]) <= b * (1 + 1e-9))                  # a real eigenvalue: |lambda| <= b
    assert np.all(np.abs(lam[~real].real) <= 0.5 * b * (1 + 1e-9))     # a complex one: |Re lambda| <= b / 2
    near = lam[np.abs(lam.imag) <= math.tan(math.radians(60)) * -lam.real]   # within 60 degrees of the axis
    assert np.all(np.abs(near) <= b * (1 + 1e-9))


@pytest.mark.parametrize("name", ["chain20", "overdamped", "loaded", "feeding"])
def test_compiled_damping_radius_is_the_scipy_one(name):
    pytest.importorskip("numba")
    from regmech.solvers._bound_kernel import mechanical_damping
    c = models()[name].compile()
    problem, _ = start(c)
    J, n = od.ode_jacobian(problem, 0.0, None), len(c.Kv)
    for M in (J, sp.csr_matrix(J)):
        ok, b = mechanical_damping(M.indptr, M.indices, M.data, sp.isspmatrix_csc(M), c.mass,
                                   np.asarray(c.Kv, np.int64), n)
        assert ok and b == od._mechanical_damping(M, c, n)


def test_what_is_not_a_symmetric_mechanical_system_has_no_damping_radius():
    from test_odeform_native import tree
    motors = tree(2, 5).compile()                     # DC motors: device states
    assert od.damping_radius(start(motors)[0]) is None
    c = benchmark_chain(6).compile()
    problem, _ = start(c)
    J, n = od.ode_jacobian(problem, 0.0, None), len(c.Kv)
    lopsided, weak = J.tolil(), J.tolil()
    lopsided[n, 1] *= 1.5                              # K no longer symmetric
    weak[n + 2, 2] *= 0.5                              # K symmetric, its diagonal below the row's other entries
    for bad in (lopsided.tocsc(), weak.tocsc()):
        assert od._mechanical_damping(bad, c, n) is None
        try:
            from regmech.solvers._bound_kernel import mechanical_damping
        except ImportError:
            continue
        assert not mechanical_damping(bad.indptr, bad.indices, bad.data, True, c.mass,
                                      np.asarray(c.Kv, np.int64), n)[0]


def test_dop853_takes_the_steps_its_tolerance_asks_for_on_a_lightly_damped_chain(monkeypatch):
    m = benchmark_chain(300, tau=Sine(amplitude=1.0, freq_hz=5.0))
    run = m.simulate(1.0, 0.01, solver="scipy:DOP853", rtol=1e-9, atol=1e-11)
    real_cap = scipy_ivp.stability_cap
    monkeypatch.setattr(scipy_ivp, "stability_cap", lambda *a, **k: None)
    free = m.simulate(1.0, 0.01, solver="scipy:DOP853", rtol=1e-9, atol=1e-11)
    assert run.stats.steps == free.stats.steps                 # the cap does not bind
    np.testing.assert_array_equal(run["J150.w"], free["J150.w"])
    # the cap on the spectral radius (every model but these) held it at 1.2 times the steps
    monkeypatch.setattr(scipy_ivp, "stability_cap", lambda method, rho, rtol=None, damped=None:
                        real_cap(method, rho, rtol))
    capped = m.simulate(1.0, 0.01, solver="scipy:DOP853", rtol=1e-9, atol=1e-11)
    assert capped.stats.steps > 1.15 * run.stats.steps
    # and the answer is as accurate as its tolerance says (against a run 1,000 times tighter)
    ref = m.simulate(1.0, 0.01, solver="scipy:DOP853", rtol=1e-12, atol=1e-14)
    speeds = [f"J{i}.w" for i in range(0, 300, 10)]
    err = max(np.max(np.abs(run[k] - ref[k])) for k in speeds) / max(np.ptp(ref[k]) for k in speeds)
    assert err < 1e-7


def test_a_damping_as_large_as_the_radius_keeps_the_cap_of_the_radius():
    c = benchmark_chain(15, c=1e3, d=400.0).compile()
    problem, u = start(c)
    rho = od.spectral_radius(problem, 0.0, u)
    b = od.damping_radius(problem)
    assert b >= 0.9 * rho                              # nearly every eigenvalue is real: damping sets them
    for rtol in (1e-3, 1e-6, 1e-9):
        new = scipy_ivp.stability_cap("DOP853", rho, rtol, b)
        old = scipy_ivp.stability_cap("DOP853", rho, rtol)
        assert old <= new <= old / 0.9 + 1e-15          # the near-real part is at most the radius
    assert scipy_ivp.stability_cap("RK45", rho, 1e-6, b) is None


def test_the_error_estimate_misses_only_near_the_negative_real_axis():
    # the measurement behind the cap: DOP853's estimate (scipy's, Hairer's) against a step's true error on
    # y' = lambda y with h lambda = z, |z| up to the cap's 5.4; below 1 only within 8 degrees of the negative
    # real axis (the coefficients are scipy's own, a private module: skipped if it moves)
    coef = pytest.importorskip("scipy.integrate._ivp.dop853_coefficients")
    A, B, E3, E5 = coef.A[:12, :12], coef.B, coef.E3, coef.E5

    def ratio(z):
        hk = z * np.linalg.solve(np.eye(12) - z * A, np.ones(12))      # h K_i of the stages from y = 1
        y = 1 + B @ hk
        hk = np.append(hk, z * y)
        e5, e3 = abs(E5 @ hk), abs(E3 @ hk)
        return e5 ** 2 / math.sqrt(e5 ** 2 + 0.01 * e3 ** 2) / abs(y - np.exp(z))
    for angle in range(90, 172, 2):
        for r in np.arange(0.5, 5.41, 0.1):
            assert ratio(r * np.exp(1j * math.radians(angle))) >= 1.0, (angle, r)
    assert ratio(-5.4 + 0j) < 0.5
