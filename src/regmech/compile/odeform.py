"""The right-hand side of the ODE form ``u' = g(t, u)`` with as few array operations as the model allows.

``u = [x_K, v_K, z]`` (``CompiledSystem.ode_state``). In general ``g`` lifts
``u`` to all coordinates through the constraints, evaluates the device
forces and solves the acceleration-level (KKT) system of the current modes
(``CompiledSystem.ode_rhs_general``): a dozen numpy and sparse calls, some
30 us on a small model before any arithmetic.

A model without constraints (no rigid links, gears, motion sources:
``m == 0``), without friction rows and whose devices are all *affine*
(springs, dampers, sources: ``compile.kernels``) needs none of that:
``u = [x, v, z]`` is the whole state, the KKT system is the diagonal mass
matrix, and

    [tau; dz] = T y + t0 + V s(t),     g = [v; -M^-1 S^T tau; dz]

with ``s(t)`` the offsets of the affine devices whose force changes in time
(a torque source's signal, evaluated by its class). These are the products
of the general path (``EvaluationPlan.device_outputs``: the same matrices,
their terms added in the same order, and a division by the masses where
the general path's LU of the diagonal divides by the same pivots), so both
give the same numbers to the last bit; large matrices whose entries lie on
a few diagonals are multiplied in DIA form (``fast_operator``), which
keeps that order. Same numbers matter: DOP853 held at its stability limit
(the hard case ``inertia_ratio_1e8``) ends 4e-6 to 1.5e-4 of the range off
depending on the last bits of g alone (measured with four orders of the
same sums), so a faster form that rounds differently would move results
that tests hold to 1e-4. The link forces are formed first and summed at the masses after:
multiplying the two matrices out into one ``A = -M^-1 S^T T`` would be one
product fewer, but a mass between a stiff and a soft link would then carry
a coefficient ``(k_stiff + k_soft) / m`` in which the soft link's share is
lost to round-off (a spurious spring to the ground: measured on the hard
case ``stretched_1e5``, accelerations off by 1e-7 of their size and scipy
Radau's Newton iteration needing 3 times the steps). ``A`` is only built
for ``jacobian`` (the spectral bound of the up-front stiffness check).

With numba installed, a form whose matrices are all sparse (DIA or CSR: a
model of some 50 inertias or more) runs in one compiled call
(``_odeform_kernels.linear_rhs``), its ``Constant``, ``Sine``, ``Step`` and
``Ramp`` signals included: the same formulas, products and order, so the
same numbers to the last bit, at 4 instead of 13 us a call on a chain of
1,000 inertias. ``NATIVE = False`` turns it off.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

#: matrices up to this many entries are used dense (as ``compile.evaluation`` does for its own)
DENSE_MAX = 6000
#: compile the linear form's right-hand side with numba when it is installed and the matrices are sparse
NATIVE = True


def fast_operator(M):
    """``M`` (sparse or dense) as the cheapest operator for ``M @ x`` that gives the same numbers as
    ``M @ x`` in CSR: dense stays dense; a CSR matrix whose entries lie on few diagonals, met by every
    row in the same order (a chain's matrices: 4 and 2 diagonals), becomes DIA with its diagonals in
    that order (scipy's DIA product adds the diagonals one by one in their stored order, i.e. each row's
    terms in the order CSR adds them, and runs along contiguous memory: 4 to 7 times faster at 10,000
    inertias); CSR otherwise."""
    if not sp.issparse(M):
        return M
    M = sp.csr_matrix(M)
    rows, cols = M.shape
    if M.nnz == 0 or rows * cols <= DENSE_MAX:
        return M
    row_of = np.repeat(np.arange(rows), np.diff(M.indptr))
    offsets = M.indices - row_of
    diagonals = np.unique(offsets)
    if len(diagonals) * min(rows, cols) > 2 * M.nnz:
        return M
    same_row = row_of[1:] == row_of[:-1]
    for order in (diagonals, np.array(list(dict.fromkeys(offsets.tolist())))):   # ascending (sorted rows), met
        by_value = np.argsort(order)                        # order[by_value] ascending
        rank = by_value[np.searchsorted(order[by_value], offsets)]    # each entry's diagonal's place in order
        if not np.any(rank[1:][same_row] <= rank[:-1][same_row]):
            break
    else:
        return M                                           # no single order serves every row
    data = np.zeros((len(order), cols))
    data[rank, M.indices] = M.data                        # DIA stores entry (i, i + o) at data[k, i + o]
    return sp.dia_matrix((data, np.array(order)), shape=M.shape)


try:        # scipy's compiled kernels behind ``M @ x``, called without its checks (5 us a product)
    from scipy.sparse._sparsetools import csr_matvec as _csr_matvec, dia_matvec as _dia_matvec
except ImportError:     # a private module of scipy: fall back on the operator when it moves
    _csr_matvec = _dia_matvec = None


class MatVec:
    """``x -> M @ x`` for a dense, DIA or CSR ``M`` (``fast_operator``), the same numbers as ``M @ x``."""

    def __init__(self, M):
        self.M = M
        self.rows, self.cols = M.shape
        self.kind = "op"
        if sp.issparse(M) and _csr_matvec is not None:
            if M.format == "dia" and M.data.dtype == np.float64:
                self.kind, self.offsets, self.data = "dia", np.ascontiguousarray(M.offsets), \
                    np.ascontiguousarray(M.data)
            elif M.format == "csr" and M.data.dtype == np.float64:
                self.kind = "csr"

    def __call__(self, x):
        if self.kind != "op":
            x = np.ascontiguousarray(x, dtype=np.float64)     # the kernels read raw memory
        if self.kind == "dia":
            y = np.zeros(self.rows)
            _dia_matvec(self.rows, self.cols, len(self.offsets), self.data.shape[1], self.offsets, self.data, x, y)
            return y
        if self.kind == "csr":
            M = self.M
            y = np.zeros(self.rows)
            _csr_matvec(self.rows, self.cols, M.indptr, M.indices, M.data, x, y)
            return y
        return self.M @ x


class OdeForm:
    """``g(t, u)`` of one compiled system (see the module docstring); ``linear`` when the fast form applies."""

    def __init__(self, c):
        self.c = c
        plan = c._plan
        self.linear = (c.m == 0 and c.mf == 0 and not plan.nonlinear and c.n > 0
                       and bool(np.all(c.mass > 0)))
        self._A = None
        self._native = None
        if self.linear:
            n = c.n
            self.n, self.n_c, self.plan = n, plan.n_c, plan
            self.size = 2 * n + c.nz
            self.T = plan.T                            # on y = [x0, v0, x1, v1, ..., z], as the general path
            self.on_u = False
            if sp.issparse(plan.T):
                # the same rows with the columns of u = [x, v, z] and every row's terms kept in their order
                # (then the product adds exactly what plan.T @ y adds, without filling y first)
                T = sp.csr_matrix(plan.T)
                where = np.empty(c.N, np.int64)
                where[c.ix], where[c.iv], where[c.iz] = np.arange(n), n + np.arange(n), 2 * n + np.arange(c.nz)
                Tu = sp.csr_matrix((T.data, where[T.indices], T.indptr), shape=(T.shape[0], self.size))
                Tu.has_sorted_indices = False
                self._Tu = Tu                          # for ``jacobian``'s compiled assembly (sorted there)
                self.T = fast_operator(Tu)
                self.on_u = True
            self.T_mv = MatVec(self.T)
            self.t0 = plan.t0
            self.t0_zero = not np.any(plan.t0)         # adding zeros changes no value: skipped
            self.ScT = fast_operator(c.ScT) if self.n_c else None
            self.ScT_mv = MatVec(self.ScT) if self.n_c else None
            self.mass = c.mass
            # -f / m and f / (-m) are the same number (IEEE division rounds the magnitude, the sign is exact)
            self.neg_mass = -np.asarray(c.mass, float)
            self.V = plan.V
            self.v_rows = self.v_cols = None
            if sp.issparse(plan.V):
                # a large model: only the rows and slots that the time-varying offsets touch, when each
                # such row has one term (then the compact product adds exactly what the full one does)
                V = sp.csr_matrix(plan.V)
                per_row = np.diff(V.indptr)
                if per_row.max(initial=0) == 1:
                    self.v_rows = np.nonzero(per_row)[0]
                    self.v_cols = V.indices[V.indptr[self.v_rows]]
                    self.v_vals = V.data[V.indptr[self.v_rows]]
            self.slots = plan.offset_slots
            self.buf = plan.buf
            self._native = self._native_arguments() if NATIVE and self.on_u else None

    def _native_arguments(self):
        """``(kernel, ih, fh, signals, kernel_into)`` of ``_odeform_kernels.linear_rhs`` (``layout``) and its
        ``linear_rhs_into``; ``signals``: the kernel evaluates the signals (else Python writes them into
        ``buf``: a signal of another class, an offset not linear in its signals, or a bank of many sines or
        steps, which one numpy expression evaluates and whose sin need not round as the C library's does).
        None when a matrix is dense (BLAS adds its products in an order of its own) or numba is not installed."""
        try:
            from . import _odeform_kernels as K
            from ._native_signals import signal_table
        except (ImportError, OSError, AttributeError):       # no numba, or one that cannot load (as ida_native)
            return None
        packed = [K.pack(M) for M in (self.T, self.ScT, None if self.v_rows is not None else self.V)]
        if any(p is None for p in packed) or (self.n_c and packed[1][0] == K.NONE):
            return None
        compact = None
        if self.v_rows is not None:
            compact = (np.asarray(self.v_rows, np.int64), np.asarray(self.v_cols, np.int64),
                       np.asarray(self.v_vals, np.float64))
        table = signal_table(self.plan)
        vectorised = any(b.vectorised for g, *_ in self.plan.input_slots for b in g.banks)
        signals = None if isinstance(table, str) or self.slots or vectorised else table
        ih, fh = K.layout(self.n, self.n_c, packed[0][3], packed[0][:3], packed[1][:3], packed[2][:3],
                          np.asarray(self.t0, np.float64), not self.t0_zero, compact, signals,
                          np.ascontiguousarray(self.neg_mass, np.float64))
        return K.linear_rhs, ih, fh, signals is not None, K.linear_rhs_into

    def rhs(self, t, u, left=None):
        """``[v; -M^-1 S^T tau; dz]`` (linear form only; see the module docstring). ``left``: the side of the
        time-varying offsets at a breakpoint (default: the current segment's, ``t >= c._t_right``)."""
        c, n, n_c = self.c, self.n, self.n_c
        if self._native is not None:
            kernel, ih, fh, signals, _ = self._native
            if left is None:
                left = t >= c._t_right
            if not signals and self.V is not None:
                self._signals_into_buf(t, left)
            return kernel(np.ascontiguousarray(u, dtype=np.float64), self.buf, float(t), bool(left), ih, fh)
        if self.on_u:
            out = self.T_mv(u)
        else:
            yb = self.plan.ybuf
            yb[c._sx] = u[:n]
            yb[c._sv] = u[n:2 * n]
            yb[c._sz] = u[2 * n:]
            out = self.T_mv(yb)
        if not self.t0_zero:
            out += self.t0
        if self.V is not None:
            buf = self._signals_into_buf(t, left)
            if self.v_rows is None:
                out += self.V @ buf
            else:
                out[self.v_rows] += self.v_vals * buf[self.v_cols]
        g = np.empty(self.size)
        g[:n] = u[n:2 * n]
        if n_c:
            np.divide(self.ScT_mv(out[:n_c]), self.neg_mass, out=g[n:2 * n])
        else:
            g[n:2 * n] = 0.0
        g[2 * n:] = out[n_c:]
        return g

    def kernel_arguments(self):
        """``(ih, fh, buf)`` of the compiled right-hand side (``_odeform_kernels.linear_rhs_into``) when it is whole on
        its own: compiled, and its signals in its own table (else Python writes them into ``buf`` before each call,
        ``rhs_into``); None otherwise."""
        if self._native is None:
            return None
        _, ih, fh, signals, _ = self._native
        if not signals and self.V is not None:
            return None
        return ih, fh, self.buf

    def rhs_into(self, t, u, out):
        """``rhs(t, u)`` written into ``out`` (length ``size``, not ``u``): the compiled kernel writes there
        directly (an integrator that keeps its stages in rows of one array saves a copy per stage); the Python
        path copies."""
        if self._native is None:
            out[:] = self.rhs(t, u)
            return
        _, ih, fh, signals, into = self._native
        left = t >= self.c._t_right
        if not signals and self.V is not None:
            self._signals_into_buf(t, left)
        into(np.ascontiguousarray(u, dtype=np.float64), self.buf, float(t), bool(left), ih, fh, out)

    def _signals_into_buf(self, t, left):
        """The time-varying offsets and signal values at t into ``buf`` (``left``: None for the side of the
        current segment, ``t >= c._t_right``); returns ``buf``."""
        if left is None:
            left = t >= self.c._t_right
        buf = self.buf
        for grp, start in self.slots:
            grp.offsets_into(buf, start, t, left)
        for bank, sl in self.plan._input_writes:       # offsets linear in their signals: the values
            buf[sl] = bank.at(t, left)
        return buf

    def jacobian(self) -> sp.csr_matrix:
        """``dg/du`` of the linear form (exact, constant; built on first use). The rows ``[0 I 0]``,
        ``-M^-1 S_c^T T_[:n_c]`` and ``T_[n_c:]`` stacked as one CSR matrix directly: what ``sp.vstack`` made,
        entries and their order alike (the spectral bound sums them in that order), without its constructors
        (the up-front stiffness check of the explicit methods builds it on a model's first run: 0.65 -> 0.45
        ms on a chain of 1,000 inertias)."""
        if self._A is None and self._native is not None and self.n_c and sp.issparse(self.c.ScT):
            self._A = self._compiled_jacobian()
        if self._A is None:
            c, n, n_c = self.c, self.n, self.n_c
            if self.on_u:
                Tu = sp.csr_matrix(self.T)      # (its entries' order is the one the spectral bound has summed)
            else:
                cols = np.concatenate([c.ix, c.iv, c.iz]).astype(np.int64)     # u = [x, v, z] in y
                Tu = sp.csr_matrix(self.plan.T)[:, cols]
            if n_c:
                # diag(1/m) as CSR directly: the product scipy makes of sp.diags(1 / m) @ S_c^T (which converts
                # the DIA diagonal to this CSR first), entries and order alike, without the conversion
                inv_m = sp.csr_matrix((1.0 / c.mass, np.arange(n), np.arange(n + 1)), shape=(n, n))
                mid = sp.csr_matrix(-(inv_m @ c.ScT) @ Tu[:n_c])
            else:
                mid = sp.csr_matrix((n, self.size))
            bottom = sp.csr_matrix(Tu[n_c:])
            blocks = [(np.arange(n + 1), n + np.arange(n), np.ones(n)), (mid.indptr, mid.indices, mid.data),
                      (bottom.indptr, bottom.indices, bottom.data)]
            indptr, base = [np.zeros(1, np.int64)], 0
            for ptr, _, _ in blocks:
                indptr.append(np.asarray(ptr[1:], np.int64) + base)
                base += int(ptr[-1])
            self._A = sp.csr_matrix((np.concatenate([b[2] for b in blocks]).astype(float),
                                     np.concatenate([b[1] for b in blocks]).astype(np.int64),
                                     np.concatenate(indptr)), shape=(self.size, self.size))
        return self._A


    def _compiled_jacobian(self) -> sp.csr_matrix:
        """``jacobian`` assembled by one compiled pass (``_odeform_kernels.linear_jacobian``) when the right-hand
        side is compiled (numba loaded): the same entries with the same sums in the same order (scipy's
        ``M^-1 S_c^T`` leaves each row of ``S_c^T`` reversed, and its product with ``T`` adds in that order and
        emits a row's columns latest first), so the spectral bound sums the same numbers in the same order.
        Why: the explicit methods' up-front stiffness check
        builds dg/du on a model's first run, and the five scipy conversions and products cost 0.45 ms of its
        0.7 ms on a chain of 1,000 inertias, 6.5 % of the dopri5 run it guards (measured: the compiled
        assembly 0.05 ms)."""
        from ._odeform_kernels import linear_jacobian
        S = sp.csr_matrix(self.c.ScT)
        # the rows of ``sp.csr_matrix(self.T)``: DIA's conversion sorts each row, a CSR operator is ``_Tu`` itself
        T = self._Tu.sorted_indices() if self.T.format == "dia" else self._Tu
        indptr, indices, data = linear_jacobian(
            self.n, self.n_c, self.size, np.ascontiguousarray(self.c.mass, np.float64),
            S.indptr.astype(np.int64), S.indices.astype(np.int64), np.ascontiguousarray(S.data, np.float64),
            T.indptr.astype(np.int64), T.indices.astype(np.int64), np.ascontiguousarray(T.data, np.float64))
        return sp.csr_matrix((data, indices, indptr), shape=(self.size, self.size))


def ode_form(c) -> OdeForm:
    """The ``OdeForm`` of a compiled system, built once (it reads only constant matrices of ``c``)."""
    form = c.__dict__.get("_ode_form")
    if form is None:
        from .reads import refuse_ode_form
        refuse_ode_form(c)
        form = c._ode_form = OdeForm(c)
    return form
