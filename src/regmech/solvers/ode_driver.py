"""Shared hybrid loop for the solvers that integrate the ODE form of a compiled model.

The compiled system offers the ODE form ``u' = g(t, u)`` with
``u = [x_K, v_K, z]`` (positions and velocities of the non-dummy coordinates,
device states); ``g`` lifts ``u`` to all coordinates through the constraints
and solves one sparse KKT system for the accelerations (cached per mode). A
solver only supplies a *stepper* (``Stepper`` below): it advances ``u`` by
one step, interpolates inside the last step and counts its work. This module
does everything else, identically for every ODE-form solver:

* segments: the run is cut at the signals' breakpoints (time events); on a
  segment the signals are evaluated as left limits at its right end
  (``c._t_right``), so a step never sees a jump;
* output: values on the output grid, plus the breakpoint (twice: left and
  right limit) and every mode change (twice: before and after);
* stick/slip (``c.friction``, a ``FrictionSet``): after every step its event
  functions are evaluated on the full unknowns; a downward crossing through
  zero is located on the step's interpolant (``locate_crossing``), the mode
  logic ``settle`` runs at the crossing and the stepper restarts there;
* the structural sparsity pattern of ``dg/du`` and a column-grouped
  finite-difference Jacobian (used by the implicit scipy methods and by the
  convolution method's time constants);
* for the error estimate of the fixed-step methods (``richardson``): a
  ``GridProbe`` that keeps the states at the output instants a run's steps
  hit exactly, a ``GroupedKnotClock`` for companion runs at exactly 2h (4h),
  and companion runs that record nothing else (``record=False``).
"""

from __future__ import annotations

import math
import time
import weakref
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import SimulationError
from ..hybrid import attach, guards_for
from ..result import Event, Result, Stats
from .blas import one_blas_thread
from . import pages
from .common import Recorder, check_times, output_grid, run_deadline, scale_hint, signal_breakpoints
from .divergence import (BLOW_UP, FEW_STEPS, FEW_STEPS_MAX_SIZE, MAX_GROWTH, ROUGH,  # noqa: F401 (BLOW_UP
                         ROUGH_STEPS, GrowthWatch)                                 # is re-exported)

EPS = np.finfo(float).eps
#: event scan inside a step (``EventWatch.scan``): the guards are read at least every h / SCAN_PROBES,
#: and at most SCAN_REFINE more times per step where the samples suggest a dip through zero
SCAN_PROBES = 4
SCAN_REFINE = 8
#: ... and at least SCAN_PER_PERIOD times per period of the fastest sine signal, at most SCAN_MAX_PROBES times
SCAN_PER_PERIOD = 8
SCAN_MAX_PROBES = 512


# ---------------------------------------------------------------------------- problem
class OdeProblem:
    """``u' = g(t, u)`` of a compiled system for the current modes, counting evaluations.

    The driver reassigns ``modes`` after each mode change and keeps the
    object, so the counters run over the whole simulation.
    """

    def __init__(self, compiled, modes):
        self.c = compiled
        self.modes = modes
        self.size = compiled.ode_size()
        self.nfev = 0       # right-hand side evaluations (including finite-difference ones)
        self.njev = 0       # Jacobians built by ``jacobian``
        from ..compile.odeform import ode_form
        form = ode_form(compiled)
        # the linear form has no modes: its right-hand side is called without the dispatch of ``ode_rhs`` (not when
        # ``ode_rhs`` is wrapped on the instance: a work budget, ``bench.guard``, counts the calls there)
        self._linear_rhs = form.rhs if form.linear and "ode_rhs" not in compiled.__dict__ else None
        # ... nor its in-place variant when ``rhs`` is replaced on the form (a test's or a user's wrapper): both
        # must give the same numbers
        self._linear_rhs_into = (form.rhs_into if self._linear_rhs is not None and "rhs" not in form.__dict__
                                 else None)

    def rhs(self, t, u):
        self.nfev += 1
        if self._linear_rhs is not None:
            return self._linear_rhs(t, u)
        return self.c.ode_rhs(t, u, self.modes)

    def rhs_into(self, t, u, out):
        """``rhs(t, u)`` written into ``out`` (not ``u``): directly by the linear form's kernel, else a copy."""
        if self._linear_rhs_into is not None:
            self.nfev += 1
            self._linear_rhs_into(t, u, out)
        else:
            out[:] = self.rhs(t, u)

    def stage_sweep(self):
        """``sweep(y, K, A, C, s0, s1, t, h, work)``: the stages ``s0 <= s < s1`` of a Runge-Kutta step in one compiled
        call (``_dopri_kernels.linear_stages``; counted here like ``rhs_into``), or None: only for the linear form
        whose compiled right-hand side evaluates its signals itself (else Python writes them before each call)."""
        if self._linear_rhs_into is None:
            return None
        from ..compile.odeform import ode_form
        from . import dopri
        args = ode_form(self.c).kernel_arguments()
        kernels = dopri.compiled_passes(self.size) if args is not None else None
        if kernels is None:
            return None
        ih, fh, buf = args
        c, stages = self.c, kernels.linear_stages

        def sweep(y, K, A, C, s0, s1, t, h, work):
            self.nfev += s1 - s0
            stages(y, K, A, C, s0, s1, float(t), float(h), float(c._t_right), work, buf, ih, fh)
        return sweep

    def jacobian(self, t, u, g=None):
        """``dg/du`` (scipy CSC) by forward differences, one evaluation per column group."""
        self.njev += 1
        pat = ode_jacobian_pattern(self.c)
        if g is None:
            g = self.rhs(t, u)
        return grouped_fd_jacobian(self.rhs, t, u, g, pat)


def ode_state_entry(c, i) -> tuple[str, str]:
    """Entry ``i`` of the ODE state ``u = [x_K, v_K, z]``: ``(kind, name)``, kind "position" or "speed" of a
    coordinate (``c.Kx``, ``c.Kv`` index ``c.structure.coord_names``) or "state" of a device."""
    nx, nv = len(c.Kx), len(c.Kv)
    names = c.structure.coord_names
    if i < nx:
        return "position", names[c.Kx[i]]
    if i < nx + nv:
        return "speed", names[c.Kv[i - nx]]
    return "state", c.state_names[i - nx - nv]


def ode_state_label(c, i) -> str:
    """Entry ``i`` of the ODE state in words (``ode_state_entry``): "the speed of 'J1'"."""
    kind, name = ode_state_entry(c, i)
    return f"the state '{name}'" if kind == "state" else f"the {kind} of '{name}'"


# ------------------------------------------------------------- Jacobian structure
_PATTERNS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _bool(m) -> sp.csr_matrix:
    """0/1 pattern of a sparse or dense matrix (always a copy: the compiled matrices stay untouched)."""
    m = sp.csr_matrix(m, dtype=float, copy=True)
    m.data[:] = 1.0
    m.eliminate_zeros()
    return m


def _lift_pattern(G, dummies, kept, n):
    """Which kept coordinates each of the n coordinates depends on, through ``G x = g``.

    Kept coordinates depend on themselves; a dummy ``x_D = G_D^-1 (g - G_K x_K)``
    on the kept coordinates that its constraint block touches (computed
    numerically: constant coefficients, so an exact zero is a true zero).
    """
    L = sp.lil_matrix((n, len(kept)))
    L[kept, np.arange(len(kept))] = 1.0
    if len(dummies):
        GD = G[:, dummies].toarray()
        GK = G[:, kept].toarray()
        dep = np.linalg.solve(GD, GK)
        rows, cols = np.nonzero(np.abs(dep) > 0)
        L[np.asarray(dummies)[rows], cols] = 1.0
    return _bool(L)


def _coupling_pattern(G, n):
    """Coordinates whose accelerations are coupled by the constraints ``G`` (block per rigid group)."""
    if G.shape[0] == 0:
        return sp.identity(n, format="csr")
    adj = _bool(_bool(G).T @ _bool(G)) + sp.identity(n)
    ncomp, label = connected_components(adj, directed=False)
    members = [np.nonzero(label == k)[0] for k in range(ncomp)]
    rows = np.concatenate([np.repeat(m, len(m)) for m in members])
    cols = np.concatenate([np.tile(m, len(m)) for m in members])
    return _bool(sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n)))


def _device_patterns(c):
    """Couplings inside each compliant device instance: rows<-rows, rows<-states, states<-rows, states<-states.

    Over-approximated per instance (every output of an instance may depend on
    every input of it), which only adds a few entries.
    """
    nr = c.Sc.shape[0]
    rr, rz, zr, zz = ([], []), ([], []), ([], []), ([], [])
    for g in c.groups:
        R = np.asarray(g.row_index, int).reshape(g.n, -1)              # rows of each instance
        Z = np.asarray(g.state_index, int).reshape(g.n, -1)            # states of each instance
        for (acc, a, b) in ((rr, R, R), (rz, R, Z), (zr, Z, R), (zz, Z, Z)):
            if a.shape[1] and b.shape[1]:       # every pair (a_i, b_j) of one instance, all instances at once
                acc[0].append(np.repeat(a, b.shape[1], axis=1).ravel())
                acc[1].append(np.tile(b, (1, a.shape[1])).ravel())

    def mat(acc, shape):
        if not acc[0]:
            return sp.csr_matrix(shape)
        i, j = np.concatenate(acc[0]), np.concatenate(acc[1])
        return _bool(sp.csr_matrix((np.ones(len(i)), (i, j)), shape=shape))

    return mat(rr, (nr, nr)), mat(rz, (nr, c.nz)), mat(zr, (c.nz, nr)), mat(zz, (c.nz, c.nz))


def ode_jacobian_pattern(c) -> sp.csc_matrix:
    """Structural nonzeros of ``dg/du`` for the ODE form (all modes at once).

    ``a = P (-S^T tau(S x, S v, z) - G_f^T f_f(v))`` with ``P`` the
    constrained inverse mass (dense per rigid group, friction rows included
    so that one pattern serves every mode), ``x = L_x u_x``, ``v = L_v u_v``
    (dummy coordinates from the constraints). Rows of ``u'``: ``x_K' = v_K``,
    ``v_K' = a_K``, ``z' = h(S x, S v, z)``.
    """
    pat = _PATTERNS.get(c)
    if pat is not None:
        return pat
    fr = c.friction
    if fr is not None and (fr.has_inputs or fr.state_rows):
        # friction laws reading the state (a command, a temperature) and friction devices' own states (whose
        # rates read the friction force, a function of everything in the rigid group): every entry may be
        # nonzero. Such drivetrains are small; the grouped differences then cost one call per column
        pat = sp.csc_matrix(np.ones((c.ode_size(), c.ode_size())))
        _PATTERNS[c] = pat
        return pat
    n = c.n
    Lx = _lift_pattern(c.Gp, c.Dx, c.Kx, n)
    Lv = _lift_pattern(c.Gpv, c.Dv, c.Kv, n)
    P = _coupling_pattern(c.Gall, n)
    S = _bool(c.Sc) if c.Sc.shape[0] else sp.csr_matrix((0, n))
    Rrr, Rrz, Rzr, Rzz = _device_patterns(c)
    PST = P @ S.T
    Ax = PST @ Rrr @ S @ Lx
    Av = PST @ Rrr @ S @ Lv
    if c.mf:
        Gf = _bool(c.Gf)
        Av = Av + P @ Gf.T @ Gf @ Lv
    Az = PST @ Rrz
    nkx, nz = len(c.Kx), c.nz
    blocks = [
        [sp.csr_matrix((nkx, nkx)), Lv[c.Kx], sp.csr_matrix((nkx, nz))],
        [Ax[c.Kv], Av[c.Kv], Az[c.Kv]],
        [Rzr @ S @ Lx, Rzr @ S @ Lv, Rzz],
    ]
    pat = _bool(sp.bmat(blocks, format="csr")).tocsc()
    pat.sort_indices()
    _PATTERNS[c] = pat
    return pat


