"""The step-doubling matrix exponential integrator (solver "expm", REFERENCES.md [002]).

What is checked:

* the coefficient matrices E = D0 - I and D_k (k = 1..3) against
  ``scipy.linalg.expm`` of the augmented (Van Loan) matrix, dense and sparse
  paths, and the doubling identities ``D0(2h) = D0(h)^2``,
  ``D_k(2h) = D0 D_k + sum_l C(k-1, l) h^(k-1-l) D_(l+1)``, to round-off;
* whole simulations of chains of up to 20 masses with polynomial forcing
  against the analytic modal solution (undamped) and against ``expm`` of the
  augmented matrix of the hand-built equations (damped), at steps of 1e-3,
  0.1, 1 and 10 lowest periods: relative error <= 1e-12;
* kinematic excitation (Position, Speed sources), rigid gears, MSL First,
  stick/slip (events located on the exact flow; analytic stop times;
  CoupledClutches against IDA), the table of the optimal split;
* a clear error for nonlinear models and for bad options.

Round-off floor (measured, ``benchmarks/bench_expm.py`` and
``benchmarks/results/expm.md``): against an exact modal solution of the
library's train over 20 s, 9e-12 for 10 cars, 1e-12 for 100 cars (dense
path) and 7e-12 for 1000 cars (sparse path), at h = 0.1 s and at h = 1 s
alike. On stretched spectra the floor grows like (w_max/w_min)^2 * 1e-16:
5e-11 at a frequency ratio of 1e3 and 1e-6 at 1e5 (scipy.linalg.expm of the
augmented matrix is no better there). Hence the 20-mass tests below keep
frequency ratios of about 30 and the bound 1e-12.
"""

import math

import numpy as np
import pytest
import scipy.linalg as la
import scipy.sparse as sp

import regmech as rm
from regmech.components import (Backlash, Clutch, Fixed, Force, FrictionContact, Inertia, Mass, Position, Speed,
                                Spring, SpringDamper, Torque)
from regmech.errors import ParameterError, SimulationError
from regmech.signals import Ramp, Signal, Sine, Step
from regmech.solvers.expm import nonlinear_components
from regmech.solvers.expm_coefficients import choose_split, coefficients, split_error

# round-off-sensitive: .ci/run runs these again under other OpenBLAS kernels (see the README)
pytestmark = pytest.mark.roundoff


# ============================================================== helpers
class Poly(Signal):
    """A polynomial signal sum c_k t^k with exact derivatives (no breakpoints)."""

    def __init__(self, *coefs):
        self.p = np.polynomial.Polynomial(coefs)

    def value(self, t, left=False):
        return float(self.p(t))

    def derivative(self, t, order=1, left=False):
        return float(self.p.deriv(order)(t))

    def breakpoints(self, t_start=-math.inf, t_end=math.inf):
        return ()


def augmented(A, p):
    """Van Loan matrix whose exponential holds D0 and D_k/(k-1)! in its first block row."""
    N = A.shape[0]
    Z = np.zeros(((p + 1) * N, (p + 1) * N))
    Z[:N, :N] = A
    for k in range(p):
        Z[k * N:(k + 1) * N, (k + 1) * N:(k + 2) * N] = np.eye(N)
    return Z


def exact_D(A, h, p):
    N = A.shape[0]
    X = la.expm(augmented(A, p) * h)
    return X[:N, :N], [math.factorial(k) * X[:N, (k + 1) * N:(k + 2) * N] for k in range(p)]


def scaled_chain_matrix(n, damping=0.01, rng=None):
    rng = rng or np.random.default_rng(1)
    k = rng.uniform(0.5, 2.0, n + 1) * 1e4
    m = rng.uniform(0.5, 2.0, n)
    K = np.diag(k[:-1] + k[1:]) - np.diag(k[1:-1], 1) - np.diag(k[1:-1], -1)
    s = 1 / np.sqrt(m)
    Ch = s[:, None] * K * s[None, :]
    Fh = damping * Ch / math.sqrt(np.abs(Ch).sum(1).max()) + 0.3 * np.eye(n)
    w = math.sqrt(np.abs(Ch).sum(1).max())
    return np.block([[-Fh, -Ch / w], [w * np.eye(n), np.zeros((n, n))]])


def chain_model(J, c, d=None, drive=None, anchored=True, name="chain"):
    """Inertias J[i] joined by springs c[i] (and dampers d[i]); c[0] anchors J[0] to the ground when
    ``anchored``; ``drive`` a torque signal on the last inertia."""
    m = rm.Model(name)
    fixed = m.add(Fixed("fixed"))
    bodies = [m.add(Inertia(f"J{i}", J=float(J[i]), phi0=0.01 * i, w0=0.1 * (-1) ** i)) for i in range(len(J))]
    prev = fixed.flange if anchored else None
    for i, b in enumerate(bodies):
        if prev is not None:
            if d is None:
                link = m.add(Spring(f"c{i}", c=float(c[i])))
            else:
                link = m.add(SpringDamper(f"c{i}", c=float(c[i]), d=float(d[i])))
            m.connect(prev, link.flange_a)
            m.connect(link.flange_b, b.flange_a)
        prev = b.flange_b
    if drive is not None:
        src = m.add(Torque("drive", tau=drive))
        m.connect(src.flange, bodies[-1].flange_b)
        m.connect(src.support, fixed.flange)
    return m


