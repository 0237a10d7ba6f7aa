"""numba kernel of the linear ODE form's right-hand side (``compile.odeform``); imported only when numba is.

One compiled call does what ``OdeForm.rhs`` does: the signal values into ``buf`` (``Constant``, ``Sine``,
``Step`` and ``Ramp`` by ``_native_signals.signal_value``, the same formulas; any other signal, and offsets
not linear in their signals, are written there by Python first), then::

    out = T u (+ t0) (+ V buf)          [tau; dz]
    g   = [v; (S_c^T tau) / (-m); dz]

with the same products, in the same order, as scipy's ``dia_matvec`` and ``csr_matvec`` behind the Python
path (``odeform.MatVec``): a DIA product adds its diagonals one by one in their stored order, a CSR row adds
its terms in their stored order from 0.0. The divisions are IEEE divisions (``error_model="numpy"``: no
zero-divisor test, which would also keep LLVM from vectorising the loop), and numba never contracts
``a * b + c`` into one fused multiply-add (no ``fastmath``), so both paths give the same numbers to the last
bit (``tests/unit/test_odeform_native.py`` checks it on chains, trees of shafts with motors and many sines).

Why: on a chain of 1,000 inertias the Python path's dozen numpy and scipy calls cost about 10 us per
right-hand side, the kernel about 3.3 us; the right-hand side is called 12 to 15 times per DOP853 step.
Everything the kernel reads comes in two arrays (``layout``), since each argument of a compiled call costs
about 0.1 us to check.

Operators arrive as ``(kind, ints, floats)`` per matrix (``pack``): kind 0 none, 1 DIA (``ints`` the offsets,
``floats`` the ``(n_diagonals, L)`` data raveled; ``L`` in ``ints``' last entry), 2 CSR (``ints`` = indptr and
indices concatenated, ``floats`` = data).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._native_signals import N_PAR, signal_value

NONE, DIA, CSR = 0, 1, 2
#: ``_native_signals.source_hash()`` of the signal formulas compiled in here (a test checks it: a change there must
#: edit this file, or numba's cache of this file's kernels keeps the old formulas)
SIGNALS_SOURCE = "4c634e02e3d2fb5c"


def pack(M):
    """``(kind, ints, floats, rows, cols)`` of a DIA or CSR matrix (``odeform.fast_operator``), or None for
    any other form (a dense matrix is multiplied by BLAS, whose order of the sums the kernel cannot repeat)."""
    import scipy.sparse as sp
    if M is None:
        return NONE, np.zeros(1, np.int64), np.zeros(0), 0, 0
    if not sp.issparse(M) or M.dtype != np.float64:
        return None
    rows, cols = M.shape
    if M.format == "dia":
        L = M.data.shape[1]
        ints = np.concatenate([np.asarray(M.offsets, np.int64), [L]])
        return DIA, ints, np.ascontiguousarray(M.data).ravel(), rows, cols
    if M.format == "csr":
        return CSR, np.concatenate([np.asarray(M.indptr, np.int64), np.asarray(M.indices, np.int64)]), \
            np.ascontiguousarray(M.data), rows, cols
    return None


@njit(cache=True, error_model="numpy", inline="always")
def _product(kind, ints, floats, rows, cols, x, y):
    """``y += M x`` for ``y`` zero (DIA, CSR: as scipy's kernels add the terms). The DIA loop runs on views
    (contiguous slices) so that LLVM vectorises it: 3 times faster than the same loop on offsets."""
    if kind == DIA:
        nd = ints.shape[0] - 1
        L = ints[nd]
        for k in range(nd):
            o = ints[k]
            i0 = max(0, -o)
            j0 = max(0, o)
            j1 = min(min(rows + o, cols), L)
            m = j1 - j0
            diag = floats[k * L + j0: k * L + j1]
            xs = x[j0:j1]
            ys = y[i0:i0 + m]
            for q in range(m):
                ys[q] += diag[q] * xs[q]
    elif kind == CSR:
        indptr = ints[:rows + 1]
        indices = ints[rows + 1:]
        for i in range(rows):
            acc = 0.0
            for q in range(indptr[i], indptr[i + 1]):
                acc += floats[q] * x[indices[q]]
            y[i] = acc


#: the header of ``ih`` (``layout``): sizes and flags, then (offset, length) of each integer part in ``ih`` and of
#: each float part in ``fh``
H_N, H_NC, H_ROWS, H_TK, H_SK, H_VK, H_T0, H_SIG = range(8)
I_PARTS = ("ti", "si", "vi", "v_rows", "v_cols", "sig_kind", "sig_slot")
F_PARTS = ("tf", "sf", "vf", "t0", "v_vals", "sig_par", "neg_mass", "out", "work", "acc")
I_PLACES = 8                                   # (offset, length) of integer part k at I_PLACES + 2 k
F_PLACES = I_PLACES + 2 * len(I_PARTS)         # ... of float part k at F_PLACES + 2 k
I_HEAD = F_PLACES + 2 * len(F_PARTS)


def layout(n, n_c, rows, T, S, V, t0, add_t0, compact, signals, neg_mass):
    """``(ih, fh)``: everything ``linear_rhs`` reads in two arrays (one crossing into compiled code costs about
    0.1 us per argument; 27 arguments cost more than the products on a chain of 1,000 inertias). ``T``, ``S``,
    ``V``: ``pack``'s ``(kind, ints, floats)``; ``compact``: ``(v_rows, v_cols, v_vals)`` or None; ``signals``:
    the table ``(kinds, slots, parameters)`` or None (Python writes the signals into ``buf``)."""
    empty = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    v_rows, v_cols, v_vals = compact if compact is not None else empty
    kinds, slots, pars = signals if signals is not None else empty
    ints = dict(ti=T[1], si=S[1], vi=V[1], v_rows=v_rows, v_cols=v_cols, sig_kind=kinds, sig_slot=slots)
    floats = dict(tf=T[2], sf=S[2], vf=V[2], t0=t0, v_vals=v_vals, sig_par=pars, neg_mass=neg_mass,
                  out=np.zeros(rows), work=np.zeros(rows), acc=np.zeros(n))
    head = [n, n_c, rows, T[0], S[0], V[0], int(bool(add_t0)), int(signals is not None)]
    for parts, pos in ((ints, I_HEAD), (floats, 0)):
        for name in (I_PARTS if parts is ints else F_PARTS):
            head += [pos, len(parts[name])]
            pos += len(parts[name])
    ih = np.concatenate([np.array(head, np.int64)] + [np.asarray(ints[k], np.int64) for k in I_PARTS])
    fh = np.concatenate([np.asarray(floats[k], np.float64) for k in F_PARTS])
    return ih, fh


@njit(cache=True, inline="always")
def _ipart(ih, k):
    off = ih[I_PLACES + 2 * k]
    return ih[off: off + ih[I_PLACES + 2 * k + 1]]


@njit(cache=True, inline="always")
def _fpart(ih, fh, k):
    off = ih[F_PLACES + 2 * k]
    return fh[off: off + ih[F_PLACES + 2 * k + 1]]


@njit(cache=True, error_model="numpy")
def linear_rhs(u, buf, t, left, ih, fh):
    """``g(t, u)`` of the linear form (module docstring) as a new array (``linear_rhs_into``)."""
    g = np.empty(u.shape[0])
    linear_rhs_into(u, buf, t, left, ih, fh, g)
    return g


@njit(cache=True, error_model="numpy")
def linear_rhs_into(u, buf, t, left, ih, fh, g):
    """``g(t, u)`` of the linear form (module docstring) written into ``g`` (an array of u's length that is not
    ``u``); ``(ih, fh)`` from ``layout``. With a signal table, its signals are evaluated at ``t`` (left limits
    when ``left``) into ``buf`` first; the other slots of ``buf`` hold what Python wrote there. ``out`` (the
    rows of [tau; dz]), ``work`` (for a general V) and ``acc`` (length n) are scratch. A compact V (one term
    per row: ``out[v_rows] += v_vals * buf[v_cols]``) when ``v_rows`` is not empty, else the operator ``vi, vf``
    (or none)."""
    n, n_c, rows = ih[H_N], ih[H_NC], ih[H_ROWS]
    ti, si, vi = _ipart(ih, 0), _ipart(ih, 1), _ipart(ih, 2)
    v_rows, v_cols = _ipart(ih, 3), _ipart(ih, 4)
    tf, sf, vf, t0 = _fpart(ih, fh, 0), _fpart(ih, fh, 1), _fpart(ih, fh, 2), _fpart(ih, fh, 3)
    v_vals, neg_mass = _fpart(ih, fh, 4), _fpart(ih, fh, 6)
    out, work, acc = _fpart(ih, fh, 7), _fpart(ih, fh, 8), _fpart(ih, fh, 9)
    if ih[H_SIG]:
        sig_kind, sig_slot, sig_par = _ipart(ih, 5), _ipart(ih, 6), _fpart(ih, fh, 5)
        for s in range(sig_kind.shape[0]):
            buf[sig_slot[s]] = signal_value(sig_kind[s], sig_par[N_PAR * s: N_PAR * (s + 1)], t, left)
    size = u.shape[0]
    out[:] = 0.0
    _product(ih[H_TK], ti, tf, rows, size, u, out)
    if ih[H_T0]:
        out += t0
    if v_rows.shape[0]:
        for q in range(v_rows.shape[0]):
            out[v_rows[q]] += v_vals[q] * buf[v_cols[q]]
    elif ih[H_VK] != NONE:
        work[:] = 0.0
        _product(ih[H_VK], vi, vf, rows, buf.shape[0], buf, work)
        out += work
    g[:n] = u[n:2 * n]
    if n_c:
        acc[:] = 0.0
        _product(ih[H_SK], si, sf, n, n_c, out, acc)
        a = g[n:2 * n]
        for i in range(n):
            a[i] = acc[i] / neg_mass[i]
    else:
        g[n:2 * n] = 0.0
    g[2 * n:] = out[n_c:]


@njit(cache=True, error_model="numpy")
def linear_jacobian(n, n_c, size, mass, s_ptr, s_idx, s_dat, t_ptr, t_idx, t_dat):
    """``(indptr, indices, data)`` of ``dg/du`` of the linear form in CSR, with the entries, sums and order of
    ``OdeForm.jacobian``'s scipy products (a middle row's columns in the reverse of their first appearance, the
    last rows' in T's order): rows ``[0 I 0]``, then
    ``-M^-1 S_c^T T_[:n_c]`` (``S_c^T``: ``s_*``, n x n_c; ``T`` on u: ``t_*``), then ``T_[n_c:]``; sums that
    cancel to exactly zero are left out, as scipy's product leaves them."""
    rows_t = t_ptr.shape[0] - 1
    acc = np.zeros(size)
    mark = np.full(size, -1, np.int64)
    # the middle rows' entries: at most the sum of the lengths of the T rows each touches
    cap = 0
    for i in range(n):
        for p in range(s_ptr[i], s_ptr[i + 1]):
            k = s_idx[p]
            cap += t_ptr[k + 1] - t_ptr[k]
    nnz = n + cap + (t_ptr[rows_t] - t_ptr[n_c])
    indptr = np.empty(size + 1, np.int64)
    indices = np.empty(nnz, np.int64)
    data = np.empty(nnz)
    indptr[0] = 0
    pos = 0
    for i in range(n):                               # x' = v
        indices[pos] = n + i
        data[pos] = 1.0
        pos += 1
        indptr[i + 1] = pos
    cols = np.empty(size, np.int64)
    for i in range(n):                               # v' = -(1/m_i) sum_k S_c^T[i, k] tau_k
        inv = 1.0 / mass[i]
        m = 0
        for p in range(s_ptr[i + 1] - 1, s_ptr[i] - 1, -1):     # scipy's M^-1 S_c^T leaves each row reversed
            a = -(inv * s_dat[p])
            k = s_idx[p]
            for q in range(t_ptr[k], t_ptr[k + 1]):
                j = t_idx[q]
                if mark[j] != i:
                    mark[j] = i
                    acc[j] = 0.0
                    cols[m] = j
                    m += 1
                acc[j] += a * t_dat[q]
        for q in range(m - 1, -1, -1):               # latest column first, as scipy's product emits them
            j = cols[q]
            if acc[j] != 0.0:
                indices[pos] = j
                data[pos] = acc[j]
                pos += 1
        indptr[n + i + 1] = pos
    for r in range(n_c, rows_t):                     # z' = T_[n_c:] u, in T's order
        for q in range(t_ptr[r], t_ptr[r + 1]):
            indices[pos] = t_idx[q]
            data[pos] = t_dat[q]
            pos += 1
        indptr[2 * n + (r - n_c) + 1] = pos
    return indptr, indices[:pos].copy(), data[:pos].copy()
