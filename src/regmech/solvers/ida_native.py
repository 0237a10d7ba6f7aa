"""IDA without Python in the loop, for linear models and friction models linear in each mode:
``simulate(..., solver="ida", native=True)``.

scikit-sundae calls a Python function for every residual evaluation: about 6 us of wrapper and solver
overhead per call plus the residual itself, and about 3 us per output point. On small models that is
nearly all of a run (MSL First, rtol 1e-6: about 1,000 residual calls and 1,001 output points).
This path drives the same SUNDIALS IDA (the library inside scikit-sundae's wheel, through ctypes) with
the residual, the Jacobian and the output loop compiled by numba (``_native_kernels``), so IDA never
calls back into Python.

It serves models whose residual is the linear ``F = L [y; y'; u(t); 1]`` of
``compile.evaluation.EvaluationPlan`` (no nonlinear device classes, time-varying offsets only through signal
values (input slots), no Position/Speed references, signals of the types ``Constant``, ``Sine``, ``Step`` and
``Ramp``, the dense or band linear solver) plus friction rows whose devices state their law in closed form
(``FrictionDevice.linear_law``: normal force ``fn = s u(t)``, kinetic torque ``k max(fn, 0)`` at every
speed, static ``peak`` times that; no lossy gears or one-way clutches). In a segment's modes a friction row
is ``G_f a = 0`` (stuck), ``lam - mode k max(fn, 0)`` (sliding) or ``lam`` (free, held), and the event
functions are those of ``hybrid.events``, all evaluated by the kernels; IDA's root finding stops the segment
at a crossing (every event terminal, downward), and the mode logic (``hybrid``) settles the modes in Python
before ``NativeIDA.set_segment`` writes the next segment's tables and IDA is re-initialised. ``eligible``
says why a model is not served; the IDA solver then runs its usual path. A run's wall-clock limit
(``timeout_s``) is read by the residual kernels (``clock_gettime``). Same solver, options and tolerances as
that path; the residual is summed in another order, so the answers differ by round-off, which IDA's step
control turns into differences of the order of the tolerance.

Cost: numba itself (an optional dependency, ``pip install regmech[native]``) takes a fresh process
about half a second to import and to load its cached kernels; the first run on a machine also compiles
them (a few seconds, then cached on disk).
"""

from __future__ import annotations

import ctypes
import glob
import os
import time
import weakref

import numpy as np

from ..errors import SimulationError
from . import sundials_log
from ._native_friction import FrictionTables, _place_pool, friction_laws  # noqa: F401 (names of this path)

_LIB = None            # the loaded libraries and kernels, or the reason they are not available

#: a compiled system of at most this many unknowns keeps its native solvers for its next runs
#: (``ida._make_solver``; a few per system, by options: memory of the order of N^2 for the dense matrix)
NATIVE_KEEP_MAX = 400


