"""IDA without Python in the loop, for linear models: ``simulate(..., solver="ida", native=True)``.

scikit-sundae calls a Python function for every residual evaluation: about 6 us of wrapper and solver
overhead per call plus the residual itself, and about 3 us per output point. On small models that is
nearly all of a run (MSL First, rtol 1e-6: about 1,000 residual calls and 1,001 output points).
This path drives the same SUNDIALS IDA (the library inside scikit-sundae's wheel, through ctypes) with
the residual, the Jacobian and the output loop compiled by numba (``_native_kernels``), so IDA never
calls back into Python.

It serves models whose residual is the linear ``F = L [y; y'; u(t); 1]`` of
``compile.evaluation.EvaluationPlan``: no friction rows, no nonlinear device classes, time-varying
offsets only through signal values (input slots), no Position/Speed references, signals of the types
``Constant``, ``Sine``, ``Step`` and ``Ramp``, the dense or band linear solver, and no wall-clock limit
(``timeout_s``: its checks need Python). ``eligible`` says why a model is not served; the IDA solver
then runs its usual path. Same solver, options and tolerances as that path; the residual is summed in
another order, so the answers differ by round-off, which IDA's step control turns into differences of
the order of the tolerance.

Cost: numba itself (an optional dependency, ``pip install regmech[native]``) takes a fresh process
about half a second to import and to load its cached kernels; the first run on a machine also compiles
them (a few seconds, then cached on disk).
"""

from __future__ import annotations

import ctypes
import glob
import os
import weakref

import numpy as np

from ..errors import SimulationError
from . import sundials_log

#: signal classes the kernels evaluate (``_native_kernels._signal``)
_SUPPORTED = ("Constant", "Sine", "Step", "Ramp")

_LIB = None            # the loaded libraries and kernels, or the reason they are not available


