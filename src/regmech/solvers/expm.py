"""The matrix numerical-analytical integrator of REFERENCES.md [002]: ``expm``.

For a *linear* model (springs, dampers, inertias, ideal gears, rigid shafts,
force sources with any signal, Position/Speed sources, friction devices with
constant coefficients) the motion in the independent coordinates ``y`` of
the current friction modes (``compile.linear``: ``x = T y + x_off``) obeys

    M y'' + B y' + C y = F s(t)                                          (1)

with constant M, B, C and a few scalar *signals* ``s(t)`` times fixed
columns F (see ``Forcing``): a constant, the offsets of the eliminated
coordinates, every device force that changes in time (sources), the
kinematic excitation (``-K_g dg - B_g g' - M_g g''`` of moving supports) and
the forces of sliding friction devices.

Scaled first-order form (REFERENCES.md [002]): with the
Cholesky factor ``M = L L^T`` (``L = M^1/2`` for a diagonal M) and
``w = sqrt(||C^||_inf)`` [1/s], an upper bound of the highest natural
frequency, the paper's form ("frequency" scaling) is

    q = [L^T y', w L^T y],     q' = A q + b(t),
    A = [[-F^, -C^/w], [w I, 0]],   F^ = L^-1 B L^-T,   C^ = L^-1 C L^-T,
    b = [L^-1 F s(t); 0].

Scaling the position half by w keeps ``||A||`` near the highest frequency
(instead of its square), which saves about six doublings and their
round-off. It still leaves a mode of frequency w_k with entries w/w_k in
D0, whose round-off the doublings amplify; the dense path therefore scales
the position half by ``S = C^^1/2`` instead ("energy" scaling,
``q2 = S L^T y``, an eigendecomposition of C^ once per mode set): the
undamped part of A becomes skew-symmetric and D0 nearly orthogonal (2 to
10 times smaller round-off on stretched spectra, see
``analysis.expm_tables.roundoff_check``). The sparse path keeps w.

On each step of length h the signals are replaced by the polynomial of
degree p - 1 (``order_p`` = p = 1, 2, 3) through their values at the
Gauss-Legendre points of the step (p = 1: the midpoint), and the step is
exact for that forcing::

    q_{j+1} = D0 q_j + sum_k D_k W beta_k       (expm_coefficients)

The D's are computed once per (modes, h) by Taylor start and step doubling
and reused; only the columns D_k W of the inputs are formed. A forcing that
is a polynomial of degree < p on every step (steps, ramps, tables with p = 2)
is integrated exactly, at any step size, to the round-off floor; another
smooth one (a user's function) with the order of the Gauss fit (2p for slow
forcing).

Sinusoidal device forces (a library ``Torque`` or ``Force`` of a ``Sine``,
``Forcing._sine_rows``, on the segments of time events where the sine is on)
are exact too: their particular solution
``q_p(t) = Re(sum_f Z_f e^{i w_f t})``, ``(i w_f I - A) Z_f = W c_f``, is
taken out of the state before a step and put back after it
(``ExpmStepper.particular``), so the polynomial fit carries only the rest.
Why: the fit's error is a ripple at the step rate, which
excites lightly damped modes near that rate and its harmonics; a run and
its companion at 2h can ring alike, so that their difference misses it (a
random tree of 113 inertias with modes of 651-697 Hz at damping ratios near
1e-3, a 5.3 Hz sine torque, 10 ms output: at 6 and 7 steps an interval the
error was 14-23 times the estimate, and accuracy 3e-5 came back 1.4e-4
off; with the particular solution every step count is within 3e-12 of the
reference). A sine that starts inside the run is exact from its start (its
start is a time event). A sine motion of a ``Position``/``Speed`` source, a
user's function or signal class, and a forcing frequency within 1e-5 of an
undamped mode (``SINE_RESONANCE_LIMIT``) keep the polynomial fit.

Storage: dense D0 for small models; above ``SPARSE_FROM`` independent
coordinates (and a diagonal mass matrix) E = D0 - I is a scipy CSR matrix
with a drop tolerance of 1e-20 (its entries decay super-exponentially
beyond the distance a wave travels in one step, so long chains stay sparse:
2.5 % of the entries for a 1000-car train at h = 0.1 s, 8 % at h = 1 s,
measured at the former 1e-17; ``expm_coefficients``).
The dense set-up grows as n^3 (6 s at n = 1000), the sparse one about
linearly (0.07 s at n = 3000). From ``SPARSE_FROM`` = 50 coordinates: above
about 55 the dense products fall off a cliff under threaded BLAS on a
loaded 2-core machine (a contract run of expm on the 60-inertia benchmark
chain: 1.4 s dense, 0.20 s sparse; 50 inertias 0.12 / 0.16 s; with one BLAS
thread both about 0.1 s), and the sparse path gives the same answer. The 2 x 2 block structure with symmetric
blocks (REFERENCES.md [002]) is not exploited: with damping that does not commute
with the stiffness the blocks are not symmetric, and the sparse path
already removes the n^3 cost for chains.

Stick/slip: the model is linear between mode changes. The shared ODE-form
driver (``ode_driver``) checks the friction event functions after each step
and locates a crossing on ``interpolate``, which here is the *exact* flow of
the step (the D's recomputed for the sub-step), then runs the mode logic
(``settle``); the D's of each mode set are cached.

Options: ``h`` [s] the step (default ``dt_out``; output instants,
breakpoints of the signals and ``t_end`` are hit exactly, cutting an
interval into equal steps), ``order_p`` (1..3, default 2), ``tol``
(default 1e-3: bound of the estimated global error relative to the range
of each kind of state, see below; None: no estimate), ``taylor_r``
(default: the cheapest order for ``taylor_tol``), ``taylor_tol`` (target
of the truncation error model of the matrix exponential, default the unit
round-off), ``sparse`` (None: automatic), ``drop_tol`` (sparse path),
``scaling`` ("energy" or "frequency"; default energy on the dense path),
``max_events``, ``chatter_window``, ``chatter_count``.

Error estimate (``regmech.solvers.richardson``): a companion run at 2h
gives ``E = |y_h - y_2h| / (2^p - 1)`` with ``p = order_p``, the
guaranteed order of holding the inputs by a polynomial of degree
``order_p - 1`` over a step (slow forcing converges faster and piecewise
polynomial forcing is exact, so this errs on the safe side). The round-off
floor below does not shrink with h, and most of it does not even depend on
h: it comes from the set-up of the scaled matrices (the slow modes of a
stretched spectrum are resolved only to ``(w_max/w_min)^2 * 1e-16``), so
two runs with the same set-up share it and their difference cannot show
it. It is therefore bounded *before* the run from the spectrum
(``roundoff_floor``: 4 ``eps (w_max/w_min)^2`` with the spread of the links'
local frequencies; the true floor measured 0.33 to 0.9 of ``eps (w_max/w_min)^2``): a bound
above ``tol`` is refused up front with ``AccuracyError`` naming the
stiffest link (the remedy is to make it rigid), and a run's
``error_estimate`` is never below the bound (``stats.extra["error_floor"]``).
The companion runs also use the *other* scaling on the dense path, whose
round-off differs, but whether that difference shows depends on the BLAS
build, so nothing relies on it (measured on the hard case
``stretched_1e7``: error 3.3e-3..5.5e-3 of the range at every step from
1e-3 to 0.1 s, bound 2.2e-2: refused).

Round-off floor (measured): the D's are accurate to about ``nu h * 1e-16``
(the data of A are rounded, so exp(A h) is defined only to that level), but
the slow part of the response of a stretched spectrum is ill-conditioned:
the error grows like ``(w_max / w_min)^2 * 1e-16`` (5e-11 at a ratio of
1e3, 1e-6 at 1e5; scipy.linalg.expm of the augmented matrix does the same).
For the library's train (frequency ratio up to 640 at 1000 cars) the error
stays at 1e-12..1e-11 for 10, 100 and 1000 cars (benchmarks/results/expm.md).
"""