def column_groups(pattern: sp.csc_matrix) -> list[np.ndarray]:
    """Greedy grouping of columns with disjoint row sets (one FD evaluation per group): each column, in
    order, joins the first group none of whose rows it touches. scipy's compiled ``group_sparse`` (the
    one ``solve_ivp`` uses) does exactly this (the same groups on every library scene and hard case) in
    microseconds where the loop below took 0.1 s at 1,000 inertias and 0.9 s at 10,000."""
    nrow, ncol = pattern.shape
    if ncol == 0:
        return []
    try:
        from scipy.optimize._group_columns import group_sparse
        label = group_sparse(nrow, ncol, pattern.indices.astype(np.int32), pattern.indptr.astype(np.int32))
        order = np.argsort(label, kind="stable")
        cuts = np.cumsum(np.bincount(label))[:-1]
        return [np.asarray(g, int) for g in np.split(order, cuts)]
    except ImportError:         # a private module of scipy: keep the plain loop when it moves
        pass
    used: list[np.ndarray] = []
    members: list[list[int]] = []
    for j in range(ncol):
        rows = pattern.indices[pattern.indptr[j]:pattern.indptr[j + 1]]
        for mask, mem in zip(used, members):
            if not mask[rows].any():
                mask[rows] = True
                mem.append(j)
                break
        else:
            mask = np.zeros(nrow, bool)
            mask[rows] = True
            used.append(mask)
            members.append([j])
    return [np.array(m, int) for m in members]


_GROUPS: dict = {}


def grouped_fd_jacobian(fun, t, u, g0, pattern: sp.csc_matrix) -> sp.csc_matrix:
    """Forward-difference ``dg/du`` on a known sparsity pattern (Curtis-Powell-Reid grouping).

    Step per column ``sqrt(eps) * max(1, |u_j|)``; entries outside the pattern are zero.
    """
    key = id(pattern)
    groups = _GROUPS.get(key)
    if groups is None or groups[0] is not pattern:
        groups = _GROUPS[key] = (pattern, column_groups(pattern))
    groups = groups[1]
    delta = math.sqrt(EPS) * np.maximum(1.0, np.abs(u))
    data = np.zeros(pattern.nnz)
    indptr, indices = pattern.indptr, pattern.indices
    col_of = np.repeat(np.arange(pattern.shape[1]), np.diff(indptr))       # column of every stored entry
    for cols in groups:
        du = np.zeros_like(u)
        du[cols] = delta[cols]
        dg = fun(t, u + du) - g0
        entries = np.concatenate([np.arange(indptr[j], indptr[j + 1]) for j in cols] + [np.zeros(0, int)]) \
            if len(cols) < 8 else np.nonzero(np.isin(col_of, cols))[0]
        data[entries] = dg[indices[entries]] / delta[col_of[entries]]
    return sp.csc_matrix((data, indices, indptr), shape=pattern.shape)


# --------------------------------------------------------------------- steppers
def hermite(t0, u0, g0, t1, u1, g1, tq):
    """Cubic Hermite interpolation of u on [t0, t1] from values and slopes at both ends."""
    h = t1 - t0
    s = (tq - t0) / h
    h00 = (1 + 2 * s) * (1 - s) ** 2
    h10 = s * (1 - s) ** 2
    h01 = s * s * (3 - 2 * s)
    h11 = s * s * (s - 1)
    return h00 * u0 + h10 * h * g0 + h01 * u1 + h11 * h * g1


class _EqualSteps:
    """Stepping from t to a target in n equal steps, the last one ending on the target exactly (no
    round-off drift); ``_next_target(t)`` of the subclass gives ``(target, n)`` when a run of steps ends."""

    _n_left = 0
    _i = 0
    _h = 0.0

    def next_step(self, t):
        """(h, t_new) of the next step from t."""
        if self._n_left == 0:
            target, n = self._next_target(t)
            self._t_from, self._target, self._h, self._n_left, self._i = t, target, (target - t) / n, n, 0
        self._i += 1
        self._n_left -= 1
        t_new = self._target if self._n_left == 0 else self._t_from + self._i * self._h
        return t_new - t, t_new


class KnotClock(_EqualSteps):
    """Equal steps of at most ``h_max`` that land exactly on every knot (output instant) and on ``t_bound``.

    Each knot interval of length L is cut into ``ceil(L / h_max)`` equal
    steps; the last one ends on the knot itself. With ``parts`` > 1 each of
    those steps is cut into ``parts`` equal ones (the half-step companion of
    ``regmech.solvers.richardson``: it lands on every instant of the main run).
    ``even_start``: the step count of the first interval (from ``t0``, a segment's start: an event instant,
    as a rule between two knots) follows ``step_counts``, so that a companion at 2h (``GroupedKnotClock``)
    lands on the following knots too and the runs are compared there.
    """

    def __init__(self, t0, knots, t_bound, h_max, parts=1, even_start=False):
        self.knots = np.asarray(knots, float)
        self.t_bound = float(t_bound)
        self.h_max = float(h_max)
        self.parts = int(parts)
        self.even_start = bool(even_start)
        self._k = 0

    def _next_target(self, t):
        while self._k < len(self.knots) and self.knots[self._k] <= t:
            self._k += 1
        target = self.knots[self._k] if self._k < len(self.knots) else self.t_bound
        n = _count(target - t, self.h_max)
        if self.even_start:             # the first interval: the rule of ``step_counts``
            self.even_start = False
            after = self.knots[self._k + 1] if self._k + 1 < len(self.knots) else self.t_bound
            n = _even_first(n, _count(after - target, self.h_max) if after > target else None, target - t,
                            self.h_max)
        return target, n * self.parts


#: a first knot interval shorter than this fraction of the step is not given one more step (``step_counts``)
FIRST_SPAN_MIN = 1e-6


def step_counts(spans, h_max, even_start=False) -> np.ndarray:
    """Equal steps of at most ``h_max`` per knot interval: ``ceil(span / h_max)`` each. ``even_start``: an odd count
    of the first interval followed by an even one (or by none) is made even (one step more). Why: after an event
    the first interval is a part of an output interval; with an odd count there and even ones after it, a
    companion of 2h steps (``GroupedKnotClock``) groups the intervals until their counts add up to an even number,
    which never happens, and the runs were compared only at the segment's end. On dct_car (rk4, h = 0.985 ms) the
    tyres' transient after a break-away 2.2 ms before an output instant was never compared: estimate 8.7e-8,
    error 2.5e-5. (Odd counts after an odd first one pair up, and a sliver of a first interval, a knot a few ulps
    past the start, is stepped to at once: half of it would not advance t.)"""
    counts = np.array([_count(float(span), h_max) for span in spans], dtype=int)
    if even_start and len(counts):
        counts[0] = _even_first(int(counts[0]), int(counts[1]) if len(counts) > 1 else None, float(spans[0]),
                                h_max)
    return counts


def _count(span, h_max) -> int:
    """Equal steps of at most ``h_max`` over ``span`` (one at least; a span of h_max to round-off is one step)."""
    return max(1, math.ceil(span / float(h_max) * (1 - 1e-12)))


def _even_first(n_first, n_next, span, h_max) -> int:
    """The first interval's count under ``step_counts``' rule (``n_next`` None: no interval after it)."""
    if n_first % 2 and (n_next is None or n_next % 2 == 0) and span > FIRST_SPAN_MIN * h_max:
        return n_first + 1
    return n_first


class GroupedKnotClock(_EqualSteps):
    """The steps of ``KnotClock(t0, knots, t_bound, h)`` merged ``factor`` at a time (the companion runs of
    ``regmech.solvers.richardson``: steps of exactly 2h or 4h where the main run takes h).

    ``KnotClock`` cuts each knot interval of length L into ``n = ceil(L / h)``
    equal steps; when h is not much below the output interval (``h = dt_out``:
    one step per interval) a clock of step 2h would take the same steps. This
    clock groups consecutive knot intervals until their step counts add up to
    a multiple of ``factor`` and takes ``sum(n) / factor`` equal steps over
    the group: on an evenly spaced grid these are exactly ``factor`` main steps
    long and land on every ``factor``-th main step. Only the instants that end
    a group are hit exactly (the others are interpolated); a group cut short
    by ``t_bound`` takes ``ceil(sum(n) / factor)`` steps, so ``ratio`` of the
    whole run can fall below ``factor`` on short segments.
    """

    def __init__(self, t0, knots, t_bound, h_max, factor=2, even_start=False):
        knots = np.asarray(knots, float)
        knots = knots[knots > t0]
        if not len(knots) or knots[-1] < t_bound:
            knots = np.append(knots, float(t_bound))
        spans = np.diff(np.concatenate([[float(t0)], knots]))
        counts = step_counts(spans, h_max, even_start)      # the main run's (``KnotClock``)
        self.plan: list[tuple[float, int]] = []       # (group end, steps over the group)
        acc = 0
        for end, n in zip(knots, counts):
            acc += int(n)
            if acc % factor == 0 or end == knots[-1]:
                self.plan.append((float(end), max(1, math.ceil(acc / factor))))
                acc = 0
        self.main_steps = int(counts.sum())
        self._g = 0

    @property
    def knots(self) -> np.ndarray:
        """The instants this clock lands on exactly."""
        return np.array([end for end, _ in self.plan])

    def _next_target(self, t):
        while self._g < len(self.plan) - 1 and self.plan[self._g][0] <= t:
            self._g += 1
        return self.plan[self._g]