class _Libraries:
    """SUNDIALS through ctypes, and the numba kernels."""

    def __init__(self):
        import sksundae
        from . import _native_kernels as K          # imports numba
        self.K = K
        folder = os.path.join(os.path.dirname(os.path.dirname(sksundae.__file__)), "scikit_sundae.libs")

        def load(name):
            found = sorted(glob.glob(os.path.join(folder, f"libsundials_{name}-*.so*")) +
                           glob.glob(os.path.join(folder, f"libsundials_{name}.so*")))
            if not found:
                raise OSError(f"libsundials_{name} not found in {folder}")
            return ctypes.CDLL(found[0], mode=ctypes.RTLD_GLOBAL)

        core, nvec, dense, lsdense = load("core"), load("nvecserial"), load("sunmatrixdense"), load("sunlinsoldense")
        band, lsband, ida = load("sunmatrixband"), load("sunlinsolband"), load("ida")
        vp, i32, d, idx, lng = ctypes.c_void_p, ctypes.c_int, ctypes.c_double, ctypes.c_int, ctypes.c_long

        def sig(f, res, *args):
            f.restype, f.argtypes = res, list(args)
            return f

        # sunindextype is a C int in scikit-sundae's build (its c_config.pxi); checked below with the vectors
        self.ctx_create = sig(core.SUNContext_Create, i32, i32, ctypes.POINTER(vp))
        self.ctx_free = sig(core.SUNContext_Free, i32, ctypes.POINTER(vp))
        # SUNDIALS' default error handler writes to the process's stderr; ours keeps the line for the
        # SimulationError (``sundials_log``)
        self.clear_err = sig(core.SUNContext_ClearErrHandlers, i32, vp)
        self.push_err = sig(core.SUNContext_PushErrHandler, i32, vp, sundials_log.HANDLER_TYPE, vp)
        self.nv_new = sig(nvec.N_VNew_Serial, vp, idx, vp)
        self.nv_ptr = sig(nvec.N_VGetArrayPointer, vp, vp)
        self.nv_length = sig(nvec.N_VGetLength_Serial, idx, vp)
        self.nv_free = sig(nvec.N_VDestroy_Serial, None, vp)
        self.dense = sig(dense.SUNDenseMatrix, vp, idx, idx, vp)
        self.dense_data = sig(dense.SUNDenseMatrix_Data, vp, vp)
        self.ls_dense = sig(lsdense.SUNLinSol_Dense, vp, vp, vp, vp)
        self.band = sig(band.SUNBandMatrix, vp, idx, idx, idx, vp)
        self.ls_band = sig(lsband.SUNLinSol_Band, vp, vp, vp, vp)
        self.mat_free = sig(core.SUNMatDestroy, None, vp)
        self.ls_free = sig(core.SUNLinSolFree, i32, vp)
        self.create = sig(ida.IDACreate, vp, vp)
        self.init = sig(ida.IDAInit, i32, vp, vp, d, vp, vp)
        self.reinit = sig(ida.IDAReInit, i32, vp, d, vp, vp)
        self.tolerances = sig(ida.IDASVtolerances, i32, vp, d, vp)
        self.set_ls = sig(ida.IDASetLinearSolver, i32, vp, vp, vp)
        self.set_jac = sig(ida.IDASetJacFn, i32, vp, vp)
        self.set_user_data = sig(ida.IDASetUserData, i32, vp, vp)
        self.set_id = sig(ida.IDASetId, i32, vp, vp)
        self.set_int = {n: sig(getattr(ida, n), i32, vp, i32) for n in
                        ("IDASetMaxNonlinIters", "IDASetMaxConvFails", "IDASetMaxOrd")}
        self.set_max_steps = sig(ida.IDASetMaxNumSteps, i32, vp, lng)
        self.set_real = {n: sig(getattr(ida, n), i32, vp, d) for n in
                         ("IDASetInitStep", "IDASetMinStep", "IDASetMaxStep", "IDASetStopTime")}
        self.clear_stop = sig(ida.IDAClearStopTime, i32, vp)
        self.n_res = sig(ida.IDAGetNumResEvals, i32, vp, ctypes.POINTER(lng))
        self.n_jac = sig(ida.IDAGetNumJacEvals, i32, vp, ctypes.POINTER(lng))
        self.n_steps = sig(ida.IDAGetNumSteps, i32, vp, ctypes.POINTER(lng))
        self.free = sig(ida.IDAFree, None, ctypes.POINTER(vp))
        self.solve_address = ctypes.cast(ida.IDASolve, vp).value
        self._check_layout()

    def _check_layout(self):
        """The kernels read a vector's (and a dense matrix's) data pointer 8 bytes into its content: checked
        here against the library's own accessors, so another SUNDIALS build is refused, not misread."""
        ctx = ctypes.c_void_p()
        if self.ctx_create(0, ctypes.byref(ctx)) != 0:
            raise OSError("SUNContext_Create failed")
        try:
            v = self.nv_new(5, ctx)
            m = self.dense(3, 3, ctx)
            try:
                if self.nv_length(v) != 5:
                    raise OSError("unexpected index type in SUNDIALS")
                for obj, data in ((v, self.nv_ptr(v)), (m, self.dense_data(m))):
                    content = ctypes.c_void_p.from_address(obj).value
                    if ctypes.c_void_p.from_address(content + 8).value != data:
                        raise OSError("unexpected N_Vector/SUNMatrix layout in SUNDIALS")
            finally:
                self.nv_free(v)
                self.mat_free(m)
        finally:
            self.ctx_free(ctypes.byref(ctx))


def libraries():
    """The loaded libraries, or a string saying why the native path is not available."""
    global _LIB
    if _LIB is None:
        try:
            _LIB = _Libraries()
        except ImportError as exc:
            _LIB = f"numba is not installed ({exc}); pip install 'regmech[native]'"
        except (OSError, AttributeError) as exc:
            _LIB = f"the SUNDIALS libraries of scikit-sundae could not be used directly ({exc})"
    return _LIB


