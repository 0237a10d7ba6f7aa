"""Sparse Jacobian assembly with a fixed pattern.

Every entry of the iteration matrix ``dF/dy + cj dF/dyp`` is a sum of
terms of three kinds: constants, constants times ``cj``, and constants times
a *weight* (an entry of some kernel Jacobian, one per device instance).
The pattern and the position of each term in the CSC data array are
computed once; each evaluation is then two axpys and one ``np.bincount``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class PatternBuilder:
    def __init__(self, n: int):
        self.n = n
        self._const = ([], [], [])
        self._cj = ([], [], [])
        self._w = ([], [], [], [])   # rows, cols, coefs, weight index

    def const(self, rows, cols, vals):
        for lst, arr in zip(self._const, (rows, cols, vals)):
            lst.append(np.atleast_1d(np.asarray(arr)).ravel())

    def cj(self, rows, cols, vals):
        for lst, arr in zip(self._cj, (rows, cols, vals)):
            lst.append(np.atleast_1d(np.asarray(arr)).ravel())

    def weighted(self, rows, cols, coefs, widx):
        for lst, arr in zip(self._w, (rows, cols, coefs, widx)):
            lst.append(np.atleast_1d(np.asarray(arr)).ravel())

    def build(self) -> "JacobianAssembly":
        def cat(lst, dtype):
            return np.concatenate(lst).astype(dtype) if lst else np.zeros(0, dtype)
        cr, cc, cv = (cat(self._const[0], int), cat(self._const[1], int), cat(self._const[2], float))
        jr, jc, jv = (cat(self._cj[0], int), cat(self._cj[1], int), cat(self._cj[2], float))
        wr, wc, wv, wi = (cat(self._w[0], int), cat(self._w[1], int), cat(self._w[2], float), cat(self._w[3], int))
        rows = np.concatenate([cr, jr, wr])
        cols = np.concatenate([cc, jc, wc])
        pat = sp.csc_matrix((np.ones(len(rows)), (rows, cols)), shape=(self.n, self.n))
        pat.sum_duplicates()
        pat.sort_indices()
        # position of (r, c) in CSC data
        key = pat.indptr[:-1]
        lookup = {}
        pr = pat.indices
        pc = np.repeat(np.arange(self.n), np.diff(pat.indptr))
        flat = pc.astype(np.int64) * self.n + pr
        order = np.argsort(flat)
        flat_sorted = flat[order]

        def pos(r, c):
            f = c.astype(np.int64) * self.n + r
            return order[np.searchsorted(flat_sorted, f)]

        nnz = pat.nnz
        const = np.bincount(pos(cr, cc), weights=cv, minlength=nnz) if len(cr) else np.zeros(nnz)
        cjv = np.bincount(pos(jr, jc), weights=jv, minlength=nnz) if len(jr) else np.zeros(nnz)
        return JacobianAssembly(self.n, pat, pr, pc, const, cjv, pos(wr, wc) if len(wr) else np.zeros(0, int), wv, wi)


class JacobianAssembly:
    def __init__(self, n, pattern, rows, cols, const, cjv, wpos, wcoef, widx):
        self.n = n
        self.pattern = pattern            # csc, ones
        self.rows = rows
        self.cols = cols
        self.nnz = pattern.nnz
        self.const = const
        self.cjv = cjv
        self.wpos = wpos
        self.wcoef = wcoef
        self.widx = widx

    def data(self, cj: float, weights: np.ndarray) -> np.ndarray:
        out = self.const + cj * self.cjv
        if len(self.wpos):
            out += np.bincount(self.wpos, weights=self.wcoef * weights[self.widx], minlength=self.nnz)
        return out

    def matrix(self, cj: float, weights: np.ndarray) -> sp.csc_matrix:
        return sp.csc_matrix((self.data(cj, weights), self.pattern.indices, self.pattern.indptr), shape=(self.n, self.n))