from __future__ import annotations

import functools
import math
from collections import OrderedDict

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from ..errors import AccuracyError, ParameterError, SimulationError, StructureError
from . import register
from .common import refuse_impacts
from .expm_coefficients import DROP_TOL, UNIT_ROUNDOFF, coefficients, fit_matrix, fit_nodes
from .ode_driver import KnotClock, Stepper
from .options import (FIXED_MAX_STEPS, Choice, Flag, Integer, OptionSet, Real, chatter_options,
                      fixed_max_steps_option, max_events_option, step_option,
                      tol_option)
from .richardson import DEFAULT_TOL, simulate_fixed_step

#: independent coordinates from which E is kept sparse (when the mass matrix is diagonal; measured, module docstring)
SPARSE_FROM = 50
#: coordinates up to which T and P are dense arrays
DENSE_MAPS_UPTO = 64
#: propagators kept per mode set (one per distinct step length)
CACHE_SIZE = 8
#: propagators of sub-steps kept per mode set for ``ExpmStepper.interpolate`` on models of at most
#: ``SUB_CACHE_UPTO`` independent coordinates: the event scan of the ODE-form driver reads every step at the same
#: fractions of it (``ode_driver.EventTracker.scan``), so with a fixed step the sub-steps repeat (fuzz CI seed
#: 4002, wheels with road contacts: 13,835 interpolations, each a new matrix exponential, 11 of 22 s of its expm
#: run); the refinements and the event location read other instants, which pass through an LRU of this size
SUB_CACHE_SIZE = 24
SUB_CACHE_UPTO = 400
#: Gauss-Legendre points for integrating a prescribed speed to a displacement
SPEED_QUADRATURE = 8
#: the Richardson companions' drop tolerance on the sparse path, relative to the main run's (``simulate_expm``): the
#: dropped entries' error is amplified far beyond their size on a stretched spectrum (a review: a random stiff chain
#: of 60 inertias, drop_tol 1e-17, the default then, left 4.4e-9 of the range of the angles, about 1e-11 at drop_tol
#: 0) and both runs shared it: the estimate said 1.6e-9
COMPANION_DROP = 1e-3
#: a library Torque or Force of a Sine is taken exactly (``Forcing._sine_rows``) when its row is affine in the signal
#: to this fraction of its size at three instants
SINE_FIT_TOL = 1e-10
#: ... and its particular solution is used unless the forcing frequency is so close to an undamped mode that the
#: response amplifies the forcing beyond this (``ModeSystem.sine_response``: the particular and the homogeneous parts
#: then cancel, leaving about eps times the amplification, which the pair of Richardson runs shares: a review
#: measured 3-6 times the estimate at 1e7-1e8; the polynomial fit takes such a force)
SINE_RESONANCE_LIMIT = 1e5
#: their nodes and weights on [-1, 1] (computed once: numpy's leggauss costs ~0.1 ms a call)
_GL_X, _GL_W = np.polynomial.legendre.leggauss(SPEED_QUADRATURE)
_GL_NODES01 = 0.5 * (_GL_X + 1.0)


@functools.lru_cache(maxsize=None)
def speed_weights(p: int) -> np.ndarray:
    """``W[i, k] = int_0^sigma_i L_k(s) ds`` for ``sigma = (fit_nodes(p), 1)``.

    ``L_k`` is the Lagrange polynomial of the ``SPEED_QUADRATURE`` Gauss-Legendre
    nodes on [0, 1], so with the prescribed speeds ``g'`` sampled once per step
    at those nodes, ``h W @ g'`` gives their displacements from the step start
    to each fit node and to the step end (exact for speeds of degree < 8 on a
    step; the last row is the Gauss-Legendre rule itself). This replaces one
    8-point quadrature per fit node and one per step (24 speed evaluations per
    step at p = 2) by 8 evaluations.
    """
    xi = _GL_NODES01
    sigmas = np.append(fit_nodes(p), 1.0)
    out = np.zeros((len(sigmas), len(xi)))
    for i, sg in enumerate(sigmas):
        s = sg * xi                          # the Gauss-Legendre nodes on [0, sigma]: exact for degree 7
        for k in range(len(xi)):
            others = np.delete(np.arange(len(xi)), k)
            lk = np.prod((s[:, None] - xi[others]) / (xi[k] - xi[others]), axis=1)
            out[i, k] = sg * float(np.sum(0.5 * _GL_W * lk))
    return out


# ===================================================================== linearity
def nonlinear_components(c, t_start: float, t_end: float, samples: int = 48) -> list[str]:
    """Names (``"Class 'name'"``) of the devices whose laws are not linear with constant coefficients.

    Compliant devices: a class whose Jacobian depends on its parameters only
    (``Template.affine``) is linear; for any other class the Jacobian is
    evaluated for all instances at once at ``samples`` random states
    (magnitudes spread from 1e-6 to 1e4, both signs, so dead zones and kinks
    are straddled) and times in ``[t_start, t_end]``; an instance whose
    entries change is reported. Friction devices: the kinetic capacity must
    not depend on the sliding speed (constant mu; a time-varying normal
    force is fine: it is a force input). Internal states (first-order
    devices) are reported too: the second-order form cannot hold them.

    The answer depends on the compiled system and the arguments only (the samples are seeded): it is kept
    on the compiled system (``solver="auto"`` asks at every call).
    """
    kept = c.__dict__.setdefault("_nonlinear_components", {})
    key = (float(t_start), float(t_end), int(samples))
    if key not in kept:
        if len(kept) > 16:
            kept.clear()
        kept[key] = _nonlinear_components(c, t_start, t_end, samples)
    return list(kept[key])