def chain_matrices(J, c, d=None, anchored=True):
    n = len(J)
    K = np.zeros((n, n))
    D = np.zeros((n, n))
    for i in range(n):
        if i == 0 and not anchored:
            continue
        a, b = i - 1, i
        for mat, val in ((K, c[i]), (D, 0.0 if d is None else d[i])):
            mat[b, b] += val
            if a >= 0:
                mat[a, a] += val
                mat[a, b] -= val
                mat[b, a] -= val
    return np.diag(J), D, K


def modal_reference(J, c, force_coefs, t, y0, v0, anchored=True):
    """Analytic solution of M y'' + C y = e_last f(t), f = sum force_coefs[k] t^k (undamped, modal)."""
    M, _, K = chain_matrices(J, c, anchored=anchored)
    lam, Phi = la.eigh(K, M)                       # Phi^T M Phi = I
    n = len(J)
    g_load = Phi[-1, :]                            # generalised load of each mode per unit force
    f = np.polynomial.Polynomial(force_coefs)
    eta0, deta0 = Phi.T @ M @ y0, Phi.T @ M @ v0
    Y = np.zeros((len(t), n))
    V = np.zeros((len(t), n))
    for i in range(n):
        g = f * g_load[i]
        if lam[i] <= 1e-9 * lam.max():            # rigid-body mode: integrate twice
            part = g.integ(2)
            a, b = eta0[i] - part(0.0), deta0[i] - part.deriv()(0.0)
            eta = part(t) + a + b * t
            deta = part.deriv()(t) + b
        else:
            om2 = lam[i]
            om = math.sqrt(om2)
            # particular solution sum_j (-1)^j g^(2j) / om^(2j+2) (a polynomial: the series ends)
            part = np.polynomial.Polynomial([0.0])
            term, factor = g, 1.0 / om2
            while np.any(term.coef != 0):
                part = part + factor * term
                term, factor = term.deriv(2), -factor / om2
            a, b = eta0[i] - part(0.0), deta0[i] - part.deriv()(0.0)
            eta = part(t) + a * np.cos(om * t) + b / om * np.sin(om * t)
            deta = part.deriv()(t) - a * om * np.sin(om * t) + b * np.cos(om * t)
        Y += np.outer(eta, Phi[:, i])
        V += np.outer(deta, Phi[:, i])
    return Y, V, np.sqrt(lam[lam > 1e-9 * lam.max()])


def rel_error(res, names, ref):
    got = np.column_stack([res[nm] for nm in names])
    return np.max(np.abs(got - ref)) / np.max(np.abs(ref))


# ============================================================== coefficients
@pytest.mark.parametrize("h", [1e-3, 0.1, 1.0])
@pytest.mark.parametrize("sparse", [False, True])
def test_coefficients_match_expm_of_augmented_matrix(h, sparse):
    A = scaled_chain_matrix(8)
    N = A.shape[0]
    coef = coefficients(sp.csr_matrix(A) if sparse else A, np.eye(N), h, 3)
    D0, Dk = exact_D(A, h, 3)
    E = coef.E.toarray() if sparse else coef.E
    assert np.abs(E + np.eye(N) - D0).max() <= 1e-12 * np.abs(D0).max()
    for k in range(3):
        assert np.abs(coef.DW[k] - Dk[k]).max() <= 1e-12 * np.abs(Dk[k]).max(), k


def test_truncated_columns_equal_full_matrices_times_w():
    A = scaled_chain_matrix(6)
    N = A.shape[0]
    W = np.zeros((N, 2))
    W[0, 0] = 1.0
    W[3, 1] = -2.0
    full = coefficients(A, np.eye(N), 0.37, 3)
    trunc = coefficients(A, W, 0.37, 3)
    for k in range(3):
        assert np.allclose(trunc.DW[k], full.DW[k] @ W, rtol=0, atol=1e-15 * np.abs(full.DW[k]).max())


def test_doubling_identities_hold_to_round_off():
    A = scaled_chain_matrix(6)
    N = A.shape[0]
    I = np.eye(N)
    h = 0.05
    one, two = coefficients(A, I, h, 3), coefficients(A, I, 2 * h, 3)
    D0, D0_2 = I + one.E, I + two.E
    assert np.abs(D0 @ D0 - D0_2).max() <= 1e-14 * np.abs(D0_2).max()
    for k in range(1, 4):
        rhs = D0 @ one.DW[k - 1] + sum(math.comb(k - 1, l) * h ** (k - 1 - l) * one.DW[l] for l in range(k))
        assert np.abs(rhs - two.DW[k - 1]).max() <= 1e-14 * np.abs(two.DW[k - 1]).max(), k