class _Libraries:
    """SUNDIALS through ctypes, and the numba kernels."""

    def __init__(self):
        import sksundae
        t0 = time.perf_counter()
        from . import _native_kernels as K          # imports numba
        # numba's import and the kernels' load from its on-disk cache (their compilation the first time on a
        # machine): about 0.5-1 s, 6 s the first time; the run that pays it says so (``load_time``)
        self.load_s = time.perf_counter() - t0
        self.reported = False           # the call that loaded them has said so (``load_time``)
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
        self.band_data = sig(band.SUNBandMatrix_Data, vp, vp)
        self.band_ldata = sig(band.SUNBandMatrix_LData, idx, vp)
        self.band_ldim = sig(band.SUNBandMatrix_LDim, idx, vp)
        self.band_smu = sig(band.SUNBandMatrix_StoredUpperBandwidth, idx, vp)
        self.mat_free = sig(core.SUNMatDestroy, None, vp)
        self.ls_free = sig(core.SUNLinSolFree, i32, vp)
        self.create = sig(ida.IDACreate, vp, vp)
        self.init = sig(ida.IDAInit, i32, vp, vp, d, vp, vp)
        self.tolerances = sig(ida.IDASVtolerances, i32, vp, d, vp)
        self.set_ls = sig(ida.IDASetLinearSolver, i32, vp, vp, vp)
        self.set_jac = sig(ida.IDASetJacFn, i32, vp, vp)
        self.set_user_data = sig(ida.IDASetUserData, i32, vp, vp)
        self.set_id = sig(ida.IDASetId, i32, vp, vp)
        self.set_int = {n: sig(getattr(ida, n), i32, vp, i32) for n in
                        ("IDASetMaxNonlinIters", "IDASetMaxConvFails", "IDASetMaxOrd")}
        self.set_max_steps = sig(ida.IDASetMaxNumSteps, i32, vp, lng)
        self.set_real = {n: sig(getattr(ida, n), i32, vp, d) for n in
                         ("IDASetInitStep", "IDASetMinStep", "IDASetMaxStep")}
        self.root_init = sig(ida.IDARootInit, i32, vp, i32, vp)
        self.root_direction = sig(ida.IDASetRootDirection, i32, vp, vp)
        # the residual kernels read the monotonic clock for a run's wall-clock limit (``_native_kernels``)
        self.clock_address = ctypes.cast(ctypes.CDLL(None).clock_gettime, vp).value
        self.free = sig(ida.IDAFree, None, ctypes.POINTER(vp))
        # the addresses ``_native_kernels.segment`` calls (IDASolve, re-initialisation, tolerances, stop time, the
        # counters, the root information); it writes IDA's counters as 64-bit C longs
        if ctypes.sizeof(ctypes.c_long) != 8:
            raise OSError("a C long of another size than 8 bytes")
        self.segment_functions = np.array([ctypes.cast(getattr(ida, name), vp).value for name in K.SEGMENT_FUNCTIONS],
                                          np.int64)
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
            self.band_data_offset = self._band_data_offset(ctx)
        finally:
            self.ctx_free(ctypes.byref(ctx))

    def _band_data_offset(self, ctx):
        """The byte offset of a band SUNMatrix's data pointer in its content (``jacobian_band`` reads it there),
        found against the library's accessor; None when not found (band runs then take IDA's difference
        quotients, as before)."""
        m = self.band(5, 1, 1, ctx)
        if not m:
            return None
        try:
            content = ctypes.c_void_p.from_address(m).value
            data = self.band_data(m)
            for offset in range(8, 72, 8):
                if ctypes.c_void_p.from_address(content + offset).value == data:
                    return offset
            return None
        finally:
            self.mat_free(m)


def load_time() -> float:
    """The seconds the compiled kernels took to load in this process, the first time it is asked after they loaded
    (the run that paid them reports them: ``Stats.extra["native_load_s"]``), else 0."""
    lib = _LIB
    if isinstance(lib, _Libraries) and not lib.reported:
        lib.reported = True
        return lib.load_s
    return 0.0


def libraries():
    """The loaded libraries, or a string saying why the native path is not available."""
    global _LIB
    if _LIB is None:
        try:
            _LIB = _Libraries()
        except ImportError as exc:
            _LIB = f"numba is not installed ({exc}); pip install numba (a dependency of regmech)"
        except (OSError, AttributeError) as exc:
            _LIB = f"the SUNDIALS libraries of scikit-sundae could not be used directly ({exc})"
    return _LIB


def eligible(c, linsolver, deadline=None):
    """None when the native path can run compiled system ``c`` with ``linsolver``, else the reason. What the
    compiled system decides is kept with it (0.1 ms a run of CoupledClutches, three times per default call);
    a residual wrapped on it since (a work budget) is checked at every call."""
    kept = c.__dict__.setdefault("_native_eligible", {})
    if linsolver not in kept:
        kept[linsolver] = _eligible(c, linsolver)
    if kept[linsolver] is not None:
        return kept[linsolver]
    if "residual" in c.__dict__:
        return "the residual is wrapped on the compiled system (a work budget counts its calls in Python)"
    return None


def solver_path(c) -> str:
    """What ``m.check()`` says of the path ida's callbacks take for compiled system ``c``: compiled (every law,
    signal and event function in compiled code) or Python, with the device or input and the reason."""
    from .ida import choose_linsolver
    try:
        why = eligible(c, choose_linsolver(c)[0])
    except Exception as exc:        # noqa: BLE001 - a report line, never a failure of the check
        why = f"not judged ({type(exc).__name__}: {exc})"
    if why is None:
        return "ida with compiled callbacks (residual, Jacobian and events of every device in compiled code)"
    return f"ida with Python callbacks: {why}"


