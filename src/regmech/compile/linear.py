"""The structural-matrix form of a compiled system about an operating point.

For given friction modes and an operating point ``(x0, v0)`` at time ``t``,
small motions of a regular mechanical system obey

    M q'' + B q' + C q = W u(t) - (K_g g + B_g g' + M_g g'')            (1)

in *independent* coordinates ``q`` (rigid constraints eliminated), where

* ``M = T^T [m] T``                      (mass matrix, [kg m^2] or [kg]),
* ``C = T^T S^T K_c S T``                (stiffness, [N m/rad] or [N/m]),
* ``B = T^T (S^T D_c S + G_s^T [d_f] G_s) T``  (damping, [N m s/rad] or [N s/m]),
* ``S`` the compliant device rows (``e = S x + e0``), ``K_c = dtau/de`` and
  ``D_c = dtau/de'`` the kernel Jacobians at the operating point (block
  diagonal, one block per device: nonlinear laws are linearised there),
  ``d_f = dlam/dw_rel`` of sliding friction rows ``G_s``,
* ``W = -T^T S_src^T``: one column per row of a force source (``Torque``,
  ``Force``; ``u`` is that source's force deviation, [N m] or [N]),
* ``g``: displacements prescribed by ``Position``/``Speed`` sources
  (kinematic inputs; a Speed source's ``g`` is the integral of its speed).

Elimination. The full coordinates are ``x = x0 + T q + P g``. The rigid
constraints are the position-level rows ``G_p`` (rigid devices, Position
sources), the Speed-source rows ``G_v`` (on perturbations they are
position-level too: ``G_v dx = integral of dg_v``) and the rows ``G_f`` of
*stuck* friction devices. With the dummy-derivative choice of dependent
coordinates ``D`` (``G_D`` nonsingular, already made by the compiler),
``T = [I; -G_D^{-1} G_K]`` (rows K independent, rows D dependent) is sparse
for chains: each column of ``G_D^{-1} G_K`` spans one rigidly joined group.
Stuck friction rows are eliminated in a second step from ``G_f T_1`` (dense
pivoted QR; there are few of them). The independent coordinates are
coordinates of the full model, so ``q_j`` is the displacement [rad or m] of
the mass named ``coords[j]``.

Kinematic inputs. A driven coordinate is not a degree of freedom: it is
eliminated and its prescribed motion enters (1) through ``K_g, B_g, M_g``
(``= T^T K_full P`` etc.). With ``g = 0`` the driven points are held fixed,
which is what modal analysis assumes (the natural frequencies of a drive
with a speed-controlled motor are those with the motor side held).

Friction modes. Stuck (0) rows are rigid constraints; sliding rows (+-1)
give the damping ``dlam/dw_rel`` of the friction characteristic (negative
for a falling ``mu(w)``: the judder mechanism); Free (2) rows nothing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ParameterError, StructureError

#: independent coordinates above which the matrices are kept sparse (``sparse=None``)
SPARSE_ABOVE = 300

#: friction modes by name; "held" (3) is what a simulation records for a device whose motion other
#: stuck devices lock (no torque of its own), so that modes read from a Result can be passed back
MODE_CODES = {"backward": -1, "stuck": 0, "forward": 1, "free": 2, "held": 3}


@dataclass
class OutputMap:
    """A linear output ``y = a0 . x + a1 . x' + a2 . x''`` over the full coordinates.

    In the frequency domain (``x = X e^{i w t}``): ``Y = (a0 + i w a1 - w^2 a2) . X``.
    """

    name: str
    a0: np.ndarray
    a1: np.ndarray
    a2: np.ndarray

    def gain(self, omega: float) -> np.ndarray:
        return self.a0 + 1j * omega * self.a1 - omega ** 2 * self.a2


@dataclass(eq=False)
class LinearModel:
    """Structural-matrix form ``M q'' + B q' + C q = W u - (K_g g + B_g g' + M_g g'')``.

    Attributes (``nq`` independent coordinates, ``n`` full coordinates):
    ``M, B, C`` (nq x nq; numpy arrays, or scipy CSR when ``sparse``);
    ``W`` (nq x nu) force inputs named ``input_names`` (``"torque.tau"``);
    ``K_g, B_g, M_g`` (nq x ng) kinematic inputs named ``kinematic_names``
    (``"motor.w_ref"``) of level ``kinematic_levels`` (``"position"`` or
    ``"speed"``); ``coords`` names of q (the mass on each coordinate);
    ``T`` (n x nq), ``P`` (n x ng) sparse maps back: ``x = x0 + T q + P g``;
    ``full_names`` names of x; ``x0, v0`` the operating point; ``t``; ``modes``.
    """

    M: object
    B: object
    C: object
    W: object
    K_g: object
    B_g: object
    M_g: object
    coords: list
    input_names: list
    kinematic_names: list
    kinematic_levels: list
    T: sp.csr_matrix
    P: sp.csr_matrix
    full_names: list
    x0: np.ndarray
    v0: np.ndarray
    t: float
    modes: np.ndarray
    sparse: bool
    compiled: object = field(repr=False)
    ST: sp.csr_matrix = field(repr=False)       # compliant rows over q: S T
    Kc: sp.csr_matrix = field(repr=False)       # dtau/de (rows x rows)
    Dc: sp.csr_matrix = field(repr=False)       # dtau/de'
    friction_damping: np.ndarray = field(repr=False, default=None)   # dlam/dw_rel per friction row (0 if not sliding)

    # ------------------------------------------------------------------ sizes
    @property
    def n(self) -> int:
        """Number of independent coordinates (degrees of freedom)."""
        return len(self.coords)

    def __repr__(self) -> str:
        return (f"LinearModel({self.compiled.model.name!r}: {self.n} coordinates, inputs {self.input_names}, "
                f"kinematic inputs {self.kinematic_names}, {'sparse' if self.sparse else 'dense'})")

    # ----------------------------------------------------------------- masses
    def mass_coordinates(self) -> dict[str, int]:
        """Body name -> full coordinate index, for every mass that is not on the ground."""
        st = self.compiled.structure
        return {b.name: k for k, node in enumerate(st.coord_node) for b in node.bodies}

    @property
    def mass_names(self) -> list[str]:
        return list(self.mass_coordinates())

    # ----------------------------------------------------------------- inputs
    def input_force(self, name: str, omega: float) -> np.ndarray:
        """Complex generalised force (nq) per unit input amplitude at ``omega`` [rad/s].

        Force input ``u = U e^{i w t}``: ``W[:, j] U``. Kinematic input of
        position level ``g = G e^{i w t}``: ``-(K_g + i w B_g - w^2 M_g)[:, j] G``;
        of speed level (amplitude of the speed) the same divided by ``i w``.
        """
        kind, j = self._input(name)
        if kind == "force":
            return np.asarray(_column(self.W, j), complex)
        return -self._kinematic_displacement(j, omega) * (
            _column(self.K_g, j) + 1j * omega * _column(self.B_g, j) - omega ** 2 * _column(self.M_g, j))

    def input_motion(self, name: str, omega: float) -> np.ndarray:
        """Full-coordinate displacement ``P g`` (n) per unit input amplitude (0 for force inputs)."""
        kind, j = self._input(name)
        if kind == "force":
            return np.zeros(len(self.full_names), complex)
        return self._kinematic_displacement(j, omega) * self.P[:, [j]].toarray().ravel()

    def _kinematic_displacement(self, j: int, omega: float) -> complex:
        if self.kinematic_levels[j] == "position":
            return 1.0
        if omega == 0.0:
            raise ParameterError(f"kinematic input '{self.kinematic_names[j]}' prescribes a speed: its displacement "
                                 f"at 0 Hz is unbounded; use frequencies > 0")
        return 1.0 / (1j * omega)

    def _input(self, name: str) -> tuple[str, int]:
        if name in self.input_names:
            return "force", self.input_names.index(name)
        if name in self.kinematic_names:
            return "kinematic", self.kinematic_names.index(name)
        bare = [n for n in self.all_inputs if n.split(".")[0] == name]
        if len(bare) == 1:
            return self._input(bare[0])
        have = self.all_inputs or "none (add a Torque, Force, Position or Speed source)"
        raise ParameterError(f"model '{self.compiled.model.name}' has no input '{name}'; its inputs are {have}")

    @property
    def all_inputs(self) -> list[str]:
        return list(self.input_names) + list(self.kinematic_names)

    # ---------------------------------------------------------------- outputs
    def outputs(self) -> list[str]:
        """Names accepted by ``output``: masses (``J1.phi``, ``J1.w``, ``J1.a``) and device
        coordinates (``spring.phi_rel``, ``spring.w_rel``, ``spring.a_rel``, ``spring.tau``)."""
        return sorted(self._output_index())

    def output(self, name: str) -> OutputMap:
        recipe = self._output_index().get(name)
        if recipe is None:
            comp = name.split(".")[0]
            have = [n for n in self.outputs() if n.split(".")[0] == comp]
            hint = f"; '{comp}' has {have}" if have else "; see LinearModel.outputs()"
            raise ParameterError(f"no linear output '{name}' in model '{self.compiled.model.name}'{hint} "
                                 f"(constraint forces of rigid devices and source forces are not linear outputs)")
        return recipe()

    def _output_index(self) -> dict:
        cache = self.__dict__.get("_outputs")
        if cache is not None:
            return cache
        c = self.compiled
        st = c.structure
        n = c.n
        zero = np.zeros(n)

        def unit(k):
            a = np.zeros(n)
            a[k] = 1.0
            return a

        idx: dict = {}
        for k, node in enumerate(st.coord_node):
            for b in node.bodies:
                pn, wn, an, _ = b.var_names()
                idx[f"{b.name}.{pn}"] = lambda k=k, nm=f"{b.name}.{pn}": OutputMap(nm, unit(k), zero, zero)
                idx[f"{b.name}.{wn}"] = lambda k=k, nm=f"{b.name}.{wn}": OutputMap(nm, zero, unit(k), zero)
                idx[f"{b.name}.{an}"] = lambda k=k, nm=f"{b.name}.{an}": OutputMap(nm, zero, zero, unit(k))
        comp_row = {id(r): i for i, r in enumerate(st.compliant)}
        fric_row = {id(r): j for j, r in enumerate(st.friction)}
        Sc = c.Sc
        for dev in st.devices:
            rows = st.rows[dev.name]
            names = dev.rel_names.get(dev.domain, (None,) * 4)
            row0 = rows[0]
            s = np.zeros(n)
            s[row0.cols] = row0.coefs
            for nm, order in zip(names[:3], range(3)):
                if nm:
                    a = [zero, zero, zero]
                    a[order] = s
                    idx[f"{dev.name}.{nm}"] = lambda a=a, nm=f"{dev.name}.{nm}": OutputMap(nm, *a)
            force_name = names[3]
            if not force_name:
                continue
            if id(row0) in comp_row and not dev.is_source:
                r = comp_row[id(row0)]
                idx[f"{dev.name}.{force_name}"] = lambda r=r, nm=f"{dev.name}.{force_name}": OutputMap(
                    nm, np.asarray((self.Kc[r] @ Sc).todense()).ravel(),
                    np.asarray((self.Dc[r] @ Sc).todense()).ravel(), zero)
            elif id(row0) in fric_row and self.modes[fric_row[id(row0)]] != 0:
                d = self.friction_damping[fric_row[id(row0)]]
                idx[f"{dev.name}.{force_name}"] = lambda d=d, s=s, nm=f"{dev.name}.{force_name}": OutputMap(
                    nm, zero, d * s, zero)
        self.__dict__["_outputs"] = idx
        return idx

    # ------------------------------------------------------------ full space
    def full(self, q, g=None) -> np.ndarray:
        """Full-coordinate deviation ``T q + P g`` of independent coordinates q (nq or nq x k)."""
        out = self.T @ q
        if g is not None and self.P.shape[1]:
            out = out + self.P @ g
        return out


def _column(A, j: int) -> np.ndarray:
    if sp.issparse(A):
        return A[:, [j]].toarray().ravel()
    return np.asarray(A)[:, j]


# ============================================================== linearize
def linearize(compiled, t: float = 0.0, modes=None, at=None, sparse: bool | None = None) -> LinearModel:
    """Structural-matrix form of ``compiled`` about an operating point (see module docstring).

    ``t`` [s]: time at which signals (normal forces, time-varying laws) are
    evaluated. ``modes``: friction modes (array of -1/0/1/2 per friction
    device, or ``{device name: mode or "Stuck"/"Forward"/...}``; default
    the compiled start modes). ``at``: operating point, ``None`` for the
    consistent initial state, a dict of mass values (``{"J1.phi": 0.1,
    "J1.w": 50.0}``; the rest adjusted consistently) or a tuple ``(x, v)``
    of full coordinate arrays. ``sparse``: keep M, B, C, W sparse (default:
    when there are more than ``SPARSE_ABOVE`` independent coordinates).
    """
    c = compiled
    st = c.structure
    if c.nz:
        owners = sorted({name.split(".")[0] for name in c.state_names})
        raise StructureError(
            f"linearize: device(s) {owners} have internal states (first-order dynamics), which the second-order "
            f"structural-matrix form M q'' + B q' + C q cannot hold; use the simulation for these models")
    modes = _resolve_modes(c, modes)
    x0, v0 = _operating_point(c, float(t), modes, at)
    z0 = c.state_start.copy()

    # full-space matrices
    Kc, Dc = _kernel_jacobians(c, x0, v0, z0, float(t))
    Sc = c.Sc
    K_full = (Sc.T @ Kc @ Sc).tocsr()
    B_full = (Sc.T @ Dc @ Sc).tocsr()
    d_fric = np.zeros(c.mf)
    if c.mf:
        sliding = np.isin(modes, (-1, 1))
        d_fric = np.where(sliding, c.friction.slopes(float(t), v0, modes), 0.0)
        if not np.all(np.isfinite(d_fric)):
            bad = [st.friction[j].device.name for j in np.nonzero(~np.isfinite(d_fric))[0]]
            raise StructureError(f"linearize: the friction characteristic slope of {bad} is not finite at the "
                                 f"operating point; choose another point (at=...)")
        B_full = (B_full + c.Gf.T @ sp.diags(d_fric) @ c.Gf).tocsr()
    M_full = sp.diags(c.mass).tocsr()

    T, P, indep = _null_space(c, modes)
    ST = (Sc @ T).tocsr()
    M = (T.T @ M_full @ T).tocsr()
    C = (ST.T @ Kc @ ST).tocsr()
    B = (T.T @ B_full @ T).tocsr()
    K_g = (T.T @ K_full @ P).tocsr()
    B_g = (T.T @ B_full @ P).tocsr()
    M_g = (T.T @ M_full @ P).tocsr()

    src_rows = [i for i, r in enumerate(st.compliant) if r.device.is_source]
    W = (-ST[src_rows].T).tocsr() if src_rows else sp.csr_matrix((T.shape[1], 0))
    input_names = []
    for i in src_rows:
        r = st.compliant[i]
        force = r.device.rel_names.get(r.device.domain, (None,) * 4)[3] or "u"
        nrows = len(st.rows[r.device.name])
        input_names.append(f"{r.device.name}.{force}" + (f"[{r.index}]" if nrows > 1 else ""))
    kin_names, kin_levels = _kinematic_inputs(st)

    use_sparse = (T.shape[1] > SPARSE_ABOVE) if sparse is None else bool(sparse)
    conv = (lambda A: A.tocsr()) if use_sparse else (lambda A: A.toarray())
    return LinearModel(
        M=conv(M), B=conv(B), C=conv(C), W=conv(W), K_g=conv(K_g), B_g=conv(B_g), M_g=conv(M_g),
        coords=[st.coord_names[k] for k in indep], input_names=input_names,
        kinematic_names=kin_names, kinematic_levels=kin_levels, T=T.tocsr(), P=P.tocsr(),
        full_names=list(st.coord_names), x0=x0, v0=v0, t=float(t), modes=modes, sparse=use_sparse,
        compiled=c, ST=ST, Kc=Kc, Dc=Dc, friction_damping=d_fric)


# ----------------------------------------------------------- operating point
def _resolve_modes(c, modes) -> np.ndarray:
    st = c.structure
    if c.mf == 0:
        if modes is not None and len(modes):
            raise ParameterError(f"model '{c.model.name}' has no friction devices, so 'modes' must be None or empty")
        return np.zeros(0, int)
    if modes is None:
        return np.asarray(c.modes0, int).copy()
    names = [r.device.name for r in st.friction]
    if isinstance(modes, dict):
        out = np.asarray(c.modes0, int).copy()
        for name, mode in modes.items():
            if name not in names:
                raise ParameterError(f"modes: '{name}' is not a friction device of model '{c.model.name}' "
                                     f"(friction devices: {names})")
            out[names.index(name)] = _mode_code(name, mode)
        return out
    arr = list(modes)
    if len(arr) != c.mf:
        raise ParameterError(f"modes: expected {c.mf} modes (for {names}), got {len(arr)}")
    return np.array([_mode_code(nm, m) for nm, m in zip(names, arr)], int)


def _mode_code(name, mode) -> int:
    if isinstance(mode, str):
        code = MODE_CODES.get(mode.lower())
    else:
        code = int(mode) if int(mode) == mode and int(mode) in (-1, 0, 1, 2, 3) else None
    if code is None:
        raise ParameterError(f"modes: '{name}' got {mode!r}; use -1/0/1/2/3 or "
                             f"'Backward'/'Stuck'/'Forward'/'Free'/'Held'")
    return code


def _operating_point(c, t, modes, at):
    st = c.structure
    if at is None:
        y, yp = c.initial_y(t, modes)
        return y[c.ix].copy(), y[c.iv].copy()
    if isinstance(at, dict):
        y, yp = c.initial_y(t, modes)
        x, v = y[c.ix].copy(), y[c.iv].copy()
        fx, fv = np.full(c.n, np.nan), np.full(c.n, np.nan)
        lookup = {}
        for k, node in enumerate(st.coord_node):
            for b in node.bodies:
                pn, wn, _, _ = b.var_names()
                lookup[f"{b.name}.{pn}"] = (fx, k)
                lookup[f"{b.name}.{wn}"] = (fv, k)
        for key, val in at.items():
            if key not in lookup:
                raise ParameterError(f"at: '{key}' is not a position or speed of a moving mass of model "
                                     f"'{c.model.name}' (e.g. {sorted(lookup)[:6]})")
            val = float(val)
            if not np.isfinite(val):
                raise ParameterError(f"at: '{key}' must be finite, got {val}")
            arr, k = lookup[key]
            arr[k] = val
        return c.project(t, x, v, fx, fv, modes)
    try:
        x, v = (np.asarray(a, float) for a in at)
    except (TypeError, ValueError):
        raise ParameterError("at: give None, a dict {'J1.phi': ..., 'J1.w': ...} or a tuple (x, v) of arrays") from None
    if x.shape != (c.n,) or v.shape != (c.n,) or not (np.all(np.isfinite(x)) and np.all(np.isfinite(v))):
        raise ParameterError(f"at: x and v must be finite arrays of length {c.n} (coordinates {st.coord_names[:6]}...)")
    xp, vp = c.project(t, x, v, None, None, modes)
    scale = 1.0 + max(np.abs(x).max(initial=0.0), np.abs(v).max(initial=0.0))
    if np.abs(xp - x).max(initial=0.0) > 1e-8 * scale or np.abs(vp - v).max(initial=0.0) > 1e-8 * scale:
        raise ParameterError("at: the operating point (x, v) violates the rigid constraints (gears, rigid shafts, "
                             "prescribed motion, stuck friction); pass a dict of mass values to get a consistent one")
    return x, v


# ---------------------------------------------------------- kernel Jacobians
def _kernel_jacobians(c, x, v, z, t, override=None):
    """``K_c = dtau/de`` and ``D_c = dtau/de'`` (compliant rows x rows, CSR) at (x, v, z, t).

    ``override``: {group index: list of parameter arrays} to evaluate a group
    with changed parameters (for sensitivities).
    """
    e = c.Sc @ x + c.e0c
    de = c.Sc @ v
    nr = c.Sc.shape[0]
    left = t >= c._t_right
    parts = {"e": ([], [], []), "de": ([], [], [])}
    for gi, g in enumerate(c.groups):
        if override and gi in override:
            g = _with_params(g, override[gi])
        out = g.evaluate(e, de, z, t, left)
        k, ns = g.tpl.k, len(g.tpl.states)
        for q, ((on, oi), (wn, wj)) in enumerate(g.tpl.jac_entries):
            if on != "tau" or wn not in parts:
                continue
            vals = np.asarray(out[k + ns + q], float)
            if not np.all(np.isfinite(vals)):
                bad = [g.devices[i].name for i in np.nonzero(~np.isfinite(vals))[0]][:5]
                raise StructureError(f"linearize: the law of {g.tpl.cls.__name__} {bad} has a non-finite derivative "
                                     f"at the operating point (a kink or a singularity); choose another point (at=...)")
            r, cc, vv = parts[wn]
            r.append(g.row_index[:, oi])
            cc.append(g.row_index[:, wj])
            vv.append(vals)
    mats = []
    for wn in ("e", "de"):
        r, cc, vv = parts[wn]
        if r:
            mats.append(sp.csr_matrix((np.concatenate(vv), (np.concatenate(r), np.concatenate(cc))), shape=(nr, nr)))
        else:
            mats.append(sp.csr_matrix((nr, nr)))
    return mats[0], mats[1]


def _with_params(g, params):
    import copy
    g2 = copy.copy(g)
    g2.param_values = params
    return g2


def stiffness_derivatives(lin: LinearModel, rel_step: float = 1e-3):
    """Derivatives of ``K_c`` with respect to every numeric parameter of every compliant device.

    Yields ``(label, value, rows, cols, dvals)`` where ``label`` is
    ``"device.param"``, and ``dK_c/dp`` has entries ``dvals`` at
    (``rows``, ``cols``) of the compliant rows. The derivative is a
    Richardson-extrapolated central difference of the class kernel
    (``(4 D(h/2) - D(h)) / 3``, error O(h^4); exact up to rounding for laws
    polynomial of degree <= 4 in the parameter, e.g. ``c * phi_rel``); all
    instances of a class are perturbed at once since each instance only
    touches its own rows. Parameters that do not change the stiffness
    (dampings) are skipped.
    """
    c = lin.compiled
    x, v, z, t = lin.x0, lin.v0, c.state_start.copy(), lin.t

    def central(gi, g, pi, h):
        base = g.param_values[pi]
        plus, minus = list(g.param_values), list(g.param_values)
        plus[pi], minus[pi] = base + h, base - h
        Kp, _ = _kernel_jacobians(c, x, v, z, t, {gi: plus})
        Km, _ = _kernel_jacobians(c, x, v, z, t, {gi: minus})
        return (Kp - Km).tocsr() / 2.0

    for gi, g in enumerate(c.groups):
        if all(d.is_source for d in g.devices):
            continue
        for pi, pname in enumerate(g.tpl.params):
            base = g.param_values[pi]
            h = rel_step * np.where(base != 0.0, np.abs(base), 1.0)
            d1 = central(gi, g, pi, h)
            d2 = central(gi, g, pi, h / 2)
            # (4 D(h/2) - D(h)) / 3 with D = diff / h: per-instance h, so scale rows by 1/h of their instance
            inst_h = np.zeros(c.Sc.shape[0])
            inst_h[g.row_index] = h[:, None]
            dK = (sp.diags(1.0 / np.where(inst_h > 0, inst_h, 1.0)) @ (4.0 * (2.0 * d2) - d1) / 3.0).tocoo()
            if dK.nnz == 0 or not np.any(dK.data):
                continue
            inst_of_row = np.full(c.Sc.shape[0], -1)
            inst_of_row[g.row_index] = np.arange(g.n)[:, None]
            inst = inst_of_row[dK.row]
            order = np.argsort(inst, kind="stable")
            bounds = np.searchsorted(inst[order], np.arange(g.n + 1))
            for i, dev in enumerate(g.devices):
                sel = order[bounds[i]:bounds[i + 1]]
                if dev.is_source or not len(sel) or not np.any(dK.data[sel]):
                    continue
                yield f"{dev.name}.{pname}", float(base[i]), dK.row[sel], dK.col[sel], dK.data[sel]


# ------------------------------------------------------------- elimination
def _null_space(c, modes):
    """``T`` (n x nq), ``P`` (n x ng) and the independent coordinates (see module docstring)."""
    n = c.n
    kin_rows = kinematic_rows(c.structure)
    if c.Gpv.shape[0]:
        T1, K1, solve1 = _eliminate(c.Gpv, np.asarray(c.Dv, int), n)
        E = np.zeros((c.Gpv.shape[0], len(kin_rows)))
        E[kin_rows, np.arange(len(kin_rows))] = 1.0
        P = _embed(solve1(E), np.asarray(c.Dv, int), n) if len(kin_rows) else sp.csr_matrix((n, 0))
    else:
        T1, K1, P = sp.identity(n, format="csr"), np.arange(n), sp.csr_matrix((n, 0))
    stuck = np.asarray(modes) == 0 if c.mf else np.zeros(0, bool)
    if not stuck.any():
        return T1, P, K1
    Gs = c.Gf[np.nonzero(stuck)[0]]
    A = np.asarray((Gs @ T1).todense())
    _, R, piv = la.qr(A, pivoting=True, mode="economic")
    diag = np.abs(np.diag(R))
    ks = Gs.shape[0]
    if len(diag) < ks or diag.min(initial=np.inf) <= 1e-10 * max(1.0, diag.max(initial=0.0)):
        raise StructureError("linearize: " + c.friction.singular_message(modes))
    D2 = np.sort(piv[:ks])
    T2, K2, solve2 = _eliminate(sp.csr_matrix(A), D2, A.shape[1])
    T = (T1 @ T2).tocsr()
    if P.shape[1]:
        P2 = _embed(-solve2(np.asarray((Gs @ P).todense())), D2, A.shape[1])
        P = (P + T1 @ P2).tocsr()
    return T, P, K1[K2]


def _eliminate(G, D, n):
    """Null-space basis ``T = [I; -G_D^{-1} G_K]`` of ``G`` (k x n) with dependent columns D.

    Returns (T as CSR n x (n-k), independent columns K, solve(b) = G_D^{-1} b).
    Only the columns of ``G_K`` that are not empty are solved for, in chunks,
    so a long rigid chain costs one solve per independent coordinate it touches.
    """
    G = sp.csc_matrix(G)
    K = np.setdiff1d(np.arange(n), D)
    try:
        lu = spla.splu(G[:, D].tocsc())
    except RuntimeError as exc:  # pragma: no cover - the compiler checked G_D
        raise StructureError(f"linearize: the dependent-coordinate block of the constraints is singular "
                             f"({exc})") from None
    GK = G[:, K].tocsc()
    used = np.nonzero(np.diff(GK.indptr))[0]
    rows, cols, vals = [K, ], [np.arange(len(K))], [np.ones(len(K))]
    for s in range(0, len(used), 256):
        chunk = used[s:s + 256]
        X = sp.coo_matrix(lu.solve(GK[:, chunk].toarray()))
        rows.append(D[X.row])
        cols.append(chunk[X.col])
        vals.append(-X.data)
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, len(K)))

    def solve(b):
        b = np.asarray(b, float)
        return lu.solve(b) if b.size else np.zeros_like(b)
    return T, K, solve


def _embed(block, D, n):
    """Rows ``D`` of an n-row sparse matrix filled with ``block``."""
    X = sp.coo_matrix(np.atleast_2d(block))
    return sp.csr_matrix((X.data, (np.asarray(D)[X.row], X.col)), shape=(n, X.shape[1]))


def kinematic_rows(st) -> list[int]:
    """Indices (in G_pv) of the rows prescribed by Position and Speed sources (kinematic inputs; shared with
    the expm solver, which treats them as inputs of the linear model)."""
    npos = len(st.position)
    return [j for j, r in enumerate(st.position) if r.device.device_kind() == "position"] + \
        [npos + j for j in range(len(st.speed))]


def _kinematic_inputs(st):
    names, levels = [], []
    for r in st.position:
        if r.device.device_kind() == "position":
            names.append(f"{r.device.name}.{r.device.ref_param}")
            levels.append("position")
    for r in st.speed:
        names.append(f"{r.device.name}.{r.device.ref_param}")
        levels.append("speed")
    return names, levels
