"""numba kernels of the native IDA path (``ida_native``); imported only when that path is used.

The residual and the dense and band Jacobians are C callbacks (``numba.cfunc``) that SUNDIALS IDA calls directly,
with no Python in between; the output loop (``drive``) calls ``IDASolve`` once per output time from
compiled code too. Everything a callback needs is in arrays whose addresses IDA passes as its user data, an int64 array
``[idata, fdata, hi, hf, ctl, clock_gettime]`` (``hi``, ``hf``: 0 without friction; ``ctl``: the wall-clock
limit, ``_past_deadline``):

* ``idata`` (int64): ``[N, W, n_sig, n_jac, off_indptr, off_indices, off_perm, off_kind, off_slot,
  off_jk, length, band_ldata, band_offset]`` and the arrays those offsets point to (the last two: the band
  Jacobian's storage, ``jacobian_band``; 0 otherwise);
* ``fdata`` (float64): ``[t_right, off_data, off_par, off_buf, off_jc, off_jcj, length]`` and the arrays;
* for a model with friction devices (``residual_friction``, ``events``), a second pair, ``hi`` (int64:
  ``[mf, off_row, off_sptr, off_sidx, off_wptr, off_widx, off_lam_buf, off_lam_sol, off_sig_kind, off_mode,
  off_evkind, off_engaged, off_relief, length]``) and ``hf`` (float64: ``[off_scoef, off_wcoef, off_sig_par,
  off_fn_scale, off_k, off_peak, off_relief_ms, off_relief_tol, off_free_capacity, length]``), written by
  ``_native_friction.FrictionTables``; the per-segment parts (mode, event kind, engagement, relief event of each
  device) are rewritten at every segment start.

The residual is ``F = L [y; y'; u(t); 1]`` (``compile.evaluation.EvaluationPlan`` of a model without
nonlinear devices or friction): ``buf`` holds that vector, ``u(t)`` the signal values at their slots.
Row ``i`` of the solver's residual is row ``perm[i]`` of ``L`` (the band solver's ordering; identity
otherwise). Every kernel is compiled with ``cache=True`` (no addresses baked in: pointers arrive as
integers), so a process pays numba's start-up but no compilation after the first one on a machine.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import carray, cfunc, njit, types
from numba.extending import intrinsic

# signal kinds and their formulas, shared with the ODE form's compiled right-hand side
from ..compile._native_signals import CONSTANT, N_PAR, RAMP, SINE, STEP      # noqa: E402,F401
from ..compile._native_signals import signal_at as _signal_at                 # noqa: E402
#: ``_native_signals.source_hash()`` of the signal formulas compiled in here (a test checks it: a change there must
#: edit this file, or numba's cache of this file's kernels keeps the old formulas)
SIGNALS_SOURCE = "4c634e02e3d2fb5c"
# a friction device's first event function in the segment's modes (``hybrid.events``)
EV_SLIDING, EV_STUCK, EV_CONSTANT, EV_STUCK_ONE_WAY, EV_FREE_ONE_WAY = 0, 1, 2, 3, 4
# the mode codes of ``regmech.modes`` (STUCK 0, FORWARD 1, BACKWARD -1; FREE and HELD carry no torque)
M_STUCK, M_FORWARD, M_BACKWARD = 0, 1, -1


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


@intrinsic
def _call_kernel(typingctx, fn, a, n, t, out):
    """A class kernel ``void f(double *a, int64 n, double t, double *out)`` (``compile.codegen``) through its
    address ``fn``; ``a`` and ``out`` are addresses given as integers."""
    def codegen(context, builder, signature, args):
        dp = ir.DoubleType().as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [dp, ir.IntType(64), ir.DoubleType(), dp])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(f, [builder.inttoptr(args[1], dp), args[2], args[3], builder.inttoptr(args[4], dp)])
        return context.get_dummy_value()
    return types.none(fn, a, n, t, out), codegen


@intrinsic
def _call_clock(typingctx, fn, clock_id, ts):
    """``clock_gettime(clock_id, ts)`` through its address ``fn`` (``ts``: the address of two int64)."""
    def codegen(context, builder, signature, args):
        vp = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.IntType(32), [ir.IntType(32), vp])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(f, [builder.trunc(args[1], ir.IntType(32)), builder.inttoptr(args[2], vp)])
    return types.int32(fn, clock_id, ts), codegen


def _ida_codegen(arg_kinds):
    """The code of a call ``int f(void *mem, ...)`` through its address, the further arguments of the kinds
    ``"d"`` (double) and ``"p"`` (a pointer given as an integer): the few SUNDIALS calls of a segment
    (``segment``) made from compiled code, as ``_call_ida_solve`` makes IDASolve's."""
    def codegen(context, builder, signature, values):
        vp = ir.IntType(8).as_pointer()
        arg_types = [vp] + [ir.DoubleType() if k == "d" else vp for k in arg_kinds]
        f = builder.inttoptr(values[0], ir.FunctionType(ir.IntType(32), arg_types).as_pointer())
        call_args = [builder.inttoptr(values[1], vp)] + [
            v if k == "d" else builder.inttoptr(v, vp) for k, v in zip(arg_kinds, values[2:])]
        return builder.call(f, call_args)
    return codegen


