"""Assemble the equation structure of a regular mechanical system.

Coordinates ``x`` are the positions of the non-ground nodes (masses and
driven points). The flattened equations are

* kinematics ``x_k' = v_k`` and motion ``m_k a_k + (S^T tau)_k + (G^T lam)_k = 0``
  for each coordinate (``a_k = v_k'``);
* compliant device rows ``tau_r = law(e_r, e_r', ...)`` with ``e = S x + e0``;
* constraint rows ``G_r x + e0_r = g_r(t)`` (rigid devices, Position sources)
  or ``G_r v = g_r(t)`` (Speed sources);
* friction rows with a mode (acceleration level when stuck).

Pantelides' algorithm on this incidence decides how often each constraint
row is differentiated (position rows twice, speed rows once); the dummy
derivative method then picks, for each differentiated set, coordinates whose
position/velocity/acceleration become algebraic (``dummy_x``, ``dummy_v``),
preferring coordinates without fixed start values. The result is an index-1
DAE (assembled numerically in ``compile``).
"""

from __future__ import annotations

import gc
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import maximum_bipartite_matching

from ..component import Device, Ground
from ..errors import ModelError, StructureError
from .pantelides import min_weight_column_matching, pantelides, structural_matching
from .regularity import check_model
from .topology import Node


@dataclass(eq=False)
class Row:
    """One row of one device: ``e = coef . x + offset``."""

    device: Device
    index: int                  # row index within the device
    cols: np.ndarray            # coordinate indices
    coefs: np.ndarray           # coefficients
    offset: float               # contribution of ground positions


@dataclass
class StartRelation:
    """A device's fixed start value of one of its rows: ``coefs . x + offset = value`` at level 0
    (positions), ``coefs . v = value`` at level 1 (speeds)."""

    row: Row
    value: float
    param: str

    def label(self) -> str:
        dev = self.row.device
        return f"{type(dev).__name__} '{dev.name}' ({self.param}={self.value:.10g})"


@dataclass
class MechanicalStructure:
    model: object
    nodes: list[Node]
    coord_node: list[Node]                  # node of each coordinate
    node_coord: dict[int, int | None]       # node index -> coordinate (None: ground)
    mass: np.ndarray
    coord_names: list[str]
    start_pos: np.ndarray                   # NaN where not fixed
    start_vel: np.ndarray
    devices: list[Device]
    rows: dict[str, list[Row]]              # device name -> rows
    compliant: list[Row] = field(default_factory=list)
    position: list[Row] = field(default_factory=list)   # level-2 constraints (rigid + Position)
    speed: list[Row] = field(default_factory=list)      # level-1 constraints (Speed)
    friction: list[Row] = field(default_factory=list)
    #: the devices' fixed start values of their own coordinate (``Device.relative_starts``):
    #: per level (0 position, 1 speed) a list of ``StartRelation``
    start_relations: tuple = ((), ())
    dummy_x: np.ndarray = None
    dummy_v: np.ndarray = None
    levels: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.mass)

    def matrix(self, rows: list[Row]) -> sp.csr_matrix:
        """Sparse matrix of the given rows over the coordinates."""
        if not rows:
            return sp.csr_matrix((0, self.n))
        ri = np.concatenate([np.full(len(r.cols), k) for k, r in enumerate(rows)])
        ci = np.concatenate([r.cols for r in rows])
        vals = np.concatenate([r.coefs for r in rows])
        return sp.csr_matrix((vals, (ri.astype(int), ci.astype(int))), shape=(len(rows), self.n))

    def offsets(self, rows: list[Row]) -> np.ndarray:
        return np.array([r.offset for r in rows], dtype=float)


def _device_label(row: Row) -> str:
    return f"{type(row.device).__name__} '{row.device.name}'"


#: Start values that must agree (several masses on one point, a mass on the ground, fixed
#: values against rigid constraints and motion sources) may differ by this much relative to
#: ``max(1, |values|)``: equal up to round-off passes, a real contradiction is refused.
START_RTOL = 1e-9

LEVELS = ("position", "velocity")
_PLURAL = ("positions", "velocities")


def start_label(body, level: int) -> str:
    """``Inertia 'J1' (w0=5)``: a mass and its fixed start value at ``level`` (0 position, 1 velocity)."""
    return f"{type(body).__name__} '{body.name}' ({body.start_params[level]}={body.start[level]:.10g})"