class Stepper:
    """What a solver supplies to the driver.

    After ``step()``: ``t_old``, ``t`` (the step), ``u`` (the new state);
    ``interpolate(tq)`` for ``t_old <= tq <= t``; counters ``nsteps``,
    ``nrejected``, ``njev``. A stepper never steps past ``t_bound``.
    """

    t: float
    t_old: float
    u: np.ndarray
    fixed_step: float | None = None     # the requested step of a fixed-step method
    slope_at_end = False                # ``g`` holds g(t, u) at the step end (reused for the output row)
    nsteps: int = 0
    nrejected: int = 0
    njev: int = 0

    def step(self) -> None:  # pragma: no cover - interface
        raise NotImplementedError

    def interpolate(self, tq: float) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError

    def interpolate_many(self, tqs) -> list:
        """``[interpolate(tq) for tq in tqs]``; a stepper whose interpolant takes many instants in one call
        (scipy's dense output) overrides it: the output instants of a step are read together."""
        return [self.interpolate(tq) for tq in tqs]

    def stats(self) -> dict:
        return {}

    #: ``h * rho`` (step times spectral radius of dg/du) up to which an explicit method is stable on the
    #: negative real axis; None for methods without such a bound. Used to explain a divergence.
    stability_bound: float | None = None

    #: ``amplification`` is the method's own factor (not a stand-in): it may overrule a roughness verdict
    amplification_exact = False

    #: the step is the model's exact flow (``expm``): its factor on a mode is ``exp(h lambda)``, above 1 only
    #: on a mode that grows in the model itself, so no roughness verdict applies (``divergence.GrowthWatch``;
    #: the growth test still does)
    exact_flow = False

    def amplification(self, J, h, eigenvalues=None) -> float | None:
        """Spectral radius of one step of length h on ``u' = J u`` (J dense; ``eigenvalues``: J's, when known),
        None when not known.

        Used for runs too short for the divergence tests of ``divergence.GrowthWatch``, and to confirm their
        roughness verdict (``RoughVerdict``)."""
        return None

    def divergence_remedy(self) -> str:
        """What the user can do when this stepper's run diverged (appended to the error message)."""
        return (" Use a smaller step or a tighter rtol, or a stiff (implicit) solver: 'ida', 'scipy:Radau', "
                "'scipy:BDF' or 'convolution'.")


# ------------------------------------------------------------------- recording
class GridProbe:
    """The ODE state ``u`` at the instants of ``times`` that a run's steps land on exactly.

    A fixed-step run and its companion at 2h (``regmech.solvers.richardson``)
    are compared where both hold a value that no interpolant has touched. At
    an instant met twice (a signal breakpoint, an event) the first value, the
    left limit, is kept.
    """

    def __init__(self, times):
        self._index = {float(t): k for k, t in enumerate(np.asarray(times, float))}
        self.samples: dict[float, np.ndarray] = {}

    def add(self, t, u):
        t = float(t)
        if t in self._index and t not in self.samples:
            self.samples[t] = np.array(u, float)


class _Sink:
    """Where a run's output goes: the ``Recorder`` of the result and/or a ``GridProbe``.

    A companion run (``record=False``) has no recorder: its grid rows cost
    nothing beyond copying u where the probe wants it (no accelerations are
    solved for output); event rows still cost what the mode logic needs.
    """

    def __init__(self, c, rec, probe):
        self.c, self.rec, self.probe = c, rec, probe
        from ..compile.odeform import ode_form
        self.form = ode_form(c)
        self.linear = self.form.linear
        # rows of the linear form whose y' is computed only when an output reads it (``deferred_rates``):
        # (row, t, side of the time-varying offsets)
        self._pending: list[tuple[int, float, bool]] = []
        # rows of the linear form recorded with their y' given (the start, breakpoints, events) while the recorder
        # has no y' array: (row, y'), written when an output reads the rates (``deferred_rates``)
        self._given: list[tuple[int, np.ndarray]] = []

    def row(self, t, y, yp, modes, left=False):
        """A row whose ``y`` and ``y'`` are known (the start, a breakpoint, an event)."""
        rec = self.rec
        if rec is None:
            return
        if self.linear and rec.YP is None:
            # its y' waits with the deferred rows': one given row must not allocate y' for every row (on a chain
            # of 10,000 inertias, 17.8 MB of fresh pages a run for the starting row's rates)
            if not np.all(np.isfinite(yp)):
                self._refuse_rate(t, yp)
            rec.row_buffer(len(y))[:] = y
            kept = yp if rec.yp_cols is None else np.asarray(yp)[rec.yp_cols]
            self._given.append((rec.k, np.array(kept, float)))
            rec.commit(t, modes, left)
        else:
            rec.add(t, y, yp, modes, left=left)

    def _refuse_rate(self, t, yp):
        """The error of a given row whose y' is not finite, naming the coordinate where it is a speed's rate."""
        c = self.c
        bad = int(np.argmax(~np.isfinite(np.asarray(yp, float))))
        at = np.flatnonzero(np.asarray(c.iv) == bad)
        what = f"the acceleration of '{c.structure.coord_names[int(at[0])]}'" if len(at) else "a rate of the state"
        raise SimulationError(f"{what} became non-finite (NaN/inf) at t={t:.6g} in model '{c.model.name}': a law "
                              f"or a signal acting on it overflows there. Check that component's parameters and "
                              f"signals, or try a tighter tolerance or 'ida'.")

    @property
    def takes_blocks(self) -> bool:
        """Whether ``states`` writes a block of interpolated rows at once (the linear form's rows into the
        result; a companion run records no interpolated rows)."""
        return self.linear and self.rec is not None

    def _place(self, y, u):
        """The linear form's ODE state ``u = [x, v, z]`` (one row, or the rows of an array) into output row(s)
        ``y`` of the compiled system's layout."""
        c, n = self.c, self.c.n
        y[..., c._sx], y[..., c._sv], y[..., c._sz] = u[..., :n], u[..., n:2 * n], u[..., 2 * n:]

    def states(self, ts, U, modes):
        """Interpolated rows (not step ends) at the instants ``ts``, ``U`` their ODE states as the rows of an
        ``(m, n)`` array: as ``state`` row by row, in one copy per kind of unknown (``takes_blocks``)."""
        c, rec = self.c, self.rec
        k = rec.k
        self._place(rec.row_block(c.N, len(ts)), U)
        right = c._t_right
        self._pending.extend((k + i, float(t), bool(t >= right)) for i, t in enumerate(ts))
        rec.commit_block(ts, modes)

    def state(self, t, u, modes, exact, left=False, row=None, g=None):
        """A row from the ODE state; ``exact``: u is a step's end value, not interpolated;
        ``row``: its ``consistent_row`` when already computed (``EventWatch.scan``); ``g``: ``g(t, u)``
        when the stepper has it (a fixed-step method's slope at its step end)."""
        if exact and self.probe is not None:
            self.probe.add(t, u)
        if self.rec is not None:
            if row is None and self.linear:     # filled in place: no row arrays to allocate and copy
                c = self.c
                if g is None:
                    # y' = g(t, u) waits until an output reads it (``deferred_rates``): most reads are positions
                    # and speeds, and g per output row cost 8 % of a DOP853 run on a chain of 1000 inertias
                    self._place(self.rec.row_buffer(c.N), u)
                    self._pending.append((self.rec.k, float(t), bool(t >= c._t_right)))
                else:
                    consistent_row(c, t, u, modes, g, out=self.rec.row_buffers(c.N))
                self.rec.commit(t, modes, left)
            else:
                self.rec.add(t, *(row or consistent_row(self.c, t, u, modes, g)), modes, left=left)

    def deferred_rates(self, YP):
        """``YP`` (the recorder's ``y'``) when every row of it is filled (zero rows when there are none); else a
        function that fills the rows ``state`` left (``g(t, u)`` of each, from its row of ``y``, with the side of
        the offsets it had then: the same numbers as at once) and the rows ``row`` kept aside (their given ``y'``),
        and returns ``YP`` (allocated then, zero, when no row had written it: ``Recorder.row_buffer``). A
        non-finite ``y'`` is refused there as the recorder refuses a non-finite row (a given one already in
        ``row``)."""
        if not self._pending and not self._given:
            return YP if YP is not None else pages.zeros((self.rec.k, self.rec.yp_width))
        c, form, pending, given = self.c, self.form, list(self._pending), list(self._given)
        Y, rows, width = self.rec.Y, self.rec.k, self.rec.yp_width
        self._pending.clear()
        self._given.clear()

        def fill():
            nonlocal YP
            if YP is None:
                YP = pages.zeros((rows, width))
            for k, yp in given:
                YP[k] = yp
            n = c.n
            for k, t, left in pending:
                y = Y[k]
                u = np.concatenate([y[c._sx], y[c._sv], y[c._sz]])
                g = form.rhs(t, u, left)
                if not np.all(np.isfinite(g)):
                    # the linear form has no constraints: u = [x, v, z] over every coordinate (Kx = Kv = all)
                    what = f"'{ode_state_entry(c, int(np.argmax(~np.isfinite(g))))[1]}'"
                    raise SimulationError(
                        f"the acceleration of {what} became non-finite (NaN/inf) at t={t:.6g} in model "
                        f"'{c.model.name}' while the states stayed finite: a law or a signal acting on it overflows "
                        f"there. Check that component's parameters and signals, or try a tighter tolerance or "
                        f"'ida'.")
                yp = YP[k]
                yp[c._sx], yp[c._sv], yp[c._sz] = u[n:2 * n], g[n:2 * n], g[2 * n:]
            return YP
        return fill


def consistent_row(c, t, u, modes, g=None, out=None):
    """Full ``(y, y')`` for the output from the ODE state.

    The same layout as ``CompiledSystem.assemble_y``, without its forward
    difference for the rates of the algebraic unknowns (only IDA's
    predictor uses those; the named outputs never do), which halves the
    cost of recording. For the linear form of ``compile.odeform`` (no
    constraints: u is the whole state) ``y'`` is ``g(t, u)`` itself, taken
    from ``g`` when the caller has it, and the row can be written into
    ``out`` (zeroed ``(y, y')``, e.g. ``Recorder.row_buffers``).
    """
    form = c.__dict__.get("_ode_form")
    if form is not None and form.linear:
        n = c.n
        if g is None:
            g = form.rhs(t, u)
        y, yp = out if out is not None else (np.zeros(c.N), np.zeros(c.N))
        y[c._sx], y[c._sv], y[c._sz] = u[:n], u[n:2 * n], u[2 * n:]
        yp[c._sx], yp[c._sv], yp[c._sz] = u[n:2 * n], g[n:2 * n], g[2 * n:]
        return y, yp
    x, v, z = c.ode_lift(t, u, modes)
    a, lam, dz = c.accelerations(t, x, v, z, modes)
    y = np.zeros(c.N)
    yp = np.zeros(c.N)
    y[c.ix], y[c.iv], y[c.iad], y[c.ilam], y[c.iz] = x, v, a[c.Dv], lam, z
    yp[c.ix], yp[c.iv], yp[c.iz] = v, a, dz
    return y, yp


