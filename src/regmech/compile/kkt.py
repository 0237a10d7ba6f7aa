"""The acceleration-level (KKT) system of one mode set: assembly and LU factorisation.

Unknowns ``(a, lam)``; rows: motion ``M a + G^T lam = f``; position and speed rows at
acceleration level ``G_pv a = g``; friction row j: ``G_f[j] a = 0`` when stuck, else
``c_own lam_j + c_cpl lam_cpl(j) = rhs_j`` (``relations``: per row ``(c_own, c_cpl)``).

Only the friction rows change with the modes. A small system (at most ``DENSE_MAX``
unknowns) is copied from a dense template made once per compiled system, its friction
rows filled in, and factorised by LAPACK (``getrf``/``getrs``); a larger one is assembled
from sparse blocks and factorised by SuperLU. Both use partial pivoting, and both count
the system as singular when the smallest pivot of ``U`` is below ``pivot_tol`` of the
largest, so the choice changes round-off only.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.linalg.lapack import dgetrf, dgetrs

#: the largest number of unknowns ``n + m`` assembled and factorised densely. Measured on chains
#: with clutches, springs and gears (one process, 2 cores under load, medians of 7): dense 0.04 ms
#: against 0.95 ms sparse at 6 unknowns, 0.16 against 1.2 ms at 133; from about 160 unknowns
#: OpenBLAS factorises with several threads, and on a loaded machine a dense LU then took
#: 450-580 ms (0.3-0.4 ms single-threaded) against 1.3 ms sparse. Below that size the dense path
#: stays single-threaded and ahead.
DENSE_MAX = 128


class DenseLU:
    """LU factors of a small dense matrix with SuperLU's ``solve(rhs)``."""

    __slots__ = ("lu", "piv")

    def __init__(self, lu, piv):
        self.lu, self.piv = lu, piv

    def solve(self, rhs):
        x, _ = dgetrs(self.lu, self.piv, rhs)
        return x


def _template(c):
    """The dense rows that no mode changes: motion and the rigid rows at acceleration level."""
    K0 = c.__dict__.get("_kkt_template")
    if K0 is None:
        n, m, mpv = c.n, c.m, c.mp + c.mv
        K0 = np.zeros((n + m, n + m))
        K0[np.arange(n), np.arange(n)] = getattr(c, "kkt_mass", c.mass)
        K0[:n, n:] = c.GallT.toarray()
        K0[n:n + mpv, :n] = c.Gpv.toarray()
        c._kkt_template = K0
        c._kkt_Gf = c.Gf.toarray()
    return K0


def _dense(c, modes, relations, pivot_tol):
    K = _template(c).copy()
    n, base = c.n, c.mp + c.mv
    if c.mf:
        coupled = c.friction.coupled
        for j, (c_own, c_cpl) in enumerate(relations):
            row = n + base + j
            if modes[j] == 0:
                K[row, :n] = c._kkt_Gf[j]
                continue
            K[row, n + base + j] = c_own
            if coupled[j] >= 0 and c_cpl != 0.0:
                K[row, n + coupled[j]] = c_cpl
    lu, piv, info = dgetrf(K, overwrite_a=True)
    d = np.abs(np.diagonal(lu))
    if info != 0 or not np.all(np.isfinite(d)) or (d.size and d.min() <= pivot_tol * d.max()):
        return None
    return DenseLU(lu, piv)


def _sparse(c, modes, relations, pivot_tol):
    m = c.m
    blocks = [[sp.diags(getattr(c, "kkt_mass", c.mass)), c.GallT], [c.Gpv, sp.csr_matrix((c.mp + c.mv, m))]]
    if c.mf:
        fr = c.friction
        stuck = np.asarray(modes) == 0
        ra = sp.diags(stuck.astype(float)) @ c.Gf
        rows, cols, vals = [], [], []
        for j, (c_own, c_cpl) in enumerate(relations):
            if stuck[j]:
                continue
            rows.append(j)
            cols.append(c.mp + c.mv + j)
            vals.append(c_own)
            if fr.coupled[j] >= 0 and c_cpl != 0.0:
                rows.append(j)
                cols.append(fr.coupled[j])
                vals.append(c_cpl)
        rl = sp.csr_matrix((vals, (rows, cols)), shape=(c.mf, m))
        blocks.append([ra, rl])
    K = sp.bmat(blocks, format="csc")
    try:
        lu = spla.splu(K)
    except RuntimeError:
        return None
    d = np.abs(lu.U.diagonal())
    if not np.all(np.isfinite(d)) or (d.size and d.min() <= pivot_tol * d.max()):
        return None
    return lu


def factorise(c, modes, relations, pivot_tol):
    """LU factors (``.solve(rhs)``) of the KKT system of ``modes``, or None when it is singular."""
    if c.n + c.m <= DENSE_MAX:
        return _dense(c, modes, relations, pivot_tol)
    return _sparse(c, modes, relations, pivot_tol)