def _nonlinear_components(c, t_start: float, t_end: float, samples: int) -> list[str]:
    bad: list[str] = []
    rng = np.random.default_rng(20240611)
    times = np.concatenate([[t_start, t_end], rng.uniform(t_start, t_end, samples)])
    for g in c.groups:
        tpl = g.tpl
        if tpl.states or tpl.reads:      # internal states, or parameters read from the unknowns (causal blocks)
            bad += [f"{type(d).__name__} '{d.name}'" for d in g.devices]
            continue
        if tpl.affine or not tpl.jac_entries:
            continue
        nvar = 2 * tpl.k
        ref = None
        changed = np.zeros(g.n, bool)
        # kinks and dead zones sit where a coordinate meets the instance's own parameters (a play centred
        # at phi_rel0, an end stop's limits): random states alone missed a narrow play away from zero,
        # and expm then integrated a Backlash as a linear spring (a silent wrong answer)
        marks = _parameter_marks(g)
        for s in range(samples + 1 + len(marks)):
            if s == 0:
                variables = [np.zeros(g.n) for _ in range(nvar)]
            elif s <= samples:
                scale = 10.0 ** rng.uniform(-6, 4, size=(nvar, 1))
                variables = list(rng.standard_normal((nvar, g.n)) * scale)
            else:
                scale = 10.0 ** rng.uniform(-6, 4, size=(tpl.k, 1))
                variables = [marks[s - samples - 1].copy() for _ in range(tpl.k)] + \
                    list(rng.standard_normal((tpl.k, g.n)) * scale)
            with np.errstate(all="ignore"):
                out = g.call(tpl.jac_fn, variables, float(times[s % len(times)]), False)
                vals = np.array([np.broadcast_to(np.asarray(o, float), (g.n,)) for o in out])
            if ref is None:
                ref = vals.copy()
                continue
            tol = 1e-9 * (np.abs(ref) + np.abs(vals)) + 1e-300
            changed |= np.any(~(np.abs(vals - ref) <= tol), axis=0)
        bad += [f"{type(d).__name__} '{d.name}'" for d, ch in zip(g.devices, changed) if ch]
    if c.mf:
        speeds = (0.0, 1e-6, 1e-3, 0.1, 1.0, 10.0, 1e3, 1e6)
        for j, dev in enumerate(c.friction.devices):
            if getattr(c.friction, "inputs", None) and c.friction.inputs[j]:
                # a law reading the state (a thermal mass's temperature, a controller's command as normal
                # force): its force is no input of the structural-matrix form
                bad.append(f"{type(dev).__name__} '{dev.name}'")
                continue
            if getattr(dev, "impact", False):
                # a hard stop: its impacts make the speeds jump (no linear flow; ``common.refuse_impacts``)
                bad.append(f"{type(dev).__name__} '{dev.name}'")
                continue
            if getattr(dev, "coupled", False):
                # a row tied to another constraint force (lossy gear): linear per quadrant, but not a
                # force input of the structural-matrix form
                bad.append(f"{type(dev).__name__} '{dev.name}'")
                continue
            laws = [sliding_law(c.friction, j, 1, w, t_start, False) for w in speeds]
            if any(abs(d) > 0 or abs(r - laws[0][0]) > 1e-12 * (1 + abs(laws[0][0])) for r, d in laws):
                bad.append(f"{type(dev).__name__} '{dev.name}'")
    return bad


def _parameter_marks(g) -> list:
    """Coordinates at which the laws of kernel group ``g`` may change: each finite parameter value,
    just beside it, and midway between two of them (per instance, arrays of shape (n,))."""
    vals = [np.nan_to_num(np.asarray(v, float)) for v in g.param_values][:8]
    marks = []
    for i, p in enumerate(vals):
        off = 1e-6 * (1.0 + np.abs(p))
        marks += [p, p + off, p - off]
        marks += [(p + q) / 2 for q in vals[i + 1:]]
    return marks


def sliding_law(friction, j, mode, w_abs, t, left):
    """(force, d force / d|w_rel|) of friction row j sliding in ``mode`` (+-1) at speed ``w_abs``.

    Uses the device's ``relation`` (``c_own lam + c_cpl lam_cpl = rhs``, with ``c_cpl = 0`` for the
    devices expm accepts) when the friction set has one, else ``mode * kinetic``.
    """
    dev = friction.devices[j]
    if hasattr(dev, "relation"):
        quadrant = int(getattr(friction, "quadrant", np.ones(friction.mf, int))[j])
        c_own, _, rhs, drhs = dev.relation(int(mode), quadrant, w_abs, t, left)
        return rhs / c_own, drhs / c_own
    tk, dk = dev.kinetic(w_abs, t, left)
    return mode * tk, mode * dk


def check_linear(c, t_start: float, t_end: float) -> None:
    """Raise ``SimulationError`` naming the components that keep the model from being linear."""
    bad = nonlinear_components(c, t_start, t_end)
    if bad:
        shown = ", ".join(bad[:12]) + (f" and {len(bad) - 12} more" if len(bad) > 12 else "")
        raise SimulationError(
            f"solver 'expm' integrates linear models only (constant mass, damping and stiffness matrices), but in "
            f"model '{c.model.name}' {shown} {'has a law' if len(bad) == 1 else 'have laws'} whose force derivatives "
            f"change with the state or time (nonlinear or time-varying stiffness/damping, speed-dependent friction, "
            f"dead zones) or internal states (a thermal mass, a controller). Use solver='ida' or a scipy solver for "
            f"this model, or replace these components by linear ones (Spring, Damper, SpringDamper, Clutch with "
            f"constant mu).")