@intrinsic
def _call_p(typingctx, fn, mem):
    """IDAClearStopTime(mem)"""
    return types.int32(fn, mem), _ida_codegen(())


@intrinsic
def _call_p_d(typingctx, fn, mem, a):
    """IDASetStopTime(mem, tstop)"""
    return types.int32(fn, mem, a), _ida_codegen(("d",))


@intrinsic
def _call_p_p(typingctx, fn, mem, a):
    """IDAGetNum...(mem, long *), IDAGetRootInfo(mem, int *)"""
    return types.int32(fn, mem, a), _ida_codegen(("p",))


@intrinsic
def _call_p_d_p(typingctx, fn, mem, a, b):
    """IDASVtolerances(mem, rtol, atol)"""
    return types.int32(fn, mem, a, b), _ida_codegen(("d", "p"))


@intrinsic
def _call_p_d_p_p(typingctx, fn, mem, a, b, c):
    """IDAReInit(mem, t0, yy, yp)"""
    return types.int32(fn, mem, a, b, c), _ida_codegen(("d", "p", "p"))


CLOCK_MONOTONIC = 1      # Linux: the clock of Python's time.monotonic()
#: entries of the user data: ``[idata, fdata, hi, hf, ctl, clock_gettime, gi, gf]``
N_UD = 8
#: header lengths of the nonlinear groups' tables ``gi`` (int64) and ``gf`` (float64), ``ida_native.GroupTables``
GI_HEAD, GF_HEAD, G_REC = 15, 7, 10
#: what ``_groups`` evaluates
G_RES, G_JAC, G_SURF = 0, 1, 2


@njit(cache=True, inline="always")
def _past_deadline(ud):
    """True (and the flag set) when the run's wall-clock limit has passed: ``ctl = [deadline_ns (0: none),
    flag, tv_sec, tv_nsec]`` at ``ud[4]``, ``clock_gettime`` at ``ud[5]``; the residual then fails
    unrecoverably and the caller raises the limit's ``SimulationTimeout`` (``ida_native.NativeIDA.solve``)."""
    ctl = carray(_i64p(ud[4]), (4,))
    if ctl[0] <= 0:
        return False
    _call_clock(ud[5], CLOCK_MONOTONIC, ud[4] + 16)
    if ctl[2] * 1000000000 + ctl[3] > ctl[0]:
        ctl[1] = 1
        return True
    return False


@njit(cache=True, inline="always")
def _second_pointer(addr):
    """The pointer stored 8 bytes into the struct that the pointer at ``addr`` points to: the data of a
    serial N_Vector (``content->data``) and of a dense SUNMatrix, checked by ``ida_native`` at load."""
    content = carray(_i64p(addr), (1,))[0]
    return carray(_i64p(content + 8), (1,))[0]


@njit(cache=True, inline="always")
def _group_tables(ud):
    gh = carray(_i64p(ud[6]), (GI_HEAD,))
    gi = carray(_i64p(ud[6]), (gh[GI_HEAD - 1],))
    fh = carray(_f64p(ud[7]), (GF_HEAD,))
    gf = carray(_f64p(ud[7]), (int(fh[GF_HEAD - 1]),))
    return gh, gi, fh, gf