def start_conflict(level: int, problems: list[str], fixes: list[str], t: float | None = None) -> StructureError:
    """The one error for fixed start values that cannot all be met (a mass on the ground,
    masses sharing a point, rigid devices and gears, motion sources): what contradicts
    what, then the fix(es)."""
    when = "" if t is None else f" at t={t:g}"
    shown = problems[:8] + ([f"... and {len(problems) - 8} more"] if len(problems) > 8 else [])
    fix = "; ".join(dict.fromkeys(fixes))
    return StructureError(f"inconsistent start {_PLURAL[level]}{when}: " + "; ".join(shown) + f". Fix: {fix}")


_FIX_GROUND = ("a mass connected to a Fixed stays at the ground's position at rest: drop its start value (or give "
               "the ground's), or join it to the ground through a compliant device (a Spring, or a Shaft with a "
               "stiffness) if it is meant to move")
_FIX_POINT = "masses joined at one point share one {what}: give it on one of them only"


def _pin_label(who, level: int) -> str:
    """The label of a fixed start value in ``_node_starts``: a mass, a ground's position, a ground at rest."""
    if isinstance(who, tuple):
        g = who[0]
        return f"{type(g).__name__} '{g.name}' (at rest)"
    if isinstance(who, Ground):
        return f"{type(who).__name__} '{who.name}' ({who.position_param}={who.position:.10g})"
    return start_label(who, level)


def _node_starts(node: Node) -> tuple[list[float], list[tuple[int, str, str]]]:
    """Fixed start (position, velocity) of a node (NaN: free) and its contradictions.

    A node pins one position and one velocity: every mass on it with a start
    value, and the ground (its ``phi0``/``s0``, at rest), must agree to ``START_RTOL``.
    Returns ``[x0, v0]`` and ``(level, problem, fix)`` triples.
    """
    out, problems = [np.nan, np.nan], []
    for level in (0, 1):
        # (who, value): who is a mass, a ground, or (ground, None) for a ground holding a speed at rest;
        # labels are written only for a contradiction (a model has 100,000 masses, rarely one conflict)
        pins = [(b, b.start[level]) for b in node.bodies if b.start[level] is not None]
        if node.grounds and level == 0:
            pins = [(g, g.position) for g in node.grounds] + pins
        elif node.grounds and pins:
            pins.insert(0, ((node.grounds[0], None), 0.0))
        if not pins:
            continue
        ref = pins[0][1]
        if any(abs(v - ref) > START_RTOL * max(1.0, abs(v), abs(ref)) for _, v in pins[1:]):
            labels = ", ".join(_pin_label(who, level) for who, _ in pins)
            if node.grounds:
                problems.append((level, f"{labels} meet at one point ({node.label()}) but disagree", _FIX_GROUND))
            else:
                problems.append((level, f"{labels} meet at one point ({node.label()}) but disagree",
                                 _FIX_POINT.format(what=LEVELS[level])))
        out[level] = ref
    return out, problems


def _coordinates(nodes: list[Node]):
    coord_node, node_coord, mass, names, p0, v0 = [], {}, [], [], [], []
    problems: list[tuple[int, str, str]] = []
    for node in nodes:
        (x0, dx0), bad = _node_starts(node)
        problems += bad
        if node.grounded:
            node_coord[node.index] = None
            continue
        k = len(coord_node)
        node_coord[node.index] = k
        coord_node.append(node)
        mass.append(sum(b.mass for b in node.bodies))
        names.append(node.bodies[0].name if node.bodies else node.label())
        p0.append(x0)
        v0.append(dx0)
    if problems:
        level = min(lv for lv, _, _ in problems)
        raise start_conflict(level, [p for lv, p, _ in problems if lv == level],
                             [f for lv, _, f in problems if lv == level])
    return coord_node, node_coord, np.array(mass, dtype=float), names, np.array(p0, float), np.array(v0, float)