# ======================================================================= forcing
class Forcing:
    """The columns F and signals s(t) of (1) for one mode set.

    Signals, in order: ``1`` (constant forces: preloads, constant sources,
    stiffness times the device offsets ``e0``); the offsets of the
    eliminated coordinates at the segment start (stiffness coupling of a
    dependent coordinate into the independent ones, constant on a segment);
    the force of every compliant row whose law has a time-varying part
    ``tau_r(0, 0, t)`` (sources; the law is affine, so the rest is in C, B);
    per kinematic input its displacement since the segment start ``dg``, its
    rate ``g'`` and acceleration ``g''`` (columns ``-K_g, -B_g, -M_g``); the
    force of each sliding friction device (columns ``-(G_f T)^T``).
    """

    def __init__(self, c, lin, modes, dep, t_samples):
        self.c = c
        st = c.structure
        ST = lin.ST.tocsr()                       # compliant rows over y
        Kc = lin.Kc.tocsr()
        nq = ST.shape[1]
        left = False
        # --- device offsets tau(0, 0, t): constant rows versus rows that change in time
        self.varying_groups = []
        const_tau = np.zeros(c.Sc.shape[0])
        varying_rows = []
        for g in c.groups:
            zeros = [np.zeros(g.n)] * (2 * g.tpl.k)
            offs = self._offsets(g, zeros, t_samples[0], left)
            varies = not g.inputs_constant or (g.tpl.affine and g.tpl.offset_uses_time)
            if not g.tpl.affine and not varies:
                varies = any(not np.array_equal(offs, self._offsets(g, zeros, float(t), left)) for t in t_samples[1:])
            if varies:
                self.varying_groups.append((g, zeros, len(varying_rows)))
                for r in range(g.tpl.k):
                    varying_rows.extend(g.row_index[:, r])
            else:
                for r in range(g.tpl.k):
                    const_tau[g.row_index[:, r]] = offs[r]
        self.varying_rows = np.asarray(varying_rows, int)
        cols = []
        names = []
        # 1: constant
        f_const = -(ST.T @ (const_tau + Kc @ c.e0c))
        cols.append(sp.csr_matrix(f_const.reshape(-1, 1)))
        names.append("constant")
        # offsets of the dependent coordinates: -ST^T Kc S[:, d]
        Phi = (-(ST.T @ (Kc @ c.Sc[:, dep]))).tocsc() if len(dep) else sp.csc_matrix((nq, 0))
        used = np.nonzero(np.diff(Phi.indptr))[0]
        self.dep_used = np.asarray(dep, int)[used]
        cols.append(Phi[:, used])
        names += [f"offset {st.coord_names[k]}" for k in self.dep_used]
        # time-varying device forces
        cols.append(-(ST[self.varying_rows].T) if len(self.varying_rows) else sp.csr_matrix((nq, 0)))
        names += [f"force row {r}" for r in self.varying_rows]
        # kinematic inputs
        from ..compile.linear import kinematic_rows
        self.kin_rows = np.asarray(kinematic_rows(st), int)
        self.n_pos = len(st.position)
        ng = len(self.kin_rows)
        if ng:
            cols += [-sp.csr_matrix(lin.K_g), -sp.csr_matrix(lin.B_g), -sp.csr_matrix(lin.M_g)]
            names += [f"{lvl} {nm}" for lvl in ("dg", "g'", "g''") for nm in lin.kinematic_names]
        # sliding friction
        self.sliding = np.zeros(0, int)
        if c.mf:
            self.sliding = np.nonzero(np.isin(np.asarray(modes), (-1, 1)))[0]
            if len(self.sliding):
                GfT = (c.Gf[self.sliding] @ lin.T).tocsr()
                cols.append(-(GfT.T))
                names += [f"friction {c.friction.devices[j].name}" for j in self.sliding]
        self.F = sp.hstack(cols).tocsr()
        self.names = names
        self.n_dep = len(self.dep_used)
        self.ng = ng
        self.modes = np.asarray(modes, int)
        self.sine_rows = self._sine_rows() if len(self.varying_rows) else []

    def _sine_rows(self) -> list:
        """``[(entry, sine, sigma, kappa)]``: the time-varying device forces that are a library ``Torque`` or
        ``Force`` of a ``Sine`` (``force_signal``: the row's value is ``kappa + sigma s(t)``), with
        their place in ``values``. Decided from the model, not from sampled values: a sampled test cannot see a
        user's function that departs from a sine between its samples (a review found a narrow bump lost that way).
        ``sigma`` and ``kappa`` come from the row at three instants a quarter period apart (the two farthest apart
        in the signal give them, the third checks them)."""
        from ..signals import Sine
        out = []
        for g, zeros, start in self.varying_groups:
            if g.tpl.k != 1:
                continue
            for i, dev in enumerate(g.devices):
                # a source whose law is its signal says which parameter that is (``Torque.force_signal``), on its
                # own class: a user's subclass may have changed the law
                name = type(dev).__dict__.get("force_signal")
                if name is None:
                    continue
                sig = dev._values.get(name)
                if type(sig) is not Sine or sig.amplitude == 0.0 or sig.freq_hz == 0.0:
                    continue
                ts = sig.start_time + np.array([0.1, 0.35, 0.6]) / abs(sig.freq_hz)
                sv = np.array([sig.value(float(t)) for t in ts])
                rv = np.array([self._offsets(g, zeros, float(t), False)[0][i] for t in ts])
                a, b = max(((0, 1), (0, 2), (1, 2)), key=lambda ab: abs(sv[ab[1]] - sv[ab[0]]))
                sigma = (rv[b] - rv[a]) / (sv[b] - sv[a])
                kappa = rv[a] - sigma * sv[a]
                if np.all(np.isfinite([sigma, kappa])) and \
                        np.all(np.abs(kappa + sigma * sv - rv) <= SINE_FIT_TOL * np.max(np.abs(rv))):
                    out.append((1 + self.n_dep + start + i, sig, float(sigma), float(kappa)))
        return out

    def sinusoids(self, t):
        """The sinusoidal device forces (``_sine_rows``) on the segment of time events that holds ``t`` (a sine is
        on or off for the whole of it: its start is a breakpoint): ``(entries, beta, coef, omegas)`` with
        ``entries`` their places in ``values``, ``beta`` their constant parts and ``coef[k, f]`` their complex
        amplitudes (the force is ``beta_k + Re(coef_kf e^{i w_f t})``), or None. ``offset + A sin(w (t - t_s) +
        phi)`` is ``Re(-i A e^{i psi} e^{i w t})`` with ``psi = phi - w t_s``."""
        on = [(e, sg, sigma, kappa) for e, sg, sigma, kappa in self.sine_rows if sg._on(t, False)]
        if not on:
            return None
        w = np.array(sorted({2.0 * math.pi * sg.freq_hz for _, sg, _, _ in on}))
        coef = np.zeros((len(on), len(w)), complex)
        beta = np.empty(len(on))
        for k, (e, sg, sigma, kappa) in enumerate(on):
            wk = 2.0 * math.pi * sg.freq_hz
            psi = sg.phase - wk * sg.start_time
            coef[k, int(np.searchsorted(w, wk))] = sigma * (-1j) * sg.amplitude * np.exp(1j * psi)
            beta[k] = kappa + sigma * sg.offset
        return np.array([e for e, *_ in on], int), beta, coef, w

    @staticmethod
    def _offsets(g, zeros, t, left):
        out = g.call(g.tpl.res_fn, zeros, t, left)
        return np.array([np.broadcast_to(np.asarray(out[r], float), (g.n,)) for r in range(g.tpl.k)])

    @property
    def size(self) -> int:
        return self.F.shape[1]

    def values(self, t: float, seg: "Segment", dg_speed: np.ndarray) -> np.ndarray:
        """s(t) on the current segment; ``dg_speed`` the displacements of the Speed inputs since its start."""
        c = self.c
        parts = [np.ones(1), seg.dep_offsets]
        if self.varying_groups:
            vals = np.empty(len(self.varying_rows))
            for g, zeros, start in self.varying_groups:
                offs = self._offsets(g, zeros, t, t >= c._t_right)
                vals[start:start + offs.size] = offs.ravel()
            parts.append(vals)
        if self.ng:
            parts.append(self.kinematics(t, seg, dg_speed))
        if len(self.sliding):
            # constant coefficients: the kinetic force mode * tau_k does not depend on the sliding speed
            left = t >= c._t_right
            parts.append(np.array([sliding_law(c.friction, j, self.modes[j], 0.0, t, left)[0]
                                   for j in self.sliding]))
        return np.concatenate(parts)

    def kinematics(self, t, seg, dg_speed):
        """[dg, g', g''] of every kinematic input at t (dg: since the segment start)."""
        gp, gv = self.c._refs(t)
        dg = np.empty(self.ng)
        g1 = np.empty(self.ng)
        g2 = np.empty(self.ng)
        si = 0
        for i, row in enumerate(self.kin_rows):
            if row < self.n_pos:
                dg[i] = gp[0, row] - seg.g_start[i]
                g1[i], g2[i] = gp[1, row], gp[2, row]
            else:
                dg[i] = dg_speed[si]
                g1[i], g2[i] = gv[0, row - self.n_pos], gv[1, row - self.n_pos]
                si += 1
        return np.concatenate([dg, g1, g2])

    def rates(self, t):
        """g' of the kinematic inputs at t (for the velocities of the driven coordinates)."""
        gp, gv = self.c._refs(t)
        return np.array([gp[1, r] if r < self.n_pos else gv[0, r - self.n_pos] for r in self.kin_rows])

    @property
    def speed_inputs(self) -> np.ndarray:
        return np.nonzero(self.kin_rows >= self.n_pos)[0]

    def speed_values(self, t) -> np.ndarray:
        gp, gv = self.c._refs(t)
        return gv[0, self.kin_rows[self.kin_rows >= self.n_pos] - self.n_pos]