def signal_table(plan):
    """(kinds, slots, parameters) of every signal the residual reads, or a string naming one it cannot."""
    from . import _native_kernels as K
    kinds, slots, pars = [], [], []
    for g, start, _, _ in plan.input_slots:
        for j, sigs in enumerate(g.signals):
            for i, s in enumerate(sigs):
                name = type(s).__name__
                if name not in _SUPPORTED or type(s).__module__ != "regmech.signals":
                    return (f"{type(g.devices[i]).__name__} '{g.devices[i].name}' has a {name} signal "
                            f"(the native path evaluates {', '.join(_SUPPORTED)})")
                p = np.zeros(K.N_PAR)
                if name == "Sine":
                    kinds.append(K.SINE)
                    p[:5] = s.offset, s.amplitude, s.freq_hz, s.phase, s.start_time
                elif name == "Step":
                    kinds.append(K.STEP)
                    p[:3] = s.offset, s.height, s.start_time
                elif name == "Ramp":
                    kinds.append(K.RAMP)
                    p[:4] = s.offset, s.height, s.duration, s.start_time
                else:
                    kinds.append(K.CONSTANT)
                    p[0] = s.value_
                slots.append(start + j * g.n + i)
                pars.append(p)
    return (np.array(kinds, np.int64), np.array(slots, np.int64),
            np.concatenate(pars) if pars else np.zeros(0))


def eligible(c, linsolver, deadline=None):
    """None when the native path can run compiled system ``c`` with ``linsolver``, else the reason."""
    plan = c._plan
    if c.mf:
        return "the model has friction or loss elements (their mode logic runs in Python)"
    if plan.nonlinear:
        return f"nonlinear device classes ({', '.join(sorted({g.tpl.cls.__name__ for g in plan.nonlinear}))})"
    if plan.offset_slots:
        return f"offsets not linear in their signals ({', '.join(g.tpl.cls.__name__ for g, _ in plan.offset_slots)})"
    if plan.pos_refs or plan.spd_refs:
        return "Position/Speed sources (their references)"
    if linsolver not in ("dense", "band"):
        return f"linear solver '{linsolver}' (the native path has dense and band)"
    if deadline is not None:
        return "a wall-clock limit (timeout_s) is active; its checks run in Python"
    if "residual" in c.__dict__:
        return "the residual is wrapped on the compiled system (a work budget counts its calls in Python)"
    lib = libraries()            # numba first: the signal table needs the kernels' constants
    if isinstance(lib, str):
        return lib
    table = signal_table(plan)
    return table if isinstance(table, str) else None


class _Result:
    """What ``ida._solve_segment`` reads of a scikit-sundae result."""

    MESSAGES = {0: "Successful function return.", 1: "Reached the specified stopping point.",
                -1: "Took mxstep internal steps but could not reach tout.",
                -2: "Could not satisfy the accuracy requested for the machine precision.",
                -3: "Error test failures occurred too many times or with |h| = hmin.",
                -4: "Convergence test failures occurred too many times or with |h| = hmin.",
                -7: "The nonlinear solver failed to converge.",
                -8: "The residual function failed unrecoverably.",
                -9: "The residual function failed repeatedly."}

    def __init__(self, t, y, yp, status, nfev, njev, unpermuted=False):
        self.t, self.y, self.yp, self.status = t, y, yp, status
        self.unpermuted = unpermuted         # rows already in the compiled system's order
        self.success = status >= 0
        self.message = self.MESSAGES.get(status, f"IDA flag {status}")
        self.nfev, self.njev = nfev, njev
        self.i_events = self.t_events = self.y_events = self.yp_events = None


def _release(lib, handles):
    mem, vectors, A, LS, ctx = handles
    try:
        lib.free(ctypes.byref(mem))
        for v in vectors:
            lib.nv_free(v)
        lib.ls_free(LS)
        lib.mat_free(A)
        lib.ctx_free(ctypes.byref(ctx))
    except Exception:       # pragma: no cover - interpreter shutdown
        pass


