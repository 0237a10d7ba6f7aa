"""numba kernels of the native IDA path (``ida_native``); imported only when that path is used.

The residual and the dense Jacobian are C callbacks (``numba.cfunc``) that SUNDIALS IDA calls directly,
with no Python in between; the output loop (``drive``) calls ``IDASolve`` once per output time from
compiled code too. Everything a callback needs is in two arrays whose addresses IDA passes as its user
data (``ida_native._UserData`` writes them):

* ``idata`` (int64): ``[N, W, n_sig, n_jac, off_indptr, off_indices, off_perm, off_kind, off_slot,
  off_jk, length]`` and the arrays those offsets point to;
* ``fdata`` (float64): ``[t_right, off_data, off_par, off_buf, off_jc, off_jcj, length]`` and the arrays.

The residual is ``F = L [y; y'; u(t); 1]`` (``compile.evaluation.EvaluationPlan`` of a model without
nonlinear devices or friction): ``buf`` holds that vector, ``u(t)`` the signal values at their slots.
Row ``i`` of the solver's residual is row ``perm[i]`` of ``L`` (the band solver's ordering; identity
otherwise). Every kernel is compiled with ``cache=True`` (no addresses baked in: pointers arrive as
integers), so a process pays numba's start-up but no compilation after the first one on a machine.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import carray, cfunc, njit, types
from numba.extending import intrinsic

# signal kinds (``ida_native.signal_table``)
CONSTANT, SINE, STEP, RAMP = 0, 1, 2, 3
N_PAR = 5


@intrinsic
def _f64p(typingctx, addr):
    """An integer address as ``double*``."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))
    return types.CPointer(types.float64)(addr), codegen


@intrinsic
def _i64p(typingctx, addr):
    """An integer address as ``int64*``."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.int64)))
    return types.CPointer(types.int64)(addr), codegen


@intrinsic
def _address(typingctx, ptr):
    """A ``void*`` as an integer."""
    def codegen(context, builder, signature, args):
        return builder.ptrtoint(args[0], ir.IntType(64))
    return types.int64(ptr), codegen


@intrinsic
def _call_ida_solve(typingctx, fn, mem, tout, tret, yy, yp, itask):
    """``IDASolve(mem, tout, tret, yy, yp, itask)`` through its address ``fn``."""
    def codegen(context, builder, signature, args):
        vp = ir.IntType(8).as_pointer()
        dp = ir.DoubleType().as_pointer()
        fnty = ir.FunctionType(ir.IntType(32), [vp, ir.DoubleType(), dp, vp, vp, ir.IntType(32)])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(f, [builder.inttoptr(args[1], vp), args[2], builder.inttoptr(args[3], dp),
                                builder.inttoptr(args[4], vp), builder.inttoptr(args[5], vp),
                                builder.trunc(args[6], ir.IntType(32))])
    return types.int32(fn, mem, tout, tret, yy, yp, itask), codegen


@njit(cache=True, inline="always")
def _second_pointer(addr):
    """The pointer stored 8 bytes into the struct that the pointer at ``addr`` points to: the data of a
    serial N_Vector (``content->data``) and of a dense SUNMatrix, checked by ``ida_native`` at load."""
    content = carray(_i64p(addr), (1,))[0]
    return carray(_i64p(content + 8), (1,))[0]


@njit(cache=True, inline="always")
def _signal(kind, p, t, left):
    """A signal's value at t, left limit when ``left``: the formulas of ``regmech.signals``."""
    if kind == SINE:             # p = offset, amplitude, freq_hz, phase, start_time
        on = t > p[4] if left else t >= p[4]
        if not on:
            return p[0]
        return p[0] + p[1] * math.sin(2.0 * math.pi * p[2] * (t - p[4]) + p[3])
    if kind == STEP:             # p = offset, height, start_time
        on = t > p[2] if left else t >= p[2]
        return p[0] + (p[1] if on else 0.0)
    if kind == RAMP:             # p = offset, height, duration, start_time
        t0 = p[3]
        if t < t0 or (left and t == t0):
            return p[0]
        if t >= t0 + p[2]:
            return p[0] + p[1]
        return p[0] + p[1] * (t - t0) / p[2]
    return p[0]                  # CONSTANT