def _fixed_label(node: Node, level: int, value: float) -> str:
    """The mass whose start value a coordinate keeps (``Inertia 'J1' (w0=5)``), or the mass and
    the value when it was given otherwise (``Inertia 'J1' (w=5)``)."""
    for b in node.bodies:
        if b.start[level] is not None and b.start[level] == value:
            return start_label(b, level)
    if node.bodies:
        b = node.bodies[0]
        return f"{type(b).__name__} '{b.name}' ({b.var_names()[level]}={value:.10g})"
    return f"the point {node.label()} ({LEVELS[level]} {value:.10g})"


def constraint_start_conflict(st: "MechanicalStructure", level: int, G: sp.spmatrix, rows: list, bad: np.ndarray,
                              fixed: np.ndarray, refs: dict, t: float, relations: dict | None = None) -> StructureError:
    """The error for fixed start values that the constraint rows ``G`` (level 0: positions,
    1: velocities) cannot meet at ``t``, naming each conflicting group.

    A group is a connected set of constraint rows and coordinates (a rigidly joined
    set of masses with its devices). For each group holding an unmet row it names the
    masses whose fixed start values are involved, the devices (a source with its
    reference value ``refs[row]``, a device joined to the ground), and the fix.
    ``rows`` are the ``Row`` objects of ``G``'s rows; ``fixed`` holds the kept value of each
    coordinate (NaN: free): start values, or values given to ``linearize(at=...)``; ``relations``: the rows
    that are devices' fixed start values (row index -> ``StartRelation``).
    """
    relations = relations or {}
    from scipy.sparse.csgraph import connected_components
    m, n = G.shape
    C = sp.coo_matrix(G)
    adj = sp.coo_matrix((np.ones(C.nnz), (C.row, m + C.col)), shape=(m + n, m + n))
    _, label = connected_components(adj, directed=False)
    problems, fixes = [], []
    for group in dict.fromkeys(int(label[i]) for i in bad):
        members = np.nonzero(label[:m] == group)[0]
        coords = [k for k in np.nonzero(label[m:] == group)[0] if np.isfinite(fixed[k])]
        masses = [_fixed_label(st.coord_node[k], level, fixed[k]) for k in coords]
        devices, sources, to_ground, stuck, relating = [], [], False, False, []
        for i in members:
            dev = rows[i].device
            name = f"{type(dev).__name__} '{dev.name}'"
            if i in relations:
                devices.append(relations[i].label())
                relating.append(f"{relations[i].param} of {name}")
            elif i in refs:
                devices.append(f"{name} ({refs[i]})")
                sources.append(name)
            elif dev.device_kind() == "friction":
                devices.append(f"{name} (stuck)")
                stuck = True
            elif len(rows[i].cols) == 1:
                # a rigid row on one coordinate: its other flanges are on the ground
                devices.append(f"{name} (to the ground)")
                to_ground = True
            else:
                devices.append(name)
        devices, sources = list(dict.fromkeys(devices)), list(dict.fromkeys(sources))
        shown = ", ".join(devices[:6]) + (f" and {len(devices) - 6} more devices" if len(devices) > 6 else "")
        if masses:
            verb = "contradicts" if len(masses) == 1 else "cannot all hold with"
            problems.append(f"{', '.join(masses[:8])}{' ...' if len(masses) > 8 else ''} {verb} {shown}")
        else:
            problems.append(f"the constraints of {shown} contradict each other")
        what = LEVELS[level]
        if sources:
            fixes.append(f"drop the start {what} of the masses driven by {', '.join(sources)} (the source sets it) "
                         f"or make it equal to what the source prescribes at t={t:g}")
        if to_ground:
            fixes.append(f"a mass rigidly joined to the ground is held by it: drop its start {what}")
        if stuck:
            fixes.append("a stuck friction device locks the masses on its sides together: give the speed on one "
                         "side only, or take a mode in which it slips")
        if relating:
            fixes.append(f"a device's start {what} ({', '.join(relating)}) fixes the masses it joins relative to "
                         f"each other: drop it, or the start {what} of one of those masses, or make them agree")
        if masses and not relating and ((len(masses) > 1 and not stuck) or not (sources or to_ground or stuck)):
            fixes.append(f"give the start {what} on one mass of each rigidly joined group only (or none); the "
                         f"devices fix the others (through a gear w_b = w_a / ratio)")
        if not masses and not relating:
            fixes.append("check the references of the motion sources at that time (a speed reference must not "
                         "jump while a rigid group is held)")
    return start_conflict(level, problems, fixes, t)