def _layout(c, linsolver, order):
    """The kernels' ``(idata, fdata)`` for compiled system ``c`` (``_native_kernels`` module docstring)."""
    import scipy.sparse as sp
    plan = c._plan
    N = c.N
    kinds, slots, pars = signal_table(plan)
    L = sp.csr_matrix(plan.L) if isinstance(plan.L, np.ndarray) else plan.L.tocsr(copy=True)
    L.sum_duplicates()
    perm = np.arange(N) if order.perm is None else np.asarray(order.perm, np.int64)
    jk = jc = jcj = np.zeros(0)
    if linsolver == "dense":
        # constant iteration-matrix entries (an eligible model has no nonlinear weights), column-major;
        # entry q of the Jacobian data sits at (jac.rows[q], jac.cols[q]), each once
        c.jacobian_data(0.0, np.zeros(N), np.zeros(N), 0.0, c.modes0)      # builds the Jacobian plan
        jp = c._jac_plan
        jk = np.asarray(c.jac.cols, np.int64) * N + np.asarray(c.jac.rows, np.int64)
        jc, jcj = np.asarray(jp.const, float), np.asarray(jp.cjv, float)
    parts_i = [L.indptr, L.indices, perm, kinds, slots, jk]
    offs_i, pos = [], 11
    for a in parts_i:
        offs_i.append(pos)
        pos += len(a)
    idata = np.concatenate([np.array([N, plan.width, len(kinds), len(jk)] + offs_i + [pos], np.int64)] +
                           [np.asarray(a, np.int64) for a in parts_i])
    buf = np.zeros(plan.width)
    buf[plan.one] = 1.0
    parts_f = [L.data, pars, buf, jc, jcj]
    offs_f, pos = [], 7
    for a in parts_f:
        offs_f.append(pos)
        pos += len(a)
    # header: t_right, then the offsets of data, par, buf, jc, jcj, then the length
    fdata = np.concatenate([np.array([np.inf] + offs_f + [pos], float)] + [np.asarray(a, float) for a in parts_f])
    return idata, fdata


