"""Fast evaluation of the residual ``F(t, y, y')`` and of the Jacobian values.

Most of a drivetrain's equations are linear with constant coefficients:
kinematics, constraints at three levels, masses, and every *affine* device
(springs, dampers, torque sources: see ``kernels``). The residual is therefore
written as one matrix product over a work vector

    buf = [ y | y' | tau_nl | dz_nl | offsets(t) | g(t) | 1 ]
    F   = L @ buf

where ``tau_nl``, ``dz_nl`` are the outputs of the *nonlinear* device classes
(evaluated per call, vectorised per class), ``offsets(t)`` the time-varying
offsets ``tau(0)`` of affine devices (a torque source's torque), ``g(t)`` the
references of Position/Speed sources, and the last entry 1 carries the
constant terms (ground offsets ``e0``, unstretched lengths). The arguments
of the nonlinear classes come from one product ``[e; de; z] = E y + e0``.

The Jacobian values follow the same split:
``data = const + cj * cjv + W @ w`` with the affine devices' constant weights
folded into ``const`` and ``w`` the weights of nonlinear classes and friction.

Below about ``DENSE_MAX`` matrix entries dense matrices are used: for tiny
models a dense product costs less than sparse bookkeeping.

The plans keep work buffers, so one compiled system serves one integration
at a time (use one compiled system per thread).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .assembly import KernelTerms, input_entries, output_entries

DENSE_MAX = 6000

try:       # the kernel behind scipy's CSR matrix-vector product, without its per-call dispatch (a few us)
    from scipy.sparse._sparsetools import csr_matvec as _csr_matvec
except ImportError:      # pragma: no cover - a scipy that moved it: the public product is used
    _csr_matvec = None


def _operator(rows, cols, vals, shape):
    """Sum duplicates; dense ndarray when small, CSR otherwise."""
    A = sp.csr_matrix((np.asarray(vals, float), (np.asarray(rows, np.int64), np.asarray(cols, np.int64))),
                      shape=shape)
    A.sum_duplicates()
    if shape[0] * shape[1] <= DENSE_MAX:
        return A.toarray()
    return A


class _Triplets:
    def __init__(self):
        self.rows, self.cols, self.vals = [], [], []

    def add(self, rows, cols, vals):
        rows = np.atleast_1d(np.asarray(rows, np.int64)).ravel()
        self.rows.append(rows)
        self.cols.append(np.broadcast_to(np.asarray(cols, np.int64), rows.shape).ravel())
        self.vals.append(np.broadcast_to(np.asarray(vals, float), rows.shape).ravel())

    def build(self, shape):
        cat = (lambda lst, dt: np.concatenate(lst) if lst else np.zeros(0, dt))
        return _operator(cat(self.rows, np.int64), cat(self.cols, np.int64), cat(self.vals, float), shape)


class EvaluationPlan:
    """The residual as ``L @ buf`` and the nonlinear kernels' arguments (see module docstring).

    ``linear_terms``: list of (rows, cols, vals, on_yp) giving the constant
    coefficients of the residual in ``y`` (``on_yp`` False) or ``y'``.
    """

    def __init__(self, c, linear_terms: list, kterms: KernelTerms):
        N = c.N
        self.N = N
        self.affine = [g for g in c.groups if g.tpl.affine]
        self.nonlinear = [g for g in c.groups if not g.tpl.affine]
        # constant weights of affine groups, in the global weight layout (zero elsewhere)
        self.const_weights = np.zeros(c.nw_kernel)
        self.weight_is_const = np.zeros(c.nw_kernel, bool)
        for g, (woff, njac) in zip(c.groups, c._wslices):
            if g.tpl.affine and njac:
                self.const_weights[woff: woff + njac * g.n] = g.constant_weights().ravel()
                self.weight_is_const[woff: woff + njac * g.n] = True
        # slots of the work vector
        slot = 2 * N
        self.nl_out = []                      # (group, first slot) of tau/dz outputs, output-major
        for g in self.nonlinear:
            self.nl_out.append((g, slot))
            slot += (g.tpl.k + len(g.tpl.states)) * g.n
        self.offset_slots = []                # (group, first slot) of time-varying affine offsets
        self.input_slots = []                 # (group, first slot, coefficients, constant offsets): see below
        for g in self.affine:
            if not g.offset_varies:
                continue
            linear = self._linear_offsets(g)
            if linear is None:
                self.offset_slots.append((g, slot))
                slot += (g.tpl.k + len(g.tpl.states)) * g.n
            else:
                # offsets linear in the signal values (a Torque's tau(0) = tau): the slots hold the values
                # u(t) themselves, bank by bank, and the coefficients d offset / d u sit in L
                self.input_slots.append((g, slot, *linear))
                slot += len(g.banks) * g.n
        self.pos_refs = [(slot + 3 * i, s) for i, (j, s) in enumerate(c._pos_sig)]
        slot += 3 * len(c._pos_sig)
        self.spd_refs = [(slot + 2 * i, s) for i, (j, s) in enumerate(c._spd_sig)]
        slot += 2 * len(c._spd_sig)
        self.one = slot
        self.width = slot + 1
        self.buf = np.zeros(self.width)
        self.buf[self.one] = 1.0
        # (bank, slice of buf) of every input slot: the residual writes the signal values there
        self._input_writes = [(b, slice(start + j * g.n, start + (j + 1) * g.n))
                              for g, start, _, _ in self.input_slots for j, b in enumerate(g.banks)]
        self.L = self._residual_matrix(c, linear_terms, kterms)
        self._dense = isinstance(self.L, np.ndarray)
        self._csr = None
        if not self._dense and _csr_matvec is not None and self.L.format == "csr" and self.L.dtype == np.float64:
            L = self.L
            self._csr = (L.shape[0], L.shape[1], L.indptr, L.indices, L.data, np.zeros(L.shape[0]))
        self._build_kernel_arguments(c)
        self._build_device_outputs(c, kterms)

    # ------------------------------------------------------------------ build
    def _residual_matrix(self, c, linear_terms, kterms):
        N, one = self.N, self.one
        T = _Triplets()
        for rows, cols, vals, on_yp in linear_terms:
            T.add(rows, np.asarray(cols) + (N if on_yp else 0), vals)
        if c.mp:
            T.add(c.r_pos, one, c.e0p)
        # affine devices: constant weights times the kernel terms, and their e0 parts
        wc = self.const_weights
        keep = self.weight_is_const[kterms.widx] if len(kterms.widx) else np.zeros(0, bool)
        T.add(kterms.row[keep], kterms.col[keep], kterms.coef[keep] * wc[kterms.widx[keep]])
        keep0 = self.weight_is_const[kterms.e0_widx] if len(kterms.e0_widx) else np.zeros(0, bool)
        T.add(kterms.e0_row[keep0], one, kterms.e0_coef[keep0] * wc[kterms.e0_widx[keep0]])
        # affine offsets: constant ones into the last column, varying ones into their slots
        varying = {id(g): start for g, start in self.offset_slots}
        inputs = {id(g): (start, coef, const) for g, start, coef, const in self.input_slots}
        for g in self.affine:
            outputs = self._outputs(c, g)
            if id(g) in inputs:
                start, coef, const = inputs[id(g)]
                for o, (ent, sign) in enumerate(outputs):
                    for j in range(len(g.banks)):
                        T.add(ent.index, start + j * g.n + ent.owner, sign * ent.coef * coef[o][j][ent.owner])
                    T.add(ent.index, one, sign * ent.coef * const[o][ent.owner])
            elif id(g) in varying:
                start = varying[id(g)]
                for o, (ent, sign) in enumerate(outputs):
                    T.add(ent.index, start + o * g.n + ent.owner, sign * ent.coef)
            else:
                values = g.offsets(0.0)
                for o, (ent, sign) in enumerate(outputs):
                    T.add(ent.index, one, sign * ent.coef * values[o][ent.owner])
        for g, start in self.nl_out:
            for o, (ent, sign) in enumerate(self._outputs(c, g)):
                T.add(ent.index, start + o * g.n + ent.owner, sign * ent.coef)
        # references: g_p, g_p', g_p'' of Position rows; g_v, g_v' of Speed rows
        for (slot, _), (j, _) in zip(self.pos_refs, c._pos_sig):
            T.add([c.r_pos[j], c.r_vel[j], c.r_acc[j]], [slot, slot + 1, slot + 2], -1.0)
        for (slot, _), (j, _) in zip(self.spd_refs, c._spd_sig):
            T.add([c.r_vel[c.mp + j], c.r_acc[c.mp + j]], [slot, slot + 1], -1.0)
        return T.build((N, self.width))

    @staticmethod
    def _linear_offsets(g):
        """``(coef, const)`` when the group's offsets are ``const + coef @ u`` in its signal values ``u``
        (``Template.offset_coef_fn``): ``coef[o][j]`` and ``const[o]`` arrays over the instances; else None."""
        fn = g.tpl.offset_coef_fn
        if fn is None or len(g.banks) != len(g.tpl.inputs):
            return None
        n = g.n
        coef = [[np.broadcast_to(np.asarray(cf, float), (n,)) for cf in row] for row in fn(*g.param_values)]
        zeros = [np.zeros(n)] * len(g.banks)
        const = [np.broadcast_to(np.asarray(o, float), (n,)) for o in g.tpl.offset_fn(*g.param_values, *zeros, 0.0)]
        if not all(np.all(np.isfinite(cf)) for row in coef for cf in row) or not all(np.all(np.isfinite(o))
                                                                                   for o in const):
            return None
        return coef, const

    @staticmethod
    def _outputs(c, g):
        k, ns = g.tpl.k, len(g.tpl.states)
        return [output_entries(c, g, "tau", i) for i in range(k)] + [output_entries(c, g, "dz", s) for s in range(ns)]

    def _build_kernel_arguments(self, c):
        """``args = E y + e0``: e, de and z of every nonlinear instance, block by block."""
        T = _Triplets()
        e0 = []
        self.nl_args = []                     # (group, first row in args, number of argument blocks)
        row = 0
        for g in self.nonlinear:
            k, ns = g.tpl.k, len(g.tpl.states)
            blocks = [("e", j) for j in range(k)] + [("de", j) for j in range(k)] + [("z", s) for s in range(ns)] + \
                [("r", j) for j in range(len(g.tpl.reads))]
            self.nl_args.append((g, row, len(blocks)))
            for b, (wname, wj) in enumerate(blocks):
                ent = input_entries(c, g, wname, wj)
                T.add(row + b * g.n + ent.owner, ent.index, ent.coef)
                e0.append(c.e0c[g.row_index[:, wj]] if wname == "e" else np.zeros(g.n))
            row += len(blocks) * g.n
        self.n_args = row
        self.E = T.build((row, self.N)) if row else None
        self.e0 = np.concatenate(e0) if e0 else np.zeros(0)

    def _build_device_outputs(self, c, kterms):
        """``[tau; dz] = T y + t0 + V buf`` for the affine devices (see ``device_outputs``)."""
        n_c = c.Sc.shape[0]
        self.n_c = n_c
        T = _Triplets()
        t0 = np.zeros(n_c + c.nz)
        V = _Triplets()
        varying = {id(g): start for g, start in self.offset_slots}
        inputs = {id(g): (start, coef, const) for g, start, coef, const in self.input_slots}
        self.nl_rows = []                        # per nonlinear group: output rows of [tau; dz]
        for g, (woff, _) in zip(c.groups, c._wslices):
            k, ns = g.tpl.k, len(g.tpl.states)
            out_rows = [g.row_index[:, i] for i in range(k)] + [n_c + g.state_index[:, s] for s in range(ns)]
            if not g.tpl.affine:
                self.nl_rows.append(out_rows)
                continue
            for q, ((oname, oi), (wname, wj)) in enumerate(g.tpl.jac_entries):
                rows = out_rows[oi if oname == "tau" else k + oi]
                w = self.const_weights[woff + q * g.n: woff + (q + 1) * g.n]
                inp = input_entries(c, g, wname, wj)
                T.add(rows[inp.owner], inp.index, w[inp.owner] * inp.coef)
                if wname == "e":
                    np.add.at(t0, rows, w * c.e0c[g.row_index[:, wj]])
            if id(g) in inputs:
                start, coef, const = inputs[id(g)]
                for o, rows in enumerate(out_rows):
                    for j in range(len(g.banks)):
                        V.add(rows, start + j * g.n + np.arange(g.n), coef[o][j])
                    np.add.at(t0, rows, const[o])
            elif id(g) in varying:
                start = varying[id(g)]
                for o, rows in enumerate(out_rows):
                    V.add(rows, start + o * g.n + np.arange(g.n), 1.0)
            else:
                for o, (rows, val) in enumerate(zip(out_rows, g.offsets(0.0))):
                    np.add.at(t0, rows, val)
        self.T = T.build((n_c + c.nz, self.N))
        self.t0 = t0
        self.V = V.build((n_c + c.nz, self.width)) if self.offset_slots or self.input_slots else None
        self.ybuf = np.zeros(self.N)

    # --------------------------------------------------------------- evaluate
    def device_outputs(self, x, v, z, t: float, left: bool, sx, sv, sz) -> np.ndarray:
        """``[tau; dz]`` of every device row and state at (x, v, z, t); ``sx, sv, sz`` place them in y."""
        yb = self.ybuf
        yb[sx] = x
        yb[sv] = v
        yb[sz] = z
        out = self.T @ yb
        out += self.t0
        if self.V is not None:
            for g, start in self.offset_slots:
                g.offsets_into(self.buf, start, t, left)
            for bank, sl in self._input_writes:
                self.buf[sl] = bank.at(t, left)
            out += self.V @ self.buf
        if self.nonlinear:
            for g_rows, (g, _, _), args in zip(self.nl_rows, self.nl_args, self.kernel_arguments(yb)):
                for rows, val in zip(g_rows, g.call(g.tpl.res_fn, args, t, left)):
                    out[rows] = val
        return out

    def kernel_arguments(self, y):
        """Per nonlinear group, the list of argument arrays (views into one vector)."""
        args = self.E @ y
        args += self.e0
        return [[args[r0 + b * g.n: r0 + (b + 1) * g.n] for b in range(nb)] for g, r0, nb in self.nl_args]

    def residual(self, t: float, y, yp, left: bool, out) -> None:
        """Fill ``out`` (length N) with ``F(t, y, y')``, friction rows excluded."""
        N, buf = self.N, self.buf
        buf[:N] = y
        buf[N: 2 * N] = yp
        if self.nonlinear:
            for (g, start), args in zip(self.nl_out, self.kernel_arguments(y)):
                n = g.n
                for o, val in enumerate(g.call(g.tpl.res_fn, args, t, left)):
                    buf[start + o * n: start + (o + 1) * n] = val
        for g, start in self.offset_slots:
            g.offsets_into(buf, start, t, left)
        for bank, sl in self._input_writes:
            buf[sl] = bank.at(t, left)
        for slot, s in self.pos_refs:
            buf[slot] = s.value(t, left)
            buf[slot + 1] = s.derivative(t, 1, left)
            buf[slot + 2] = s.derivative(t, 2, left)
        for slot, s in self.spd_refs:
            buf[slot] = s.value(t, left)
            buf[slot + 1] = s.derivative(t, 1, left)
        if self._dense:
            try:
                np.dot(self.L, buf, out=out)       # no temporary: ``out`` is IDA's own vector
                return
            except (TypeError, ValueError):        # an ``out`` that is not a contiguous float vector
                pass
        elif self._csr is not None:
            n_row, n_col, indptr, indices, data, acc = self._csr
            acc.fill(0.0)
            _csr_matvec(n_row, n_col, indptr, indices, data, buf, acc)     # acc += L buf, as ``L @ buf`` does
            out[:] = acc
            return
        out[:] = self.L @ buf

    def nonlinear_weights_into(self, w, t: float, y, left: bool) -> None:
        """Jacobian entries of the nonlinear groups, written group by group into ``w``."""
        pos = 0
        for (g, _, _), args in zip(self.nl_args, self.kernel_arguments(y)):
            n = g.n
            for val in g.call(g.tpl.jac_fn, args, t, left):
                w[pos: pos + n] = val
                pos += n


class JacobianPlan:
    """``data = const + cj * cjv + W @ w`` for one ``JacobianAssembly`` (see module docstring).

    ``w`` = [nonlinear kernel weights (group by group) | extra weights]; the
    extra weights (friction) are those with index >= ``nw_kernel`` in ``jac``.
    """

    def __init__(self, jac, plan: EvaluationPlan, nw_kernel: int):
        self.jac = jac
        self.plan = plan
        wpos, wcoef, widx = jac.wpos, jac.wcoef, jac.widx
        is_kernel = widx < nw_kernel
        const_term = np.zeros(len(widx), bool)
        const_term[is_kernel] = plan.weight_is_const[widx[is_kernel]]
        self.const = jac.const.copy()
        if const_term.any():
            self.const += np.bincount(wpos[const_term], weights=wcoef[const_term] *
                                      plan.const_weights[widx[const_term]], minlength=jac.nnz)
        self.cjv = jac.cjv
        # compact index of every variable weight
        compact = np.full(nw_kernel, -1, np.int64)
        variable_kernel = ~plan.weight_is_const
        self.n_nonlinear = int(variable_kernel.sum())
        compact[variable_kernel] = np.arange(self.n_nonlinear)
        n_extra = int(widx.max()) + 1 - nw_kernel if len(widx) and widx.max() >= nw_kernel else 0
        self.n_extra = n_extra
        var = ~const_term
        cols = widx[var] - nw_kernel + self.n_nonlinear          # extra weights follow the kernel ones
        from_kernel = widx[var] < nw_kernel
        cols[from_kernel] = compact[widx[var][from_kernel]]
        self.width = self.n_nonlinear + n_extra
        self.W = _operator(wpos[var], cols, wcoef[var], (jac.nnz, self.width)) if self.width else None
        self.w = np.zeros(self.width)

    def data(self, t: float, y, cj: float, left: bool, extra=None) -> np.ndarray:
        out = self.cjv * cj
        out += self.const
        if self.W is not None:
            w = self.w
            if self.n_nonlinear:
                self.plan.nonlinear_weights_into(w, t, y, left)
            if self.n_extra:
                w[self.n_nonlinear:] = extra
            out += self.W @ w
        return out