def _eligible(c, linsolver):
    """``eligible`` computed, but for a wrapped residual."""
    plan = c._plan
    if getattr(c, "dae_only", False) or getattr(c, "has_reads", False):
        return ("causal blocks or massless points (parameters read from the unknowns; algebraic, sampled or branch "
                "states; speeds of massless points)")
    if getattr(c, "n_surf", 0):
        nonlinear = {id(g) for g in plan.nonlinear}
        for g, _, _ in c.surface_groups:
            if id(g) not in nonlinear:
                dev = g.devices[0]
                return (f"{type(dev).__name__} '{dev.name}' has switching surfaces on a law that is affine "
                        f"between them (evaluated in Python)")
    if plan.offset_slots:
        return f"offsets not linear in their signals ({', '.join(g.tpl.cls.__name__ for g, _ in plan.offset_slots)})"
    if linsolver not in ("dense", "band"):
        return f"linear solver '{linsolver}' (the native path has dense and band)"
    lib = libraries()            # numba first: the signal table needs the kernels' constants
    if isinstance(lib, str):
        return lib
    from ..compile._native_signals import signal_table
    table = signal_table(plan, pooled=True)
    if isinstance(table, str):
        return table
    if plan.nonlinear:
        groups = group_tables(c)
        if isinstance(groups, str):
            return groups
    if c.mf:
        laws = friction_laws(c.friction)
        if isinstance(laws, str):
            return laws
    return None


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


def _band_storage(N, lband, uband):
    """``(s_mu, ldim)`` of SUNDIALS' band matrix of N unknowns with these bandwidths: the stored upper
    bandwidth (room for the LU's fill-in) and the column length (checked against the library's accessors
    when a solver is made)."""
    s_mu = min(N - 1, uband + lband)
    return s_mu, s_mu + lband + 1


def _band_places(c, order, lband, uband):
    """Where each constant Jacobian entry (``c.jac.rows[q]``, ``c.jac.cols[q]``, compiled order) sits in the band
    storage of the solver's ordering: column j (solver order) starts at ``j ldim``, row i lies ``i - j + s_mu``
    into it (SUNDIALS' ``SM_COLUMN_ELEMENT_B``). None when an entry lies outside the band (the bandwidths come
    from this pattern, ``ida._band_widths``, so it should not happen): the run then takes IDA's difference
    quotients, whose columns outside the band are simply not formed."""
    N = c.N
    inv = np.arange(N) if order.perm is None else np.asarray(order.inv, np.int64)
    i = inv[np.asarray(c.jac.rows, np.int64)]
    j = inv[np.asarray(c.jac.cols, np.int64)]
    if np.any(i - j > lband) or np.any(j - i > uband):
        return None
    s_mu, ldim = _band_storage(N, lband, uband)
    return j * ldim + (i - j + s_mu)


def _layout(c, linsolver, order, lband=0, uband=0):
    """The kernels' ``(idata, fdata)`` for compiled system ``c`` (``_native_kernels`` module docstring)."""
    import scipy.sparse as sp
    plan = c._plan
    N = c.N
    from ..compile._native_signals import signal_table
    kinds, slots, pars, pool = signal_table(plan, pooled=True)
    pars = np.array(pars)
    L = sp.csr_matrix(plan.L) if isinstance(plan.L, np.ndarray) else plan.L.tocsr(copy=True)
    L.sum_duplicates()
    perm = np.arange(N) if order.perm is None else np.asarray(order.perm, np.int64)
    jk = jc = jcj = np.zeros(0)
    band_ldata = 0
    if linsolver in ("dense", "band"):
        # constant iteration-matrix entries (an eligible model has no nonlinear weights); entry q of the Jacobian
        # data sits at (jac.rows[q], jac.cols[q]), each once: dense column-major, band in its storage
        jp = jacobian_plan(c)
        if linsolver == "dense":
            jk = np.asarray(c.jac.cols, np.int64) * N + np.asarray(c.jac.rows, np.int64)
        else:
            places = _band_places(c, order, lband, uband)
            if places is not None:        # else no closed-form Jacobian (band_ldata 0: ``NativeIDA`` checks it)
                jk = places
                band_ldata = N * _band_storage(N, lband, uband)[1]
        jc, jcj = np.asarray(jp.const, float), np.asarray(jp.cjv, float)
    parts_i = [L.indptr, L.indices, perm, kinds, slots, jk]
    offs_i, pos = [], 13
    for a in parts_i:
        offs_i.append(pos)
        pos += len(a)
    # header: sizes, offsets, the length, then the band Jacobian's storage length and data offset (set per solver)
    idata = np.concatenate([np.array([N, plan.width, len(kinds), len(jk)] + offs_i + [pos, band_ldata, 0],
                                     np.int64)] + [np.asarray(a, np.int64) for a in parts_i])
    buf = np.zeros(plan.width)
    buf[plan.one] = 1.0
    parts_f = [L.data, pars, buf, jc, jcj, pool]
    offs_f, pos = [], 7
    for a in parts_f:
        offs_f.append(pos)
        pos += len(a)
    _place_pool(pars, kinds, offs_f[5] - len(pars))
    # header: t_right, then the offsets of data, par, buf, jc, jcj, then the length (the tables' points last)
    fdata = np.concatenate([np.array([np.inf] + offs_f[:5] + [pos], float)] + [np.asarray(a, float) for a in parts_f])
    return idata, fdata


