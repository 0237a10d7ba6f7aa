"""numba kernels of ``ode_driver.spectral_bound`` (the explicit methods' up-front stiffness check);
imported only when the model's right-hand side is compiled too (numba is loaded already, so the check costs
no import).

The bound's numpy path makes about twenty passes and twenty arrays over the entries and rows of the
Jacobian; cold, on a freshly compiled chain of 1,000 inertias, it cost 0.96 ms (6 % of the cheapest explicit
run it guards), on 10,000 inertias 3.8 ms, of which the selection of the candidate rows
(``np.argpartition`` of four keys) alone was 0.9 ms a side. Here, two kernels (loading them from numba's
cache costs 10-17 ms once per process, beside numba's own start-up of about a second; four had cost about as
much):

* ``sums_and_rows``: the row and column sums ``p, q, r`` in one pass over the stored entries, in the order
  ``np.bincount`` adds them (the storage order), with the same arithmetic: the same numbers. Then, for
  each side, the rows among the ``k`` largest of any of the four keys, ties going to the lower row
  (``np.argpartition`` breaks them as its selection happens to run). The search only uses the upper
  envelope of these rows, and rows of equal ``(p, q, r)`` are interchangeable; rows that tie on one key and
  differ on another are another set, and may move the point the search lands on (any point gives a valid
  bound: the bound is evaluated on every row).
* ``envelope``: the grid point where the largest of the kept rows' sums ``p s + q + r / s`` is least
  (first on ties, as ``np.argmin``), and that value (over every row at one ``s``: the bound). ``s`` itself
  comes from numpy's ``exp`` and Python's, whose last bit numba's need not share.

No ``fastmath``: no fused multiply-add, no reordering.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always", error_model="numpy")
def _weighted_sums(indptr, indices, data, by_column, w, e, size):
    """``out[k]``: the sums of ``|J_ij| w_i / w_j`` over the entries of power ``e_i - e_j`` = 1, 0, -1
    (``k`` = 0, 1, 2) of every row (``out[k]``) and column (``out[3 + k]``), from a CSR (``by_column`` False)
    or CSC matrix's arrays, each sum in storage order (as ``np.bincount`` over the matrix's triplets)."""
    out = np.zeros((6, size))
    for major in range(indptr.shape[0] - 1):
        for k in range(indptr[major], indptr[major + 1]):
            minor = indices[k]
            if by_column:
                i, j = minor, major
            else:
                i, j = major, minor
            val = abs(data[k]) * w[i] / w[j]
            part = 1 - (e[i] - e[j])
            out[part, i] += val
            out[3 + part, j] += val
    return out


@njit(cache=True, inline="always")
def _mark_largest(key, k, mark):
    """Mark the ``k`` largest entries of ``key`` (ties to the lower index; NaN never): a bounded insertion
    list."""
    top = np.empty(k, np.int64)
    count = 0
    for i in range(key.shape[0]):
        v = key[i]
        if count == k and not (v > key[top[k - 1]]):
            continue
        if count < k and not (v == v):
            continue
        pos = count if count < k else k - 1
        while pos > 0 and v > key[top[pos - 1]]:
            if pos < k:
                top[pos] = top[pos - 1]
            pos -= 1
        top[pos] = i
        if count < k:
            count += 1
    for m in range(count):
        mark[top[m]] = True


@njit(cache=True, inline="always", error_model="numpy")
def _largest_rows(p, q, r, scale, k):
    """The rows (ascending) among the ``k`` largest of ``p``, ``q``, ``r`` or ``p scale + q + r / scale``."""
    n = p.shape[0]
    k = min(k, n)
    mark = np.zeros(n, np.bool_)
    both = np.empty(n)
    for i in range(n):
        both[i] = p[i] * scale + q[i] + r[i] / scale
    _mark_largest(p, k, mark)
    _mark_largest(q, k, mark)
    _mark_largest(r, k, mark)
    _mark_largest(both, k, mark)
    return np.nonzero(mark)[0]


@njit(cache=True, error_model="numpy")
def sums_and_rows(indptr, indices, data, by_column, mass, kx, kv, size, k):
    """The row and column sums (``_weighted_sums``, with ``w`` the square roots of the masses of the position
    coordinates ``kx`` and speed coordinates ``kv``, a mass of 0 counting as 1, and ``e`` 1 on positions),
    and for the rows' side and the columns' side: the largest ``p`` and ``r``, the scale ``sqrt(max r /
    max p)`` where the search starts, and the rows it searches (``_largest_rows``)."""
    w = np.ones(size)
    e = np.zeros(size, np.int64)
    nkx = kx.shape[0]
    for a in range(nkx):
        m = mass[kx[a]]
        w[a] = math.sqrt(m if m > 0 else 1.0)
        e[a] = 1
    for a in range(kv.shape[0]):
        m = mass[kv[a]]
        w[nkx + a] = math.sqrt(m if m > 0 else 1.0)
    out = _weighted_sums(indptr, indices, data, by_column, w, e, size)
    facts = np.empty((2, 3))               # max p, max r, scale
    rows = []
    for side in range(2):
        p, q, r = out[3 * side], out[3 * side + 1], out[3 * side + 2]
        p_max, r_max = p.max(), r.max()
        # Python's max (the numpy path's): the first argument unless the second is larger, so NaN stays
        scale = math.sqrt((1e-300 if 1e-300 > r_max else r_max) / (1e-300 if 1e-300 > p_max else p_max))
        facts[side, 0], facts[side, 1], facts[side, 2] = p_max, r_max, scale
        rows.append(_largest_rows(p, q, r, scale, k))
    return out, facts, rows[0], rows[1]


@njit(cache=True, error_model="numpy")
def envelope(p, q, r, rows, s):
    """``(j, v)``: ``v = min_j max_{i in rows} (p_i s_j + q_i + r_i / s_j)`` and its first ``j`` (as
    ``np.argmin``); NaN when a sum is NaN (as ``np.max``)."""
    best, at = np.inf, 0
    for j in range(s.shape[0]):
        sj = s[j]
        top = -np.inf
        for i in rows:
            v = p[i] * sj + q[i] + r[i] / sj
            if v > top:
                top = v
            elif v != v:
                return j, v
        if top < best:
            best, at = top, j
    return at, best