class Segment:
    """Reference values of one segment (from one (re)start of the stepper)."""

    def __init__(self, dep_offsets, g_start):
        self.dep_offsets = dep_offsets
        self.g_start = g_start


# =================================================================== mode system
class ModeSystem:
    """Everything about one friction mode set: matrices, scaling, forcing columns, propagators."""

    def __init__(self, c, modes, t, x, v, options):
        from ..compile.linear import linearize
        self.c = c
        try:
            lin = linearize(c, t=t, modes=modes, at=(x, v), sparse=True)
        except StructureError as exc:
            raise SimulationError(f"solver 'expm': {exc}") from None
        st = c.structure
        index = {name: k for k, name in enumerate(st.coord_names)}
        if len(index) != len(st.coord_names):      # pragma: no cover - the structure names coordinates uniquely
            raise SimulationError("solver 'expm': coordinate names are not unique")
        self.indep = np.array([index[nm] for nm in lin.coords], int)
        self.dep = np.setdiff1d(np.arange(c.n), self.indep)
        # small models: dense maps back to all coordinates (a sparse product costs more than it saves)
        small = c.n <= DENSE_MAPS_UPTO
        self.T = lin.T.toarray() if small else lin.T.tocsr()
        self.P = lin.P.toarray() if small else lin.P.tocsr()
        self.nq = nq = lin.n
        self.N = 2 * nq
        self.options = options
        t_samples = [t, options["t_end"]] + list(np.linspace(t, options["t_end"], 5)[1:-1])
        self.forcing = Forcing(c, lin, modes, self.dep, t_samples)
        M, B, C = (sp.csr_matrix(X) for X in (lin.M, lin.B, lin.C))
        mdiag = M.diagonal()
        diagonal = (M - sp.diags(mdiag)).count_nonzero() == 0
        if np.any(mdiag <= 0):
            raise SimulationError(f"solver 'expm': the mass matrix of model '{c.model.name}' is singular "
                                  f"(a coordinate without mass); give every moving node a mass")
        want_sparse = options["sparse"]
        self.sparse = (nq >= SPARSE_FROM if want_sparse is None else bool(want_sparse)) and diagonal
        if self.sparse:
            s = 1.0 / np.sqrt(mdiag)
            Fh = (sp.diags(s) @ B @ sp.diags(s)).tocsr()
            Ch = (sp.diags(s) @ C @ sp.diags(s)).tocsr()
            self._L = ("diag", np.sqrt(mdiag))
            Win_top = sp.diags(s) @ self.forcing.F
        else:
            Md = M.toarray()
            if diagonal:
                self._L = ("diag", np.sqrt(mdiag))
                s = 1.0 / np.sqrt(mdiag)
                Fh = s[:, None] * B.toarray() * s[None, :]
                Ch = s[:, None] * C.toarray() * s[None, :]
            else:
                try:
                    Lc = la.cholesky(Md, lower=True)
                except la.LinAlgError:
                    raise SimulationError(f"solver 'expm': the mass matrix of model '{c.model.name}' is not "
                                          f"positive definite") from None
                self._L = ("full", Lc)
                Fh = self._l_inv(self._l_inv(B.toarray()).T).T
                Ch = self._l_inv(self._l_inv(C.toarray()).T).T
                Fh = 0.5 * (Fh + Fh.T)
                Ch = 0.5 * (Ch + Ch.T)
            Win_top = self._l_inv(self.forcing.F.toarray())
        c_norm = float(abs(Ch).sum(axis=1).max()) if nq else 0.0
        f_norm = float(abs(Fh).sum(axis=1).max()) if nq else 0.0
        # w: an upper bound of the highest natural frequency (Gershgorin); without springs any rate
        # scale works (A is then nilpotent or first order), the damping rate or 1/s
        self.w = math.sqrt(c_norm) if c_norm > 0 else (f_norm if f_norm > 0 else 1.0)
        w = self.w
        scaling = options.get("scaling") or ("frequency" if self.sparse else "energy")
        if scaling == "energy" and self.sparse:
            raise ParameterError("solver 'expm': scaling='energy' needs the dense path (sparse=False)")
        self.scaling = scaling
        self._S = None
        if self.sparse:
            self.A = sp.bmat([[-Fh, -Ch / w], [w * sp.identity(nq), None]], format="csr")
            self.Win = np.vstack([np.asarray(Win_top.toarray()), np.zeros((nq, Win_top.shape[1]))])
            self.nu = float(abs(self.A).sum(axis=1).max()) if nq else 0.0
        elif scaling == "energy":
            self.A, self.nu = self._energy_form(Fh, Ch, f_norm)
            self.Win = np.vstack([Win_top, np.zeros((nq, Win_top.shape[1]))])
        else:
            self.A = np.block([[-Fh, -Ch / w], [w * np.eye(nq), np.zeros((nq, nq))]])
            self.Win = np.vstack([Win_top, np.zeros((nq, Win_top.shape[1]))])
            self.nu = float(abs(self.A).sum(axis=1).max()) if nq else 0.0
        self.p = options["order_p"]
        self.Vinv = fit_matrix(self.p)
        self.nodes = fit_nodes(self.p)
        self._sine_cache: dict = {}
        self._cache: OrderedDict = OrderedDict()
        self._sub_cache: OrderedDict = OrderedDict()
        self.setups = 0
        self.setup_time = 0.0
        self.last_stats: dict = {}

    # ------------------------------------------------------- sinusoidal forces
    def sine_response(self, sine):
        """``(Z, omegas)``: the particular solution ``q_p(t) = Re(sum_f Z_f e^{i w_f t})`` of ``q' = A q + b(t)`` for
        the sinusoidal device forces ``sine`` of a segment (``Forcing.sinusoids``): ``(i w_f I - A) Z_f = sum_k W_k
        coef_kf``, kept for the next segment with the same forces. Or None (no such force, or a forcing frequency
        within 1 / ``SINE_RESONANCE_LIMIT`` of an undamped mode): the step's polynomial fit then carries them (why
        the particular solution: the module docstring)."""
        if sine is None or not self.N:
            return None
        entries, beta, coef, w = sine
        key = (entries.tobytes(), coef.tobytes(), w.tobytes())
        if key not in self._sine_cache:
            if len(self._sine_cache) >= CACHE_SIZE:
                self._sine_cache.pop(next(iter(self._sine_cache)))
            self._sine_cache[key] = self._solve_sine(entries, coef, w)
        return self._sine_cache[key]

    def _solve_sine(self, entries, coef, w):
        Wk = np.asarray(self.Win[:, entries])
        Z = np.empty((len(w), self.N), complex)
        for f, wf in enumerate(w):
            rhs = Wk @ coef[:, f]
            size = float(np.max(np.abs(rhs), initial=0.0))
            if size == 0.0:
                Z[f] = 0.0
                continue
            try:
                with np.errstate(all="ignore"):
                    if sp.issparse(self.A):
                        from scipy.sparse.linalg import spsolve
                        z = spsolve((1j * wf * sp.identity(self.N, format="csc") - self.A).tocsc(), rhs)
                    else:
                        z = np.linalg.solve(1j * wf * np.eye(self.N) - self.A, rhs)
            except (np.linalg.LinAlgError, RuntimeError):
                return None
            if not np.all(np.isfinite(z)) or float(np.max(np.abs(z))) * wf > SINE_RESONANCE_LIMIT * size:
                return None
            Z[f] = z
        return Z, np.asarray(w)

    # ------------------------------------------------------------- scaling
    def _energy_form(self, Fh, Ch, f_norm):
        """A for the position half scaled by ``S = (C^ + sigma^2 I)^1/2`` instead of ``w``.

        With ``C^ = V diag(lam) V^T``, ``s = sqrt(lam + sigma^2)``: ``q2 = S L^T y``,
        ``A = [[-F^, -V diag(lam/s) V^T], [S, 0]]``. Each undamped mode then has the block
        ``[[0, -lam/s], [s, 0]]``, skew-symmetric up to sigma, so D0 is (nearly) orthogonal
        and the round-off of the doublings is not amplified. With the single scale w = w_max a
        mode of frequency w_k has entries w_max/w_k in D0, and the doublings amplify their
        round-off by that factor: the floor grows like (w_max/w_min) * nu h * 1e-16
        (measured in benchmarks/results/expm.md). ``sigma`` only matters for rigid-body modes
        (lam = 0): the smallest non-zero lam (or the damping rate, or 1/s).
        """
        lam, V = la.eigh(Ch)
        lam = np.maximum(lam, 0.0)
        lmax = lam.max(initial=0.0)
        rigid = lam <= 1e-12 * lmax
        if rigid.any():
            sigma2 = lam[~rigid].min() if (~rigid).any() else max(f_norm, 1.0) ** 2
        else:
            sigma2 = 0.0
        sv = np.sqrt(lam + sigma2)
        S = (V * sv) @ V.T
        self._S = (S, (V / sv) @ V.T)
        nq = len(lam)
        A = np.block([[-Fh, -(V * (lam / sv)) @ V.T], [S, np.zeros((nq, nq))]])
        # ||A||_2 <= ||F^||_2 + max(||S||_2, ||V lam/s V^T||_2) and ||F^||_2 <= ||F^||_inf (symmetric)
        nu = f_norm + float(sv.max(initial=0.0))
        return A, nu

    def _position_scale(self, y_l):
        return self.w * y_l if self._S is None else self._S[0] @ y_l

    def _position_unscale(self, q2):
        return q2 / self.w if self._S is None else self._S[1] @ q2

    def _l_inv(self, X):
        kind, L = self._L
        if kind == "diag":
            return X / L.reshape((-1,) + (1,) * (np.ndim(X) - 1))
        return la.solve_triangular(L, X, lower=True)

    def _lt_inv(self, X):
        kind, L = self._L
        if kind == "diag":
            return X / L
        return la.solve_triangular(L, X, lower=True, trans="T")

    def _lt(self, X):
        kind, L = self._L
        return L * X if kind == "diag" else L.T @ X

    def state(self, y, yd) -> np.ndarray:
        """q = [L^T y', w L^T y]."""
        return np.concatenate([self._lt(yd), self._position_scale(self._lt(y))])

    def coordinates(self, q):
        """(y, y') from q."""
        nq = self.nq
        return self._lt_inv(self._position_unscale(q[nq:])), self._lt_inv(q[:nq])

    # --------------------------------------------------------- propagators
    def propagator(self, h: float, cache: bool = True, sub: bool = False) -> "Propagator":
        """The propagator of a step h, kept in the step cache (``cache``) or, for a sub-step of the interpolation
        (``sub``), in the sub-step cache of a small model (``SUB_CACHE_SIZE``)."""
        key = float(f"{h:.12e}")
        store = self._cache if cache else (self._sub_cache if sub and self.nq <= SUB_CACHE_UPTO else None)
        limit = CACHE_SIZE if cache else SUB_CACHE_SIZE
        prop = store.get(key) if store is not None else None
        if prop is not None:
            store.move_to_end(key)
            return prop
        import time
        t0 = time.perf_counter()
        opts = self.options
        coef = coefficients(self.A, self.Win, h, self.p, nu=self.nu, tol=opts["taylor_tol"], r=opts["taylor_r"],
                            drop_tol=opts["drop_tol"])
        prop = Propagator(coef, self.Vinv)
        self.setups += 1
        self.setup_time += time.perf_counter() - t0
        self.last_stats = coef.stats
        if store is not None:
            store[key] = prop
            if len(store) > limit:
                store.popitem(last=False)
        return prop