def jacobian_plan(c):
    """The compiled system's Jacobian plan (``compile.evaluation.JacobianPlan``), built without evaluating it."""
    from ..compile.evaluation import JacobianPlan
    jp = c.__dict__.get("_jac_plan")
    if jp is None or jp.jac is not c.jac:       # the pattern grows when friction rows are added
        jp = c._jac_plan = JacobianPlan(c.jac, c._plan, c.nw_kernel)
    return jp


def friction_jacobian(c, modes):
    """``(jc, jcj)``: the constant and the ``cj`` part of the Jacobian entries in ``modes`` apart from the
    nonlinear device classes' weights, which the kernels add at every call (a model whose friction laws are
    ``linear_law``s: the rest depends on the modes only), cached per mode set."""
    jp = jacobian_plan(c)
    kept = c.__dict__.get("_native_friction_jac")
    if kept is None or kept[0] is not jp:       # a grown pattern makes every cached entry the wrong length
        kept = c._native_friction_jac = (jp, {})
    cache = kept[1]
    key = np.asarray(modes, np.int64).tobytes()
    hit = cache.get(key)
    if hit is None:
        z = np.zeros(c.N)

        def entries(cj):
            out = jp.cjv * cj + jp.const
            if jp.n_extra:
                w = np.zeros(jp.width)
                w[jp.n_nonlinear:] = c.friction.weights(0.0, z[c._sv], cj, modes, z[c._slam], y=z)[:jp.n_extra]
                out = out + jp.W @ w
            return np.asarray(out, float)
        j0 = entries(0.0)
        hit = (j0, entries(1.0) - j0)
        if len(cache) > 256:
            cache.clear()
        cache[key] = hit
    return hit


def group_tables(c):
    """The kernels' tables ``(gi, gf)`` of the compiled system's nonlinear device classes (``_native_kernels._groups``),
    or a string naming the first device whose law or input the kernels cannot evaluate. Kept with the compiled
    system (for its Jacobian pattern)."""
    kept = c.__dict__.get("_native_groups")
    if kept is None or kept[0] is not c.jac:
        kept = c._native_groups = (c.jac, _group_tables(c))
    return kept[1]