@njit(cache=True)
def _groups(ud, fdata, buf, t, left, what):
    """The nonlinear device classes (``compile.codegen`` kernels): their signal inputs at t, their arguments
    ``[e; de; z] = E y + e0`` from the unknowns at ``fdata[buf:buf + N]`` (compiled order), then per group its
    ``res`` kernel into its output slots of ``buf`` (``what`` G_RES), its ``jac`` kernel into ``w`` (G_JAC) or its
    ``surf`` kernel into its block of surface values (G_SURF).

    ``gi``: ``[n_groups, n_erows, off_ptr, off_idx, off_dest, off_grp, n_gsig, off_gkind, off_gdest, n_w,
    off_wptr, off_widx, n_surf, off_sidx, length]``, a record per group ``[n, n_args, res, jac, args, out_slot,
    w, n_jac, surf, surf_values]``; ``gf``: ``[off_edata, off_e0, off_gpar, off_wdata, off_w, off_sides,
    length]``."""
    gh, gi, fh, gf = _group_tables(ud)
    for s in range(gh[6]):
        gf[gi[gh[8] + s]] = _signal_at(gi[gh[7] + s], gf, int(fh[2]) + N_PAR * s, t, left)
    ptr, idx, dest = gh[2], gh[3], gh[4]
    edata, e0 = int(fh[0]), int(fh[1])
    for r in range(gh[1]):
        acc = gf[e0 + r]
        for q in range(gi[ptr + r], gi[ptr + r + 1]):
            acc += gf[edata + q] * fdata[buf + gi[idx + q]]
        gf[gi[dest + r]] = acc
    for g in range(gh[0]):
        rec = gh[5] + G_REC * g
        n = gi[rec]
        a = ud[7] + 8 * gi[rec + 4]
        if what == G_JAC:
            if gi[rec + 7] > 0:
                _call_kernel(gi[rec + 3], a, n, t, ud[7] + 8 * (int(fh[4]) + gi[rec + 6]))
        elif what == G_SURF:
            if gi[rec + 8] != 0:
                _call_kernel(gi[rec + 8], a, n, t, ud[7] + 8 * gi[rec + 9])
        else:
            _call_kernel(gi[rec + 2], a, n, t, ud[1] + 8 * (buf + gi[rec + 5]))


@njit(cache=True, inline="always")
def _fill_unknowns(ud, yy, yp):
    """y and y' (solver order) into ``buf`` (compiled order); returns ``(fdata, buf, N)``."""
    ih = carray(_i64p(ud[0]), (11,))
    idata = carray(_i64p(ud[0]), (ih[10],))
    fh = carray(_f64p(ud[1]), (7,))
    fdata = carray(_f64p(ud[1]), (int(fh[6]),))
    N = ih[0]
    y = carray(_f64p(_second_pointer(_address(yy))), (N,))
    ydot = carray(_f64p(_second_pointer(_address(yp))), (N,))
    buf, perm = int(fh[3]), ih[6]
    for i in range(N):
        k = idata[perm + i]
        fdata[buf + k] = y[i]
        fdata[buf + N + k] = ydot[i]
    return fdata, buf, N


@njit(cache=True, inline="always")
def _variable_entries(ud, t, yy, yp):
    """Entry q of the Jacobian's nonlinear part ``W w`` is ``acc[q]``; computed into the groups' ``w`` first
    (their ``jac`` kernels at (t, y)). Returns ``(gh, gi, fh, gf)``; nothing when the model has no groups."""
    fdata, buf, N = _fill_unknowns(ud, yy, yp)
    _groups(ud, fdata, buf, t, t >= fdata[0], G_JAC)
    return _group_tables(ud)


@njit(cache=True, inline="always")
def _w_entry(gh, gi, fh, gf, q):
    """``(W w)[q]``: row q of the CSR matrix W (``gi[off_wptr]``...) times the groups' weights ``w``."""
    acc = 0.0
    wdata, w = int(fh[3]), int(fh[4])
    for p in range(gi[gh[10] + q], gi[gh[10] + q + 1]):
        acc += gf[wdata + p] * gf[w + gi[gh[11] + p]]
    return acc


_RES_SIG = types.int32(types.float64, types.voidptr, types.voidptr, types.voidptr, types.voidptr)