def test_small_parts_keep_precision_at_tiny_steps():
    # E = D0 - I is carried, so at h = 1e-9 it still has ~16 correct digits (D0 itself would keep ~7)
    A = scaled_chain_matrix(4)
    h = 1e-9
    coef = coefficients(A, np.eye(A.shape[0]), h, 1)
    E_series = A * h + (A @ A) * h ** 2 / 2
    assert np.abs(coef.E - E_series).max() <= 1e-15 * np.abs(E_series).max()


def test_split_choice_meets_its_error_model():
    for nu_h in (0.01, 1.0, 50.0, 3e4):
        r, m = choose_split(nu_h)
        assert split_error(r, m, nu_h) <= 2.0 ** -53
        if m > 0:
            assert split_error(r, m - 1, nu_h) > 2.0 ** -53
    # the paper: 2^m ~ w_max / w_min (m = 10..20 for spectra of 1e3..1e6 at h ~ 1/w_min): the start
    # step theta = nu h / 2^m stays between 1e-3 and 1 at any nu h
    for nu_h in (1e3, 1e6):
        r, m = choose_split(nu_h)
        assert 1e-3 <= nu_h / 2 ** m <= 1.0 and 6 <= r <= 18


# ============================================================ simulations
def _undamped_case(n, rng):
    J = rng.uniform(0.5, 2.0, n)
    c = rng.uniform(0.5, 2.0, n) * 1e3
    return J, c


@pytest.mark.parametrize("periods,n,p", [(1e-3, 20, 3), (0.1, 20, 3), (1.0, 12, 2), (10.0, 6, 3)])
def test_undamped_chain_matches_analytic_modal_solution(periods, n, p):
    rng = np.random.default_rng(7)
    J, c = _undamped_case(n, rng)
    coefs = (2.0, -3.0, 0.8)[:p]                   # a polynomial of degree p - 1: exact for order_p = p
    m = chain_model(J, c, drive=Poly(*coefs))
    _, _, om = modal_reference(J, c, coefs, np.zeros(1), np.zeros(n), np.zeros(n))
    h = periods * 2 * math.pi / om.min()
    # exp(A t) is only defined to about (w_max t) * 1e-16 by the rounded data: the analytic solution and
    # scipy's expm differ by 2e-12 after 50 lowest periods of this chain, so the long steps run 20 periods
    t_end = 2 * h if periods >= 10 else (200 * h if periods < 0.01 else 5 * h if periods >= 1 else 20 * h)
    res = m.simulate(t_end, dt_out=h, solver="expm", h=h, order_p=p)
    y0 = np.array([0.01 * i for i in range(n)])
    v0 = np.array([0.1 * (-1) ** i for i in range(n)])
    Y, V, _ = modal_reference(J, c, coefs, res.t, y0, v0)
    assert rel_error(res, [f"J{i}.phi" for i in range(n)], Y) <= 1e-12
    assert rel_error(res, [f"J{i}.w" for i in range(n)], V) <= 1e-12


def test_free_free_chain_with_rigid_mode_matches_modal_solution():
    rng = np.random.default_rng(3)
    J, c = _undamped_case(8, rng)
    coefs = (1.0, 0.5, -0.25)
    m = chain_model(J, c, drive=Poly(*coefs), anchored=False)
    _, _, om = modal_reference(J, c, coefs, np.zeros(1), np.zeros(8), np.zeros(8), anchored=False)
    h = 2 * math.pi / om.min()
    res = m.simulate(4 * h, dt_out=h / 2, solver="expm", order_p=3)
    Y, V, _ = modal_reference(J, c, coefs, res.t, 0.01 * np.arange(8), 0.1 * (-1.0) ** np.arange(8), anchored=False)
    assert rel_error(res, [f"J{i}.phi" for i in range(8)], Y) <= 1e-12
    assert rel_error(res, [f"J{i}.w" for i in range(8)], V) <= 1e-12


@pytest.mark.parametrize("periods", [1e-3, 0.1, 1.0, 10.0])
def test_damped_chain_matches_expm_of_augmented_system(periods):
    rng = np.random.default_rng(11)
    n = 10
    J = rng.uniform(0.5, 2.0, n)
    c = rng.uniform(0.5, 2.0, n) * 1e3
    d = rng.uniform(0.0, 2.0, n)                 # not proportional: F and C do not commute
    coefs = (1.5, -2.0)
    m = chain_model(J, c, d=d, drive=Poly(*coefs))
    M, D, K = chain_matrices(J, c, d)
    Mi = np.diag(1 / J)
    # z = [y, y', 1, t]: exact solution by one matrix exponential per output instant
    A = np.zeros((2 * n + 2, 2 * n + 2))
    A[:n, n:2 * n] = np.eye(n)
    A[n:2 * n, :n] = -Mi @ K
    A[n:2 * n, n:2 * n] = -Mi @ D
    A[2 * n - 1, 2 * n] = coefs[0] / J[-1]
    A[2 * n - 1, 2 * n + 1] = coefs[1] / J[-1]
    A[2 * n + 1, 2 * n] = 1.0
    om_min = math.sqrt(la.eigh(K, M, eigvals_only=True).min())
    h = periods * 2 * math.pi / om_min
    steps = 100 if periods < 0.01 else 8
    res = m.simulate(steps * h, dt_out=h, solver="expm", order_p=2)
    z0 = np.concatenate([0.01 * np.arange(n), 0.1 * (-1.0) ** np.arange(n), [1.0, 0.0]])
    Z = np.array([la.expm(A * t) @ z0 for t in res.t])
    names = [f"J{i}.phi" for i in range(n)] + [f"J{i}.w" for i in range(n)]
    assert rel_error(res, names, Z[:, :2 * n]) <= 1e-12