def _group_tables(c):
    """``group_tables`` computed."""
    import scipy.sparse as sp
    from ..compile import codegen
    from ..compile._native_signals import N_PAR, SUPPORTED_POOLED, pooled_entries, signal_entry
    K = libraries().K
    plan, jp = c._plan, jacobian_plan(c)
    recs, entries, dest_rel, regions = [], [], [], []
    start = w_pos = s_pos = 0
    surf_at = {id(g): (first, active) for g, first, active in getattr(c, "surface_groups", ())}
    n_surf = int(getattr(c, "n_surf", 0))
    sidx_rel = np.zeros(n_surf, np.int64)
    for (g, r0, nb), (_, slot) in zip(plan.nl_args, plan.nl_out):
        dev = g.devices[0]
        what = f"{type(dev).__name__} '{dev.name}'"
        ker = codegen.class_kernels(g.tpl)
        if isinstance(ker, str):
            return f"{what}: {ker}"
        n, n_p = g.n, len(g.param_values)
        if ker.n_args != nb + n_p + len(g.signals):
            return f"{what}: its compiled law reads {ker.n_args} arguments, its devices give {nb + n_p + len(g.signals)}"
        for j, sigs in enumerate(g.signals):
            for i, sig in enumerate(sigs):
                entry = signal_entry(sig, pooled=True)
                if entry is None:
                    return (f"{type(g.devices[i]).__name__} '{g.devices[i].name}' has a {type(sig).__name__} "
                            f"input (the native path evaluates {', '.join(SUPPORTED_POOLED)})")
                entries.append(entry)
                dest_rel.append(start + (nb + n_p + j) * n + i)
        regions.append((g, r0, nb, start))
        surf, s_off = 0, 0
        if id(g) in surf_at:
            # surface k of the model is value (code i, instance active[a]) of the group's block: ``surface_values``
            first, active = surf_at[id(g)]
            inst = np.arange(n) if active is None else np.asarray(active, np.int64)
            codes = np.arange(ker.n_surf)
            sidx_rel[first: first + ker.n_surf * len(inst)] = s_pos + (codes[:, None] * n + inst[None, :]).ravel()
            surf, s_off = ker.surf, s_pos
            s_pos += ker.n_surf * n
        recs.append([n, ker.n_args, ker.res, ker.jac, start, slot, w_pos, ker.n_jac, surf, s_off])
        start += ker.n_args * n
        w_pos += ker.n_jac * n
    if w_pos != jp.n_nonlinear:
        return f"the nonlinear weights ({w_pos}) do not match the Jacobian's ({jp.n_nonlinear})"
    E = sp.csr_matrix(plan.E)
    E.sum_duplicates()
    W = sp.csr_matrix(np.zeros((c.jac.nnz, 0)) if jp.W is None else jp.W)[:, :jp.n_nonlinear].tocsr()
    W.sum_duplicates()
    kinds, gpar, pool = pooled_entries(entries, 0)
    args = np.zeros(start)
    for g, r0, nb, a0 in regions:
        for p, vals in enumerate(g.param_values):
            args[a0 + (nb + p) * g.n: a0 + (nb + p + 1) * g.n] = vals
    # gf: header, E data, e0, the groups' argument blocks, w, signal parameters, W data, the surfaces' values and
    # sides (``NativeIDA.set_segment`` writes these), the tables' points
    parts_f = [E.data, plan.e0, args, np.zeros(w_pos), gpar, W.data, np.zeros(s_pos), np.ones(n_surf), pool]
    offs_f, pos = [], K.GF_HEAD
    for a in parts_f:
        offs_f.append(pos)
        pos += len(a)
    _place_pool(gpar, kinds, offs_f[8] - len(gpar))
    a_start = offs_f[2]
    for rec in recs:
        rec[9] += offs_f[6]
    dest = np.zeros(E.shape[0], np.int64)
    for g, r0, nb, a0 in regions:
        dest[r0: r0 + nb * g.n] = a_start + a0 + np.arange(nb * g.n)
    for rec in recs:
        rec[4] += a_start
    fh = [offs_f[0], offs_f[1], offs_f[4], offs_f[5], offs_f[3], offs_f[7], pos]
    gf = np.concatenate([np.array(fh, float)] + [np.asarray(a, float) for a in parts_f])
    parts_i = [E.indptr, E.indices, dest, np.array(recs, np.int64).ravel(), kinds,
               np.asarray(dest_rel, np.int64) + a_start, W.indptr, W.indices, sidx_rel + offs_f[6]]
    offs_i, pos = [], K.GI_HEAD
    for a in parts_i:
        offs_i.append(pos)
        pos += len(a)
    head = [len(recs), E.shape[0], offs_i[0], offs_i[1], offs_i[2], offs_i[3], len(entries), offs_i[4], offs_i[5],
            w_pos, offs_i[6], offs_i[7], n_surf, offs_i[8], pos]
    gi = np.concatenate([np.array(head, np.int64)] + [np.asarray(a, np.int64) for a in parts_i])
    for a in (gi, gf):
        a.flags.writeable = False          # each solver works on its own copy of gf
    return gi, gf


