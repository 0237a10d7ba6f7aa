"""Massless coordinates that no constraint makes dependent: first-order nodes (a Maxwell element).

A node of compliant devices without a mass (a spring and a damper in series, ``structure.regularity``) keeps
its coordinate ``p``: its position ``x_p`` stays a differential unknown (``x_p' = v_p``), and its motion row,
with no ``m a`` term, is the force balance

    sum_r S_rp tau_r(e, e', z, t) = 0,

an algebraic equation for ``v_p`` (``v_p`` is marked algebraic for IDA). It determines ``v_p`` where the forces
depend on it (a damper at the node: ``d (v_p - v_J) = -c (x_p - x_J)``, so ``x_p`` relaxes with ``d / c``);
where they do not (two springs, a spring under a source) the node is indeterminate and refused with the
regularity rules' message.

At every consistent start (``CompiledSystem.assemble_y``) the speeds ``v_p`` are solved from the balance by
Newton's method on a finite-difference Jacobian (the massless coordinates are few). The acceleration-level
solve (``kkt``) gives these coordinates a stand-in mass (their acceleration is no unknown of the DAE; the
balance is met, so the stand-in receives no force and the accelerations of the others are unchanged).
"""

from __future__ import annotations

import numpy as np

from ..errors import RegularityError, SimulationError

#: Newton iterations for the speeds of massless coordinates (a linear balance converges in one)
NEWTON_MAX = 30


def attach(c) -> None:
    """``c.massless`` (coordinates) and ``c.kkt_mass`` (the masses with the stand-in)."""
    # a massless coordinate in a rigid row has the mass that row reflects onto it (the acceleration solve sees it);
    # the first-order nodes are those no rigid row joins
    in_rows = np.zeros(c.n, bool)
    in_rows[c.Gpv.indices] = True
    c.massless = np.nonzero((np.asarray(c.mass) == 0.0) & ~c.is_dummy_v & ~in_rows)[0]
    kkt_mass = np.asarray(c.mass, float).copy()
    if len(c.massless):
        positive = kkt_mass[kkt_mass > 0]
        kkt_mass[c.massless] = float(positive.mean()) if len(positive) else 1.0
    c.kkt_mass = kkt_mass


def _balance(c, t, x, v, z, left):
    plan = c._plan
    tau = plan.device_outputs(x, v, z, t, left, c._sx, c._sv, c._sz)[:plan.n_c]
    return (c.ScT @ tau)[c.massless]


def speeds(c, t, x, v, z) -> np.ndarray:
    """``v`` with the speeds of the massless coordinates solving their force balance (a copy)."""
    P = c.massless
    v = np.array(v, float)
    left = t >= c._t_right
    f = _balance(c, t, x, v, z, left)
    for _ in range(NEWTON_MAX):
        scale = 1.0 + np.max(np.abs(f))
        J = np.empty((len(P), len(P)))
        for j, k in enumerate(P):
            h = 1e-7 * max(1.0, abs(v[k]))
            vh = v.copy()
            vh[k] += h
            J[:, j] = (_balance(c, t, x, vh, z, left) - f) / h
        if not np.all(np.isfinite(J)) or np.linalg.cond(J) > 1e12:
            _indeterminate(c, P[np.argmin(np.abs(np.diag(J))) if len(P) else 0])
        v[P] -= np.linalg.solve(J, f)
        f = _balance(c, t, x, v, z, left)
        if np.max(np.abs(f)) <= 1e-13 * scale:
            return v
    raise SimulationError(f"the speeds of the massless points {[c.structure.coord_names[k] for k in P]} do not "
                          f"balance their forces at t={t:g} (Newton's method did not converge); insert a small "
                          f"Inertia there")


def _indeterminate(c, k):
    from ..structure.regularity import _massless_node_message
    node = c.structure.coord_node[int(k)]
    raise RegularityError(_massless_node_message(node) + " (its force balance does not depend on its speed, so "
                          "neither its speed nor its motion is determined)")


def check(c) -> None:
    """Refuse an indeterminate massless node at compile time (at the start guesses)."""
    if not len(c.massless):
        return
    st = c.structure
    x = np.where(np.isfinite(st.start_pos), st.start_pos, 0.0)
    v = np.where(np.isfinite(st.start_vel), st.start_vel, 0.0)
    speeds(c, 0.0, x, v, c.state_start.copy())