def test_step_and_ramp_forcing_exact_with_p2_across_breakpoints():
    # a ramp that ends inside the run and a step: piecewise polynomial, the driver stops at the breakpoints
    J, c = np.array([1.0, 2.0, 1.5]), np.array([4e3, 2e3, 1e3])
    m = chain_model(J, c, drive=Ramp(height=5.0, duration=0.3, start_time=0.1))
    h = 0.05
    res = m.simulate(1.0, dt_out=h, solver="expm", order_p=2)
    ref = m.simulate(1.0, dt_out=h, solver="scipy:DOP853", rtol=1e-13, atol=1e-14)
    names = [f"J{i}.w" for i in range(3)]
    assert rel_error(res, names, np.column_stack([ref[nm] for nm in names])) <= 1e-9
    # step size does not matter for piecewise-linear forcing: h/10 gives the same numbers
    fine = m.simulate(1.0, dt_out=h, solver="expm", h=h / 10, order_p=2)
    assert rel_error(res, names, np.column_stack([fine[nm] for nm in names])) <= 1e-12


def off(res, ref, names) -> float:
    """``rel_error`` of ``res`` against the reference run ``ref`` on the signals ``names``."""
    return rel_error(res, names, np.column_stack([ref[nm] for nm in names]))


def test_sine_forcing_is_exact_at_any_step():
    # a Sine torque is taken by its particular solution (ExpmStepper.particular): no fit error at one step per output
    # interval, whatever the order of the fit
    J, c = np.array([1.0, 1.0]), np.array([1e2, 1e2])
    m = chain_model(J, c, d=[0.1, 0.1], drive=Sine(amplitude=3.0, freq_hz=1.0, phase=0.3, offset=0.5))
    ref = m.simulate(2.0, dt_out=0.1, solver="scipy:DOP853", rtol=1e-13, atol=1e-14)
    names = ["J0.w", "J1.w", "J0.phi", "J1.phi"]
    for p in (1, 2):
        r = m.simulate(2.0, dt_out=0.1, solver="expm", order_p=p)
        assert r.stats.steps == 20                      # one step per output interval: no fit error to resolve
        assert off(r, ref, names) <= 1e-10


def test_a_sine_that_starts_inside_the_run_is_exact_from_its_start():
    # the sines are found per segment (between breakpoints): before 0.35 s the force is the offset, after it the sine
    J, c = np.array([1.0, 2.0]), np.array([3e2, 1e2])
    m = chain_model(J, c, d=[0.2, 0.1], drive=Sine(amplitude=2.0, freq_hz=3.0, offset=0.5, start_time=0.35))
    ref = m.simulate(2.0, dt_out=0.1, solver="scipy:DOP853", rtol=1e-13, atol=1e-14)
    names = ["J0.w", "J1.w", "J0.phi", "J1.phi"]
    r = m.simulate(2.0, dt_out=0.1, solver="expm")
    assert off(r, ref, names) <= 1e-10


@pytest.mark.slow
def test_sine_near_resonance_is_exact_where_the_fit_rang():
    # the fit's ripple at the step rate excites a lightly damped mode near that rate (here 650 Hz, damping
    # ratio 1e-3) and the companion run at 2h rings alike: at 6 and 7 steps per 10 ms the error was 14-23 times the
    # estimate. With the particular solution both runs are exact and the estimate is a bound
    w1 = 2 * math.pi * 650.0
    J, c = np.array([1.0, 1e-3]), np.array([1e3, 1e-3 * w1 ** 2])
    m = chain_model(J, c, d=[0.1, 2 * 1e-3 * 1e-3 * w1], drive=Sine(amplitude=10.0, freq_hz=5.3))
    ref = m.simulate(1.0, dt_out=1e-2, solver="scipy:DOP853", rtol=1e-13, atol=1e-15, max_steps=10**6)
    names = ["J0.w", "J1.w"]
    want = np.column_stack([ref[nm] for nm in names])
    for n_steps in (6, 7):
        r = m.simulate(1.0, dt_out=1e-2, solver="expm", h=1e-2 / n_steps)
        err = rel_error(r, names, want)
        assert err <= max(r.stats.error_estimate, 1e-9), (n_steps, err, r.stats.error_estimate)