def _device_rows(devices, node_of, node_coord, n) -> dict[str, list[Row]]:
    out: dict[str, list[Row]] = {}
    for dev in devices:
        rows = []
        spec = dev.rows()
        for r, coef_map in enumerate(spec):
            acc: dict[int, float] = {}
            offset = 0.0
            for fname, c in coef_map.items():
                fl = dev.get_flange(fname)
                node = node_of[fl]
                k = node_coord[node.index]
                if k is None:
                    offset += c * node.ground_position
                else:
                    acc[k] = acc.get(k, 0.0) + float(c)
            cols = np.array(sorted(k for k, c in acc.items() if c != 0.0), dtype=int)
            rows.append(Row(dev, r, cols, np.array([acc[k] for k in cols], dtype=float), offset))
        out[dev.name] = rows
    return out


def _levels(st: MechanicalStructure) -> dict:
    """Pantelides on the incidence of the mechanical equations.

    Only coordinates touched by some constraint row take part: the motion
    equation of a coordinate holds its own x, v, v' and the multipliers of
    the constraints on it (device forces are known functions of x, v), so an
    untouched coordinate's pair (kinematics, motion) is matched on its own and
    never lies on an augmenting path. A model of 10,000 springs and no
    constraints skips the search entirely.
    """
    cons = st.position + st.speed + st.friction
    if not cons:
        return {}
    npos, nspd = len(st.position), len(st.speed)
    touching: dict[int, list] = {}
    for j, row in enumerate(cons):
        for k in row.cols:
            touching.setdefault(int(k), []).append(("lam", j))
    eqs: dict = {}
    derivative = {}
    # Variables in a fixed order (lists, not sets): the search of ``pantelides`` takes the
    # first eligible one, so the motion equation of a coordinate prefers its own acceleration
    # and the result and its cost do not depend on string hashing (PYTHONHASHSEED).
    for k in sorted(touching):
        derivative[("x", k)] = ("dx", k)
        derivative[("v", k)] = ("dv", k)
        eqs[("kin", k)] = [("dx", k), ("v", k)]
        eqs[("motion", k)] = [("dv", k), ("x", k), ("v", k), *touching[k]]
    for j, row in enumerate(cons):
        if j < npos:
            eqs[("con", j)] = [("x", int(k)) for k in row.cols]
        elif j < npos + nspd:
            eqs[("con", j)] = [("v", int(k)) for k in row.cols]
        else:
            eqs[("con", j)] = [("dv", int(k)) for k in row.cols] + [("lam", j)]
    # structural nonsingularity of the original system (all derivatives as unknowns)
    # (Pantelides needs every equation matchable when all derivatives count as unknowns)
    un_eq = []
    if not _fully_matchable(eqs):
        match, un_eq, un_var = structural_matching(eqs)   # the reference matching names the culprits
    if un_eq:
        bad_rows = [cons[e[1]] for e in un_eq if e[0] == "con"]
        names = sorted({_device_label(r) for r in bad_rows})
        if names:
            raise StructureError(
                "structurally singular model: the constraint(s) of " + ", ".join(names) +
                " involve no free mass (they act only on the ground or on points fixed by other constraints); "
                "remove the redundant device or connect it to a mass")
        raise StructureError(f"structurally singular model: equations {un_eq} cannot be matched to unknowns")
    counts = pantelides(eqs, derivative)
    return {j: counts[("con", j)] for j in range(len(cons))}


def _fully_matchable(eqs: dict) -> bool:
    """True when every equation can be matched to a distinct variable (scipy's Hopcroft-Karp, fast)."""
    var_index: dict = {}
    rows, cols = [], []
    for i, vs in enumerate(eqs.values()):
        for v in vs:
            rows.append(i)
            cols.append(var_index.setdefault(v, len(var_index)))
    if len(var_index) < len(eqs):
        return False
    incidence = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(eqs), len(var_index)))
    return bool(np.all(maximum_bipartite_matching(incidence, perm_type="column") >= 0))