# ----------------------------------------------------------------------- events
class EventWatch:
    """The friction event functions along the integration (each crosses downward through zero).

    A function that is not positive at a (re)start is *disarmed* until it
    becomes positive: the mode logic has just accepted that state, and a
    "crossing" at the restart instant would loop at the event.

    The functions are also checked inside each step (``scan``: at the output
    instants, whose rows are computed for the output anyway, at probes a
    quarter step apart, and where the samples bracket a dip): integrated with
    the smooth continuation of the segment's laws, a function can cross zero
    and come back within one large step, which the step ends alone do not
    see. Found on DOP853 at rtol 1e-6 (a lossy gear between a brake and sine
    loads): a slip that reversed and returned, a sine normal force that
    engaged and released a brake, and a lossy gear's driving side, each inside
    one 0.2-0.3 s step, so that friction drove the motion, the brake never
    acted and the gear supplied power; and on fuzz seed 31 (``scan``).
    """

    def __init__(self, c, friction, period=math.inf):
        self.c = c
        self.fr = friction
        self.period = period        # the shortest period of the model's sine signals [s] (``scan``)
        self.armed = np.ones(friction.n_events, bool)
        self._start_values = None       # the guards at the start of the current step (``scan``)

    def values(self, t, u, modes):
        y, yp = consistent_row(self.c, t, u, modes)      # event functions read y only
        return np.array(self.fr.event_values(t, y, yp, modes), float)   # a copy: the buffer is reused

    def arm(self, values):
        self.armed = values > 0
        self._start_values = values

    def crossed(self, values):
        self._start_values = values
        hit = self.armed & (values <= 0)
        self.armed |= values > 0
        return np.nonzero(hit)[0]

    def scan(self, stepper, inside, end_values, modes, rows):
        """Crossings inside the last step [t_old, t] that its end values cannot show: the guards go
        + -> - -> + within it. Returns their brackets ``(index, a, b)`` for ``locate``, earliest first, or [].

        Why: the step control resolves the state, not the guards. A guard can vary much faster than
        the state it is read from: under a constant friction torque the state is a polynomial that
        one long step integrates exactly, while the guard (a relative speed against a servo's motion,
        a holding torque against a sine normal force) swings through zero and back within that step.
        Seen on fuzz seed 31 (a 26 Hz servo against a clutch): with ``dt_out = 0.2`` DOP853 took 6
        steps, found 1 of 11 slip reversals, and the driven angle ended 21 times too large.

        How: the guards are read on the step's dense output at the output instants inside it and at
        probes that leave no gap wider than ``h / SCAN_PROBES`` (probes within half a gap of an output
        instant are not added; a fine ``dt_out`` costs nothing more). Where the samples of an armed
        guard bracket a local minimum (a sample below both neighbours, or the step start or end below
        its neighbour) that the parabola through the three samples puts at or below zero, the guard
        is read again at the parabola's vertex (or the middle of the wider half of the bracket), at
        most ``SCAN_REFINE`` times per step: a dip that reaches zero is found, a minimum that stays
        clearly positive costs one or two more reads. A crossing at a sample goes to ``locate`` as a
        bracket (last positive, first non-positive). An excursion narrower than the probe spacing
        that leaves no lower sample beside it can still be missed; ``dt_out`` smaller than it resolves
        it. Cost: ``SCAN_PROBES - 1`` evaluations of the guards per step (one KKT solve each) on models
        with friction events and sparse output; none on models without events.
        """
        a, b = float(stepper.t_old), float(stepper.t)
        h = b - a
        armed = self.armed.copy()
        if not armed.any() or not h > 0 or self._start_values is None:
            return []
        given = sorted(float(s) for s, _ in inside)
        states = {float(s): u for s, u in inside}
        pts = list(given)
        n = min(max(SCAN_PROBES, math.ceil(h * SCAN_PER_PERIOD / self.period)), SCAN_MAX_PROBES)
        for j in range(1, n):
            p = a + h * j / n
            k = np.searchsorted(given, p)
            near = min([abs(given[i] - p) for i in (k - 1, k) if 0 <= i < len(given)], default=np.inf)
            if near > 0.5 * h / n:
                pts.append(p)
        pts.sort()
        vals = {}
        fresh = [s for s in pts if s not in states]
        if fresh:       # the probes' states in one call of the interpolant
            states.update(zip(fresh, stepper.interpolate_many(fresh)))

        def read(s):
            u = states.get(s)
            if u is None:
                u = stepper.interpolate(s)
            y, yp = rows[s] = consistent_row(self.c, s, u, modes)
            vals[s] = np.array(self.fr.event_values(s, y, yp, modes), float)     # a copy (see ``values``)
            return vals[s]

        grid = [(a, self._start_values)] + [(s, read(s)) for s in pts] + [(b, end_values)]
        min_gap = h / (n * SCAN_PER_PERIOD)
        for _ in range(SCAN_REFINE + 1):
            hits = self._first_dip(grid, armed)
            # before a dip is taken, the samples before it must not suggest an earlier one
            s = self._suspect(grid, armed, hits[0][2] if hits else b, min_gap)
            if s is None or len(vals) >= len(pts) + SCAN_REFINE:
                if hits and hits[0][2] < b:
                    return hits
                return []           # nothing inside, or a crossing by the step end (``crossed``)
            grid = sorted(grid + [(s, read(s))], key=lambda e: e[0])
        return []       # pragma: no cover - the loop returns once the reads are spent

    @staticmethod
    def _first_dip(grid, armed):
        """The earliest sample where an armed guard is not positive: ``[(index, previous time, its time)]`` for
        every guard not positive there ([] when none is). All of them: ``locate`` finds which one crossed
        first between the two samples. Returning the lowest index only took a lossy gear's driving side
        (crossing at 0.504 s) for a gearbox's slip reversal that crossed before it in the same interval
        (calibration seed 6060, DOP853 at accuracy 1e-2); the reversal was lost and the run refused at the
        next event (``_check_sliding_sides``)."""
        arm = armed.copy()
        prev = grid[0][0]
        for s, v in grid[1:]:
            hit = arm & (v <= 0)
            if hit.any():
                return [(int(k), prev, s) for k in np.nonzero(hit)[0]]
            arm |= v > 0
            prev = s
        return []

    @staticmethod
    def _suspect(grid, armed, upto, min_gap):
        """Where to read the guards next, looking at the sample intervals up to ``upto`` in time order:

        * the vertex of the parabola through three consecutive samples of an armed guard, all positive,
          when it falls in the interval and the parabola puts it at or below zero (the middle of the
          interval when the vertex is too close to a sample);
        * the middle of an interval longer than ``min_gap`` over which an armed guard, positive at both
          ends, moves by more than its distance from zero (the samples do not resolve it: a swing
          faster than the probes, aliased).

        None when no interval suggests a dip."""
        ts = np.array([e[0] for e in grid])
        g = np.array([e[1] for e in grid])[:, armed]
        close = 1e-3 * (ts[-1] - ts[0])
        n_int = len(ts) - 1
        # the parabolas through every three consecutive samples at once (the same element-wise operations, in
        # the same order, as one triple at a time: a step's scan has some 50 samples, and a Python loop of small
        # numpy calls over them cost 5 ms per step on CoupledClutches with dt_out = 1 ms); the intervals are
        # then visited in time order as before, only those where a candidate or an aliased swing shows
        cand_in = np.zeros((max(n_int, 0), g.shape[1]), bool)       # triple j's vertex inside interval j
        cand_next = np.zeros_like(cand_in)                          # triple j's vertex inside interval j + 1
        xv = None
        if len(ts) >= 3:
            x0, x1, x2 = ts[:-2, None], ts[1:-1, None], ts[2:, None]
            f0, f1, f2 = g[:-2], g[1:-1], g[2:]
            with np.errstate(all="ignore"):      # a straight guard (curv = 0) gives inf/NaN: no candidate
                d1 = (f1 - f0) / (x1 - x0)
                d2 = (f2 - f1) / (x2 - x1)
                curv = (d2 - d1) / (x2 - x0)
                xv = 0.5 * (x0 + x1) - d1 / (2 * curv)
                fv = f0 + d1 * (xv - x0) + curv * (xv - x0) * (xv - x1)
                base = (f0 > 0) & (f1 > 0) & (f2 > 0) & (curv > 0) & (fv <= 0)
                cand_in[:-1] = base & (xv > x0) & (xv < x1)
                cand_next[:-1] = base & (xv > x1) & (xv < x2)
        with np.errstate(all="ignore"):
            fl, fh = g[:-1], g[1:]
            moved = ((fl > 0) & (fh > 0) & (np.abs(fh - fl) > np.minimum(fl, fh))).any(axis=1)
            moved &= np.diff(ts) > min_gap
        any_in, any_next = cand_in.any(axis=1), cand_next.any(axis=1)
        look = moved | any_in
        look[1:] |= any_next[:-1]
        for j in np.nonzero(look)[0]:
            if ts[j + 1] > upto:
                break
            lo, hi = ts[j], ts[j + 1]
            for i, cand in ((j - 1, cand_next), (j, cand_in)):
                if i < 0 or i + 2 >= len(ts) or not cand[i].any():
                    continue
                v = float(xv[i][np.argmax(cand[i])])
                if min(abs(ts - v)) <= close:
                    v = 0.5 * (lo + hi)
                if min(abs(ts - v)) > close:
                    return v
            if moved[j]:
                return float(0.5 * (lo + hi))
        return None

    def locate(self, stepper, modes, which, dips=()):
        """Earliest crossing in the last step: (t*, u*, index).

        Illinois-modified regula falsi on the stepper's interpolant, keeping a
        bracket [a, b] with value > 0 at a and <= 0 at b; returns b, so the
        restart point is on the crossed side (the condition has strictly flipped).
        ``which`` cross by the step end, ``dips`` (index, a, b) inside the step (``dips``).
        """
        best = None
        for k, a, b in [(k, stepper.t_old, stepper.t) for k in which] + list(dips):
            fa = self._value_at(stepper, a, modes, k)
            fb = self._value_at(stepper, b, modes, k)
            if not fa > 0:          # the interpolant disagrees at the step start: crossing at once
                tb = a
            else:
                tb = locate_crossing(lambda s: self._value_at(stepper, s, modes, k), a, b, fa, fb)
            if best is None or tb < best[0]:
                best = (tb, k)
        t_star, k = best
        return t_star, stepper.interpolate(t_star), k

    def _value_at(self, stepper, s, modes, k):
        return self.values(s, stepper.interpolate(s), modes)[k]


def shortest_period(model) -> float:
    """The shortest period [s] of the ``Sine`` signals of ``model`` (inf without one): the time scale on
    which a guard read from a prescribed motion or a normal force can swing through zero and back
    while the state stays smooth (``EventWatch.scan``). A plain callable's time scale is not known."""
    from ..signals import Sine
    period = math.inf
    for comp in model.components.values():
        for val in comp._values.values():
            val = getattr(val, "inner", val)       # a checked wrapper of a signal
            if isinstance(val, Sine) and val.freq_hz != 0 and val.amplitude != 0:
                period = min(period, 1.0 / abs(val.freq_hz))
    return period


#: most re-integrations of ``_relocate`` per located event
RELOCATE_ROUNDS = 3


