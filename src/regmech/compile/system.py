"""The compiled system: an index-1 DAE ``F(t, y, y') = 0`` for IDA, its
sparse Jacobian, consistent initial values, the ODE form for explicit
solvers, and every named output.

Unknowns ``y = [x, v, a_d, lam, z]`` (interleaved x_k, v_k per coordinate):
positions and velocities of all coordinates, the accelerations of the dummy
coordinates ``D_v`` (for the others ``a_k = v_k'``), the constraint forces
``lam`` (rigid rows, Position, Speed, friction) and device internal states.

Residual rows (``M`` diagonal masses, ``S`` compliant rows, ``G`` constraints):

    x_k' - v_k                          k not in D_x   (differential)
    G_p x + e0_p - g_p(t)                              (position constraints)
    G_p v - g_p'(t);  G_v v - g_v(t)                   (their derivatives / speed rows)
    M a + S^T tau(e, e', z, t) + G^T lam               (motion, n rows)
    G_p a - g_p''(t); G_v a - g_v'(t)                  (acceleration level)
    friction rows by mode (see ``compile.friction_rows``)
    z' - h(e, e', z, t)                                (device states)

with ``e = S x + e0``. This is the dummy-derivative form: the position
constraints appear at all three levels and D_x/D_v make it square.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import RegularityWarning, SimulationError, StructureError
from ..structure.system import (START_RTOL, MechanicalStructure, build_structure, constraint_start_conflict,
                                gc_paused)
from . import kkt, massless, reads
from .assembly import PatternBuilder, kernel_terms
from .evaluation import EvaluationPlan, JacobianPlan
from .friction_rows import FrictionRows
from .kernels import KernelGroup, template_for

#: the acceleration-level (KKT) system counts as singular when its smallest LU pivot is below this fraction
#: of the largest; a mass this many times lighter than another on its own coordinate trips it too
PIVOT_TOL = 1e-13
#: constraint blocks of the ODE form's lift up to this many entries are used dense (``_dummy_solve``,
#: ``_independent_blocks``), by the inverse when its condition number is below DENSE_LIFT_COND (the product then
#: loses at most some 1e-10 relative to the LU solve; gear and lever blocks are of condition 1 to 1e3)
DENSE_LIFT = 4096
DENSE_LIFT_COND = 1e6


class CompiledSystem:
    def __init__(self, st: MechanicalStructure):
        self.structure = st
        self.model = st.model
        n = st.n
        self.n = n
        self.mass = st.mass
        self.Sc = st.matrix(st.compliant).tocsr()
        self.ScT = self.Sc.T.tocsr()
        self.e0c = st.offsets(st.compliant)
        self.Gp = st.matrix(st.position).tocsr()
        self.e0p = st.offsets(st.position)
        self.Gv = st.matrix(st.speed).tocsr()
        self.Gpv = sp.vstack([self.Gp, self.Gv]).tocsr()
        self.Gf = st.matrix(st.friction).tocsr()
        self.Gall = sp.vstack([self.Gp, self.Gv, self.Gf]).tocsr()
        self.GallT = self.Gall.T.tocsr()
        self.mp, self.mv, self.mf = self.Gp.shape[0], self.Gv.shape[0], self.Gf.shape[0]
        self.m = self.mp + self.mv + self.mf
        self.Dx, self.Dv = st.dummy_x, st.dummy_v
        self.Kx = np.setdiff1d(np.arange(n), self.Dx)      # coordinates with differential x
        self.Kv = np.setdiff1d(np.arange(n), self.Dv)      # coordinates with differential v
        self._t_right = np.inf
        self._build_kernels()
        reads.attach(self)
        self._build_layout()
        self._build_references()
        self._build_jacobian()
        self._kkt_cache: dict = {}
        self._hold_cache: dict = {}
        self.friction = None
        self.nw_friction = 0
        if st.friction:
            # the rows' equations in their current modes; regmech.hybrid.attach adds the mode logic
            self.friction = FrictionRows(self, st.friction)
            self.nw_friction = self.friction.add_pattern(self._pb, self.nw_kernel)
            self.jac = self._pb.build()
        self.modes0 = self.friction.initial_modes() if self.friction else np.zeros(0, int)
        massless.check(self)

    # -------------------------------------------------------------- pickling
    #: caches that hold SuperLU factorisations (not picklable), plans derived from them, maps keyed by
    #: ``id()`` of the structure's rows (``_output_maps``: other objects after unpickling), or the native
    #: path's tables, which hold the addresses of compiled kernels in this process (``_native_groups``) and
    #: slots laid out for them; rebuilt on use
    _UNPICKLED = ("_kkt_cache", "_dummy_lu", "_jac_plan", "_ode_form", "_native_solvers", "_reference_noise",
                  "_output_maps", "_native_groups", "_native_layouts", "_native_friction_jac", "_native_eligible")

    def __getstate__(self):
        """Everything but the factorisation caches (``KernelGroup`` leaves out its lambdified template)."""
        state = {k: v for k, v in self.__dict__.items() if k not in self._UNPICKLED}
        state["_kkt_cache"] = {}
        return state

    # ------------------------------------------------------------------ build
    def _build_kernels(self):
        st = self.structure
        row_of = {id(r): i for i, r in enumerate(st.compliant)}
        by_tpl: dict = {}
        for dev in st.devices:
            if dev.device_kind() != "compliant":
                continue
            tpl = template_for(dev)
            by_tpl.setdefault(id(tpl), (tpl, []))[1].append(dev)
        self.groups: list[KernelGroup] = []
        nz = 0
        self.state_names: list[str] = []
        self.state_start: list[float] = []
        #: per state the datum its entry of ``z`` departs from (``FrictionDevice.friction_state_datum``): the
        #: state's value is ``z + state_datum``; 0 but for a thermal mass's temperature
        self.state_datum: list[float] = []
        for tpl, devs in by_tpl.values():
            rows = np.array([[row_of[id(r)] for r in st.rows[d.name]] for d in devs], dtype=int).reshape(len(devs), tpl.k)
            ns = len(tpl.states)
            sidx = (nz + np.arange(len(devs) * ns)).reshape(len(devs), ns) if ns else np.zeros((len(devs), 0), int)
            for d in devs:
                for s, start_param in type(d).states.items():
                    self.state_names.append(f"{d.name}.{s}")
                    val = d._values.get(start_param) if start_param else None
                    self.state_start.append(0.0 if val is None else float(val))
                    self.state_datum.append(0.0)
            nz += len(devs) * ns
            self.groups.append(KernelGroup(tpl, devs, rows, sidx))
        # friction devices' own states (a thermal mass's temperature): after the kernels' states, their
        # rates stated by the device and evaluated with the friction rows (they read its friction force)
        self._fstate_z: list[dict] = []
        for row in st.friction:
            d = row.device
            own = {}
            datum = d.friction_state_datum() if hasattr(d, "friction_state_datum") else {}
            for s, start in (d.friction_states() if hasattr(d, "friction_states") else {}).items():
                own[s] = nz
                self.state_names.append(f"{d.name}.{s}")
                self.state_datum.append(float(datum.get(s, 0.0)))
                self.state_start.append(float(start) - self.state_datum[-1])
                nz += 1
            self._fstate_z.append(own)
        self.nz = nz
        self.state_start = np.array(self.state_start, float)
        self.state_datum = np.array(self.state_datum, float)
        # switching surfaces of piecewise laws (``Device.switching_surfaces``): surface k of instance i of a
        # group is entry ``start + k * n + i``; ``surface_owner`` names its device and state code
        self.surface_groups = []
        self.surface_owner: list[tuple[str, int]] = []
        #: device name -> the ``Event`` kind of its surfaces' changes (``Device.switching_kind``)
        self.surface_kinds: dict[str, str] = {}
        for g in self.groups:
            if g.tpl.surf_fn is None:
                continue
            active = np.array([i for i, d in enumerate(g.devices) if d.switching_active()], dtype=int)
            if not len(active):
                continue
            self.surface_groups.append((g, len(self.surface_owner), None if len(active) == g.n else active))
            self.surface_owner += [(g.devices[i].name, code) for code in g.tpl.surf_codes for i in active]
            self.surface_kinds.update((g.devices[i].name, g.devices[i].switching_kind) for i in active)
        self.n_surf = len(self.surface_owner)

    def _build_layout(self):
        n, nd, m, nz = self.n, len(self.Dv), self.m, self.nz
        self.ix = 2 * np.arange(n)
        self.iv = 2 * np.arange(n) + 1
        self.iad = 2 * n + np.arange(nd)
        self.ilam = 2 * n + nd + np.arange(m)
        self.iz = 2 * n + nd + m + np.arange(nz)
        self.N = 2 * n + nd + m + nz
        # the same index sets as slices: views instead of gathers in the hot path
        self._sx, self._sv = slice(0, 2 * n, 2), slice(1, 2 * n, 2)
        self._sad = slice(2 * n, 2 * n + nd)
        self._slam = slice(2 * n + nd, 2 * n + nd + m)
        self._sz = slice(2 * n + nd + m, self.N)
        # residual slots
        self.r_kin = self.ix[self.Kx]
        self.r_pos = self.ix[self.Dx]          # mp rows (len(Dx) == mp)
        self.r_vel = self.iad                  # mp + mv rows (len(Dv))
        self.r_mot = self.iv
        self.r_acc = self.ilam[: self.mp + self.mv]
        self.r_fric = self.ilam[self.mp + self.mv:]
        self.r_z = self.iz
        self.is_dummy_v = np.zeros(n, bool)
        self.is_dummy_v[self.Dv] = True
        massless.attach(self)           # massless coordinates of first-order nodes: their speeds are algebraic
        self.dae_only = self.dae_only or bool(len(self.massless))
        alg = np.concatenate([self.ix[self.Dx], self.iv[self.Dv], self.iad, self.ilam,
                              self.iz[reads.algebraic_rows(self)], self.iv[self.massless]])
        self.algebraic = np.sort(alg).astype(int)
        self.pos_in_Dv = np.full(n, -1)
        self.pos_in_Dv[self.Dv] = np.arange(len(self.Dv))

    def _build_references(self):
        st = self.structure
        self._pos_sig = [(j, r.device._values[r.device.ref_param]) for j, r in enumerate(st.position)
                         if r.device.device_kind() == "position"]
        self._spd_sig = [(j, r.device._values[r.device.ref_param]) for j, r in enumerate(st.speed)]

    def _refs(self, t):
        """g_p, g_p', g_p'' (mp) and g_v, g_v' (mv) at t."""
        if not self._pos_sig and not self._spd_sig:        # no motion source: the references are all zero
            zeros = self.__dict__.get("_zero_refs")
            if zeros is None:
                zeros = self._zero_refs = (np.zeros((3, self.mp)), np.zeros((2, self.mv)))
                for z in zeros:
                    z.flags.writeable = False
            return zeros
        left = t >= self._t_right
        gp = np.zeros((3, self.mp))
        for j, s in self._pos_sig:
            gp[0, j] = s.value(t, left)
            gp[1, j] = s.derivative(t, 1, left)
            gp[2, j] = s.derivative(t, 2, left)
        gv = np.zeros((2, self.mv))
        for j, s in self._spd_sig:
            gv[0, j] = s.value(t, left)
            gv[1, j] = s.derivative(t, 1, left)
        return gp, gv

    def _build_jacobian(self):
        """Pattern of ``dF/dy + cj dF/dy'`` and the evaluation plans (``compile.evaluation``).

        The constant coefficients of the residual are listed once (``terms``)
        and feed both the Jacobian pattern and the residual matrix; the device
        kernels' terms come from ``assembly.kernel_terms`` (vectorised over instances).
        """
        ones = np.ones
        Gp, Gpv, GT = self.Gp.tocoo(), self.Gpv.tocoo(), self.Gall.tocoo()
        dmask = self.is_dummy_v[Gpv.col]
        zalg = reads.algebraic_rows(self)
        # (residual rows, y columns, coefficients, coefficient of y' rather than y)
        terms = [
            (self.r_kin, self.ix[self.Kx], ones(len(self.Kx)), True),              # x' - v
            (self.r_kin, self.iv[self.Kx], -ones(len(self.Kx)), False),
            (self.r_pos[Gp.row], self.ix[Gp.col], Gp.data, False),                 # G_p x
            (self.r_vel[Gpv.row], self.iv[Gpv.col], Gpv.data, False),              # G_pv v
            (self.r_mot[self.Kv], self.iv[self.Kv], self.mass[self.Kv], True),     # M a
            (self.r_mot[self.Dv], self.iad, self.mass[self.Dv], False),
            (self.r_mot[GT.col], self.ilam[GT.row], GT.data, False),               # G^T lam
            (self.r_acc[Gpv.row[~dmask]], self.iv[Gpv.col[~dmask]], Gpv.data[~dmask], True),   # G_pv a
            (self.r_acc[Gpv.row[dmask]], self.iad[self.pos_in_Dv[Gpv.col[dmask]]], Gpv.data[dmask], False),
            (self.r_z[~zalg], self.iz[~zalg], ones(self.nz - int(zalg.sum())), True),  # z' (differential states)
        ]
        pb = PatternBuilder(self.N)
        for rows, cols, vals, on_yp in terms:
            (pb.cj if on_yp else pb.const)(rows, cols, vals)
        # kernel Jacobians: weights of group g, entry q, instance i at woff_g + q * n_g + i
        self._wslices = []
        woff = 0
        for g in self.groups:
            self._wslices.append((woff, len(g.tpl.jac_entries)))
            woff += len(g.tpl.jac_entries) * g.n
        self.nw_kernel = woff
        kt = kernel_terms(self)
        pb.weighted(kt.row, kt.col, kt.coef, kt.widx)
        self._pb = pb
        self.jac = pb.build()
        self._plan = EvaluationPlan(self, terms, kt)

    # --------------------------------------------------------------- evaluate
    def unpack(self, y, yp):
        x = y[self._sx].copy()
        v = y[self._sv].copy()
        a = yp[self._sv].copy()
        a[self.Dv] = y[self._sad]
        return x, v, a, y[self._slam].copy(), y[self._sz].copy()

    def kernel_outputs(self, x, v, z, t):
        """e, de (compliant rows), tau, dz and the kernel Jacobian weights at (x, v, z, t).

        Affine devices come from constant matrices (``EvaluationPlan.device_outputs``),
        nonlinear classes from their kernels; weights of affine classes are constants.
        """
        e = self.Sc @ x + self.e0c
        de = self.Sc @ v
        left = t >= self._t_right
        plan = self._plan
        out = plan.device_outputs(x, v, z, t, left, self._sx, self._sv, self._sz)
        tau, dz = out[:plan.n_c], out[plan.n_c:]
        weights = plan.const_weights.copy()
        if plan.nonlinear:
            w = np.empty(len(weights) - int(plan.weight_is_const.sum()))
            plan.nonlinear_weights_into(w, t, plan.ybuf, left)      # ybuf holds (x, v, z) now
            weights[~plan.weight_is_const] = w
        return e, de, tau, dz, weights

    def surface_values(self, t, y):
        """The ``n_surf`` switching surfaces at ``(t, y)`` (order of ``surface_owner``); the hybrid layer
        turns them into event functions."""
        x, v, z = y[self._sx], y[self._sv], y[self._sz]
        e = self.Sc @ x + self.e0c
        de = self.Sc @ v
        left = t >= self._t_right
        out = np.empty(self.n_surf)
        for g, start, active in self.surface_groups:
            vals = g.surfaces(e, de, z, t, left)
            if active is not None:
                vals = vals[:, active]
            out[start:start + vals.size] = vals.ravel()
        return out

    def residual(self, t, y, yp, res, modes=None):
        """``F(t, y, y')`` into ``res`` (see the module docstring; one matrix product, ``compile.evaluation``)."""
        self._plan.residual(t, y, yp, t >= self._t_right, res)
        if self.mf:
            # the friction rows read v, a and lam only: views where ``unpack`` would copy all five
            a = yp[self._sv].copy()
            a[self.Dv] = y[self._sad]
            fr = self.friction
            q = fr.q_all(t, y) if fr.has_inputs else None
            res[self.r_fric] = fr.residual_rows(t, y[self._sv], a, y[self._slam], modes, q)
            if fr.state_rows:
                # z' - h: the plan wrote z' (these states have no kernel); subtract the device's rates
                zi, rates = fr.state_rates(t, y[self._sv], y[self._slam], q, modes)
                res[self.r_z[zi]] -= rates

    def jacobian_data(self, t, y, yp, cj, modes=None):
        """CSC values of ``dF/dy + cj dF/dy'`` on ``self.jac.pattern``."""
        plan = self.__dict__.get("_jac_plan")
        if plan is None or plan.jac is not self.jac:      # the pattern grows when friction rows are added
            plan = self._jac_plan = JacobianPlan(self.jac, self._plan, self.nw_kernel)
        extra = self.friction.weights(t, y[self._sv], cj, modes, y[self._slam], y=y) if self.mf else None
        if extra is not None:
            extra = extra[: plan.n_extra]        # trailing weights without pattern entries (no coupled rows)
        return plan.data(t, y, cj, t >= self._t_right, extra)

    # ----------------------------------------------------- consistent values
    def _kkt(self, modes, relations):
        """LU of the acceleration-level system for a mode set (``compile.kkt``), cached per mode set."""
        key = (np.asarray(modes, np.int64).tobytes(), relations) if self.mf else ()
        hit = self._kkt_cache.get(key)
        if hit is not None:
            return hit
        lu = kkt.factorise(self, modes, relations, PIVOT_TOL)
        if lu is None:
            msg = self.mass_spread_message()
            if msg is None:
                msg = self.friction.singular_message(modes) if self.mf else \
                    "the mass matrix restricted to the constraints is singular"
            raise StructureError(msg)
        if len(self._kkt_cache) > 256:      # speed-dependent loss tables give many keys
            self._kkt_cache.clear()
        self._kkt_cache[key] = lu
        return lu

    def mass_spread_message(self) -> str | None:
        """Why the acceleration-level system failed when a mass on its own coordinate is more than
        ``1 / PIVOT_TOL`` times lighter than the heaviest (None when the spread is within that): the solve
        of the motion equations then has pivots below ``PIVOT_TOL`` of the largest and the light mass's
        acceleration is lost (``J = 1e-300`` beside ``J = 1``)."""
        nodes = self.structure.coord_node
        massive = np.nonzero(self.mass > 0)[0]
        if massive.size < 2:
            return None
        light = int(massive[np.argmin(self.mass[massive])])
        heavy = int(massive[np.argmax(self.mass[massive])])
        ratio = self.mass[heavy] / self.mass[light]
        if ratio * PIVOT_TOL < 1.0:
            return None

        def label(k):
            body = max(nodes[k].bodies, key=lambda b: b.mass)
            unit = getattr(getattr(type(body), body.mass_param, None), "unit", "")
            return (f"{type(body).__name__} '{body.name}' ({body.mass_param} = {body.mass:.3g}"
                    f"{' ' + unit if unit else ''})")
        name = max(nodes[light].bodies, key=lambda b: b.mass).name
        return (f"the motion equations cannot be solved in double precision: {label(light)} is {ratio:.3g} "
                f"times lighter than {label(heavy)}, beyond the {1 / PIVOT_TOL:.0e} that the solve of the "
                f"accelerations resolves (its acceleration would be lost to round-off). Give '{name}' a "
                f"realistic value, join it rigidly to a neighbour (Shaft(stiffness=None), IdealGear: the masses "
                f"then add up), or ground the heavy one (a Fixed, or rm.Scene(..., heavy_ratio=...)).")

    def accelerations(self, t, x, v, z, modes):
        """Solve the motion and acceleration-level equations for (a, lam, dz)."""
        plan = self._plan       # the device outputs only (``kernel_outputs`` adds e, e' and Jacobian weights)
        out = plan.device_outputs(x, v, z, t, t >= self._t_right, self._sx, self._sv, self._sz)
        tau, dz = out[:plan.n_c], out[plan.n_c:]
        gp, gv = self._refs(t)
        ScT = self.__dict__.get("_ScT_fast")
        if ScT is None:
            # a small model's dense copy: scipy's sparse product costs some 10 us of dispatch per call, and the
            # mode logic solves this system several times at every event
            ScT = self._ScT_fast = (self.ScT.toarray() if self.ScT.shape[0] * self.ScT.shape[1] <= 4096
                                    else self.ScT)
        parts = [-(ScT @ tau), gp[2], gv[1]]
        relations = ()
        q = None
        if self.mf:
            fr = self.friction
            if fr.has_inputs:
                q = fr.q_all(t, plan.ybuf)      # device_outputs left (x, v, z) in the plan's buffer
            relations, rhs_f = fr.relations(t, v, modes, q)
            parts.append(rhs_f)
        rhs = np.concatenate(parts)
        if not len(rhs):
            return np.zeros(0), np.zeros(0), dz
        sol = self._kkt(modes, relations).solve(rhs)
        if len(self.massless):
            sol[self.massless] = 0.0        # no acceleration of their own (``compile.massless``)
        if self.mf and self.friction.state_rows:
            # friction devices' own states read their friction force: known after the solve
            zi, rates = self.friction.state_rates(t, v, sol[self.n:], q, modes)
            dz = dz.copy()
            dz[zi] = rates
        return sol[: self.n], sol[self.n:], dz

    def project(self, t, x_guess, v_guess, fixed_x=None, fixed_v=None, modes=None, starts=()):
        """Closest consistent (x, v) to the guesses: position and velocity
        constraints hold exactly; entries of ``fixed_*`` (non-NaN) are kept.
        Corrections are mass-weighted (an impulse for velocities).

        ``starts``: the levels (0 positions, 1 speeds) at which the devices' fixed start values of their
        own coordinates (``phi_rel_start``, ``w_rel_start``: ``structure.start_relations``) are equations
        too (the start of a run; not a state taken from a run).

        Fixed values that the constraints (rigid devices, gears, motion sources
        at ``t``, stuck friction rows, devices' start values) cannot meet raise ``StructureError``
        naming the masses and devices of each conflicting group."""
        gp, gv = self._refs(t)
        rel = [self.structure.start_relations[k] if k in starts else () for k in (0, 1)]
        G, rhs = [self.Gp], [gp[0] - self.e0p]
        if rel[0]:
            R, r = self._relation_rows(rel[0], 0)
            G.append(R)
            rhs.append(r)
        x = self._project_level(sp.vstack(G).tocsr() if rel[0] else self.Gp, np.concatenate(rhs), x_guess,
                                fixed_x, 0, t, lambda: self._constraint_labels(0, gp, gv, (), rel[0]))
        G = [self.Gpv]
        rhs = [np.concatenate([gp[1], gv[0]])]
        stuck = ()
        if self.mf and modes is not None:
            stuck = np.nonzero(np.asarray(modes) == 0)[0]
            G.append(self.Gf[stuck])
            rhs.append(np.zeros(len(stuck)))
        if rel[1]:
            R, r = self._relation_rows(rel[1], 1)
            G.append(R)
            rhs.append(r)
        v = self._project_level(sp.vstack(G).tocsr(), np.concatenate(rhs), v_guess, fixed_v, 1, t,
                                lambda: self._constraint_labels(1, gp, gv, stuck, rel[1]))
        return x, v

    def _relation_rows(self, relations, level):
        """``(R, r)``: the devices' start values as rows ``R x = r`` (positions: ``value - offset``, the ground's
        share of the row moved to the right; speeds: ``value``)."""
        data, cols, ptr, r = [], [], [0], []
        for rel in relations:
            data.extend(rel.row.coefs)
            cols.extend(rel.row.cols)
            ptr.append(len(cols))
            r.append(rel.value - (rel.row.offset if level == 0 else 0.0))
        R = sp.csr_matrix((np.asarray(data, float), np.asarray(cols, np.int64), np.asarray(ptr, np.int64)),
                          shape=(len(relations), self.n))
        return R, np.asarray(r, float)

    def _constraint_labels(self, level, gp, gv, stuck, relations=()):
        """The ``Row`` of each constraint row at ``level`` (0: G_p; 1: G_p, G_v, stuck friction
        rows; then the devices' start ``relations``), for source rows what the source prescribes, and
        the start relations by row (for error messages only)."""
        st = self.structure
        if level == 0:
            rows = list(st.position)
            refs = {j: f"{r.device.ref_param}={gp[0, j]:.10g}" for j, r in enumerate(st.position)
                    if r.device.device_kind() == "position"}
        else:
            refs = {j: f"d/dt {r.device.ref_param}={gp[1, j]:.10g}" for j, r in enumerate(st.position)
                    if r.device.device_kind() == "position"}
            refs.update({self.mp + j: f"{r.device.ref_param}={gv[0, j]:.10g}" for j, r in enumerate(st.speed)})
            rows = st.position + st.speed + [st.friction[j] for j in stuck]
        by_row = {len(rows) + k: rel for k, rel in enumerate(relations)}
        return rows + [rel.row for rel in relations], refs, by_row

    def _project_level(self, G, g, guess, fixed, level, t, describe):
        """``G x = g`` with the fixed entries kept and the least mass-weighted change of the others.

        The correction of the free coordinates ``F`` is ``dx = M_F^-1 G_F^T y`` with
        ``(G_F M_F^-1 G_F^T) y = r`` (a sparse direct solve, linear in the size of a chain;
        an iterative least-squares solve needed ~n iterations on an n-link rigid chain).
        When that matrix is singular (fixed values on several masses of a group) the
        least-squares solution is taken, and rows still unmet beyond ``START_RTOL`` of
        their own scale are conflicts (``describe()`` gives their rows and labels).
        """
        guess = np.array(guess, float)
        fixed = np.full(self.n, np.nan) if fixed is None else np.asarray(fixed, float)
        fmask = np.isfinite(fixed)
        guess[fmask] = fixed[fmask]
        if G.shape[0] == 0:
            return guess
        absG = abs(G)

        def unmet(x):
            scale = np.maximum(1.0, np.maximum(np.abs(g), absG @ np.abs(x)))
            return np.abs(g - G @ x) > START_RTOL * scale

        r = g - G @ guess
        if not np.any(r):
            return guess
        free = np.nonzero(~fmask)[0]
        out = guess.copy()
        if free.size:
            Gf = G[:, free].tocsr()
            inv_m = 1.0 / np.maximum(self.mass[free], 1e-300 + 1e-12 * self.mass.max(initial=1.0))
            active = np.nonzero(np.diff(Gf.indptr))[0]            # rows with a free coordinate
            dx = self._min_correction(Gf[active], inv_m, r[active])
            out[free] += dx
        bad = np.nonzero(unmet(out))[0]
        if bad.size:
            rows, refs, relations = describe()
            kept = np.where(fmask, fixed, np.nan)
            raise constraint_start_conflict(self.structure, level, G, rows, bad, kept, refs, t, relations)
        return out

    @staticmethod
    def _min_correction(A, inv_m, r):
        """Least mass-weighted ``dx`` with ``A dx = r`` (least squares when inconsistent).

        Direct: ``dx = M^-1 A^T y``, ``(A M^-1 A^T) y = r`` by sparse LU with one step of
        iterative refinement (on a 10,000-link chain the plain solve leaves 1e-12 of r,
        the refined one round-off). A singular or unusable solve (fixed values that
        over-determine a group) falls back to least squares; the caller judges the rows.
        """
        if A.shape[0] == 0:
            return np.zeros(A.shape[1])
        absA = abs(A)

        def misfit(dx):
            scale = np.maximum(1.0, np.abs(r) + absA @ np.abs(dx))
            return float(np.max(np.abs(A @ dx - r) / scale))

        S = (A @ sp.diags(inv_m) @ A.T).tocsc()
        dx = None
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", spla.MatrixRankWarning)
                lu = spla.splu(S)
            dx = inv_m * (A.T @ lu.solve(r))
            dx += inv_m * (A.T @ lu.solve(r - A @ dx))
            if np.all(np.isfinite(dx)) and misfit(dx) <= 1e-3 * START_RTOL:
                return dx
        except (RuntimeError, spla.MatrixRankWarning):
            dx = None
        w = np.sqrt(inv_m)
        sol = w * spla.lsqr(A @ sp.diags(w), r, atol=1e-15, btol=1e-15, iter_lim=10 * (A.shape[1] + 10))[0]
        if dx is not None and np.all(np.isfinite(dx)) and misfit(dx) < misfit(sol):
            return dx
        return sol

    def initial_y(self, t0, modes=None):
        st = self.structure
        modes = self.modes0 if modes is None else modes
        guess_x = np.where(np.isfinite(st.start_pos), st.start_pos, 0.0)
        guess_v = np.where(np.isfinite(st.start_vel), st.start_vel, 0.0)
        x, v = self.project(t0, guess_x, guess_v, st.start_pos, st.start_vel, modes, starts=(0, 1))
        z = self.state_start.copy()
        return self.assemble_y(t0, x, v, z, modes, start=True)

    def assemble_y(self, t, x, v, z, modes, rates=True, known=None, start=False):
        """Consistent (y, y') from positions, velocities and device states.

        The derivatives of the algebraic unknowns (dummy accelerations and
        constraint forces) are not needed by the residual but feed IDA's
        first predictor: left at zero, a force that starts growing linearly
        fails the error test at any step size, so they are taken from a
        forward difference along the motion (``rates=False`` skips that: only IDA's
        predictor uses them). ``known``: ``accelerations(t, x, v, z, modes)`` when the caller has it. ``start``:
        the values are a run's start (``initial_y``), which a non-finite value's message says.
        """
        if len(self.massless):
            v = massless.speeds(self, t, x, v, z)
            known = None
        if self.n_alg or self.sampled or self.branches or self.latches:
            z = reads.settle(self, t, x, v, np.array(z, float))
            known = None
        a, lam, dz = self.accelerations(t, x, v, z, modes) if known is None else known
        if self.n_alg:
            dz = np.where(self.z_algebraic, 0.0, dz)       # algebraic states: no rate in the residual
        y = np.zeros(self.N)
        yp = np.zeros(self.N)
        # (the index sets as slices: views, no gathers; the mode logic assembles a restart at every event)
        y[self._sx], y[self._sv], y[self._sad], y[self._slam], y[self._sz] = x, v, a[self.Dv], lam, z
        yp[self._sx], yp[self._sv], yp[self._sz] = v, a, dz
        if rates and (len(self.iad) or self.m):
            d = 1e-7 * max(1.0, abs(t))
            if t + d < self._t_right:
                a2, lam2, _ = self.accelerations(t + d, x + d * v, v + d * a, z + d * dz, modes)
                yp[self._sad] = (a2[self.Dv] - a[self.Dv]) / d
                yp[self._slam] = (lam2 - lam) / d
        if not (np.isfinite(y).all() and np.isfinite(yp).all()):
            raise SimulationError(self._non_finite_message(t, x, v, z, a, lam, dz, start))
        return y, yp

    def _non_finite_message(self, t, x, v, z, a, lam, dz, start):
        """What ``assemble_y`` found non-finite at ``t``, by name: the positions, speeds and accelerations of which
        masses, the forces of which devices' constraints, which device states; and whether the state itself was
        already non-finite (the motion ran away before ``t``) or only what the laws made of a finite state."""
        st = self.structure
        names = st.coord_names
        cons = st.position + st.speed + st.friction

        def listed(label, values, name_of):
            bad = np.flatnonzero(~np.isfinite(np.asarray(values, float)))
            if not len(bad):
                return []
            shown = ", ".join(dict.fromkeys(name_of(int(k)) for k in bad[:6]))
            return [f"{label} of {shown}{' ...' if len(bad) > 6 else ''}"]

        state = listed("the position", x, names.__getitem__) + listed("the speed", v, names.__getitem__) + \
            listed("the state", z, self.state_names.__getitem__)
        try:
            tau = self.kernel_outputs(x, v, z, t)[2] if not state else np.zeros(0)
        except Exception:       # the message must not fail where the laws do: their forces are then not named
            tau = np.zeros(0)
        laws = listed("the force", tau, lambda i: st.compliant[i].device.name) + \
            listed("the acceleration", a, names.__getitem__) + \
            listed("the constraint force", lam, lambda j: cons[j].device.name) + \
            listed("the rate of the state", dz, self.state_names.__getitem__)
        when = f"at the start t={float(t):.9g} s" if start else f"at t={float(t):.9g} s"
        if state:
            why = ("the start values are not finite: check the components' start values and parameters" if start
                   else "the motion itself is no longer finite there: the model ran away before this instant (a "
                        "law or signal that grows without bound, an unstable loop); look at the run up to it with "
                        "a shorter t_end")
            return f"non-finite values {when}: {'; '.join(state)}; {why}"
        what = "; ".join(laws) or "the rates of the algebraic unknowns"
        return (f"non-finite values {when}: {what}, from a finite state (positions, speeds and device states): "
                f"the laws of the components named give no number there (an overflow, 0/0, a signal out of its "
                f"range); check their parameters and signals")

    # --------------------------------------------------------------- ODE form
    def ode_size(self) -> int:
        return len(self.Kx) + len(self.Kv) + self.nz

    def ode_state(self, y):
        return np.concatenate([y[self.ix[self.Kx]], y[self.iv[self.Kv]], y[self.iz]])

    def ode_lift(self, t, u, modes):
        """Full (x, v, z) from the ODE state: dummy coordinates from the constraints."""
        nkx, nkv = len(self.Kx), len(self.Kv)
        x = np.zeros(self.n)
        v = np.zeros(self.n)
        x[self.Kx] = u[:nkx]
        v[self.Kv] = u[nkx:nkx + nkv]
        z = u[nkx + nkv:]
        if len(self.Dv):
            gp, gv = self._refs(t)
            GpK, GpvK = self._independent_blocks()
            if self.mp:
                x[self.Dx] = self._dummy_solve("x", gp[0] - self.e0p - GpK @ x[self.Kx])
            rhs = np.concatenate([gp[1], gv[0]]) - GpvK @ v[self.Kv]
            v[self.Dv] = self._dummy_solve("v", rhs)
        return x, v, z

    def _independent_blocks(self):
        """G_p[:, K_x] and G_pv[:, K_v], sliced once (slicing sparse matrices per call is slow)."""
        blocks = self.__dict__.get("_ind_blocks")
        if blocks is None:
            # a small model's blocks dense: scipy's sparse product costs some 10 us of dispatch per call, and
            # the ODE form lifts u at every right-hand side and output row
            blocks = self._ind_blocks = tuple(
                B.toarray() if B.shape[0] * B.shape[1] <= DENSE_LIFT else B
                for B in (self.Gp[:, self.Kx].tocsr(), self.Gpv[:, self.Kv].tocsr()))
        return blocks

    def _dummy_solve(self, level, rhs):
        """The dummy coordinates from the constraints, ``G[:, D] w = rhs``: a small well-conditioned block
        by its inverse (one product; SuperLU's solve costs 10 us of call overhead), else by its sparse LU."""
        cache = self.__dict__.setdefault("_dummy_lu", {})
        solve = cache.get(level)
        if solve is None:
            G, D = (self.Gp, self.Dx) if level == "x" else (self.Gpv, self.Dv)
            block = G[:, D].tocsc()
            lu = spla.splu(block)
            solve = lu.solve
            if block.shape[0] * block.shape[1] <= DENSE_LIFT:
                dense = block.toarray()
                if np.linalg.cond(dense) < DENSE_LIFT_COND:
                    solve = np.linalg.inv(dense).__matmul__
            cache[level] = solve
        return solve(rhs)

    def ode_rhs(self, t, u, modes):
        """``u' = g(t, u)``; a linear model without constraints takes ``compile.odeform``'s ``A u + b(t)``."""
        form = self.__dict__.get("_ode_form")
        if form is None:
            from .odeform import ode_form
            form = ode_form(self)
        if form.linear:
            return form.rhs(t, u)
        return self.ode_rhs_general(t, u, modes)

    def ode_rhs_general(self, t, u, modes):
        """``u' = g(t, u)`` through the lift, the device forces and the KKT solve (any model)."""
        x, v, z = self.ode_lift(t, u, modes)
        a, lam, dz = self.accelerations(t, x, v, z, modes)
        if self.mf:
            a = self._hold_stuck(a, modes)
        return np.concatenate([v[self.Kx], a[self.Kv], dz])

    def _hold_stuck(self, a, modes):
        """Make the relative accelerations of stuck friction rows zero to round-off of ``a`` itself.

        The KKT solve leaves ``G_s a`` at the round-off of the forces, ``eps |f| / m``
        (a vehicle held by its brake on a slope: 4e-16 m/s^2), which the ODE form
        integrates into a drift of the held motion (1.9e-8 m over 10^4 s). The
        mass-weighted projection ``a -= M^-1 G_s^T (G_s M^-1 G_s^T)^-1 G_s a`` removes it
        (a held body at rest then has exactly a = 0). IDA does not need it: its
        residual row of a stuck device is ``G_s a = 0`` itself.
        """
        stuck = np.asarray(modes) == 0
        if not stuck.any():
            return a
        key = stuck.tobytes()
        hit = self._hold_cache.get(key)
        if hit is None:
            Gs = self.Gf[np.nonzero(stuck)[0]].tocsr()
            cols = np.unique(Gs.indices)
            if np.any(self.mass[cols] <= 0):
                hit = False           # a massless coordinate in the row: leave the KKT answer as it is
            else:
                minv = np.zeros(self.n)
                minv[cols] = 1.0 / self.mass[cols]
                S = (Gs @ sp.diags(minv) @ Gs.T).toarray()
                try:
                    hit = (Gs, minv, np.linalg.inv(S)) if np.linalg.cond(S) < 1e12 else False
                except np.linalg.LinAlgError:
                    hit = False
            self._hold_cache[key] = hit
        if hit is False:
            return a
        Gs, minv, Sinv = hit
        r = Gs @ a
        if not np.any(r):
            return a
        return a - minv * (Gs.T @ (Sinv @ r))

    def y_from_ode(self, t, u, modes):
        x, v, z = self.ode_lift(t, u, modes)
        return self.assemble_y(t, x, v, z, modes)

    # ------------------------------------------------------------- utilities
    def solver_pattern(self):
        return self.jac.pattern

    def stiffness_estimate(self):
        """Diagonal stiffness of each compliant row at the start (for warnings), computed once per compiled
        system (every run asks for it, some twice: the stiffness check and IDA's force tolerances)."""
        k = self.__dict__.get("_stiffness")
        if k is None:
            t_right, self._t_right = self._t_right, np.inf    # at t = 0 as a fresh system sees it
            try:
                k = self._stiffness = self._stiffness_at_start()
            finally:
                self._t_right = t_right
        return k.copy()

    def _stiffness_at_start(self):
        y, yp = self.initial_y(0.0)
        x, v, a, lam, z = self.unpack(y, yp)
        e, de, tau, dz, w = self.kernel_outputs(x, v, z, 0.0)
        k = np.zeros(self.Sc.shape[0])
        for g, (woff, njac) in zip(self.groups, self._wslices):
            for q, ((on, oi), (wn, wj)) in enumerate(g.tpl.jac_entries):
                if on == "tau" and wn == "e" and oi == wj:
                    k[g.row_index[:, oi]] = w[woff + q * g.n: woff + (q + 1) * g.n]
        return k

    def link_frequencies(self) -> np.ndarray:
        """Local frequency estimate [rad/s] of every compliant row: ``sqrt(k * sum_j S_rj^2 / m_j)``
        (once per compiled system, as ``stiffness_estimate``)."""
        w = self.__dict__.get("_link_frequencies")
        if w is None:
            w = self._link_frequencies = self._link_frequencies_now()
        return w.copy()

    def _link_frequencies_now(self):
        k = self.stiffness_estimate()
        inv_m = np.where(self.mass > 0, 1.0 / np.where(self.mass > 0, self.mass, 1.0), 0.0)
        S2 = self.Sc.multiply(self.Sc)
        return np.sqrt(np.abs(k) * (S2 @ inv_m))

    def fastest_link(self):
        """``(device, omega [rad/s], spread)`` of the compliant link with the highest local frequency
        (``link_frequencies``), ``spread`` = highest over lowest positive one (1 for a single link);
        None without a link of positive stiffness."""
        if self.Sc.shape[0] == 0:
            return None
        w = self.link_frequencies()
        pos = w[w > 0]
        if pos.size == 0:
            return None
        i = int(np.argmax(w))
        return self.structure.compliant[i].device, float(w[i]), float(pos.max() / pos.min())

    def stiffness_hint(self, ratio: float = 1e3, always: bool = False) -> str:
        """Names the stiffest link when the link spectrum is stretched (for error messages).

        With ``always`` (the divergence of a fixed or explicit step, whose
        stability limit the fastest link sets whatever the spread) the link
        with the highest local frequency is named even when the spread is
        below ``ratio``.
        """
        link = self.fastest_link()
        if link is None:
            return ""
        dev, w, spread = link
        if spread < ratio:
            if not always:
                return ""
            return (f" The fastest link, {type(dev).__name__} '{dev.name}' (local mode {w / 2 / np.pi:.3g} Hz, "
                    f"i.e. {w:.3g} rad/s), sets the step an explicit method needs.")
        return (f" The stiffest link, {type(dev).__name__} '{dev.name}' (local mode {w / 2 / np.pi:.3g} Hz, "
                f"{spread:.3g} times the softest), is the likely cause: make it rigid "
                f"(Shaft(stiffness=None)) or let rm.Scene(band_hz=...) do it.")

    def warn_spectrum(self, ratio: float = 1e3):
        """Position 2: warn when link frequencies or masses spread over many decades."""
        if self.Sc.shape[0] == 0:
            return None
        w2 = self.link_frequencies() ** 2
        w2 = w2[w2 > 0]
        msg = []
        if w2.size >= 2 and np.sqrt(w2.max() / w2.min()) > ratio:
            msg.append(f"link frequencies spread over a ratio of {np.sqrt(w2.max() / w2.min()):.3g}")
        mpos = self.mass[self.mass > 0]
        if mpos.size >= 2 and mpos.max() / mpos.min() > ratio ** 2:
            msg.append(f"masses spread over a ratio of {mpos.max() / mpos.min():.3g}")
        if msg:
            warnings.warn(
                f"model '{self.model.name}': stretched spectrum ({'; '.join(msg)}). Regular-system Position 2: "
                f"masses far larger than the rest may be replaced by ground and links far stiffer than the rest by "
                f"rigid links; rm.Scene reduces the model automatically.", RegularityWarning, stacklevel=3)
        return msg


def compile_model(model) -> CompiledSystem:
    # the compiled system allocates per-row and per-device objects that all stay alive, like the
    # structure: automatic full collections would walk the whole model again and again (measured on the
    # 100,000-inertia chain: a third of the time of CompiledSystem)
    with gc_paused():
        return CompiledSystem(build_structure(model))