def _mobility_rank(G: sp.csr_matrix, mass: np.ndarray) -> np.ndarray:
    """Rank of each coordinate as a dummy, 0 the best: by decreasing mobility ``max_i |G_ij| / M_j``.

    A dummy is computed from the constraint, ``x_d = (g - sum_s G_is x_s) / G_id``, so it inherits the
    states' absolute errors. Where a row leaves a free mode between coordinates of very different inertia
    (an ideal differential between a heavy and a light wheel, its carrier driven), the constraint force
    moves the light coordinate most: keeping the light one as a state and the heavy one as the dummy made
    the heavy one's small motion the difference of two large ones. IDA's error test on its dummy
    acceleration then failed step after step (fuzz seed 60000: J2 = 2.014, J3 = 0.01519 kg m^2, 42,814
    steps and 4e-2 of J2's speed range off at rtol 1e-4). The coordinate that the rows' forces move most
    (the largest coefficient over its inertia; a massless point first) is taken as the dummy.

    The inertia ``M_j`` is the one the rows' forces meet at ``j``: its own mass plus the masses joined to it
    by two-coordinate rows (rigid shafts, ideal gears), reflected through their ratios
    (``_reflected_mass``). With its own mass alone, the light inertia of a wheel rigidly shafted to heavy
    ones (fuzz CI seed 4004: 0.040 kg m^2 of a 2.22 kg m^2 hub, rolling radius 0.134 m against a 2 kg tread
    mass) was taken as the rolling constraint's dummy; the whole hub then followed the tread's state divided
    by the radius, its speed carried 15x its error weight in noise, and IDA failed its error test at every
    other step (181,710 step attempts over 0.98 s; DOP853 648 steps).
    Ties keep the coordinates' order (a unique, stable choice).
    """
    n = G.shape[1]
    coef = np.zeros(n)
    A = abs(G.tocsc())
    if A.nnz:
        coef = np.asarray(A.max(axis=0).toarray()).ravel()
    inertia = _reflected_mass(G, mass)
    with np.errstate(divide="ignore", invalid="ignore"):
        mob = np.where(inertia > 0, coef / np.where(inertia > 0, inertia, 1.0), np.inf)
    order = np.lexsort((np.arange(n), -mob))
    rank = np.empty(n)
    rank[order] = np.arange(n)
    return rank


def _reflected_mass(G: sp.csr_matrix, mass: np.ndarray) -> np.ndarray:
    """Each coordinate's mass plus those joined to it by rows with two coordinates, reflected to it [kg or
    kg m^2]: a row ``G_ia x_a + G_ib x_b = g(t)`` moves ``x_b`` by ``r = -G_ia / G_ib`` per unit of ``x_a``,
    so a group joined that way has ``M_j = sum_k m_k (f_k / f_j)^2`` with ``f`` the motion of each member per
    unit motion of one of them. Rows with more coordinates (rolling, differentials) join nothing."""
    from scipy.sparse.csgraph import breadth_first_order, connected_components
    n = G.shape[1]
    mass = np.asarray(mass, float)
    G = G.tocsr()
    nnz = np.diff(G.indptr)
    pair_rows = np.flatnonzero(nnz == 2)
    if not len(pair_rows):
        return mass.copy()
    starts = G.indptr[pair_rows]
    a, b = G.indices[starts], G.indices[starts + 1]
    ga, gb = G.data[starts], G.data[starts + 1]
    ratio = {}
    for i, j, gi, gj in zip(a.tolist(), b.tolist(), ga.tolist(), gb.tolist()):
        if gi != 0.0 and gj != 0.0:
            ratio.setdefault((i, j), -gi / gj)       # x_j per unit x_i
            ratio.setdefault((j, i), -gj / gi)
    if not ratio:
        return mass.copy()
    ij = np.array(list(ratio), dtype=np.int64)
    adj = sp.csr_matrix((np.ones(len(ij)), (ij[:, 0], ij[:, 1])), shape=(n + 1, n + 1))
    ncomp, label = connected_components(adj[:n, :n], directed=False)
    sizes = np.bincount(label, minlength=ncomp)
    grouped = sizes[label] > 1
    if not grouped.any():
        return mass.copy()
    # one traversal for all groups: a virtual root (index n) joined to the first member of each
    _, first = np.unique(label[grouped], return_index=True)
    roots = np.flatnonzero(grouped)[first]
    adj = adj + sp.csr_matrix((np.ones(len(roots)), (np.full(len(roots), n), roots)), shape=(n + 1, n + 1))
    order, pred = breadth_first_order(adj, n, directed=False, return_predecessors=True)
    f = np.ones(n)
    for k in order[1:].tolist():
        p = int(pred[k])
        if p != n:
            f[k] = f[p] * ratio[(p, k)]
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        total = np.bincount(label, weights=mass * f * f, minlength=ncomp)
        out = np.where(grouped, total[label] / (f * f), mass)
    return np.where(np.isfinite(out), out, mass)


