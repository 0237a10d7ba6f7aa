"""The energy book of a passive linear model: a run whose energy grew is refused, not returned.

A model whose ODE form is the linear one (``compile.odeform``: masses, springs,
dampers, no constraints, no device states) and that nothing drives (every
signal a ``Constant`` and the rates at rest zero: no source, no preload, no
offset) obeys ``M x'' + B x' + K x = 0`` with ``M`` the diagonal masses,
``K = -M dg_v/dx`` and ``B = -M dg_v/dv``, both symmetric, ``B`` diagonally
dominant with a non-negative diagonal (so positive semidefinite: any network
of dampers ``d >= 0``). Its energy

    E(x, v) = 1/2 v^T M v + 1/2 x^T K x        [J]

can only stay (no damping) or fall: ``dE/dt = -v^T B v <= 0`` for the
symmetric positive semidefinite ``B`` of dampers. The common motion of a
group of masses that nothing grounds keeps its momentum, and its kinetic
energy ``p^2 / (2 M)`` apart: the book leaves it out, so that a drivetrain's
spin does not hide the growth of its vibration. A numerical method that is
unstable on the model's fastest mode at the settings asked (an explicit
Runge-Kutta method at a loose rtol on an undamped chain) makes it grow.
``GrowthWatch`` stops a geometric blow-up of the state by ``1e4``; an energy
that grows 12,000-fold is a state grown about 110-fold, below that. Measured
on the hard case ``long_horizon`` (undamped 4-inertia chain, 100 s, about 300
periods of its highest mode): ``scipy:RK45`` and ``dopri5`` at rtol 1e-2
returned an answer whose energy had grown 12,169-fold, 38 times the range off,
with no error; at 1e-3 the largest energy was 1.0012 times the start, DOP853
at 1e-2 1.0038 times.

``check`` refuses a run whose largest energy over its output rows exceeds
``ENERGY_GROWTH`` (2, an amplitude 41 % above what the start holds) times
the start energy: no consistent answer of a passive model can show that, at
any tolerance regmech accepts. It holds every run of a named solver made
without ``accuracy=`` (``solvers.simulate``): such a run has no estimate of
its error. The contract's runs are held by its estimate instead, which sees
such a run as far off its companion (and its fixed-step retries need the step
that Richardson suggests, not a refusal). Cost: one pass over the output rows
(kinetic energy) and one sparse product with ``K`` (potential), for the
passive models only. Models the test cannot judge (nonlinear laws,
friction, constraints, device states, any non-constant signal or non-zero
forcing, a start at rest) are not checked; the contract (``accuracy=``) and
the divergence tests remain their guard.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import SimulationError

#: a passive model's energy may grow to at most this many times its start value over a run
ENERGY_GROWTH = 2.0
#: relative asymmetry of M dg_v/du up to which K and B count as symmetric (round-off of the 1/m products)
SYMMETRY_TOL = 1e-9


class PassiveEnergy:
    """``E = 1/2 v^T M v + 1/2 x^T K x`` of a passive linear model (module docstring), less the kinetic energy
    ``p_g^2 / (2 M_g)`` of each free group's common motion (``free``: the index arrays of the groups of masses
    that springs and dampers join to each other and to nothing else, whose momentum ``p_g`` is conserved)."""

    def __init__(self, c, mass, K, free=()):
        self.c, self.mass, self.K, self.free = c, mass, K, tuple(free)

    def of_rows(self, Y) -> np.ndarray:
        """The energy [J] of every output row ``Y`` (rows of the compiled system's ``y``) beyond the free groups'
        common motion (what the springs and dampers can exchange)."""
        c = self.c
        X, V = Y[:, c._sx], Y[:, c._sv]
        kinetic = 0.5 * (V * V) @ self.mass
        if self.free:
            # a free group's common angle leaves the springs unstretched (K 1_g = 0): taken out of the positions
            # (a copy: Y is the result's) so that x'Kx has the round-off of the twist, not of an angle grown to
            # 1e5 rad at 190 rad/s over 500 s
            X = np.array(X)
            for idx in self.free:
                m = self.mass[idx]
                kinetic -= 0.5 * (V[:, idx] @ m) ** 2 / m.sum()
                X[:, idx] -= ((X[:, idx] @ m) / m.sum())[:, None]
        potential = 0.5 * np.einsum("ij,ij->i", X, np.asarray((self.K @ X.T).T))
        return kinetic + potential


def passive_energy(c):
    """The ``PassiveEnergy`` of compiled system ``c``, or None when the model is not one it can judge (kept
    with the compiled system: dropped with it on any change of the model)."""
    if "_passive_energy" not in c.__dict__:
        c._passive_energy = _build(c)
    return c._passive_energy


def _build(c):
    from ..compile.odeform import ode_form
    from ..signals import Constant
    from .common import model_signals
    if c.nz or c.mf or c.n == 0:
        return None
    if not all(isinstance(val, Constant) for val in model_signals(c.model, c)):
        return None
    try:
        form = ode_form(c)
        if not form.linear or form.size != 2 * c.n:
            return None
        t0 = 0.0
        rest = form.rhs(t0, np.zeros(form.size))
        if np.any(rest != 0.0):
            return None                     # a source, a preload or an offset: the book needs its work
        J = sp.csr_matrix(form.jacobian())
    except Exception:       # noqa: BLE001 - a model the linear form cannot hold is simply not checked
        return None
    n = c.n
    mass = np.asarray(c.mass, float)
    if not np.all(mass > 0):
        return None
    M = sp.diags(mass)
    K = sp.csr_matrix(-(M @ J[n:2 * n, :n]))
    B = sp.csr_matrix(-(M @ J[n:2 * n, n:2 * n]))
    for A in (K, B):
        scale = abs(A).max() if A.nnz else 0.0
        if scale and abs(A - A.T).max() > SYMMETRY_TOL * scale:
            return None
    if B.nnz:
        # dE/dt = -v'Bv <= 0 needs B positive semidefinite; a symmetric B whose diagonal is at least the sum of
        # the magnitudes off it is (Gershgorin), and every network of dampers d >= 0 (grounded or between masses)
        # makes one. A negative speed-dependent load between two damped masses has a positive diagonal and an
        # indefinite B: its energy grows, and the book would have refused its exact flow
        diag = B.diagonal()
        off = np.asarray(abs(B).sum(axis=1)).ravel() - np.abs(diag)
        if np.any(diag < off - SYMMETRY_TOL * max(float(np.abs(diag).max()), 1e-300)):
            return None
    return PassiveEnergy(c, mass, K, _free_groups(K, B))


def _free_groups(K, B):
    """The groups of masses joined by springs and dampers to each other only (rows of ``K`` and ``B`` summing to
    zero over the group: nothing grounds it). Their common motion keeps its momentum and its kinetic energy
    ``p^2 / (2 M)``, which the springs cannot reach: a drivetrain spinning at 190 rad/s holds so much of it that a
    vibration's energy grown 40-fold moved the total by 5 % (dopri5 at rtol 0.0136 on a free 4-inertia chain, an
    answer 5 times the range off, a fuzz run of the book), so the book leaves it out."""
    from scipy.sparse.csgraph import connected_components
    n = K.shape[0]
    links = sp.csr_matrix((abs(K) + abs(B)))
    _, label = connected_components(links, directed=False)
    groups = []
    for g in range(int(label.max()) + 1 if n else 0):
        idx = np.nonzero(label == g)[0]
        for A in (K, B):
            sub = A[idx][:, idx]
            scale = abs(sub).max() if sub.nnz else 0.0
            if scale and np.abs(np.asarray(sub.sum(axis=1)).ravel()).max() > SYMMETRY_TOL * scale * len(idx):
                break
        else:
            groups.append(idx)
    return groups


def check(c, T, Y, solver: str, settings: str = "") -> None:
    """Raise ``SimulationError`` when the run's energy (output rows ``T``, ``Y``) grew beyond ``ENERGY_GROWTH``
    times its start value on a passive model (module docstring); nothing for a model it cannot judge."""
    book = passive_energy(c)
    if book is None or len(T) < 2:
        return
    E = book.of_rows(np.asarray(Y))
    e0 = float(E[0])
    if not e0 > 0.0:
        return                              # at rest: nothing moves, nothing to grow
    k = int(np.argmax(E))
    if E[k] <= ENERGY_GROWTH * e0:
        return
    raise SimulationError(
        f"solver '{solver}' on model '{c.model.name}': the model is passive (no source, no preload: its energy "
        f"1/2 v'Mv + 1/2 x'Kx{', less the common spin of its free masses,' if book.free else ''} can only stay or "
        f"fall), yet the run's energy grew {E[k] / e0:.3g}-fold, from "
        f"{e0:.4g} J to {E[k]:.4g} J by t={T[k]:.6g} s: the method's errors at these settings"
        f"{(' (' + settings + ')') if settings else ''} pumped energy into the motion (a numerical instability), "
        f"and the answer is wrong.{c.stiffness_hint(always=True)} Use a tighter rtol (or a smaller h), ask for "
        f"accuracy=... (the contract), or use 'ida' or 'expm'.")