class NativeIDA:
    """A drop-in for ``sksundae.ida.IDA`` on an eligible model (``eligible``): ``solve(tspan, y0, yp0)``, whose
    output rows come back in the compiled system's order (``_Result.unpermuted``).

    Built with the options ``ida._make_solver`` gives scikit-sundae (scikit-sundae's defaults for the
    rest: Newton at most 4 iterations, 10 convergence failures, IDA's own first step); the first
    ``solve`` initialises IDA, later ones re-initialise it (``IDAReInit``), as scikit-sundae does.
    """

    def __init__(self, c, rtol, atol, linsolver, order, max_step, max_order, max_steps, lband=0, uband=0):
        lib = libraries()
        K = lib.K
        self.lib, self.K, self.c = lib, K, c
        N = c.N
        self.N = N
        key = (linsolver, None if order.perm is None else tuple(order.perm))
        layout = c.__dict__.setdefault("_native_layouts", {}).get(key)
        if layout is None:
            layout = c._native_layouts[key] = _layout(c, linsolver, order)
        self.idata, self.fdata = layout[0].copy(), layout[1].copy()      # the kernels write into fdata
        self.user = np.array([self.idata.ctypes.data, self.fdata.ctypes.data], np.int64)
        ctx = ctypes.c_void_p()
        if lib.ctx_create(0, ctypes.byref(ctx)) != 0:
            raise SimulationError(f"the native IDA path could not create a SUNDIALS context for model "
                                  f"'{c.model.name}'; run it without native=True")
        if lib.clear_err(ctx) != 0 or lib.push_err(ctx, sundials_log.handler, None) != 0:
            lib.ctx_free(ctypes.byref(ctx))
            raise SimulationError(f"the native IDA path could not install its error handler for model "
                                  f"'{c.model.name}'; run it without native=True")
        yy, yp, at, idv = (lib.nv_new(N, ctx) for _ in range(4))
        if linsolver == "dense":
            A = lib.dense(N, N, ctx)
            LS = lib.ls_dense(yy, A, ctx)
        else:
            A = lib.band(N, int(uband), int(lband), ctx)
            LS = lib.ls_band(yy, A, ctx)
        mem = lib.create(ctx)
        if not (yy and yp and at and idv and A and LS and mem):
            raise SimulationError(f"SUNDIALS could not allocate the native IDA solver for model '{c.model.name}' "
                                  f"({N} unknowns); run it without native=True")
        self._handles = (ctypes.c_void_p(mem), (yy, yp, at, idv), A, LS, ctx)
        weakref.finalize(self, _release, lib, self._handles)
        self.mem, self.yy, self.yp = mem, yy, yp
        self.ya = np.ctypeslib.as_array(ctypes.cast(lib.nv_ptr(yy), ctypes.POINTER(ctypes.c_double)), (N,))
        self.ypa = np.ctypeslib.as_array(ctypes.cast(lib.nv_ptr(yp), ctypes.POINTER(ctypes.c_double)), (N,))
        self.ya_address, self.ypa_address = lib.nv_ptr(yy), lib.nv_ptr(yp)
        np.ctypeslib.as_array(ctypes.cast(lib.nv_ptr(at), ctypes.POINTER(ctypes.c_double)), (N,))[:] = (
            np.broadcast_to(np.asarray(atol, float), (N,)))
        ident = np.ctypeslib.as_array(ctypes.cast(lib.nv_ptr(idv), ctypes.POINTER(ctypes.c_double)), (N,))
        ident[:] = 1.0
        alg = c.algebraic if order.perm is None else order.inv[c.algebraic]
        ident[alg] = 0.0
        self._at, self._id = at, idv
        self._opts = (float(rtol), linsolver, A, LS, max_step, int(max_order), int(max_steps))
        self.perm = np.arange(N) if order.perm is None else np.asarray(order.perm, np.int64)
        self._initialised = False
        self.tret = np.zeros(1)
        # steps taken in the last solve, as the usual path's counter (``ida._make_solver``) reports them:
        # here IDA's own count of accepted steps (IDAReInit sets it back to zero)
        self.regmech_attempts = [None, 0]

    def _setup(self, t0):
        lib, K = self.lib, self.K
        rtol, linsolver, A, LS, max_step, max_order, max_steps = self._opts
        mem = self.mem
        flags = [lib.set_user_data(mem, self.user.ctypes.data),
                 lib.init(mem, K.residual.address, t0, self.yy, self.yp),
                 lib.tolerances(mem, rtol, self._at),
                 lib.set_ls(mem, LS, A)]
        if linsolver == "dense":
            flags.append(lib.set_jac(mem, K.jacobian_dense.address))
        flags += [lib.set_int["IDASetMaxNonlinIters"](mem, 4), lib.set_int["IDASetMaxConvFails"](mem, 10),
                  lib.set_id(mem, self._id), lib.set_real["IDASetInitStep"](mem, 0.0),
                  lib.set_real["IDASetMinStep"](mem, 0.0),
                  lib.set_real["IDASetMaxStep"](mem, float(max_step) if max_step else 0.0),
                  lib.set_int["IDASetMaxOrd"](mem, max_order), lib.set_max_steps(mem, max_steps)]
        if any(f < 0 for f in flags):
            raise RuntimeError(f"setting up the native IDA solver failed (flags {flags})")
        self._initialised = True

    def solve(self, tspan, y0, yp0):
        tspan = np.ascontiguousarray(tspan, float)
        self.fdata[0] = self.c._t_right
        self.ya[:] = y0
        self.ypa[:] = yp0
        lib = self.lib
        if not self._initialised:
            self._setup(float(tspan[0]))
        elif lib.reinit(self.mem, float(tspan[0]), self.yy, self.yp) < 0:
            raise RuntimeError("IDAReInit failed")
        if lib.set_real["IDASetStopTime"](self.mem, float(tspan[-1])) < 0:
            raise RuntimeError("IDASetStopTime failed")
        n = len(tspan)
        T = np.empty(n)
        Y = np.empty((n, self.N))
        YP = np.empty((n, self.N))
        T[0] = tspan[0]
        Y[0, self.perm], YP[0, self.perm] = self.ya, self.ypa
        rows, flag = self.K.drive(self.lib.solve_address, self.mem, tspan, self.tret, self.yy, self.yp,
                                  self.ya_address, self.ypa_address, self.perm, T, Y, YP)
        lib.clear_stop(self.mem)
        nf, nj = ctypes.c_long(), ctypes.c_long()
        lib.n_res(self.mem, ctypes.byref(nf))
        lib.n_jac(self.mem, ctypes.byref(nj))
        ns = ctypes.c_long()
        lib.n_steps(self.mem, ctypes.byref(ns))
        self.regmech_attempts[1] += int(ns.value)
        return _Result(T[:rows], Y[:rows], YP[:rows], int(flag), int(nf.value), int(nj.value), unpermuted=True)