def test_smooth_forcing_converges_with_the_gauss_order():
    # a user's function (not a Sine: no particular solution) goes through the step's polynomial fit
    J, c = np.array([1.0, 1.0]), np.array([1e2, 1e2])
    m = chain_model(J, c, d=[0.1, 0.1], drive=lambda t: 3.0 * math.sin(2 * math.pi * t))
    ref = m.simulate(2.0, dt_out=0.1, solver="expm", h=1e-3, order_p=3)
    errs = {}
    for p in (1, 2):
        e = []
        for h in (0.02, 0.01):
            r = m.simulate(2.0, dt_out=0.1, solver="expm", h=h, order_p=p, tol=None)
            e.append(np.max(np.abs(r["J0.w"] - ref["J0.w"])))
        errs[p] = math.log2(e[0] / e[1])
    assert errs[1] == pytest.approx(2.0, abs=0.3)     # midpoint: order 2
    assert errs[2] == pytest.approx(4.0, abs=0.5)     # two Gauss points: order 4


# ============================================================ other inputs
def _driven_chain(source):
    m = rm.Model("driven")
    fixed = m.add(Fixed("fixed"))
    J = [m.add(Inertia("J0", J=1.0))] + [m.add(Inertia(f"J{i}", J=1.0 + 0.5 * i, phi0=0.0, w0=0.0))
                                         for i in (1, 2)]
    src = m.add(source)
    k0 = m.add(Spring("k0", c=2e3))
    m.connect(src.support, fixed.flange)
    m.connect(src.flange, J[0].flange_a)
    m.connect(J[0].flange_b, k0.flange_a)
    m.connect(k0.flange_b, J[1].flange_a)
    k1 = m.add(SpringDamper("k1", c=1e3, d=0.5))
    m.connect(J[1].flange_b, k1.flange_a)
    m.connect(k1.flange_b, J[2].flange_a)
    return m


@pytest.mark.parametrize("source", [lambda: Position("drive", phi_ref=Poly(0.0, 0.3, 0.2)),
                                    lambda: Speed("drive", w_ref=Poly(0.3, 0.4))])
def test_kinematic_excitation(source):
    m = _driven_chain(source())
    res = m.simulate(1.0, dt_out=0.02, solver="expm", order_p=3)
    ref = m.simulate(1.0, dt_out=0.02, solver="scipy:DOP853", rtol=1e-11, atol=1e-13)
    names = ["J1.phi", "J2.phi", "J1.w", "J2.w", "J0.phi", "J0.w", "k0.tau", "drive.tau"]
    for nm in names:
        assert np.max(np.abs(res[nm] - ref[nm])) <= 1e-8 * np.max(np.abs(ref[nm])), nm
    # any step: the polynomial excitation is integrated exactly, one step per 0.5 s gives the same values
    coarse = m.simulate(1.0, dt_out=0.5, solver="expm", order_p=3)
    k = np.searchsorted(res.t, coarse.t)
    assert np.max(np.abs(coarse["J2.w"] - res["J2.w"][k])) <= 1e-12 * np.max(np.abs(res["J2.w"]))


def test_rigid_gear_and_msl_first_against_dop853():
    from regmech.library import first
    m = first()
    res = m.simulate(0.3, dt_out=2e-3, solver="expm", order_p=3, h=5e-4)
    ref = m.simulate(0.3, dt_out=2e-3, solver="scipy:DOP853", rtol=1e-11, atol=1e-13)
    for nm in ("inertia1.w", "inertia2.w", "inertia3.w", "spring.tau", "idealGear.tau"):
        assert np.max(np.abs(res[nm] - ref[nm])) <= 1e-8 * np.max(np.abs(ref[nm])), nm


def test_result_interface_and_stats():
    J, c = np.array([1.0, 2.0]), np.array([1e3, 1e3])
    m = chain_model(J, c, drive=Step(height=2.0, start_time=0.25))
    res = m.simulate(0.5, dt_out=0.05, solver="expm")
    assert res.stats.solver == "expm"
    assert res.stats.extra["setups"] >= 1 and res.stats.extra["doublings_m"] >= 0
    assert np.all(np.diff(res.t) >= 0) and res.t[-1] == 0.5
    assert "J1.a" in res.names and np.all(np.isfinite(res["c1.tau"]))
    assert np.sum(res.t == 0.25) == 2                 # the step instant: left and right values


# ============================================================ friction
def test_coulomb_oscillator_stops_at_analytic_time():
    # m x'' + k x = -F sign(x') from x0 > 0 at rest: half cycles of pi/omega about +-F/k, amplitude
    # shrinking by 2F/k per half cycle, until the spring force is within the static capacity
    mass, k, F, x0 = 2.0, 800.0, 3.0, 0.05
    m = rm.Model("coulomb")
    fixed = m.add(Fixed("ground", domain="translational"))
    body = m.add(Mass("body", m=mass, s0=x0, v0=0.0))
    spring = m.add(Spring("spring", c=k, domain="translational"))
    contact = m.add(FrictionContact("contact", mu=1.0, peak=1.0, fn=F))
    m.connect(spring.flange_a, fixed.flange)
    m.connect(spring.flange_b, body.flange_a)
    m.connect(body.flange_b, contact.flange_a)
    m.connect(contact.flange_b, fixed.flange)
    omega = math.sqrt(k / mass)
    half_cycles = math.ceil((x0 - F / k) / (2 * F / k))
    res = m.simulate(2.0, dt_out=0.01, solver="expm")
    # each reversal passes through Stuck within one event iteration (the spring breaks it away at once)
    expected = [(i + 1) * math.pi / omega for i in range(half_cycles)]
    assert len(res.events) == half_cycles and res.events[-1].new_mode == 0
    assert np.allclose([e.t for e in res.events], expected, rtol=0, atol=1e-9)
    x_final = x0 - half_cycles * 2 * F / k
    assert res["body.s"][-1] == pytest.approx(x_final * (-1) ** half_cycles, abs=1e-9)