def _relocate(problem, make_stepper, watch, modes, t0, u0, t_hit, u_hit, k_hit, stats, t_b=None, instants=(),
              states=None):
    """A crossing located on a step's interpolant, located again on steps that end at it.

    Why: the step that carried the guard through zero integrated the old mode's law past the crossing
    (a sliding law past a slip reversal, where the friction table has a kink in |w_rel|), and its
    interpolant, fitted to the whole step, is off near the crossing by far more than the tolerance. Both
    runs of the accuracy contract's pair took the same long step and put the reversal 1.3e-4 s late
    (fuzz finding F6, seed 84), so the pair agreed while the answer was 5.7e-4 off. The run is therefore
    repeated from the step start (t0, u0) with the steps bounded at the located instant: the old law is
    then integrated past the true crossing by at most the previous location error, and the crossing is
    located again on those steps; at most ``RELOCATE_ROUNDS`` rounds, stopping when the instant moves by
    less than the round-off of t.

    The interpolant can as well cross too *early*: on fuzz seed 184, DOP853 at rtol 1e-10 took one 4.4 ms
    step over a clutch's slip reversal and over the knee of its friction table 0.3 ms before it (a
    feature narrower than the step's stage spacing, which the error estimate did not see) and put the
    reversal 1.3e-5 s early; the state there was 1.2e-4 of the speed range off. When the re-integration
    reaches the located instant without a crossing, it goes on from there to the end ``t_b`` of the
    original step (which ended past the crossing) and locates the crossing on those steps. If it shows
    none up to ``t_b`` either, the located instant and state stand as they were. Both marches look for
    crossings as the main loop does: at the steps' ends and inside them (``EventWatch.scan``).

    ``instants`` (output instants inside the original step) get their states from the re-integration's
    steps in ``states`` (a dict), so that the rows before the event do not come from the interpolant
    that was off. Adaptive steppers only: a fixed-step method's step is the user's."""
    first = (t_hit, u_hit, k_hit)
    instants = sorted(float(q) for q in instants)
    states = {} if states is None else states
    t_b = t_hit if t_b is None else float(t_b)

    def march(ta, ua, bound):
        """Steps from (ta, ua) up to ``bound``: (crossing or None, start time and state of its step, end)."""
        sub = make_stepper(problem, ta, ua, bound, np.array([bound]))
        watch.arm(watch.values(ta, ua, modes))
        for q in instants:                  # what an earlier round put here is re-integrated now
            if q > ta:
                states.pop(q, None)
        found, start = None, (ta, ua)
        try:
            for _k in range(100_000):                 # bounded: a stepper never steps past its bound
                if not sub.t < bound:
                    break
                start = (sub.t, sub.u.copy())
                sub.step()
                if not sub.t > sub.t_old:
                    break
                for q in instants:
                    if sub.t_old < q <= sub.t:
                        states[q] = np.array(sub.interpolate(q), float)
                # the same look as the main loop's: a guard that dips through zero and back inside one of these
                # steps is a crossing too (fuzz calibration seed 5114: a lossy gear's driving side, located by
                # the interpolant a round-off early, was not crossed yet at the located instant; the run went on
                # to the original step's end in one step, over the gear's 6 ms round trip, and took a later
                # crossing of another gear instead: both runs of the accuracy pair lost the trip alike, 6.6e-3
                # of the range off against an estimate of 1.4e-5)
                end_values = watch.values(sub.t, sub.u, modes)
                dips = watch.scan(sub, [], end_values, modes, {})
                which = watch.crossed(end_values)
                if len(which) or dips:
                    found = watch.locate(sub, modes, which, dips)
                    break
        finally:
            stats.steps += sub.nsteps
        return found, start, (float(sub.t), np.array(sub.u, float))

    ta, ua = t0, u0
    best, kept = first, {}            # the latest location and the states that go with it
    for _ in range(RELOCATE_ROUNDS):
        found, start, reached = march(ta, ua, t_hit)
        if found is None and reached[0] >= t_hit and t_hit < t_b:
            # no crossing up to the located instant: it was early; look on up to the original step's end
            found, start, reached = march(reached[0], reached[1], t_b)
        if found is None:
            break                          # the latest location stands (the first: the original step's rows)
        moved = abs(found[0] - t_hit)
        best = t_hit, u_hit, k_hit = found
        kept = dict(states)
        if moved <= 1e-12 * max(1.0, abs(t_hit)) or not t_hit > start[0]:
            break
        ta, ua = start
    states.clear()
    states.update(kept)
    return best


#: most partial steps of ``_fixed_step_crossing`` per located event (the search converges in about ten)
FIXED_LOCATE_EVALS = 60


def _fixed_step_crossing(problem, make_stepper, watch, modes, t0, u0, t1, t_hit, u_hit, k_hit, instants, stats):
    """A crossing of a fixed-step method's step, located on steps that end at it.

    Why: the step from ``t0`` to ``t1`` carried event function ``k_hit`` through zero with the law of the old
    branch sampled past the crossing (a contact's force law, evaluated where the gap has opened), so its end
    state and the cubic interpolant through it are off near the crossing by the law's change, not by the
    method's local error: the crossing time and the restart state then carry an error of lower order than the
    method's (rk4 on the excavator's located contacts: 7.65e-7 of the range at h = 4 ms and 2 ms alike, 6.1e-7
    at 1 ms), the same at h and 2h, so the error estimate's comparison of the two did not see it. The state at
    ``s`` is taken instead from a run of steps ending at ``s`` (``make_stepper`` from ``(t0, u0)`` with the run's
    own clock: two steps of ``(s - t0) / 2`` in the main run, one of ``s - t0`` in the companion at 2h), on the
    old branch throughout, and the crossing is the root of the event function
    along those states (``locate_crossing``, at most ``FIXED_LOCATE_EVALS`` evaluations). ``instants``: output
    instants in ``(t0, t_hit)``, whose states are taken the same way. Their steps are counted in
    ``stats.extra["crossing_steps"]``, not in ``stats.steps``. Returns ``(t*, u*, {instant: state})``; the
    interpolant's crossing stands when the steps show no bracket (the crossing is then where it was found)."""
    evals = [0]

    def state_at(s):
        sub = make_stepper(problem, t0, u0, s, np.array([s]))
        try:
            for _k in range(64):                        # bounded: the clock ends on s in a step or two
                if not sub.t < s:
                    break
                sub.step()
        finally:
            # counted apart from the run's steps: the estimate's ratio of steps between its runs (h against 2h)
            # is that of their step lengths
            stats.extra["crossing_steps"] = stats.extra.get("crossing_steps", 0) + sub.nsteps
        evals[0] += 1
        return np.array(sub.u, float)

    def value(s):
        if evals[0] >= FIXED_LOCATE_EVALS:
            raise _LocateBudget
        return float(watch.values(s, state_at(s), modes)[k_hit])

    fa = float(watch.values(t0, u0, modes)[k_hit])
    better = {}
    try:
        if not fa > 0:
            return t_hit, u_hit, better
        f_hit = value(t_hit)
        if f_hit <= 0:
            a, b, fb = t0, t_hit, f_hit
        else:
            f_end = value(t1)
            if f_end > 0:
                return t_hit, u_hit, better             # no bracket on the steps: the interpolant's crossing
            a, fa, b, fb = t_hit, f_hit, t1, f_end
        t_star = locate_crossing(value, a, b, fa, fb)
        u_star = state_at(t_star)
        if not float(watch.values(t_star, u_star, modes)[k_hit]) <= 0:
            return t_hit, u_hit, better
    except _LocateBudget:
        return t_hit, u_hit, better
    for tq in instants:
        if tq < t_star:
            better[tq] = state_at(tq)
    return t_star, u_star, better


class _LocateBudget(Exception):
    """``_fixed_step_crossing`` made its most partial steps."""


def locate_crossing(f, a, b, fa, fb, max_iter=200):
    """Smallest-bracket search for the downward crossing of f on [a, b] (fa > 0 >= fb); returns b."""
    xtol = 4 * EPS * max(1.0, abs(a), abs(b))
    side = 0
    for _ in range(max_iter):
        if b - a <= xtol:
            break
        # Illinois: halve the weight of an end point that stays twice in a row
        s = (a * fb - b * fa) / (fb - fa) if fb != fa else 0.5 * (a + b)
        if not (a < s < b):
            s = 0.5 * (a + b)
        fs = f(s)
        if fs > 0:
            a, fa = s, fs
            if side == -1:
                fb *= 0.5
            side = -1
        else:
            b, fb = s, fs
            if side == 1:
                fa *= 0.5
            side = 1
    return b


# ------------------------------------------------------------------------ driver
@dataclass
class SegmentEnd:
    t: float
    u: np.ndarray
    crossed: np.ndarray | None = None      # indices of the event functions crossed there, None at the segment end


#: up to this ODE size the exact spectral radius (dense eigenvalues, tens of microseconds) is used directly
EXACT_BELOW = 40
#: above this ODE size the exact spectral radius comes from ARPACK (bounded) instead of dense ``eigvals``
DENSE_EIG_MAX = 600
#: ARPACK's iteration cap for the spectral radius of a large model (a pair of nearly equal |lambda| at the top
#: of a long chain's spectrum took 200,840 iterations, 12 s, unbounded); beyond it the bound is used
ARPACK_MAXITER = 300


def ode_jacobian(problem, t, u):
    """``dg/du`` (CSC): exact and free for the linear form of ``compile.odeform``, else grouped differences."""
    from ..compile.odeform import ode_form
    form = ode_form(problem.c)
    if form.linear:
        return form.jacobian().tocsc()
    return problem.jacobian(t, u)


def stiff_equation_hint(problem, t, u) -> str:
    """A sentence naming where the fastest rate of ``dg/du`` sits, for a model whose stiffness no link
    explains (``CompiledSystem.stiffness_hint`` names links only): the ODE state whose row of ``dg/du`` has the
    largest sum, its mass or device, and the devices acting on that mass. Fuzz seed 78 of the random
    calibration: an ``InverseSpeedDependentForce`` regularised over 0.03 m/s on a 0.109 kg mass, a rate of
    3.2e6 1/s, refused with no component named. Empty when the Jacobian cannot be had."""
    c = problem.c
    try:
        J = sp.csr_matrix(ode_jacobian(problem, t, u))
    except Exception:       # noqa: BLE001 - only the message loses this sentence
        return ""
    if J.nnz == 0:
        return ""
    sums = np.asarray(abs(J).sum(axis=1)).ravel()
    k = int(np.argmax(sums))
    nkx, nkv = len(c.Kx), len(c.Kv)
    names = c.structure.coord_names
    if nkx <= k < nkx + nkv:
        coord = names[int(c.Kv[k - nkx])]
        devices = []
        for node in c.structure.nodes:
            if any(b.name == coord for b in node.bodies):
                devices += [d.name for d in node.devices() if d.name not in devices]
        acting = f", set by what acts on it: {', '.join(repr(d) for d in devices[:6])}" if devices else ""
        return (f" The fastest rate, {sums[k]:.3g} 1/s, is in the motion of '{coord}'{acting} (a regularised law "
                f"or a damper on a light mass is stiff: a heavier mass or a wider regularisation eases it).")
    if k >= nkx + nkv and len(c.state_names) > k - nkx - nkv:
        return f" The fastest rate, {sums[k]:.3g} 1/s, is in the device state '{c.state_names[k - nkx - nkv]}'."
    if k < nkx:
        return f" The fastest rate, {sums[k]:.3g} 1/s, is in the position of '{names[int(c.Kx[k])]}'."
    return ""


class _Triplets(NamedTuple):
    """``(row, col, data, shape)`` of a sparse matrix, as ``sp.coo_matrix`` holds them."""

    row: np.ndarray
    col: np.ndarray
    data: np.ndarray
    shape: tuple


