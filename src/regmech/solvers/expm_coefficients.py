"""Coefficient matrices of the step-doubling exponential integrator (REFERENCES.md [002]).

For ``q' = A q + b(t)`` with ``b`` a polynomial on a step of length h,
``b(t_j + s) = sum_{k=1..p} beta_k s^(k-1)``, the exact step is

    q_{j+1} = D0 q_j + sum_k D_k beta_k,
    D0 = exp(A h),   D_k = int_0^h exp(A (h - s)) s^(k-1) ds.

Only the columns of the inputs are ever needed: ``beta_k = W c_k`` with a
fixed (N x n_in) input matrix W, so the module computes ``D_k W`` (N x n_in,
"truncated") and never the full D_k; with W = I the same code gives the full
matrices (used by the tests).

Taylor start at ``tau = h / 2^m`` (order r), carrying the small parts
``E = D0 - I`` and ``Delta_k = D_k - (tau^k / k) I`` so that nothing of order
tau is added to the identity before the end (this is what keeps the
precision when tau is tiny)::

    E(tau)           = sum_{j=1..r} (A tau)^j / j!
    Delta_k(tau) W   = sum_{j=1..r} A^j W tau^(j+k) (k-1)! / (j+k)!

Doubling (re-derived from REFERENCES.md [002]; ``D0(2t) = D0(t)^2`` and
``D_k(2t) = D0 D_k + sum_l C(k-1, l) t^(k-1-l) D_(l+1)``), in the carried
parts, with ``c_k = tau^k / k``::

    E'         = 2 E + E E
    Delta_k' W = Delta_k W + E (Delta_k W) + c_k E W
                 + sum_{l=0..k-1} C(k-1, l) tau^(k-1-l) Delta_(l+1) W

(the identity parts add up to ``(2 tau)^k / k`` exactly, because
``sum_l C(k-1, l) / (l+1) = (2^k - 1) / k``).

Choice of (r, m). The per-step relative error of the start, amplified by the
doublings, is ``eps ~ 2^m theta^(r+1) / (r+1)!`` with ``theta = nu h / 2^m``
(``nu`` a norm of A); the work is about ``m + r`` matrix products.
``choose_split`` takes the cheapest (r, m) whose ``eps`` is below the
target (default: the unit round-off), see also
``regmech.analysis.expm_tables``.

Two storage paths for E (the D_k W are always dense N x n_in):

* dense numpy arrays (BLAS products), for up to a few hundred masses;
* scipy CSR with a drop tolerance (entries below ``drop_tol``, default
  1e-20, are removed after every product). In the scaled state D0 is of
  order one, so such a tolerance is below its round-off; the entries of D0
  decay super-exponentially beyond the distance a wave travels in one step,
  so for long chains E stays sparse (measured: about 8 % of the entries kept
  on a chain of 1,000 masses at 1e-17). Not 1e-17: on a stretched spectrum (the sparse path
  scales positions by one frequency) the slow modes amplify what is dropped
  like round-off (a random stiff chain of 60 inertias, link spread in the
  thousands: 4.4e-9 of the range of the angles at 1e-17, where its estimate
  said 1.6e-9, and about 1e-11 at 1e-20 or with nothing dropped), while the
  benchmark chains of 1,000 and 10,000 inertias and a train of 500 cars
  changed by under 5e-13 and ran in about the same time (80/86, 580/587 and
  182/179 ms). The Richardson companions drop 1000
  times less again (``expm.COMPANION_DROP``), so that what is dropped
  shows in the estimate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

UNIT_ROUNDOFF = 2.0 ** -53
MAX_TAYLOR_ORDER = 18
DROP_TOL = 1e-20


# ------------------------------------------------------------------ error model
def split_error(r: int, m: int, nu_h: float) -> float:
    """``eps = 2^m theta^(r+1) / (r+1)!`` with ``theta = nu_h / 2^m`` (per-step relative error).

    Beyond m = 1000 doublings (``2.0 ** m`` overflows at 1024; an absurd ``nu_h`` such as a
    1e-300 kg m^2 inertia on a spring, 1e150 rad/s, asks for them) it is evaluated in logarithms and
    saturates at 1e304."""
    if nu_h <= 0:
        return 0.0
    if m <= 1000:
        theta = nu_h / 2.0 ** m
        return 2.0 ** m * math.exp((r + 1) * math.log(theta) - math.lgamma(r + 2))
    log2 = math.log(2.0)
    return math.exp(min(m * log2 + (r + 1) * (math.log(nu_h) - m * log2) - math.lgamma(r + 2), 700.0))


def doublings_for(r: int, nu_h: float, tol: float) -> int:
    """Smallest m >= 0 with ``split_error(r, m, nu_h) <= tol``.

    ``eps = nu_h theta^r / (r+1)!`` decreases by 2^r per doubling, so
    ``theta <= (tol (r+1)! / nu_h)^(1/r)``.
    """
    if nu_h <= 0:
        return 0
    log_theta_max = (math.log(tol) + math.lgamma(r + 2) - math.log(nu_h)) / r
    m = max(0, math.ceil((math.log(nu_h) - log_theta_max) / math.log(2.0)))
    while m > 0 and split_error(r, m - 1, nu_h) <= tol:      # guard the rounding of the closed form
        m -= 1
    while split_error(r, m, nu_h) > tol:
        m += 1
    return m


def choose_split(nu_h: float, tol: float = UNIT_ROUNDOFF, r: int | None = None) -> tuple[int, int]:
    """(Taylor order r, doublings m) of least cost ``m + r`` with error <= tol.

    With ``r`` given, only m is chosen. Ties go to the smaller r (fewer
    products before the first doubling, where the matrices are sparsest).
    """
    if r is not None:
        return int(r), doublings_for(int(r), nu_h, tol)
    best = None
    for rr in range(1, MAX_TAYLOR_ORDER + 1):
        m = doublings_for(rr, nu_h, tol)
        if best is None or m + rr < best[0] + best[1]:
            best = (rr, m)
    return best


# -------------------------------------------------------------------- matrices
def _is_sparse(X) -> bool:
    return sp.issparse(X)


def _drop(X, drop_tol):
    """Remove entries with |x| < drop_tol from a CSR matrix (in place) and return it."""
    if drop_tol > 0:
        X.data[np.abs(X.data) < drop_tol] = 0.0
        X.eliminate_zeros()
    return X


def _identity_like(A):
    n = A.shape[0]
    return sp.identity(n, format="csr") if _is_sparse(A) else np.eye(n)


@dataclass
class Coefficients:
    """``E = D0 - I`` and ``DW[k-1] = D_k W`` (k = 1..p) for one step h."""

    h: float
    E: object                      # N x N, dense ndarray or CSR
    DW: list                       # p arrays N x n_in
    r: int
    m: int
    nu_h: float
    stats: dict = field(default_factory=dict)

    def apply_D0(self, q):
        return q + self.E @ q


def taylor_start(A, W, tau: float, r: int, p: int, drop_tol: float = 0.0):
    """E(tau) and Delta_k(tau) W (k = 1..p), Taylor order r (see the module docstring)."""
    sparse = _is_sparse(A)
    X = (A * tau).tocsr() if sparse else A * tau
    # Horner for E = X (I + X/2 (I + X/3 (... (I + X/r)))): r - 1 matrix products
    I = _identity_like(A)
    E = X / r
    for j in range(r - 1, 0, -1):
        E = X @ (I + E) / j
        if sparse:
            E = _drop(E.tocsr(), drop_tol)
    # Delta_k W = sum_j A^j W tau^(j+k) (k-1)!/(j+k)!  =  sum_j (X^j W) tau^k (k-1)!/(j+k)!
    Wd = np.asarray(W.toarray() if sp.issparse(W) else W, float)
    deltas = [np.zeros_like(Wd) for _ in range(p)]
    XjW = Wd
    for j in range(1, r + 1):
        XjW = X @ XjW
        for k in range(1, p + 1):
            deltas[k - 1] += XjW * (tau ** k * math.exp(math.lgamma(k) - math.lgamma(j + k + 1)))
    return E, deltas


def double(E, deltas, EW, tau: float, drop_tol: float = 0.0):
    """One doubling tau -> 2 tau of (E, Delta_k W); ``EW = E @ W`` at tau. Returns the new pair."""
    p = len(deltas)
    new = []
    for k in range(1, p + 1):
        d = deltas[k - 1] + E @ deltas[k - 1] + (tau ** k / k) * EW
        for l in range(k):
            d = d + math.comb(k - 1, l) * tau ** (k - 1 - l) * deltas[l]
        new.append(d)
    E2 = E @ E
    if _is_sparse(E):
        E_new = _drop((2.0 * E + E2).tocsr(), drop_tol)
    else:
        E_new = 2.0 * E + E2
    return E_new, new


def coefficients(A, W, h: float, p: int, nu: float | None = None, tol: float = UNIT_ROUNDOFF,
                 r: int | None = None, drop_tol: float = DROP_TOL) -> Coefficients:
    """``E = exp(A h) - I`` and ``D_k W`` (k = 1..p) by Taylor start and step doubling.

    ``A``: N x N (dense ndarray, or scipy sparse for the sparse path);
    ``W``: N x n_in input columns; ``nu``: a norm of A (default the inf-norm);
    ``tol``: target of the truncation error model; ``r``: Taylor order
    (default: the cheapest one for ``tol``); ``drop_tol``: sparse path only.
    """
    if p < 1:
        raise ValueError("p must be >= 1")
    sparse = _is_sparse(A)
    if sparse:
        A = sp.csr_matrix(A, dtype=float)
    else:
        A = np.asarray(A, float)
    if nu is None:
        nu = float(abs(A).sum(axis=1).max()) if A.shape[0] else 0.0
    nu_h = float(nu) * h
    r, m = choose_split(nu_h, tol, r)
    tau = h / 2.0 ** m
    E, deltas = taylor_start(A, W, tau, r, p, drop_tol if sparse else 0.0)
    Wd = np.asarray(W.toarray() if sp.issparse(W) else W, float)
    for _ in range(m):
        EW = E @ Wd
        E, deltas = double(E, deltas, EW, tau, drop_tol if sparse else 0.0)
        tau *= 2.0
    DW = [deltas[k - 1] + (h ** k / k) * Wd for k in range(1, p + 1)]
    stats = {"taylor_r": r, "doublings_m": m, "nu_h": nu_h}
    if sparse:
        stats["E_density"] = E.nnz / max(1, E.shape[0] * E.shape[1])
    return Coefficients(h=h, E=E, DW=DW, r=r, m=m, nu_h=nu_h, stats=stats)


def fit_nodes(p: int) -> np.ndarray:
    """Gauss-Legendre nodes on [0, 1] at which the forcing is sampled (p = 1: the midpoint)."""
    x, _ = np.polynomial.legendre.leggauss(p)
    return 0.5 * (x + 1.0)


def fit_matrix(p: int) -> np.ndarray:
    """``V^-1`` for the monomials ``sigma^(k-1)`` at ``fit_nodes(p)``: coefficients = V^-1 @ values."""
    s = fit_nodes(p)
    V = s[:, None] ** np.arange(p)[None, :]
    return np.linalg.inv(V)


__all__ = ["coefficients", "Coefficients", "choose_split", "split_error", "doublings_for", "taylor_start",
           "double", "fit_nodes", "fit_matrix", "UNIT_ROUNDOFF", "DROP_TOL"]