_RES_SIG = types.int32(types.float64, types.voidptr, types.voidptr, types.voidptr, types.voidptr)


@cfunc(_RES_SIG, cache=True)
def residual(t, yy, yp, rr, user_data):
    ud = carray(_i64p(_address(user_data)), (2,))
    ih = carray(_i64p(ud[0]), (11,))
    idata = carray(_i64p(ud[0]), (ih[10],))
    fh = carray(_f64p(ud[1]), (7,))
    fdata = carray(_f64p(ud[1]), (int(fh[6]),))
    N, n_sig = ih[0], ih[2]
    y = carray(_f64p(_second_pointer(_address(yy))), (N,))
    ydot = carray(_f64p(_second_pointer(_address(yp))), (N,))
    r = carray(_f64p(_second_pointer(_address(rr))), (N,))
    indptr, indices, perm = ih[4], ih[5], ih[6]
    kind, slot = ih[7], ih[8]
    data, par, buf = int(fh[1]), int(fh[2]), int(fh[3])
    for i in range(N):
        k = idata[perm + i]
        fdata[buf + k] = y[i]
        fdata[buf + N + k] = ydot[i]
    left = t >= fdata[0]
    for s in range(n_sig):
        fdata[buf + idata[slot + s]] = _signal(idata[kind + s], fdata[par + N_PAR * s: par + N_PAR * (s + 1)], t, left)
    for i in range(N):
        row = idata[perm + i]
        acc = 0.0
        for q in range(idata[indptr + row], idata[indptr + row + 1]):
            acc += fdata[data + q] * fdata[buf + idata[indices + q]]
        r[i] = acc
    return 0


_JAC_SIG = types.int32(types.float64, types.float64, types.voidptr, types.voidptr, types.voidptr, types.voidptr,
                       types.voidptr, types.voidptr, types.voidptr, types.voidptr)


@cfunc(_JAC_SIG, cache=True)
def jacobian_dense(t, cj, yy, yp, rr, jac, user_data, tmp1, tmp2, tmp3):
    """``dF/dy + cj dF/dy'`` of the linear residual: constant entries ``jc + cj jcj`` on the pattern."""
    ud = carray(_i64p(_address(user_data)), (2,))
    ih = carray(_i64p(ud[0]), (11,))
    idata = carray(_i64p(ud[0]), (ih[10],))
    fh = carray(_f64p(ud[1]), (7,))
    fdata = carray(_f64p(ud[1]), (int(fh[6]),))
    N, n_jac, jk = ih[0], ih[3], ih[9]
    jc, jcj = int(fh[4]), int(fh[5])
    J = carray(_f64p(_second_pointer(_address(jac))), (N * N,))
    for k in range(N * N):
        J[k] = 0.0
    for q in range(n_jac):
        J[idata[jk + q]] = fdata[jcj + q] * cj + fdata[jc + q]
    return 0


@njit(cache=True)
def drive(solve_fn, mem, tspan, tret, yy, yp, y_addr, yp_addr, perm, T, Y, YP):
    """IDASolve to each of ``tspan[1:]`` (normal mode), rows into T, Y, YP in the compiled system's order
    (solver entry i is unknown ``perm[i]``; row 0: the start, written by the caller); returns (rows written,
    last flag). Stops after a flag < 0 (that row kept, as scikit-sundae does) or the stop time (flag 1)."""
    N = Y.shape[1]
    ya = carray(_f64p(y_addr), (N,))
    ypa = carray(_f64p(yp_addr), (N,))
    tr = tret.ctypes.data
    flag = 0
    k = 1
    while k < tspan.size:
        flag = _call_ida_solve(solve_fn, mem, tspan[k], tr, yy, yp, 1)
        T[k] = tret[0]
        for i in range(N):
            Y[k, perm[i]] = ya[i]
            YP[k, perm[i]] = ypa[i]
        k += 1
        if flag < 0 or flag == 1:
            break
    return k, flag