class NativeIDA:
    """A drop-in for ``sksundae.ida.IDA`` on an eligible model (``eligible``): ``solve(tspan, y0, yp0)``, whose
    output rows come back in the compiled system's order (``_Result.unpermuted``).

    Built with the options ``ida._make_solver`` gives scikit-sundae (scikit-sundae's defaults for the
    rest: Newton at most 4 iterations, 10 convergence failures, IDA's own first step); the first
    ``solve`` initialises IDA, later ones re-initialise it (``IDAReInit``), as scikit-sundae does.
    """

    def __init__(self, c, rtol, atol, linsolver, order, max_step, max_order, max_steps, lband=0, uband=0,
                 deadline=None):
        lib = libraries()
        K = lib.K
        self.lib, self.K, self.c = lib, K, c
        N = c.N
        self.N = N
        key = (linsolver, None if order.perm is None else tuple(order.perm), int(lband), int(uband))
        self.pattern = c.jac        # the Jacobian pattern the slots below are laid out for
        kept = c.__dict__.get("_native_layouts")
        if kept is None or kept[0] is not c.jac:       # friction rows added at an event grow the pattern
            kept = c._native_layouts = (c.jac, {})
        layout = kept[1].get(key)
        if layout is None:
            layout = kept[1][key] = _layout(c, linsolver, order, int(lband), int(uband))
        self.idata, self.fdata = layout[0].copy(), layout[1].copy()      # the kernels write into fdata
        self.friction = None
        # the wall-clock limit (deadline in ns of time.monotonic, 0: none), the flag the residual sets past it, and
        # clock_gettime's scratch
        self.ctl = np.zeros(4, np.int64)
        self.deadline = deadline
        if deadline is not None:
            self.ctl[0] = max(1, int(deadline.at * 1e9))
        hi_ptr = hf_ptr = 0
        if c.mf:
            self.friction = FrictionTables(c, order, friction_laws(c.friction))
            hi_ptr, hf_ptr = self.friction.hi.ctypes.data, self.friction.hf.ctypes.data
        gi_ptr = gf_ptr = 0
        if c._plan.nonlinear:
            gi, gf = group_tables(c)
            self.gi, self.gf = gi, gf.copy()          # the kernels write the arguments and weights into gf
            gi_ptr, gf_ptr = self.gi.ctypes.data, self.gf.ctypes.data
        self.user = np.array([self.idata.ctypes.data, self.fdata.ctypes.data, hi_ptr, hf_ptr, self.ctl.ctypes.data,
                              lib.clock_address, gi_ptr, gf_ptr], np.int64)
        # the event functions: the friction devices' two each, then the switching surfaces (``hybrid.surfaces``)
        self.n_events = 2 * c.mf + int(getattr(c, "n_surf", 0))
        if self.n_events:
            self._rootdir = np.full(self.n_events, -1, np.int32)
            self.rootsfound = np.zeros(self.n_events, np.int32)
        if getattr(c, "n_surf", 0):
            self._sides = slice(int(self.gf[5]), int(self.gf[5]) + c.n_surf)
        if c.mf:
            hdr = self.fdata[:7]
            self._jc = slice(int(hdr[4]), int(hdr[5]))
            # the cj part is as long as the constant part (the tables' pooled points follow it)
            self._jcj = slice(int(hdr[5]), 2 * int(hdr[5]) - int(hdr[4]))
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
        # the band Jacobian in closed form (``jacobian_band``) where the storage is as ``_band_places`` placed it;
        # else IDA's difference quotients, lband + uband + 1 residuals per Jacobian (a sixth of the residuals of
        # a run on the benchmark chains)
        self._jac = K.jacobian_dense if linsolver == "dense" else None
        if linsolver == "band" and A and lib.band_data_offset is not None and \
                (lib.band_smu(A), lib.band_ldim(A)) == _band_storage(N, int(lband), int(uband)) and \
                lib.band_ldata(A) == self.idata[11]:
            self.idata[12] = lib.band_data_offset
            self._jac = K.jacobian_band
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
        self._counts = np.zeros(3, np.int64)       # IDA's residuals, Jacobians and steps (``segment`` writes them)
        self._roots = self.rootsfound if self.n_events else np.zeros(1, np.int32)
        self._new_tolerances = False
        self._atol = np.ctypeslib.as_array(ctypes.cast(lib.nv_ptr(at), ctypes.POINTER(ctypes.c_double)), (N,))

    def start_run(self, deadline):
        """Serve another run of the same compiled system (kept by ``ida._make_solver``): its wall-clock limit."""
        self.deadline = deadline
        self.ctl[:] = 0
        if deadline is not None:
            self.ctl[0] = max(1, int(deadline.at * 1e9))
        self.regmech_attempts[1] = 0

    def set_segment(self, modes, atol):
        """Prepare the next ``solve`` for a segment in ``modes`` with absolute tolerances ``atol`` (solver order):
        the friction rows' modes and event functions (from the friction set's state after ``settle``) and the
        Jacobian's constants of the mode set."""
        self._atol[:] = atol
        self._new_tolerances = True
        if self.n_events > 2 * self.c.mf:
            self.gf[self._sides] = self.c.surfaces.sides       # the side each surface starts the segment on
        if self.friction is None:
            return
        fr = self.c.friction
        self.friction.set_segment(modes, fr.engaged, fr._relief)
        if self._jac is not None:
            jc, jcj = friction_jacobian(self.c, modes)
            self.fdata[self._jc] = jc
            self.fdata[self._jcj] = jcj

    def _setup(self, t0):
        lib, K = self.lib, self.K
        rtol, linsolver, A, LS, max_step, max_order, max_steps = self._opts
        mem = self.mem
        res = K.residual if self.friction is None else K.residual_friction
        flags = [lib.set_user_data(mem, self.user.ctypes.data),
                 lib.init(mem, res.address, t0, self.yy, self.yp),
                 lib.tolerances(mem, rtol, self._at),
                 lib.set_ls(mem, LS, A)]
        if self._jac is not None:
            flags.append(lib.set_jac(mem, self._jac.address))
        flags += [lib.set_int["IDASetMaxNonlinIters"](mem, 4), lib.set_int["IDASetMaxConvFails"](mem, 10),
                  lib.set_id(mem, self._id), lib.set_real["IDASetInitStep"](mem, 0.0),
                  lib.set_real["IDASetMinStep"](mem, 0.0),
                  lib.set_real["IDASetMaxStep"](mem, float(max_step) if max_step else 0.0),
                  lib.set_int["IDASetMaxOrd"](mem, max_order), lib.set_max_steps(mem, max_steps)]
        if self.n_events:
            # every event terminal, each crossing downwards (``hybrid.events``), as the usual path asks of IDA
            flags += [lib.root_init(mem, self.n_events, K.events.address),
                      lib.root_direction(mem, self._rootdir.ctypes.data)]
        if any(f < 0 for f in flags):
            raise RuntimeError(f"setting up the native IDA solver failed (flags {flags})")
        self._initialised = True

    def solve(self, tspan, y0, yp0):
        tspan = np.ascontiguousarray(tspan, float)
        self.fdata[0] = self.c._t_right
        self.ya[:] = y0
        self.ypa[:] = yp0
        reinit = self._initialised
        if not reinit:
            self._setup(float(tspan[0]))
        new_tol = reinit and self._new_tolerances
        self._new_tolerances = False
        n = len(tspan)
        T = np.empty(n)
        Y = np.empty((n, self.N))
        YP = np.empty((n, self.N))
        T[0] = tspan[0]
        Y[0, self.perm], YP[0, self.perm] = self.ya, self.ypa
        # re-initialisation, tolerances, stop time, the output loop and IDA's counters in one compiled call
        rows, flag = self.K.segment(self.lib.segment_functions, self.mem, reinit, new_tol, self._opts[0], self._at,
                                    tspan, self.tret, self.yy, self.yp, self.ya_address, self.ypa_address,
                                    self.perm, T, Y, YP, self._counts, self._roots)
        if flag <= -1000:
            raise RuntimeError(f"{self.K.SEGMENT_FUNCTIONS[-1000 - flag]} failed")
        if self.ctl[1]:
            # the residual stopped IDA at the run's wall-clock limit
            raise self.deadline.error(float(T[rows - 1]))
        nf, nj, ns = self._counts.tolist()
        self.regmech_attempts[1] += ns
        out = _Result(T[:rows], Y[:rows], YP[:rows], flag, nf, nj, unpermuted=True)
        if flag == 2:            # a root: the last row is the state there (scikit-sundae's event arrays)
            out.i_events = self._roots.copy()[None, :]
            out.t_events = T[rows - 1:rows].copy()
            out.y_events, out.yp_events = Y[rows - 1:rows].copy(), YP[rows - 1:rows].copy()
        return out