@njit(cache=True, inline="always")
def _linear_rows(t, yy, yp, rr, ud):
    """``F = L [y; y'; u(t); 1]`` into ``rr``; returns ``(fdata, buf offset, left)`` for the friction rows."""
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
        fdata[buf + idata[slot + s]] = _signal_at(idata[kind + s], fdata, par + N_PAR * s, t, left)
    if ud[6] != 0:
        _groups(ud, fdata, buf, t, left, G_RES)
    for i in range(N):
        row = idata[perm + i]
        acc = 0.0
        for q in range(idata[indptr + row], idata[indptr + row + 1]):
            acc += fdata[data + q] * fdata[buf + idata[indices + q]]
        r[i] = acc
    return fdata, buf, left


@cfunc(_RES_SIG, cache=True)
def residual(t, yy, yp, rr, user_data):
    ud = carray(_i64p(_address(user_data)), (N_UD,))
    if _past_deadline(ud):
        return -1
    _linear_rows(t, yy, yp, rr, ud)
    return 0


@njit(cache=True, inline="always")
def _friction_tables(ud):
    hh = carray(_i64p(ud[2]), (14,))
    hi = carray(_i64p(ud[2]), (hh[13],))
    fh = carray(_f64p(ud[3]), (10,))
    hf = carray(_f64p(ud[3]), (int(fh[9]),))
    return hh, hi, fh, hf


@njit(cache=True, inline="always")
def _normal_force(hh, hi, fh, hf, j, t, left):
    """``fn_scale_j * u_j(t)``: device j's normal force (its law: ``FrictionDevice.linear_law``)."""
    return hf[int(fh[3]) + j] * _signal_at(hi[hh[8] + j], hf, int(fh[2]) + N_PAR * j, t, left)


@cfunc(_RES_SIG, cache=True)
def residual_friction(t, yy, yp, rr, user_data):
    """The linear rows, then each friction row in the segment's mode (``compile.friction_rows``):
    stuck ``G_f[j] a = 0``; sliding ``lam_j - mode k_j max(fn_j(t), 0) = 0``; free or held ``lam_j = 0``."""
    ud = carray(_i64p(_address(user_data)), (N_UD,))
    if _past_deadline(ud):
        return -1
    fdata, buf, left = _linear_rows(t, yy, yp, rr, ud)
    hh, hi, fh, hf = _friction_tables(ud)
    ih = carray(_i64p(ud[0]), (1,))
    r = carray(_f64p(_second_pointer(_address(rr))), (ih[0],))
    for j in range(hh[0]):
        m = hi[hh[9] + j]
        if m == M_STUCK:
            acc = 0.0
            for q in range(hi[hh[2] + j], hi[hh[2] + j + 1]):
                acc += hf[int(fh[0]) + q] * fdata[buf + hi[hh[3] + q]]
        else:
            acc = fdata[buf + hi[hh[6] + j]]
            if m == M_FORWARD or m == M_BACKWARD:
                fn = _normal_force(hh, hi, fh, hf, j, t, left)
                if fn > 0.0:
                    acc -= m * hf[int(fh[4]) + j] * fn
        r[hi[hh[1] + j]] = acc
    return 0


_EV_SIG = types.int32(types.float64, types.voidptr, types.voidptr, types.CPointer(types.float64), types.voidptr)


@njit(cache=True, inline="always")
def _friction_events(hh, hi, fh, hf, j, y, t, left):
    """Device j's two event functions (``events``)."""
    fn = _normal_force(hh, hi, fh, hf, j, t, left)
    kind = hi[hh[10] + j]
    rel = hi[hh[12] + j]
    if rel >= 0:
        v = hf[int(fh[6]) + j] * y[rel] + hf[int(fh[7]) + j]
    elif kind == EV_SLIDING:
        w = 0.0
        for q in range(hi[hh[4] + j], hi[hh[4] + j + 1]):
            w += hf[int(fh[1]) + q] * y[hi[hh[5] + q]]
        v = hi[hh[9] + j] * w
        if v == 0.0:
            v = 1e-300
    elif kind == EV_STUCK:
        tau0 = hf[int(fh[4]) + j] * fn if fn > 0.0 else 0.0
        v = hf[int(fh[5]) + j] * tau0 - abs(y[hi[hh[7] + j]])
    elif kind == EV_STUCK_ONE_WAY:        # releases forward only; disengaged, its freewheel's small capacity
        cap = hf[int(fh[5]) + j] * hf[int(fh[4]) + j] * fn if fn > 0.0 else hf[int(fh[8]) + j]
        v = cap - y[hi[hh[7] + j]]
    elif kind == EV_FREE_ONE_WAY:         # locks where w_rel reaches 0
        v = 0.0
        for q in range(hi[hh[4] + j], hi[hh[4] + j + 1]):
            v += hf[int(fh[1]) + q] * y[hi[hh[5] + q]]
        if v == 0.0:
            v = 1e-300
    else:
        v = 1.0
    if hi[hh[11] + j]:
        return v, fn
    return v, (-fn if fn != 0.0 else 1e-300)