#: the two grids of log s of ``spectral_bound``'s search (a wide bracket, then a fine one), made once
_BOUND_GRIDS = (np.linspace(-30.0, 30.0, 121), np.linspace(-0.5, 0.5, 101))


def spectral_bound(J, c, compiled=False) -> float:
    """An upper bound of the spectral radius of ``J = dg/du`` from the sizes of its entries (microseconds).

    Any induced norm bounds the spectral radius, and so does the norm of any
    similar matrix ``D J D^-1``. Row sums (Gershgorin) of ``J`` itself are
    poor for a mechanical system: the block ``a = -M^-1 K x`` makes them of
    order ``omega^2`` where the eigenvalues are of order ``omega``. With
    ``D = diag(s sqrt(m_x), sqrt(m_v), 1)`` (positions scaled by s and the
    masses of their coordinates, speeds by their masses, device states as
    they are) an entry from column j to row i is multiplied by
    ``s^(e_i - e_j) sqrt(m_i / m_j)`` (``e = 1`` on positions), so each row
    sum is ``p_i s + q_i + r_i / s``. The bound is the smallest over s of the
    largest row sum, and of the largest column sum likewise, which for a
    chain of springs and dampers is ``2 sqrt(c / J) + 4 d / J``: the highest
    frequency itself, plus twice the fastest decay. (Measured against the exact radius:
    see ``spectral_radius``.)

    ``compiled``: the passes in numba (``_bound_kernel``; for a model whose
    right-hand side is compiled, so numba is loaded): the same sums, and the
    same search but for which of the rows that tie in one of its keys it
    keeps (the bound to the last bit on the models of the tests).
    """
    if compiled and (sp.isspmatrix_csc(J) or sp.isspmatrix_csr(J)):
        return _compiled_spectral_bound(J, c)
    if sp.isspmatrix_csc(J) or sp.isspmatrix_csr(J):
        # the triplets of ``sp.coo_matrix(J)`` (the same arrays, in the same order) without its constructor:
        # a sixth of the bound on a chain of 1,000 inertias
        major = np.repeat(np.arange(len(J.indptr) - 1, dtype=J.indices.dtype), np.diff(J.indptr))
        row, col = (J.indices, major) if sp.isspmatrix_csc(J) else (major, J.indices)
        J = _Triplets(row, col, J.data, J.shape)
    else:
        J = sp.coo_matrix(J)
    if J.data.size == 0:
        return 0.0
    size = J.shape[0]
    val, power = _scaled_entries(J.row, J.col, J.data, size, c)

    parts = [np.where(power == k, val, 0.0) for k in (1, 0, -1)]

    def sums(index):                            # p (times s), q, r (over s) of every row (or column)
        return [np.bincount(index, weights=w, minlength=size) for w in parts]

    best = np.inf
    for p, q, r in (sums(J.row), sums(J.col)):
        if not np.any(p) and not np.any(r):
            best = min(best, float(q.max()))
            continue
        best = min(best, _smallest_largest_sum(p, q, r, size))
    return float(best)


def _smallest_largest_sum(p, q, r, size) -> float:
    """``min over s > 0 of max_i (p_i s + q_i + r_i / s)`` (``p`` or ``r`` not all zero), to about 1 % of s."""
    def norm(log_s):
        s_ = math.exp(log_s)
        return float(np.max(p * s_ + q + r / s_))
    scale = math.sqrt(max(r.max(), 1e-300) / max(p.max(), 1e-300))
    # the search runs on the few rows that can be the largest near the optimum (the largest p, q, r and
    # sums); the bound is then the norm over every row at the s found (valid for any s, so the search
    # needs no more precision than the bound is worth: 1 % of s at the end)
    keys = (p, q, r, p * scale + q + r / scale)
    keep = np.unique(np.argpartition(-np.stack(keys), min(32, size - 1), axis=1)[:, :33])
    pk, qk, rk = p[keep], q[keep], r[keep]
    # max of convex functions of s: unimodal in log s; a coarse grid over a wide bracket, then a fine one
    # around its best point, each in one array operation (a golden-section search of 120 scalar
    # evaluations cost 1-2 ms, 5-8 % of a 100-inertia chain's DOP853 run)
    centre = math.log(scale)
    for grid in _BOUND_GRIDS:
        log_s = centre + grid
        s_ = np.exp(log_s)
        vals = np.max(pk[:, None] * s_[None, :] + qk[:, None] + rk[:, None] / s_[None, :], axis=0)
        centre = float(log_s[int(np.argmin(vals))])
    return min(norm(centre), norm(math.log(scale)))


def _scaled_entries(row, col, data, size, c):
    """``(val, power)`` of ``spectral_bound``'s scaling: each entry's magnitude times ``sqrt(m_i / m_j)`` and the
    power of s it scales with (-1, 0 or 1; positions ``e = 1``)."""
    nkx, nkv = len(c.Kx), len(c.Kv)
    w = np.ones(size)
    mass = np.where(c.mass > 0, c.mass, 1.0)
    w[:nkx] = np.sqrt(mass[c.Kx])
    w[nkx:nkx + nkv] = np.sqrt(mass[c.Kv])
    e = np.zeros(size, int)
    e[:nkx] = 1
    return np.abs(data) * w[row] / w[col], e[row] - e[col]


def spectral_split(J, c) -> tuple[float, float]:
    """``(oscillation, damping)``: the two parts of ``spectral_bound``'s scaled row sums ``p_i s + q_i + r_i /
    s``, bounded apart [1/s]. ``oscillation = min over s of max_i (p_i s + r_i / s)`` bounds the natural
    frequencies (``2 sqrt(c / J)`` on a chain of springs and inertias: the springs' entries and the positions'
    ``x' = v``), ``damping = max_i q_i`` the rates of the entries that do not scale with s (dampers on the
    speeds, device states: ``4 d / J`` on that chain, twice its fastest decay). Their sum bounds the
    spectral radius as
    ``spectral_bound`` does. Where the damping is well below the oscillation, the top of the spectrum is
    lightly damped oscillation (an explicit method's step limit there is the motion a stepping method
    resolves while it rings); where it is above, the fastest rates are decays that an implicit method steps
    over once they have died out (``solvers.auto``, rule E). Row and column sums alike, the smaller kept."""
    J = sp.csr_matrix(J)
    if J.data.size == 0:
        return 0.0, 0.0
    major = np.repeat(np.arange(len(J.indptr) - 1, dtype=J.indices.dtype), np.diff(J.indptr))
    row, col = major, J.indices
    size = J.shape[0]
    val, power = _scaled_entries(row, col, J.data, size, c)
    best_osc, best_damp = np.inf, np.inf
    for index in (row, col):
        p, q, r = (np.bincount(index, weights=np.where(power == k, val, 0.0), minlength=size) for k in (1, 0, -1))
        best_damp = min(best_damp, float(q.max()))
        if not np.any(p) or not np.any(r):
            best_osc = 0.0          # no spring (or no position): nothing oscillates
            continue
        best_osc = min(best_osc, _smallest_largest_sum(p, np.zeros(size), r, size))
    return best_osc, best_damp


def _compiled_spectral_bound(J, c) -> float:
    """``spectral_bound`` of a CSR or CSC matrix by the kernels of ``_bound_kernel`` (its docstring)."""
    from ._bound_kernel import envelope, sums_and_rows
    if J.data.size == 0:
        return 0.0
    size = J.shape[0]
    sums, facts, *rows = sums_and_rows(J.indptr, J.indices, J.data, sp.isspmatrix_csc(J), c.mass,
                                       np.asarray(c.Kx, np.int64), np.asarray(c.Kv, np.int64), size, 33)
    every = np.arange(size)              # the bound itself is the largest sum over every row
    best = np.inf
    for side in range(2):
        p, q, r = sums[3 * side], sums[3 * side + 1], sums[3 * side + 2]
        p_max, r_max, scale = facts[side]
        if not p_max and not r_max:          # sums of absolute values: nothing scales with s (NaN does)
            best = min(best, float(q.max()))
            continue
        centre = math.log(scale)
        for grid in _BOUND_GRIDS:
            log_s = centre + grid
            centre = float(log_s[envelope(p, q, r, rows[side], np.exp(log_s))[0]])
        best = min(best, envelope(p, q, r, every, np.array([math.exp(centre)]))[1],
                   envelope(p, q, r, every, np.array([math.exp(math.log(scale))]))[1])
    return float(best)


def spectral_radius(problem, t, u, above=None):
    """The spectral radius of dg/du at (t, u), or None when it cannot be computed.

    Up to ``EXACT_BELOW`` states the dense eigenvalues are computed at once.
    ``above``: only whether the radius exceeds this value matters (an up-front
    check); then the cheap upper bound ``spectral_bound`` settles every case
    where it is not above, and only the rest is computed exactly (dense
    eigenvalues up to ``DENSE_EIG_MAX`` states; ARPACK with at most
    ``ARPACK_MAXITER`` restarts beyond, the bound when that does not
    converge). So the decisions are those of the exact radius, and the check
    costs a bound in the common case. Without ``above`` the exact radius is
    returned up to ``DENSE_EIG_MAX`` states and the bound beyond (messages).

    Bound against exact radius (measured): 1.00 to 1.02 on the spring-damper
    chains of the benchmarks (10 to 10,000 inertias), 1.0 to 1.4 on the hard
    cases and the library scenes (see ``benchmarks/bench_ode_path.py``).

    The linear form's ``dg/du`` is constant: its answer is kept with the
    compiled system (dropped with it on any change of the model), so a
    model's later runs skip the check (1.5 ms of a 33 ms DOP853 run on a
    chain of 1000 inertias, before the bound was compiled; 0.7 ms now).
    """
    from ..compile.odeform import ode_form
    if ode_form(problem.c).linear:
        kept = problem.c.__dict__.setdefault("_spectral_radius", {})
        key = None if above is None else float(above)
        if key not in kept:
            kept[key] = _spectral_radius_of(problem, t, u, above)
        return kept[key]
    return _spectral_radius_of(problem, t, u, above)


def segment_radius(problem, t, u):
    """The spectral radius of dg/du at a segment's start (t, u), for the step cap of a capped method
    (``scipy_ivp.stability_cap``), or None: exact up to ``EXACT_BELOW`` states, the cheap upper bound
    (``spectral_bound``) beyond, the kept radius of the linear form (constant).

    Why again during a run: a mode, a contact or a nonlinear law's state changes the fastest motion. Fuzz seed
    92005: the cap was taken from the radius at the run's start, 303 1/s (a clutch's thermal state); a Magic
    Formula wheel's slip later made it 1,330-1,490 1/s, and DOP853 at rtol 1e-8 took its first step after a Pulse
    edge at h rho = 5.7, near its stability limit, where its error estimate passed an endpoint 2,000 times its
    tolerance off (rows 7e-4 of the range off; 8e-6 at rtol 1e-6). When it is asked: ``scipy_ivp``."""
    from ..compile.odeform import ode_form
    if ode_form(problem.c).linear:
        return spectral_radius(problem, t, u)
    try:
        J = ode_jacobian(problem, t, u)
        if J.shape[0] <= EXACT_BELOW:
            return float(np.max(np.abs(np.linalg.eigvals(J.toarray())), initial=0.0))
        bound = spectral_bound(J, problem.c)
        return bound if math.isfinite(bound) else None
    except Exception:  # as spectral_radius: no radius, no cap (the run's start radius stays)
        return None