def _select_dummies(G: sp.csr_matrix, prefer_state: np.ndarray, rows: list[Row], exclude=(),
                    dummy_rank: np.ndarray | None = None) -> np.ndarray:
    """Pick one coordinate per constraint row (a nonsingular square block of G).

    Coordinates with fixed start values (``prefer_state``) are kept as states
    when possible; among the others, the order ``dummy_rank`` (``_mobility_rank``;
    default the coordinates' order) decides. Raises StructureError naming the
    devices of redundant or conflicting constraints.
    """
    m, n = G.shape
    if m == 0:
        return np.zeros(0, dtype=int)
    G = G.tocsr().copy()
    if len(exclude):
        mask = np.ones(n)
        mask[list(exclude)] = 0.0
        G = sp.csr_matrix(G @ sp.diags(mask))
        G.eliminate_zeros()
    # column weights: 1 free, 5.5 a fixed start velocity, 10 a fixed start position; the tiny
    # rank term orders the coordinates of one class and makes the weights distinct (a unique, stable
    # choice; it stays below 1e-4 up to 100,000 coordinates, far below the classes' steps)
    rank = np.arange(n) if dummy_rank is None else dummy_rank
    weight = 1.0 + 9.0 * prefer_state + 1e-9 * rank
    cols = min_weight_column_matching(G, weight)
    if cols is not None:
        block = G[:, cols].tocsc()
        try:
            lu = sp.linalg.splu(block)
            diag = np.abs(lu.U.diagonal())
            if diag.min() > 1e-12 * max(1.0, diag.max()):
                return cols
        except RuntimeError:
            pass
    _raise_redundant(G, rows)


def _nonsingular(block) -> bool:
    try:
        lu = sp.linalg.splu(sp.csc_matrix(block))
    except RuntimeError:
        return False
    d = np.abs(lu.U.diagonal())
    return bool(d.size == 0 or d.min() > 1e-12 * max(1.0, d.max()))


def _raise_redundant(G: sp.csr_matrix, rows: list[Row]):
    import scipy.linalg as la
    if G.shape[0] > 4000:
        # a dense rank analysis would need O(m^2) memory (800 MB for a 10,000-link chain)
        names = sorted({_device_label(r) for r in rows})
        raise StructureError("constraints are redundant or conflicting (rank-deficient); devices involved: " +
                             ", ".join(names[:20]) + (f" and {len(names) - 20} more" if len(names) > 20 else "") +
                             ". Fix: remove the device that fixes a motion a second time (two rigid links or gears "
                             "in parallel, a closed loop of gears), or make one compliant.")
    A = G[:, np.unique(G.indices)].toarray()          # only the coordinates the rows touch
    # rows that are combinations of others: pivoted QR of A^T orders rows by independence
    q, r, piv = la.qr(A.T, pivoting=True, mode="economic")
    d = np.abs(np.diag(r))
    tol = 1e-10 * (d.max() if d.size else 1.0)
    rank = int(np.sum(d > tol))
    dependent = piv[rank:]
    involved = set(dependent)
    for j in dependent:
        # the independent rows that explain the dependent one
        coeff = la.lstsq(A[piv[:rank]].T, A[j])[0]
        involved |= {int(piv[i]) for i in np.nonzero(np.abs(coeff) > 1e-9)[0]}
    names = sorted({_device_label(rows[i]) for i in involved})
    raise StructureError(
        "redundant or conflicting rigid constraints (over-determined motion): " + ", ".join(names) +
        " fix the same motion more than once (e.g. two rigid links or gears in parallel, a closed loop of gears, "
        "or a motion source on a rigidly held mass). Fix: remove one of them, or make one compliant (a Shaft with "
        "finite stiffness).")