@cfunc(_EV_SIG, cache=True)
def events(t, yy, yp, gout, user_data):
    """The event functions of ``hybrid.surfaces.Guards`` in the segment's modes: the ``2 mf`` friction functions
    of ``hybrid.events`` (``_event_values_small``), per device its first function (sliding ``mode w_rel``, stuck
    ``tau0_max - |lam|``, else 1; a relief event ``ms lam_holder + tol`` in its place) and its engagement (``fn``
    engaged, ``-fn`` not); then the switching surfaces of the nonlinear device classes, ``side_k g_k``."""
    ud = carray(_i64p(_address(user_data)), (N_UD,))
    ih = carray(_i64p(ud[0]), (11,))
    fdata = carray(_f64p(ud[1]), (1,))
    N = ih[0]
    y = carray(_f64p(_second_pointer(_address(yy))), (N,))
    left = t >= fdata[0]
    mf = 0
    if ud[2] != 0:
        hh, hi, fh, hf = _friction_tables(ud)
        mf = hh[0]
        g = carray(gout, (2 * mf,))
        for j in range(mf):
            g[2 * j], g[2 * j + 1] = _friction_events(hh, hi, fh, hf, j, y, t, left)
    if ud[6] != 0:
        gh, gi, gfh, gf = _group_tables(ud)
        ns = gh[12]
        if ns > 0:
            full, buf, _ = _fill_unknowns(ud, yy, yp)
            _groups(ud, full, buf, t, left, G_SURF)
            g = carray(gout, (2 * mf + ns,))
            sides, sidx = int(gfh[5]), gh[13]
            for k in range(ns):
                g[2 * mf + k] = gf[sides + k] * gf[gi[sidx + k]]
    return 0


_JAC_SIG = types.int32(types.float64, types.float64, types.voidptr, types.voidptr, types.voidptr, types.voidptr,
                       types.voidptr, types.voidptr, types.voidptr, types.voidptr)


@cfunc(_JAC_SIG, cache=True)
def jacobian_dense(t, cj, yy, yp, rr, jac, user_data, tmp1, tmp2, tmp3):
    """``dF/dy + cj dF/dy'``: entries ``jc + cj jcj`` on the pattern (constant in a segment's modes), plus the
    nonlinear device classes' part ``W w(t, y)`` (``_variable_entries``) where the model has them."""
    ud = carray(_i64p(_address(user_data)), (N_UD,))
    ih = carray(_i64p(ud[0]), (11,))
    idata = carray(_i64p(ud[0]), (ih[10],))
    fh = carray(_f64p(ud[1]), (7,))
    fdata = carray(_f64p(ud[1]), (int(fh[6]),))
    N, n_jac, jk = ih[0], ih[3], ih[9]
    jc, jcj = int(fh[4]), int(fh[5])
    J = carray(_f64p(_second_pointer(_address(jac))), (N * N,))
    for k in range(N * N):
        J[k] = 0.0
    if ud[6] != 0:
        gh, gi, gfh, gf = _variable_entries(ud, t, yy, yp)
        for q in range(n_jac):
            J[idata[jk + q]] = fdata[jcj + q] * cj + fdata[jc + q] + _w_entry(gh, gi, gfh, gf, q)
        return 0
    for q in range(n_jac):
        J[idata[jk + q]] = fdata[jcj + q] * cj + fdata[jc + q]
    return 0