def test_coupled_clutches_events_and_speeds_against_ida():
    from regmech.library import coupled_clutches
    m = coupled_clutches()
    res = m.simulate(1.5, dt_out=1e-3, solver="expm", order_p=3)
    ref = m.simulate(1.5, dt_out=1e-3, solver="ida", rtol=1e-10, atol=1e-12)
    got = [(e.component, e.old_mode, e.new_mode) for e in res.events]
    assert got == [(e.component, e.old_mode, e.new_mode) for e in ref.events]
    assert np.allclose([e.t for e in res.events], [e.t for e in ref.events], rtol=0, atol=1e-7)
    for nm in ("J1.w", "J2.w", "J3.w", "J4.w"):
        assert np.max(np.abs(np.interp(ref.t, res.t, res[nm]) - ref[nm])) <= 1e-6, nm


@pytest.mark.slow
def test_one_way_clutch_against_dymola_including_the_grazing_lock(reference_dir):
    # at t = 1.5 the relative speed touches zero tangentially; Dymola's reference locks there and
    # releases at 1.50000159 s (duplicated time rows); on the exact flow expm finds the same touch
    from regmech.library import one_way_clutch
    ref = np.genfromtxt(reference_dir / "OneWayClutch.csv", delimiter=",", names=True)
    res = one_way_clutch(True).simulate(2.0, dt_out=1e-3, solver="expm", order_p=3)
    for name, col in (("inertiaIn.w", "inertiaInw"), ("oneWayClutch.w_rel", "oneWayClutchw_rel")):
        assert np.max(np.abs(np.interp(ref["time"], res.t, res[name]) - ref[col])) < 2e-4, name
    ref_rows = ref["time"][:-1][np.diff(ref["time"]) == 0]
    release = [e.t for e in res.events if abs(e.t - 1.5) < 1e-3 and e.new_mode == 2]
    assert len(release) == 1 and np.min(np.abs(ref_rows - release[0])) < 1e-9


# ============================================================ errors
def test_nonlinear_model_is_refused_with_the_component_named():
    from regmech.library import train
    m = train(3)                                   # rolling resistance: f_roll tanh(v / v_eps)
    with pytest.raises(SimulationError, match="RoadLoad 'road0', RoadLoad 'road1', RoadLoad 'road2'"):
        m.simulate(0.1, solver="expm")


def test_backlash_and_speed_dependent_friction_are_reported():
    m = chain_model(np.array([1.0, 1.0]), np.array([1e3, 1e3]), drive=Sine())
    gap = m.add(Backlash("gap", c=1e4, b=1e-3))
    m.connect(gap.flange_a, m["J0"].flange_b)
    m.connect(gap.flange_b, m["J1"].flange_a)
    clutch = m.add(Clutch("slip", mu_table=[(0.0, 0.5), (1.0, 0.3)], fn_max=10.0))
    j2 = m.add(Inertia("J2", J=1.0))
    m.connect(m["J1"].flange_b, clutch.flange_a)
    m.connect(clutch.flange_b, j2.flange_a)
    bad = nonlinear_components(m.compile(), 0.0, 1.0)
    assert "Backlash 'gap'" in bad and "Clutch 'slip'" in bad
    assert not any("c0" in b or "drive" in b for b in bad)


def test_linear_instances_of_a_nonlinear_class_are_accepted():
    # RoadLoad with every coefficient zero has a zero (constant) Jacobian: the train scene without rolling
    # resistance is linear
    from regmech.library import train
    m = train(4, c_r=0.0)
    assert nonlinear_components(m.compile(), 0.0, 20.0) == []
    res = m.simulate(12.0, dt_out=0.5, solver="expm")
    ref = m.simulate(12.0, dt_out=0.5, solver="scipy:DOP853", rtol=1e-11, atol=1e-12)
    assert np.max(np.abs(res["car3.v"] - ref["car3.v"])) <= 1e-7 * np.max(np.abs(ref["car3.v"]))


@pytest.mark.parametrize("bad", [{"h": -1.0}, {"order_p": 4}, {"taylor_r": 0}, {"tol": 2.0}, {"rtol": 1e-6}])
def test_bad_options(bad):
    m = chain_model(np.array([1.0]), np.array([1e3]), drive=Sine())
    with pytest.raises(ParameterError):
        m.simulate(0.1, solver="expm", **bad)


