"""Sparse Jacobian assembly with a fixed pattern.

Every entry of the iteration matrix ``dF/dy + cj dF/dyp`` is a sum of
terms of three kinds: constants, constants times ``cj``, and constants times
a *weight* (an entry of some kernel Jacobian, one per device instance).
The pattern and the position of each term in the CSC data array are
computed once; each evaluation is then two axpys and one ``np.bincount``.

``kernel_terms`` lists the weighted terms of all device instances at once
with array operations (no Python loop over instances): a device row's
force ``tau_r`` enters the motion rows through the nonzeros of row r of the
structure matrix ``S`` and depends on ``e_j = S_j x + e0_j`` through the
nonzeros of row j, so the entry ``d tau_r / d e_j`` of instance i gives the
outer product of the two (ragged) coefficient lists of that instance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


def ragged_arange(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """``concatenate([arange(s, s + l) for s, l in zip(starts, lengths)])`` without the loop."""
    lengths = np.asarray(lengths, dtype=np.int64)
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    first = np.cumsum(lengths) - lengths               # position of each run in the output
    out = np.arange(total, dtype=np.int64)
    out += np.repeat(np.asarray(starts, dtype=np.int64) - first, lengths)
    return out


@dataclass
class Ragged:
    """Per-instance lists of (y index, coefficient), flattened; ``owner`` is the instance of each entry."""

    owner: np.ndarray
    index: np.ndarray
    coef: np.ndarray
    lengths: np.ndarray

    @property
    def starts(self) -> np.ndarray:
        return np.cumsum(self.lengths) - self.lengths


def csr_rows(A: sp.csr_matrix, rows: np.ndarray, target: np.ndarray) -> Ragged:
    """Nonzeros of the given CSR rows, their columns mapped through ``target``."""
    rows = np.asarray(rows, dtype=np.int64)
    lo = A.indptr[rows]
    lengths = A.indptr[rows + 1] - lo
    pos = ragged_arange(lo, lengths)
    return Ragged(np.repeat(np.arange(len(rows)), lengths), np.asarray(target)[A.indices[pos]],
                  A.data[pos].astype(float), lengths)


def single(index: np.ndarray, coef: float = 1.0) -> Ragged:
    """One entry per instance."""
    n = len(index)
    return Ragged(np.arange(n), np.asarray(index, dtype=np.int64), np.full(n, float(coef)), np.ones(n, np.int64))


def outer_pairs(a: Ragged, b: Ragged) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per instance, every pair of an entry of ``a`` with an entry of ``b``.

    Returns (entry of a, entry of b, instance) index arrays.
    """
    counts = a.lengths * b.lengths
    inst = np.repeat(np.arange(len(counts)), counts)
    local = np.arange(int(counts.sum()), dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)
    nb = b.lengths[inst]
    return a.starts[inst] + local // nb, b.starts[inst] + local % nb, inst


@dataclass
class KernelTerms:
    """All weighted Jacobian terms of the device kernels.

    Term t adds ``coef[t] * w[widx[t]]`` to entry ``(row[t], col[t])`` of
    ``dF/dy``. ``e0_*`` are the matching constant parts of the residual:
    ``d tau / d e`` times the ground offset ``e0`` of the row.
    """

    row: np.ndarray
    col: np.ndarray
    coef: np.ndarray
    widx: np.ndarray
    e0_row: np.ndarray
    e0_coef: np.ndarray
    e0_widx: np.ndarray


def output_entries(c, g, oname: str, oi: int) -> tuple[Ragged, float]:
    """Residual rows fed by output (oname, oi) of group g, with the sign of the feed.

    Forces enter the motion rows through ``S^T`` (+), state rates the state rows as ``z' - dz`` (-).
    """
    if oname == "tau":
        return csr_rows(c.Sc, g.row_index[:, oi], c.r_mot), 1.0
    return single(c.r_z[g.state_index[:, oi]]), -1.0


def input_entries(c, g, wname: str, wj: int) -> Ragged:
    """Entries of y that variable (wname, wj) of group g depends on (``e = S x + e0``, ``de = S v``)."""
    if wname == "e":
        return csr_rows(c.Sc, g.row_index[:, wj], c.ix)
    if wname == "de":
        return csr_rows(c.Sc, g.row_index[:, wj], c.iv)
    if wname == "r":           # a signal parameter read from the unknowns (``compile.reads``)
        return single(c.iz[g.read_index[:, wj]])
    return single(c.iz[g.state_index[:, wj]])