class Propagator:
    """One step of length h: ``q_new = q + E q + sum_i H_i s(t + sigma_i h)``.

    ``G[k-1] = D_k W / h^(k-1)`` act on the coefficients of the fitted
    polynomial in the normalised time ``sigma = s/h``; ``H`` folds the fit
    (``V^-1``) into them, so a step takes the signal values at the nodes.
    """

    def __init__(self, coef, Vinv):
        self.h = coef.h
        self.E = coef.E
        p = len(coef.DW)
        self.G = [coef.DW[k] / coef.h ** k for k in range(p)]
        self.H = [sum(Vinv[k, i] * self.G[k] for k in range(p)) for i in range(p)]
        self.Hcat = np.hstack(self.H)
        self.coef = coef

    def step(self, q, node_values):
        """node_values: p x n_sig signal values at the fit nodes."""
        return q + self.E @ q + self.Hcat @ np.ravel(node_values)

    def step_poly(self, q, beta, scale):
        """Step with polynomial coefficients ``beta`` (p x n_sig) of ``sigma^(k-1)``, each scaled by ``scale^(k-1)``."""
        out = q + self.E @ q
        for k, G in enumerate(self.G):
            out = out + G @ (beta[k] * scale ** k)
        return out


# ======================================================================= stepper
class ExpmStepper(Stepper):
    """Fixed steps of at most h on one segment, exact for the fitted forcing."""

    #: never judged rough (``Stepper.exact_flow``): a lightly damped mode of several kHz read every millisecond
    #: changes completely from one output step to the next while a step input drives the state up from rest
    #: (a random tree of 193 inertias, modes up to 4.4 kHz, a step torque, dt_out 1e-3: the exact flow was
    #: stopped as diverged at t = 0.18 s)
    exact_flow = True

    def __init__(self, engine, problem, t0, u0, t_bound, knots, h, clock=KnotClock):
        self.engine = engine
        c = self.c = problem.c
        modes = problem.modes
        self.ms = engine.mode_system(modes, t0, u0)
        ms, fo = self.ms, self.ms.forcing
        x, v, z = c.ode_lift(t0, u0, modes)
        y, yd = x[ms.indep], v[ms.indep]
        x_off = x - ms.T @ y
        g_start = np.zeros(fo.ng)
        if fo.ng:
            gp, _ = c._refs(t0)
            for i, row in enumerate(fo.kin_rows):
                if row < fo.n_pos:
                    g_start[i] = gp[0, row]
        self.seg = Segment(x_off[fo.dep_used], g_start)
        self.x_off = x_off
        self.t = self.t_old = float(t0)
        self.q = self.q_old = ms.state(y, yd)
        self.n_speed = len(fo.speed_inputs)
        self._no_speed = np.zeros(self.n_speed)
        self.dg_speed = self.dg_speed_old = self._no_speed
        self.u = np.array(u0, float)
        self.u_old = self.u
        self.clock = clock(t0, knots, t_bound, h)
        self.fixed_step = float(h)
        # the segment's sinusoidal device forces, exact through their particular solution (``ModeSystem.sine_response``)
        sine = fo.sinusoids(float(t0))
        response = ms.sine_response(sine)
        # Z and omegas of q_p (``particular``), and the forces' places in ``values`` with their constant parts
        self._sine_Z, self._sine_w = response if response is not None else (None, None)
        self._sine_entries, self._sine_beta = (sine[0], sine[1]) if response is not None else (None, None)
        self.nsteps = self.nrejected = self.njev = 0
        self._step_beta = None
        self._interp = 0

    # --------------------------------------------------------------- helpers
    def _speed_displacement(self, t_from, t_to):
        """Integral of the prescribed speeds over [t_from, t_to] (Gauss-Legendre)."""
        fo = self.ms.forcing
        if not self.n_speed or t_to == t_from:
            return self._no_speed
        half = 0.5 * (t_to - t_from)
        return half * sum(wi * fo.speed_values(t_from + half * (xi + 1.0)) for xi, wi in zip(_GL_X, _GL_W))

    def _step_displacements(self, t, h):
        """Displacements of the prescribed speeds from t to each fit node and to t + h ((p + 1) x n_speed)."""
        fo = self.ms.forcing
        speeds = np.array([fo.speed_values(t + h * x) for x in _GL_NODES01])
        return h * (speed_weights(self.ms.p) @ speeds)

    def _node_values(self, t, h, disp):
        ms, fo = self.ms, self.ms.forcing
        vals = np.empty((ms.p, fo.size))
        for i, s in enumerate(ms.nodes):
            dgs = self.dg_speed + disp[i] if self.n_speed else self._no_speed
            vals[i] = fo.values(t + s * h, self.seg, dgs)
        if self._sine_Z is not None:
            # the sinusoidal parts are in the particular solution (``particular``): the fit carries the constant part
            vals[:, self._sine_entries] = self._sine_beta
        return vals

    def particular(self, t: float):
        """``q_p(t)`` of the segment's sinusoidal device forces, or 0."""
        if self._sine_Z is None:
            return 0.0
        return (np.exp(1j * self._sine_w * t) @ self._sine_Z).real

    def _to_u(self, t, q, dg_speed):
        """The ODE state [x_K, v_K] of the driver from q (all coordinates through T, P)."""
        ms, fo, c = self.ms, self.ms.forcing, self.c
        y, yd = ms.coordinates(q)
        x = ms.T @ y + self.x_off
        v = ms.T @ yd
        if fo.ng:
            dg = fo.kinematics(t, self.seg, dg_speed)[:fo.ng]
            x = x + ms.P @ dg
            v = v + ms.P @ fo.rates(t)
        return np.concatenate([x[c.Kx], v[c.Kv]])

    # ------------------------------------------------------------------ step
    def step(self):
        h, t_new = self.clock.next_step(self.t)
        prop = self.ms.propagator(h)
        disp = self._step_displacements(self.t, h) if self.n_speed else None
        vals = self._node_values(self.t, h, disp)
        # exact for sinusoidal forces: the flow of the rest from q - q_p, plus q_p at the end (``ExpmStepper.particular``)
        q_new = prop.step(self.q - self.particular(self.t), vals) + self.particular(t_new)
        dg_new = self.dg_speed + disp[-1] if self.n_speed else self._no_speed
        self.t_old, self.q_old, self.u_old, self.dg_speed_old = self.t, self.q, self.u, self.dg_speed
        self._step_h, self._step_beta = h, self.ms.Vinv @ vals
        self.t, self.q, self.dg_speed = t_new, q_new, dg_new
        self.u = self._to_u(t_new, q_new, dg_new)
        self.nsteps += 1

    def interpolate(self, tq):
        """The exact flow of the last step (same fitted forcing) at t_old <= tq <= t."""
        if tq == self.t:
            return self.u
        if tq == self.t_old:
            return self.u_old
        tau = tq - self.t_old
        prop = self.ms.propagator(tau, cache=False, sub=True)
        self._interp += 1
        q = (prop.step_poly(self.q_old - self.particular(self.t_old), self._step_beta, tau / self._step_h)
             + self.particular(tq))
        dg = self.dg_speed_old + self._speed_displacement(self.t_old, tq)
        return self._to_u(tq, q, dg)

    def stats(self):
        return {"interpolation_setups": self._interp}