@contextmanager
def gc_paused():
    """Pause Python's cyclic garbage collector for a bulk-allocation phase.

    Building the structure of a large model allocates hundreds of thousands of
    small objects (tuples, sets, dict entries) that all stay alive; every
    automatic full collection then walks the whole model, which made
    structure building of a 10,000-mass chain about twice as slow. Nothing
    here creates garbage cycles worth collecting early; the previous state is
    restored on exit.
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def build_structure(model) -> MechanicalStructure:
    with gc_paused():
        return _build_structure(model)


def _build_structure(model) -> MechanicalStructure:
    report = check_model(model)
    nodes = report.nodes
    node_of = {fl: nd for nd in nodes for fl in nd.flanges}
    coord_node, node_coord, mass, names, p0, v0 = _coordinates(nodes)
    devices = [c for c in model.components.values() if isinstance(c, Device)]
    rows = _device_rows(devices, node_of, node_coord, len(mass))
    st = MechanicalStructure(model=model, nodes=nodes, coord_node=coord_node, node_coord=node_coord,
                             mass=mass, coord_names=names, start_pos=p0, start_vel=v0,
                             devices=devices, rows=rows)
    for dev in devices:
        for kind, row in zip(dev.row_kinds(), rows[dev.name]):
            target = {"compliant": st.compliant, "rigid": st.position, "position": st.position,
                      "speed": st.speed, "friction": st.friction}.get(kind)
            if target is None:
                raise ModelError(f"{type(dev).__name__} '{dev.name}': unknown device kind {kind!r}")
            target.append(row)
    for row in st.position + st.speed:
        if len(row.cols) == 0:
            raise StructureError(
                f"{_device_label(row)} constrains only points fixed to the ground; it is redundant "
                f"(remove it) or one of its flanges should go to a mass")
    relations = ([], [])
    for dev in devices:
        for level, r, value, pname in dev.relative_starts():
            relations[level].append(StartRelation(rows[dev.name][r], value, pname))
    st.start_relations = (tuple(relations[0]), tuple(relations[1]))
    st.levels = _levels(st)
    npos = len(st.position)
    for j, row in enumerate(st.position):
        if st.levels[j] != 2:
            raise StructureError(f"{_device_label(row)}: expected a position-level constraint (2 differentiations), "
                                 f"Pantelides found {st.levels[j]}")
    for j, row in enumerate(st.speed):
        if st.levels[npos + j] != 1:
            raise StructureError(f"{_device_label(row)}: expected a velocity-level constraint, "
                                 f"Pantelides found {st.levels[npos + j]}")
    fixed_p = np.isfinite(p0).astype(float)
    fixed_v = np.isfinite(v0).astype(float)
    Gp = st.matrix(st.position)
    Gv = st.matrix(st.speed)
    # One matching for the stacked position and speed rows (their velocity-level forms must be
    # nonsingular together); the position rows' own columns then make G_p[:, D_x] square.
    # Choosing D_x first and excluding it would leave a speed row on a rigid group no column.
    G_all = sp.vstack([Gp, Gv]).tocsr()
    rank = _mobility_rank(G_all, np.asarray(mass, float))
    cols = _select_dummies(G_all, fixed_p + 0.5 * fixed_v, st.position + st.speed, dummy_rank=rank)
    dx = cols[: Gp.shape[0]]
    if len(dx) and not _nonsingular(Gp[:, dx]):
        outside = np.setdiff1d(np.arange(st.n), cols)
        dx = _select_dummies(Gp, fixed_p + 0.5 * fixed_v, st.position, exclude=outside, dummy_rank=rank)
    st.dummy_x = np.sort(dx).astype(int)
    st.dummy_v = np.sort(cols).astype(int)
    driven = set(st.dummy_v.tolist())
    for k, node in enumerate(coord_node):
        if mass[k] == 0.0 and k not in driven and any(k in r.cols for r in st.friction) \
                and not any(k in r.cols for r in st.position + st.speed):
            # a friction row on a massless coordinate that no rigid row joins to a mass: its closing cannot be
            # computed (Position 3); a rigid row reflects a mass onto it (the acceleration solve sees that mass)
            raise StructureError(f"the point {node.label()} has no mass and is not fully driven; insert a mass there")
    return st