def kernel_terms(c) -> KernelTerms:
    """Weighted terms of every group of ``c.groups``; weight layout ``woff + q * n + instance``."""
    parts = {k: [] for k in ("row", "col", "coef", "widx", "e0_row", "e0_coef", "e0_widx")}
    woff = 0
    for g in c.groups:
        for q, ((oname, oi), (wname, wj)) in enumerate(g.tpl.jac_entries):
            out, sign = output_entries(c, g, oname, oi)
            inp = input_entries(c, g, wname, wj)
            ia, ib, inst = outer_pairs(out, inp)
            base = woff + q * g.n
            parts["row"].append(out.index[ia])
            parts["col"].append(inp.index[ib])
            parts["coef"].append(sign * out.coef[ia] * inp.coef[ib])
            parts["widx"].append(base + inst)
            if wname == "e":
                e0 = c.e0c[g.row_index[:, wj]]
                parts["e0_row"].append(out.index)
                parts["e0_coef"].append(sign * out.coef * e0[out.owner])
                parts["e0_widx"].append(base + out.owner)
        woff += len(g.tpl.jac_entries) * g.n
    dtypes = {"coef": float, "e0_coef": float}
    return KernelTerms(**{k: (np.concatenate(v) if v else np.zeros(0)).astype(dtypes.get(k, np.int64))
                          for k, v in parts.items()})


def banded_ordering(pattern: sp.spmatrix) -> tuple[np.ndarray, int, int]:
    """A permutation that makes ``pattern`` narrow-banded (reverse Cuthill-McKee).

    Returns ``(perm, lband, uband)``: position i of the permuted vector holds
    entry ``perm[i]`` of the original, and the permuted pattern
    ``pattern[perm][:, perm]`` has lower/upper bandwidths ``lband``/``uband``.
    The layout ``y = [x, v, a_d, lam, z]`` puts constraint forces far from the
    coordinates they act on (bandwidth ~ N as soon as there is a gear or a
    rigid shaft); reordered, a chain of gears and shafts has bandwidth ~4,
    and a banded solver beats the sparse one (SuperLU_MT in scikit-sundae
    has a fixed cost of milliseconds per factorization).
    """
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    P = sp.csr_matrix(pattern, dtype=float)
    sym = (abs(P) + abs(P).T).tocsr()
    perm = np.asarray(reverse_cuthill_mckee(sym, symmetric_mode=True), dtype=np.int64)
    Q = P[perm][:, perm].tocoo()
    if Q.nnz == 0:
        return perm, 0, 0
    return perm, int(max(0, (Q.row - Q.col).max())), int(max(0, (Q.col - Q.row).max()))


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
        cr, cc, cv = (cat(self._const[0], np.int64), cat(self._const[1], np.int64), cat(self._const[2], float))
        jr, jc, jv = (cat(self._cj[0], np.int64), cat(self._cj[1], np.int64), cat(self._cj[2], float))
        wr, wc, wv, wi = (cat(self._w[0], np.int64), cat(self._w[1], np.int64), cat(self._w[2], float),
                          cat(self._w[3], np.int64))
        rows = np.concatenate([cr, jr, wr])
        cols = np.concatenate([cc, jc, wc])
        pat = sp.csc_matrix((np.ones(len(rows)), (rows, cols)), shape=(self.n, self.n))
        pat.sum_duplicates()
        pat.sort_indices()
        pr = pat.indices
        pc = np.repeat(np.arange(self.n), np.diff(pat.indptr))
        # CSC data is sorted by (column, row): the flat key c*n + r is increasing, so positions are a searchsorted
        flat = pc.astype(np.int64) * self.n + pr

        def pos(r, c):
            return np.searchsorted(flat, c * self.n + r)

        nnz = pat.nnz
        const = np.bincount(pos(cr, cc), weights=cv, minlength=nnz) if len(cr) else np.zeros(nnz)
        cjv = np.bincount(pos(jr, jc), weights=jv, minlength=nnz) if len(jr) else np.zeros(nnz)
        return JacobianAssembly(self.n, pat, pr, pc, const, cjv, pos(wr, wc) if len(wr) else np.zeros(0, np.int64),
                                wv, wi)


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
