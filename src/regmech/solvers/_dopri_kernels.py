"""numba passes of the Dormand-Prince integrators (``solvers.dopri``); imported only when numba is.

* ``blend``: ``out = y0 + c (y1 - y0) + h sum_{j<rows} w_j K_j``: a stage's argument (``y1 = y0``, ``c = 0``:
  ``y0 + 0 + h sum``, the same number as ``y0 + h sum``) and a dense output's value;
* ``rms_error``: ``dopri5``'s error norm, ``sqrt(mean((h sum_j e_j K_j / scale)^2))`` with
  ``scale = atol + rtol max(|y|, |y_new|)``, no array made;
* ``blended_sums``: ``dop853``'s two sums of squares ``sum (sum_j e5_j K_j / scale)^2`` and the same of ``e3``.

Each works through the states in blocks of ``BLOCK``: the block's sums stay in the first-level cache while the
stages are added into them one row at a time, a loop over contiguous slices that LLVM vectorises (the same
sums taken state by state, reading down the rows, ran 2 to 4 times slower than numpy's matrix product).
No ``fastmath``: the sums are the plain ones, in stage order, with the terms of zero weight left out (``_combine``:
each would read a row of stages from memory for an exact zero; on the chain of 10,000 inertias ``dop853`` at
rtol 3e-9 took 112 instead of 137 ms, the same numbers to the last bit).

Why: scipy's stepping (and the numpy path in ``dopri``) reads and writes each stage's vectors three to five
times; on 20,000 states those passes cost more than the right-hand side (module docstring of ``dopri``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..compile._odeform_kernels import linear_rhs_into

#: states per block: 256 sums (2 kB) beside one slice of each of up to 16 stage rows
BLOCK = 256


@njit(cache=True, error_model="numpy", inline="always")
def _combine(K, a, rows, i0, m, acc):
    """``acc[:m] = sum_{j<rows} a[j] K[j, i0:i0+m]``, in stage order, the terms of zero weight left out.

    Why left out: DOP853's tables are a third zeros (its stages' rows of A: 50 of 66 weights, B 8 of 12, the
    error weights 8 of 13, the dense output's stages 24 of 42), and each term reads a row of K from memory, the
    cost of these passes on a large model. A term ``0 K[j, i]`` adds an exact zero, so the sums are the same
    numbers (up to the sign of a sum that is exactly zero), except that a non-finite entry of a row of zero
    weight does not turn them into NaN. Every stage but the step's end rate has weight in a later stage or in the
    error norm; that rate has none in DOP853's error weights, so ``DormandPrince._step_impl`` tests it apart."""
    first = True
    for j in range(rows):
        aj = a[j]
        if aj == 0.0:
            continue
        kj = K[j, i0:i0 + m]
        if first:
            for q in range(m):
                acc[q] = aj * kj[q]
            first = False
        else:
            for q in range(m):
                acc[q] += aj * kj[q]
    if first:
        for q in range(m):
            acc[q] = 0.0


@njit(cache=True, error_model="numpy", inline="always")
def _scaled(acc, m, i0, y, y_new, atol, rtol):
    """``acc[q] /= atol_i + rtol max(|y_i|, |y_new_i|)`` for ``i = i0 + q``, q < m (a loop LLVM vectorises)."""
    ys = y[i0:i0 + m]
    yn = y_new[i0:i0 + m]
    at = atol[i0:i0 + m]
    for q in range(m):
        acc[q] /= at[q] + max(abs(ys[q]), abs(yn[q])) * rtol


@njit(cache=True, error_model="numpy", inline="always")
def _squares(acc, m):
    """``sum acc[:m]^2`` in four interleaved partial sums (one running sum would wait on each addition)."""
    s0 = s1 = s2 = s3 = 0.0
    q = 0
    while q + 4 <= m:
        s0 += acc[q] * acc[q]
        s1 += acc[q + 1] * acc[q + 1]
        s2 += acc[q + 2] * acc[q + 2]
        s3 += acc[q + 3] * acc[q + 3]
        q += 4
    while q < m:
        s0 += acc[q] * acc[q]
        q += 1
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, error_model="numpy")
def rms_error(K, e, h, y, y_new, atol, rtol):
    """``sqrt(sum_i (h sum_j e[j] K[j, i] / scale_i)^2 / n)``, ``scale_i = atol_i + rtol max(|y_i|, |y_new_i|)``."""
    n = y.shape[0]
    acc = np.empty(BLOCK)
    total = 0.0
    for i0 in range(0, n, BLOCK):
        m = min(BLOCK, n - i0)
        _combine(K, e, e.shape[0], i0, m, acc)
        _scaled(acc, m, i0, y, y_new, atol, rtol)
        total += _squares(acc, m)
    return abs(h) * math.sqrt(total / n) if n else 0.0


@njit(cache=True, error_model="numpy")
def blended_sums(K, e5, e3, rows, y, y_new, atol, rtol):
    """``(sum_i (sum_{j<rows} e5[j] K[j, i] / scale_i)^2, the same with e3)``."""
    n = y.shape[0]
    a5 = np.empty(BLOCK)
    a3 = np.empty(BLOCK)
    t5 = 0.0
    t3 = 0.0
    for i0 in range(0, n, BLOCK):
        m = min(BLOCK, n - i0)
        _combine(K, e5, rows, i0, m, a5)
        _combine(K, e3, rows, i0, m, a3)
        _scaled(a5, m, i0, y, y_new, atol, rtol)
        _scaled(a3, m, i0, y, y_new, atol, rtol)
        t5 += _squares(a5, m)
        t3 += _squares(a3, m)
    return t5, t3


@njit(cache=True, error_model="numpy")
def blend(y0, y1, c, K, w, rows, h, out):
    """``out[i] = y0[i] + c (y1[i] - y0[i]) + h sum_{j<rows} w[j] K[j, i]`` (module docstring)."""
    n = y0.shape[0]
    acc = np.empty(BLOCK)
    for i0 in range(0, n, BLOCK):
        m = min(BLOCK, n - i0)
        _combine(K, w, rows, i0, m, acc)
        a = y0[i0:i0 + m]
        b = y1[i0:i0 + m]
        os = out[i0:i0 + m]
        for q in range(m):
            os[q] = a[q] + c * (b[q] - a[q]) + h * acc[q]


@njit(cache=True, error_model="numpy")
def linear_stages(y, K, A, C, s0, s1, t, h, t_right, work, buf, ih, fh):
    """``K[s] = g(t + C[s] h, y + h sum_{j<s} A[s, j] K[j])`` for ``s0 <= s < s1``, with ``g`` the linear ODE form's
    right-hand side (``compile._odeform_kernels.linear_rhs_into`` on its ``(buf, ih, fh)``, its signals in the
    kernel's table; left limits at ``t_right``, the segment's end, and beyond): the stages of a Runge-Kutta step
    in one call. The same passes in the same order as one ``blend`` and one right-hand side per stage, so the
    same numbers; what it saves is the Python around each stage (``dopri``: about a third of a step on a model
    of a few hundred states). ``work``: the stage argument (scratch)."""
    for s in range(s0, s1):
        blend(y, y, 0.0, K, A[s], s, h, work)
        ts = t + C[s] * h
        linear_rhs_into(work, buf, ts, ts >= t_right, ih, fh, K[s])