def test_forced_taylor_order_and_sparse_path_agree_with_default():
    rng = np.random.default_rng(5)
    J, c = _undamped_case(12, rng)
    m = chain_model(J, c, d=np.full(12, 0.3), drive=Poly(1.0, 2.0))
    base = m.simulate(1.0, dt_out=0.05, solver="expm")
    for opts in ({"taylor_r": 3}, {"sparse": True}, {"sparse": True, "taylor_r": 12}, {"scaling": "frequency"}):
        other = m.simulate(1.0, dt_out=0.05, solver="expm", **opts)
        names = [f"J{i}.w" for i in range(12)]
        assert rel_error(other, names, np.column_stack([base[nm] for nm in names])) <= 1e-12, opts


def test_a_mid_size_chain_takes_the_sparse_path_and_agrees_with_the_dense_one():
    # regression: chains of 55 to 200 coordinates took the dense path, whose n^3 set-up under threaded BLAS on
    # a loaded 2-core machine cost 10x the sparse one (100 inertias: 1.6 s against 0.18 s); from SPARSE_FROM
    # coordinates (diagonal mass matrix) the sparse path is the default, and it gives the dense path's answer
    from regmech.solvers.expm import SPARSE_FROM
    n = SPARSE_FROM
    rng = np.random.default_rng(11)
    J, c = _undamped_case(n, rng)
    m = chain_model(J, c, d=np.full(n, 0.3), drive=Sine(amplitude=1.0, freq_hz=2.0))
    base = m.simulate(0.2, dt_out=0.02, solver="expm")
    assert bool(base.stats.extra["sparse"]) is True
    dense = m.simulate(0.2, dt_out=0.02, solver="expm", sparse=False)
    assert bool(dense.stats.extra["sparse"]) is False
    names = [f"J{i}.w" for i in range(n)]
    assert rel_error(base, names, np.column_stack([dense[nm] for nm in names])) <= 1e-9
    small = chain_model(J[:SPARSE_FROM - 1], c[:SPARSE_FROM - 1], drive=Sine(amplitude=1.0, freq_hz=2.0))
    assert not small.simulate(0.02, dt_out=0.01, solver="expm", tol=None).stats.extra["sparse"]


# ============================================================ the paper's tables
def test_optimal_split_table_reproduces_the_paper():
    from regmech.analysis.expm_tables import PAPER_TABLE, optimal_split_table
    for row in optimal_split_table():
        assert row["theta"] == pytest.approx(row["theta_closed_form"], rel=1e-10)
        paper_theta, paper_eps = PAPER_TABLE[row["r"]]
        assert row["theta"] == pytest.approx(paper_theta, abs=0.006)          # the paper rounds to 2 digits
        assert 0.5 * paper_eps <= row["eps"] <= 1.5 * paper_eps               # ... and eps to 1 digit


def test_roundoff_check_on_a_stretched_spectrum():
    from regmech.analysis.expm_tables import roundoff_check
    rows = roundoff_check(1e3, periods=(0.1, 10.0), n_steps=2)
    assert [r["ratio"] for r in rows] == pytest.approx([1e3, 1e3], rel=1e-6)
    for r in rows:
        # measured: ~1e-11; the floor of a ratio-1e3 spectrum is ~(w_max/w_min)^2 * 1e-16 = 1e-10
        assert r["err_phi"] <= 1e-9 and r["err_w"] <= 1e-9, r


def test_only_a_library_source_of_a_sine_is_taken_as_one():
    # a sampled test took a user's smooth function with a narrow bump between its samples for
    # a constant once the model held a Sine elsewhere, and dropped the bump (0.14 of the range off, estimate 3e-14).
    # Now only a Torque/Force of a Sine is taken exactly; the function keeps the fit and its estimate sees the bump
    J, c = np.array([1.0, 1.0, 1.0]), np.array([1e2, 1e2, 1e2])
    m = chain_model(J, c, d=[0.1, 0.1, 0.1], drive=Sine(amplitude=3.0, freq_hz=1.0))
    bump = m.add(Torque("bump", tau=lambda t: 1.0 + 5.0 * math.exp(-((t - 1.0) / 0.01) ** 2)))
    m.connect(bump.flange, m["J0"].flange_b)
    m.connect(bump.support, m["fixed"].flange)
    ref = m.simulate(2.0, dt_out=1e-2, solver="scipy:DOP853", rtol=1e-12, atol=1e-14)
    names = ["J0.w", "J1.w", "J2.w"]
    want = np.column_stack([ref[nm] for nm in names])
    try:
        r = m.simulate(2.0, dt_out=1e-2, solver="expm", accuracy=1e-6)
    except rm.AccuracyError:
        return                                   # refused: no wrong answer
    assert rel_error(r, names, want) <= 1e-6