def _spectral_radius_of(problem, t, u, above):
    """``spectral_radius`` computed."""
    try:
        J = ode_jacobian(problem, t, u)
        if J.shape[0] <= EXACT_BELOW:              # dense eigenvalues cost less than the bound here
            return float(np.max(np.abs(np.linalg.eigvals(J.toarray())), initial=0.0))
        # a compiled right-hand side (numba loaded): the bound's passes compiled too
        from ..compile.odeform import ode_form
        form = ode_form(problem.c)
        bound = spectral_bound(J, problem.c, compiled=form.linear and form._native is not None)
        if not math.isfinite(bound):
            bound = None
        if above is not None and bound is not None and bound <= above:
            return bound
        if J.shape[0] <= DENSE_EIG_MAX:
            return float(np.max(np.abs(np.linalg.eigvals(J.toarray()))))
        if above is None:
            return bound
        from scipy.sparse.linalg import ArpackNoConvergence, eigs
        try:
            return float(np.abs(eigs(J, k=1, which="LM", return_eigenvectors=False, maxiter=ARPACK_MAXITER,
                                     tol=1e-3))[0])
        except ArpackNoConvergence:
            return bound
    except Exception:  # the spectral radius only explains the failure; the failure itself is reported anyway
        return None


def _spectral_radius(problem, t, u):
    """Largest |eigenvalue| of dg/du at (t, u) (``spectral_radius`` without a threshold), or None."""
    return spectral_radius(problem, t, u)


def _stability_message(problem, t, u, stepper):
    """Explain the divergence of an explicit method by the spectral radius of dg/du at (t, u)."""
    rho = _spectral_radius(problem, t, u)
    if not rho:
        return stepper.divergence_remedy()
    bound = stepper.stability_bound
    limit = (f"this method is stable for h * rho up to about {bound:g} on the negative real axis, i.e. "
             f"h <= {bound / rho:.3g} s" if bound else f"an explicit method needs a step of order "
             f"1/{rho:.3g} = {1 / rho:.3g} s or below")
    return (f" The spectral radius of the Jacobian is about {rho:.3g} 1/s; {limit}. Pass a smaller h (h=...), "
            f"or use a stiff (implicit) solver: 'ida', 'scipy:Radau', 'scipy:BDF' or 'convolution'.")


#: the roughness verdict is checked against the method's amplification up to this many ODE states (a dense
#: eigen-decomposition of dg/du, about 0.1 s at 600 states; above, the verdict stands as found)
ROUGH_CONFIRM_MAX = 600
#: a step whose amplification on every eigenvalue of dg/du is at most this is stable: the growth is the model's
AMPLIFICATION_STABLE = 1.0 + 1e-9


class RoughVerdict:
    """Second opinion on the roughness test of ``divergence.GrowthWatch`` (a state that grew by ``ROUGH_GROWTH``
    over ``ROUGH_STEPS`` steps while changing by more than ``ROUGH`` of its size at each) from the method itself:
    the amplification ``q = max |R(h lambda)|`` of one step on the eigenvalues ``lambda`` of dg/du at the state
    reached. A numerical instability needs ``q > 1``. A resolved oscillation that a high-order method crosses in
    a few steps per period is rough too, and its beating grows (the undamped chain ``long_horizon`` of the hard
    cases: DOP853 at rtol 1e-4 took 6 steps per period of its fastest mode, h = 0.087 s, and was stopped as
    diverged at t = 7.3 s while its state grew from 0.27 to 1.09 as the reference's does; there q = 1 - 1e-13).
    The verdict is overruled when ``q <= AMPLIFICATION_STABLE``; it stands when the stepper knows no ``q`` of
    its own (``amplification_exact``: abm's is RK4's, whose region is larger; the implicit scipy methods give
    none) or the model has more than ``ROUGH_CONFIRM_MAX`` states. The eigenvalues are kept for the modes they
    were found in (the linear form's dg/du is constant; a nonlinear one's is taken again once the run has moved
    on by ``ROUGH_STEPS`` steps of the current length)."""

    def __init__(self):
        self._key = None
        self._J = self._eigenvalues = None
        self._t = -math.inf
        self.overruled_count = 0

    def overruled(self, problem, stepper) -> bool:
        if problem.size > ROUGH_CONFIRM_MAX or not stepper.amplification_exact:
            return False
        from ..compile.odeform import ode_form
        linear = ode_form(problem.c).linear
        key = np.asarray(problem.modes).tobytes()
        h = stepper.t - stepper.t_old
        # a nonlinear model's dg/du is taken again once the state has moved on by the test's window of steps
        # (a verdict upheld or overruled there judged that window), so at most one per ROUGH_STEPS steps
        stale = not linear and stepper.t - self._t > ROUGH_STEPS * h
        if self._J is None or key != self._key or stale:
            with np.errstate(all="ignore"):
                J = ode_jacobian(problem, stepper.t, stepper.u).toarray()
            if not np.all(np.isfinite(J)):
                return False
            self._J, self._eigenvalues, self._key, self._t = J, np.linalg.eigvals(J), key, float(stepper.t)
        q = stepper.amplification(self._J, h, eigenvalues=self._eigenvalues)
        if q is None or not q <= AMPLIFICATION_STABLE:
            return False
        self.overruled_count += 1
        return True


def _divergence_error(problem, stepper, name, why, growth, explicit, t_seg, u_seg):
    """The ``SimulationError`` for a run stopped by the divergence criterion (``divergence.GrowthWatch``);
    an explicit method's message gives the spectral radius at the segment start (t_seg, u_seg)."""
    c = problem.c
    h = stepper.t - stepper.t_old
    if why.kind == "blow-up":
        what = f"a state became non-finite or beyond {BLOW_UP:g} (|u|max = {why.norm:.3g})"
    elif why.kind == "growth":
        what = (f"the state grew to |u|max = {why.norm:.3g}, more than max_growth = {growth.max_growth:g} "
                f"times its reference scale {why.reference:.3g} (its largest value in the first half of the "
                f"run, or what the forcing can explain)")
    else:
        what = (f"over the last {ROUGH_STEPS} steps the state grew from |u|max = {why.reference:.3g} to "
                f"{why.norm:.3g} while changing at every step by more than {ROUGH:g} times its size (a growing "
                f"oscillation that the steps do not resolve)")
    remedy = _stability_message(problem, t_seg, u_seg, stepper) if explicit else stepper.divergence_remedy()
    return SimulationError(
        f"solver '{name}' diverged at t={stepper.t:.6g} s (step h={h:.3g} s) in model '{c.model.name}': {what}; "
        f"the integration is numerically unstable (see regmech.solvers.divergence).{remedy}"
        f"{c.stiffness_hint(always=True)}")


def _few_steps_check(problem, stepper, name, t, u, t_end, growth, explicit):
    """A run of fixed steps too short for the growth tests (fewer than ``FEW_STEPS`` steps to go): refuse it
    when one step amplifies the linearisation at (t, u) by q with ``q^n > max_growth`` over the n steps left."""
    h = stepper.fixed_step
    if h is None or growth.max_growth is None or problem.size > FEW_STEPS_MAX_SIZE:
        return
    n_left = math.ceil((t_end - t) / h * (1 - 1e-12))
    if n_left >= FEW_STEPS:
        return
    J = problem.jacobian(t, u).toarray()
    with np.errstate(all="ignore"):
        q = stepper.amplification(J, h)
    if q is None or not q > 1 or n_left * math.log(q) <= math.log(growth.max_growth):
        return
    remedy = _stability_message(problem, t, u, stepper) if explicit else stepper.divergence_remedy()
    raise SimulationError(
        f"solver '{name}' would diverge from t={t:.6g} s (step h={h:.3g} s) in model '{problem.c.model.name}': "
        f"one step amplifies the linearised motion by up to {q:.3g}, i.e. {q:.3g}^{n_left} over the {n_left} "
        f"steps left, beyond max_growth = {growth.max_growth:g}; a run this short has no history for the growth "
        f"tests, so it is judged before it starts (see regmech.solvers.divergence).{remedy}"
        f"{problem.c.stiffness_hint(always=True)}")


def simulate_ode(model, name, make_stepper, t_start=0.0, t_end=1.0, dt_out=None, *, max_events=100000,
                 chatter_window=None, chatter_count=50, explicit=False, max_growth=MAX_GROWTH, probe=None,
                 record=True):
    """Run ``model`` with the stepper factory of an ODE-form solver; returns a ``Result``.

    ``make_stepper(problem, t0, u0, t_bound, knots)`` builds a stepper for one
    segment; ``knots`` are the output instants in ``(t0, t_bound]`` (fixed-step
    methods land on them exactly, adaptive ones interpolate). A run whose
    state grows more than ``max_growth`` times beyond the scale of its start
    state and forcing (``divergence.GrowthWatch``; None: only non-finite or
    beyond 1e100) stops with ``SimulationError``; ``explicit`` adds the
    spectral radius and the stable step to the message.

    ``probe`` (a ``GridProbe``) collects the states at the output instants and
    breakpoints that the steps hit exactly; with ``record=False`` (the
    companion runs of ``richardson``) nothing is recorded and the run returns
    its ``Stats`` only.

    The run holds numpy's BLAS at one thread (``blas.one_blas_thread``: scipy's steppers form their stages
    with memory-bound products that threads slow down).
    """
    with one_blas_thread():
        return _simulate_ode(model, name, make_stepper, t_start, t_end, dt_out, max_events=max_events,
                             chatter_window=chatter_window, chatter_count=chatter_count, explicit=explicit,
                             max_growth=max_growth, probe=probe, record=record)