class ExpmEngine:
    """Mode systems (cached per mode set) and options of one simulation (shared by the error estimate's
    companion runs, so their step matrices are computed once per mode set and step length)."""

    def __init__(self, c, options):
        self.c = c
        self.options = options
        self.systems: dict = {}

    def mode_system(self, modes, t, u) -> ModeSystem:
        key = tuple(int(m) for m in modes)
        ms = self.systems.get(key)
        if ms is None:
            x, v, _ = self.c.ode_lift(t, u, modes)
            ms = self.systems[key] = ModeSystem(self.c, modes, t, x, v, self.options)
        return ms

    def other_scaling(self) -> str | None:
        """The scaling of the error estimate's companion runs: on the dense path the one this engine did not
        use, so that the round-off of the set-up (which does not shrink with h) differs between the runs and
        shows in their difference; the sparse path has the frequency scaling only."""
        ms = next(iter(self.systems.values()), None)
        if ms is None or ms.sparse:
            return self.options["scaling"]
        return "frequency" if ms.scaling == "energy" else "energy"

    def stats(self) -> dict:
        out = {"mode_sets": len(self.systems),
               "setups": sum(ms.setups for ms in self.systems.values()),
               "setup_time": sum(ms.setup_time for ms in self.systems.values())}
        if self.systems:
            ms = next(iter(self.systems.values()))
            out.update({"sparse": ms.sparse, "scaling": ms.scaling, "w": ms.w, "nu": ms.nu,
                        "inputs": ms.forcing.size})
            out.update({k: v for k, v in ms.last_stats.items()})
        return out