@cfunc(_JAC_SIG, cache=True)
def jacobian_band(t, cj, yy, yp, rr, jac, user_data, tmp1, tmp2, tmp3):
    """``dF/dy + cj dF/dy'`` into a band SUNMatrix: the entries of ``jacobian_dense`` at their places in the band
    storage, ``idata[jk + q]`` (``ida_native._band_places``); the storage's length (``ldata``) and the byte offset
    of its data pointer in the matrix's content are header slots 11 and 12."""
    ud = carray(_i64p(_address(user_data)), (N_UD,))
    ih = carray(_i64p(ud[0]), (13,))
    idata = carray(_i64p(ud[0]), (ih[10],))
    fh = carray(_f64p(ud[1]), (7,))
    fdata = carray(_f64p(ud[1]), (int(fh[6]),))
    n_jac, jk, ldata, offset = ih[3], ih[9], ih[11], ih[12]
    jc, jcj = int(fh[4]), int(fh[5])
    content = carray(_i64p(_address(jac)), (1,))[0]
    J = carray(_f64p(carray(_i64p(content + offset), (1,))[0]), (ldata,))
    for k in range(ldata):
        J[k] = 0.0
    if ud[6] != 0:
        gh, gi, gfh, gf = _variable_entries(ud, t, yy, yp)
        for q in range(n_jac):
            J[idata[jk + q]] = fdata[jcj + q] * cj + fdata[jc + q] + _w_entry(gh, gi, gfh, gf, q)
        return 0
    for q in range(n_jac):
        J[idata[jk + q]] = fdata[jcj + q] * cj + fdata[jc + q]
    return 0


@njit(cache=True)
def drive(solve_fn, mem, tspan, tret, yy, yp, y_addr, yp_addr, perm, T, Y, YP):
    """IDASolve to each of ``tspan[1:]`` (normal mode), rows into T, Y, YP in the compiled system's order
    (solver entry i is unknown ``perm[i]``; row 0: the start, written by the caller); returns (rows written,
    last flag). Stops after a flag < 0 (that row kept, as scikit-sundae does), the stop time (flag 1) or a root
    of the event functions (flag 2: every event is terminal; the row is the state at the root)."""
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
        if flag < 0 or flag == 1 or flag == 2:
            break
    return k, flag


#: the SUNDIALS functions ``segment`` calls, in the order of its ``fns`` argument (``ida_native.NativeIDA``)
SEGMENT_FUNCTIONS = ("IDASolve", "IDAReInit", "IDASVtolerances", "IDASetStopTime", "IDAClearStopTime",
                     "IDAGetNumResEvals", "IDAGetNumJacEvals", "IDAGetNumSteps", "IDAGetRootInfo")


@njit(cache=True)
def segment(fns, mem, reinit, new_tol, rtol, atol_nv, tspan, tret, yy, yp, y_addr, yp_addr, perm, T, Y, YP,
            counts, roots):
    """One segment of a native run in one call from Python (each ctypes call costs about a microsecond, and a
    friction model's run has a segment per event): IDAReInit at ``tspan[0]`` from the values in yy, yp (when
    ``reinit``), the tolerances (when ``new_tol``), the stop time ``tspan[-1]``, ``drive``, IDAClearStopTime,
    then IDA's counts of residuals, Jacobians and steps into ``counts`` (int64, C long) and, at a root, its
    root information into ``roots`` (int32). Returns ``(rows, flag)`` as ``drive``; a failed call k of
    ``SEGMENT_FUNCTIONS`` gives ``(0, -1000 - k)``."""
    if reinit and _call_p_d_p_p(fns[1], mem, tspan[0], yy, yp) < 0:
        return 0, -1001
    if new_tol and _call_p_d_p(fns[2], mem, rtol, atol_nv) < 0:
        return 0, -1002
    if _call_p_d(fns[3], mem, tspan[tspan.size - 1]) < 0:
        return 0, -1003
    rows, flag = drive(fns[0], mem, tspan, tret, yy, yp, y_addr, yp_addr, perm, T, Y, YP)
    _call_p(fns[4], mem)
    base = counts.ctypes.data
    for k in range(3):
        _call_p_p(fns[5 + k], mem, base + 8 * k)
    if flag == 2 and _call_p_p(fns[8], mem, roots.ctypes.data) < 0:
        return rows, -1008
    return rows, flag