def _simulate_ode(model, name, make_stepper, t_start, t_end, dt_out, *, max_events, chatter_window, chatter_count,
                  explicit, max_growth, probe, record):
    """``simulate_ode``'s run."""
    t_start, t_end, dt_out = check_times(t_start, t_end, dt_out)
    deadline = run_deadline(name, model, t_end)
    tc = time.perf_counter()
    c = model.compile()
    compile_time = time.perf_counter() - tc
    t0 = time.perf_counter()
    grid = output_grid(t_start, t_end, dt_out)
    stops = signal_breakpoints(model, t_start, t_end) + [t_end]
    fr = attach(c).friction      # the friction rows with their mode logic (hybrid/)
    modes = fr.start_modes(t_start) if fr else c.modes0
    stop_iter = iter(stops)
    t_stop = next(stop_iter)
    c._t_right = t_stop
    stats = Stats(solver=name, compile_time=compile_time)
    events: list[Event] = []
    if fr:
        y, yp, modes, changes = fr.settle(t_start, None, modes, initial=True)
    else:
        y, yp = c.initial_y(t_start, modes)
    problem = OdeProblem(c, modes)
    u = c.ode_state(y)
    rec = Recorder(c.mf, capacity=len(grid) + 2 * len(stops) + 8) if record else None
    out = _Sink(c, rec, probe)
    out.row(t_start, y, yp, modes)
    if probe is not None:
        probe.add(t_start, u)
    # the friction functions and the switching surfaces of piecewise laws (hybrid.surfaces)
    surf = c.__dict__.get("surfaces")
    if surf is not None:
        surf.reset()
    guards = guards_for(c)
    watch = EventWatch(c, guards, shortest_period(model)) if guards is not None else None
    guard = fr.chatter_guard(chatter_window, chatter_count, name) if fr else None
    # a compiled right-hand side (numba loaded) gets the divergence test's per-step pass compiled too
    growth = GrowthWatch(t_start, u, max_growth, compiled=out.linear and out.form._native is not None)
    growth.verdict = RoughVerdict()

    def settle(t, state, modes, crossed):
        """The mode logic at an event or a breakpoint: its changes recorded (events, chatter guard, growth
        watch); returns the restart row and the new modes."""
        y, yp, new_modes, changes = fr.settle(t, state, modes, crossed=crossed)
        for (comp, old, new, kind, *value) in changes:
            events.append(Event(t, comp, old, new, kind, value=value[0] if value else None,
                                work=value[1] if len(value) > 1 else None))
        guard.record_settle(t, changes, crossed, fr.devices)     # a crossing that changed nothing: silent
        if changes:
            growth.mode_change()
        return y, yp, new_modes
    extra = {"rejected": 0}
    t = t_start
    while True:
        if deadline is not None:
            deadline.note(stats.steps, len(events))
            deadline.check(t)
        c._t_right = t_stop
        problem.modes = modes
        # grid points inside (t, t_stop) by bisection (not a scan of the grid per segment)
        inner = grid[np.searchsorted(grid, t, side="right"):np.searchsorted(grid, t_stop, side="left")]
        knots = np.append(inner, t_stop)
        if t < t_stop:
            if surf is not None:
                for (comp, old, new, kind) in surf.begin(t, consistent_row(c, t, u, modes)[0]):
                    events.append(Event(t, comp, old, new, kind))      # reached at another event's instant
            end = _run_segment(problem, make_stepper, t, u, t_stop, knots, watch, growth, out, stats, extra, name,
                               explicit, t_end, deadline)
            stats.segments += 1
        else:
            end = SegmentEnd(t_stop, u)     # an event landed on the breakpoint: nothing left of this segment
        if end.crossed is not None:
            t, u = end.t, end.u
            y_ev, yp_ev = c.y_from_ode(t, u, modes)
            out.row(t, y_ev, yp_ev, modes)
            crossed = np.zeros(guards.n_events, int)
            crossed[end.crossed] = -1
            # every function not positive here with the one located (``_crossed_together``): surfaces at zero with
            # the crossed one (two symmetric backlashes; a contact and the damper's saturation within it, which
            # leave together) flip here with its event. Left to the next segment's start (``SurfaceSet.begin``),
            # one exactly at zero there kept its side, started disarmed and was never seen to cross: its device's
            # state then jumped at a later event, -1 -> +1
            f_crossed, s_crossed = guards.split(crossed)
            if len(s_crossed):
                # a contact (a kink of a piecewise law): the state is continuous, the run goes on from it
                for (comp, old, new, kind) in surf.cross(s_crossed):
                    events.append(Event(t, comp, old, new, kind))
            if fr is not None and np.any(f_crossed):
                y, yp, modes = settle(t, (y_ev, yp_ev), modes, f_crossed)
                u = c.ode_state(y)
                out.row(t, y, yp, modes)
            if len(events) > max_events:
                raise SimulationError(f"more than {max_events} mode changes and contacts in model '{model.name}'; "
                                      f"raise max_events or simplify the model")
            continue
        t, u = t_stop, end.u
        out.state(t, u, modes, exact=True, left=True)
        if t >= t_end:
            if fr is not None:
                fr.check_final(t, *c.y_from_ode(t, u, modes), modes)     # no device left sliding the wrong way
            break
        t_stop = next(stop_iter)
        c._t_right = t_stop
        if fr:
            y, yp, modes = settle(t, c.y_from_ode(t, u, modes), modes, None)
            u = c.ode_state(y)
        elif rec is not None:
            y, yp = consistent_row(c, t, u, modes)
        out.row(t, y, yp, modes)
    stats.wall_time = time.perf_counter() - t0
    stats.rhs_calls = problem.nfev
    stats.jac_calls += problem.njev
    stats.events = len(events)
    extra["state_growth"] = growth.largest_ratio          # how close the run came to the divergence tests
    extra["roughness"] = growth.largest_roughness
    if growth.verdict.overruled_count:
        extra["rough_verdicts_overruled"] = growth.verdict.overruled_count     # RoughVerdict: stable steps
    stats.extra.update(extra)
    if rec is None:
        stats.extra["event_list"] = events     # the companion's mode changes (compared by solvers.accuracy)
        return stats
    from ..compile.outputs import Trajectory
    T, Y, YP, L, MO = rec.arrays()
    return Result(Trajectory(c, T, Y, out.deferred_rates(YP), L, MO), events, stats, model.name)


def _crossed_together(watch, modes, t_hit, u_hit, k_hit, armed_before):
    """The event functions crossed at a located event: the one located (``k_hit``) and every other one that was
    armed at the start of the step and is not positive at ``(t_hit, u_hit)``.

    Why: ``locate`` returns one function, the earliest; two that cross at the same instant (to round-off) left the
    other unreported, and the next segment started with it at -1e-17, disarmed until positive: it was never seen
    again. Fuzz seed 91079: a brake on a torque converter's pump reversed its slip at the instant the converter's
    locked-up flow crossed its kink (both speeds through zero); DOP853 kept the brake sliding backward at up to
    276 rad/s, its friction supplying power, until a breakpoint's check refused the run 0.66 s later."""
    values = watch.values(t_hit, u_hit, modes)
    return np.union1d([k_hit], np.nonzero(armed_before & (values <= 0))[0]).astype(int)


def _run_segment(problem, make_stepper, t, u, t_stop, knots, watch, growth, out, stats, extra, name, explicit,
                 t_end, deadline=None):
    """Integrate one segment; record the grid points inside it; stop at a crossing or at ``t_stop``;
    ``deadline`` (``common.Deadline``, the run's wall-clock limit) is checked after every step."""
    c, modes = problem.c, problem.modes
    growth.segment_start(problem.rhs, t, t_stop, len(u))
    with np.errstate(all="ignore"):     # a starting step estimate that overflows: the steps' checks report it
        stepper = make_stepper(problem, t, u, t_stop, knots)
    _few_steps_check(problem, stepper, name, t, u, t_end, growth, explicit)
    if watch is not None:
        watch.arm(watch.values(t, u, modes))
    inner = knots[:-1]
    k_next = 0
    try:
        while stepper.t < t_stop:
            u_before = stepper.u.copy() if watch is not None else None       # the step start, for _relocate
            armed_before = watch.armed.copy() if watch is not None else None     # for ``_crossed_together``
            # a blow-up is reported just below, by regmech (numpy's warnings from inside the step would only be
            # noise before that error)
            with np.errstate(all="ignore"):
                stepper.step()
            if not stepper.t > stepper.t_old:
                # a NaN or non-advancing time would leave this loop (or spin in it) without the outputs
                raise SimulationError(
                    f"solver '{name}' could not advance from t={stepper.t_old:.9g} s in model '{c.model.name}' "
                    f"(the step ended at t={float(stepper.t)!r}): the model's time scales are probably beyond "
                    f"double precision.{scale_hint(c)} Check the masses and stiffnesses, or try 'ida'.")
            if deadline is not None:
                deadline.check(stepper.t)
            diverged = growth.check(stepper.t, stepper.u)
            if diverged is not None and not (diverged.kind == "rough" and (
                    stepper.exact_flow or growth.verdict.overruled(problem, stepper))):
                raise _divergence_error(problem, stepper, name, diverged, growth, explicit, t, u)
            t_hit = None
            # the output instants this step covers (fixed-step methods land on them: at its end)
            k_end = k_next
            while k_end < len(inner) and inner[k_end] <= stepper.t:
                k_end += 1
            covered = [(tq, tq == stepper.t) for tq in inner[k_next:k_end]]
            rows, states = {}, {}
            if watch is not None or out.rec is not None:
                # the output instants inside the step, read from the interpolant in one call
                between = [tq for tq, exact in covered if not exact]
                if between:
                    block = stepper.interpolate_many(between)
                    if watch is None and out.takes_blocks and isinstance(block, np.ndarray):
                        # no event to look for: the step's instants go to the result as one block of rows
                        out.states(between, block, modes)
                        k_next += len(between)
                        covered = covered[len(between):]        # the step's end, when it is an output instant
                    else:
                        states.update(zip(between, block))
            if watch is not None:
                inside = [(tq, states[tq]) for tq, exact in covered if not exact]
                end_values = watch.values(stepper.t, stepper.u, modes)
                dips = watch.scan(stepper, inside, end_values, modes, rows)
                which = watch.crossed(end_values)
                if len(which) or dips:
                    t_hit, u_hit, k_hit = watch.locate(stepper, modes, which, dips)
                    if stepper.fixed_step is None and t_hit > stepper.t_old:
                        better = {}
                        t_hit, u_hit, k_hit = _relocate(problem, make_stepper, watch, modes, stepper.t_old, u_before,
                                                        t_hit, u_hit, k_hit, stats, stepper.t,
                                                        [tq for tq, exact in covered], better)
                        for tq, uq in better.items():       # states of the re-integration, not the interpolant
                            states[tq] = uq
                            rows.pop(tq, None)
                    elif stepper.fixed_step is not None and t_hit > stepper.t_old:
                        before = [tq for tq, exact in covered if tq < t_hit]
                        t_hit, u_hit, better = _fixed_step_crossing(problem, make_stepper, watch, modes,
                                                                    stepper.t_old, u_before, stepper.t, t_hit,
                                                                    u_hit, k_hit, before, stats)
                        for tq, uq in better.items():
                            states[tq] = uq
                            rows.pop(tq, None)
            t_upto = stepper.t if t_hit is None else t_hit
            for tq, exact in covered:
                if tq > t_upto or (t_hit is not None and tq == t_hit):
                    break                   # past the event, or recorded as the event's "before" row
                if exact or out.rec is not None:        # a companion run keeps exact step ends only
                    uq = stepper.u if exact else states.get(tq)
                    out.state(tq, stepper.interpolate(tq) if uq is None else uq, modes, exact, row=rows.get(tq),
                              g=stepper.g if exact and stepper.slope_at_end else None)
                k_next += 1
            if t_hit is not None:
                return SegmentEnd(t_hit, u_hit, _crossed_together(watch, modes, t_hit, u_hit, k_hit, armed_before))
        return SegmentEnd(t_stop, stepper.u)
    finally:
        stats.steps += stepper.nsteps
        stats.jac_calls += stepper.njev
        extra["rejected"] += stepper.nrejected
        for key, val in stepper.stats().items():
            extra[key] = extra.get(key, 0) + val