EXPM_OPTIONS = OptionSet(
    "the fixed-step matrix exponential for linear models: it takes a step h and a bound tol of its estimated "
    "global error instead of rtol/atol",
    h=step_option("step [s] (default dt_out)"),
    order_p=Integer("number of forcing polynomial coefficients per step (default 2)", 1, 3),
    tol=tol_option(),
    taylor_r=Integer("order of the Taylor start of the exponential (default: chosen from taylor_tol)", 1, 18,
                     optional=True),
    taylor_tol=Real("relative truncation error allowed in the Taylor start (default 2^-53)", 0.0, 1.0),
    sparse=Flag("keep the propagator sparse (default: from the model's size)", optional=True),
    drop_tol=Real(f"relative size below which sparse entries are dropped (default {DROP_TOL:g})", 0.0, 1e-6,
                  lo_closed=True),
    scaling=Choice("scaling of the coordinates (default: energy on the dense path, frequency on the sparse one)",
                   ("energy", "frequency"), optional=True),
    max_steps=fixed_max_steps_option(),
    max_events=max_events_option(),
    **chatter_options(),
)


@register("expm", EXPM_OPTIONS)
def simulate_expm(model, t_start=0.0, t_end=1.0, dt_out=None, h=None, order_p=2, tol=DEFAULT_TOL, taylor_r=None,
                  taylor_tol=UNIT_ROUNDOFF, sparse=None, drop_tol=DROP_TOL, scaling=None, max_steps=FIXED_MAX_STEPS,
                  max_events=100000,
                  chatter_window=None, chatter_count=50):
    """The step-doubling matrix exponential integrator for linear models (see regmech.solvers.expm).

    ``tol`` (default 1e-3): bound of the Richardson estimate of the global error relative to the range of
    each kind of state (``AccuracyError`` beyond it; None: no estimate; see regmech.solvers.richardson).
    """
    refuse_impacts(model, "expm")
    c = model.compile()
    check_linear(c, t_start, t_end)
    floor = roundoff_floor(c)
    if tol is not None and floor is not None and floor[0] > tol:
        raise AccuracyError(_floor_refusal(c, tol, *floor), component=floor[1].name, estimate=floor[0], accuracy=tol)
    step = dt_out if h is None else h
    options = {"order_p": order_p, "taylor_r": taylor_r, "taylor_tol": float(taylor_tol), "sparse": sparse,
               "drop_tol": float(drop_tol), "t_end": float(t_end), "scaling": scaling}
    engine = ExpmEngine(c, options)
    engines = {False: engine}

    def make_stepper(clock, companion):
        if companion and True not in engines:
            # the companions use the other scaling on the dense path, and on the sparse one a drop tolerance
            # COMPANION_DROP times smaller: the round-off of the set-up and the dropped entries, which do not shrink
            # with h, then differ between the runs and show in their difference
            engines[True] = ExpmEngine(c, {**options, "scaling": engine.other_scaling(),
                                           "drop_tol": options["drop_tol"] * COMPANION_DROP})
        used = engines[companion]

        def make(problem, t0, u0, t_bound, knots):
            return ExpmStepper(used, problem, t0, u0, t_bound, knots, float(step), clock=clock)
        return make

    def after_main(res):
        res.stats.extra.update(engine.stats())
        res.stats.extra["h"] = float(step)
        res.stats.extra["order_p"] = order_p

    return simulate_fixed_step(model, "expm", make_stepper, h=float(step), order=order_p, tol=tol, t_start=t_start,
                               t_end=t_end, dt_out=dt_out, after_main=after_main, max_steps=max_steps,
                               max_events=max_events,
                               chatter_window=chatter_window, chatter_count=chatter_count,
                               floor=floor[0] if floor is not None else 0.0)


#: safety factor of the round-off bound over ``eps (w_max/w_min)^2`` (measured 0.33 to 0.9 of it, below)
ROUNDOFF_SAFETY = 4.0


def roundoff_floor(c):
    """``(bound, device, omega, ratio)``: a-priori bound of expm's round-off floor, or None without links.

    The slow part of the response of a stretched spectrum is resolved only to
    about ``eps (w_max / w_min)^2`` of the range (the set-up of the scaled
    matrices, not the steps: the floor does not depend on h, so two runs that
    share a set-up also share it and no companion run can be relied on to show
    it, whatever the BLAS build). ``w_max / w_min`` is the spread of the links'
    local frequencies (``CompiledSystem.fastest_link``). Measured on the hard
    cases' stretched chains (frequency ratios 1e3 to 1e7) against 30-digit
    answers at h = 0.01 s, the error is 0.33 to 0.9 of ``eps (w_max/w_min)^2``
    (the same at h from 1e-3 to 0.1 s), so the bound is ``ROUNDOFF_SAFETY``
    times that.
    """
    link = c.fastest_link()
    if link is None:
        return None
    dev, w, ratio = link
    return float(ROUNDOFF_SAFETY * np.finfo(float).eps * ratio ** 2), dev, w, ratio


def _floor_refusal(c, tol, bound, dev, w, ratio) -> str:
    return (f"solver 'expm' on model '{c.model.name}': the round-off floor of the matrix exponential on this "
            f"spectrum, up to {ROUNDOFF_SAFETY:g} eps * {ratio:.3g}^2 = {bound:.2g} of the range, exceeds tol = {tol:g}, at any step. "
            f"The stiffest link, {type(dev).__name__} '{dev.name}' (local mode {w / 2 / np.pi:.3g} Hz), is "
            f"{ratio:.3g} times faster than the softest: make it rigid (Shaft(stiffness=None)) or let "
            f"rm.Scene(band_hz=...) do it, which removes the floor; or loosen tol; or pass tol=None to take the "
            f"answer unchecked. (See regmech.solvers.expm.roundoff_floor.)")


__all__ = ["simulate_expm", "check_linear", "nonlinear_components", "ModeSystem", "Propagator", "Forcing"]