def test_tiny_sines_that_start_apart_are_not_confused():
    # the particular solutions were cached under amplitudes rounded to 1e-12, so that on a
    # model scaled by 1e-13 a sine starting at 0.5 s reused the solution of the segment before it (0.26 off)
    sc = 1e-13
    m = rm.Model("nano")
    f = m.add(Fixed("fixed", domain="translational"))
    M0, M1 = m.add(Mass("M0", m=2.0 * sc)), m.add(Mass("M1", m=0.7 * sc))
    s0 = m.add(SpringDamper("s0", c=1e3 * sc, d=1.0 * sc, domain="translational"))
    s1 = m.add(SpringDamper("s1", c=4e3 * sc, d=0.5 * sc, domain="translational"))
    F1 = m.add(Force("F1", f=Sine(amplitude=3.0 * sc, freq_hz=6.0, offset=sc)))
    F2 = m.add(Force("F2", f=Sine(amplitude=2.0 * sc, freq_hz=6.0, phase=1.0, offset=2.0 * sc, start_time=0.5)))
    m.connect(f.flange, s0.flange_a)
    m.connect(s0.flange_b, M0.flange_a)
    m.connect(M0.flange_b, s1.flange_a)
    m.connect(s1.flange_b, M1.flange_a)
    m.connect(F1.flange, M1.flange_b)
    m.connect(F2.flange, M0.flange_b)
    ref = m.simulate(2.0, 0.01, solver="scipy:DOP853", rtol=1e-13, atol=1e-15 * sc, max_steps=10**6)
    names = ["M0.v", "M1.v", "M0.s", "M1.s"]
    r = m.simulate(2.0, 0.01, solver="expm")
    assert off(r, ref, names) <= 1e-9


@pytest.mark.slow
def test_sines_through_clutch_events_meet_tight_accuracies():
    # each stepper restarted at a located clutch event decided anew whether its (short) span
    # showed a sine, so the runs at h, 2h and 4h mixed exact and fitted spans and the contract refused 1e-5 to 1e-9
    from regmech.components import Clutch
    m = rm.Model("clutched")
    f = m.add(Fixed("fixed"))
    J0, J1, J2 = m.add(Inertia("J0", J=1.0)), m.add(Inertia("J1", J=0.5)), m.add(Inertia("J2", J=0.3))
    s0, s1 = m.add(SpringDamper("s0", c=200.0, d=0.5)), m.add(SpringDamper("s1", c=800.0, d=0.3))
    cl = m.add(Clutch("cl", mu=0.4, fn_max=10.0, f_normalized=1.0, peak=1.2))
    src = m.add(Torque("drive", tau=Sine(amplitude=12.0, freq_hz=1.5, offset=0.5)))
    src2 = m.add(Torque("drive2", tau=Sine(amplitude=3.0, freq_hz=2.5, start_time=0.3)))
    m.connect(f.flange, s0.flange_a)
    m.connect(s0.flange_b, J0.flange_a)
    m.connect(J0.flange_b, cl.flange_a)
    m.connect(cl.flange_b, J1.flange_a)
    m.connect(J1.flange_b, s1.flange_a)
    m.connect(s1.flange_b, J2.flange_a)
    m.connect(src.flange, J2.flange_b)
    m.connect(src2.flange, J0.flange_b)
    ref = m.simulate(3.0, 0.05, solver="scipy:DOP853", rtol=1e-13, atol=1e-15, max_steps=10**6)
    assert ref.events
    names = ["J0.w", "J1.w", "J2.w", "J0.phi", "J2.phi"]
    for acc in (1e-5, 1e-9):
        r = m.simulate(3.0, 0.05, solver="expm", accuracy=acc)
        assert off(r, ref, names) <= acc


def test_the_sparse_path_drops_nothing_its_estimate_cannot_see():
    # on a random stiff chain of 60 inertias (the sparse path) the entries dropped below 1e-17
    # left 4.4e-9 of the range of the angles, which both Richardson runs shared: the estimate said 1.6e-9. The
    # default drop tolerance is 1e-20 now (about 1e-11 there) and the companions drop 1000 times less
    rng = np.random.default_rng(7)
    n = 60
    m = rm.Model("stiff_chain")
    fixed = m.add(Fixed("fixed"))
    J = [m.add(Inertia(f"J{i}", J=float(10 ** rng.uniform(-3, 1)))) for i in range(n)]
    drive = m.add(Torque("drive", tau=Sine(amplitude=10.0, freq_hz=5.3, start_time=0.1)))
    m.connect(drive.flange, J[0].flange_a)
    for i in range(1, n):
        sd = m.add(SpringDamper(f"sd{i}", c=float(10 ** rng.uniform(2, 6)), d=0.013 * float(10 ** rng.uniform(-1, 1))))
        m.connect(J[i - 1].flange_b, sd.flange_a)
        m.connect(sd.flange_b, J[i].flange_a)
    end = m.add(Spring("ground", c=1e3))
    m.connect(J[-1].flange_b, end.flange_a)
    m.connect(end.flange_b, fixed.flange)
    # the reference: the dense path, which drops nothing (against DOP853 at rtol 1e-13 it is within 2.3e-11)
    ref = m.simulate(1.0, 1e-2, solver="expm", sparse=False, tol=None)
    r = m.simulate(1.0, 1e-2, solver="expm", accuracy=1.5e-8)
    for kind in ("w", "phi"):
        names = [f"J{i}.{kind}" for i in range(n)]
        assert off(r, ref, names) <= r.stats.error_estimate, kind
