"""The right-hand side of the ODE form ``u' = g(t, u)`` with as few array operations as the model allows.

``u = [x_K, v_K, z]`` (``CompiledSystem.ode_state``). In general ``g`` lifts
``u`` to all coordinates through the constraints, evaluates the device
forces and solves the acceleration-level (KKT) system of the current modes
(``CompiledSystem.ode_rhs_general``): a dozen numpy and sparse calls, some
30 us on a small model before any arithmetic.

A model without constraints (no rigid links, gears, motion sources:
``m == 0``), without friction rows and whose devices are all *affine*
(springs, dampers, sources: ``compile.kernels``) needs none of that:
``u = [x, v, z]`` is the whole state, the KKT system is the diagonal mass
matrix, and

    [tau; dz] = T y + t0 + V s(t),     g = [v; -M^-1 S^T tau; dz]

with ``s(t)`` the offsets of the affine devices whose force changes in time
(a torque source's signal, evaluated by its class). These are the products
of the general path (``EvaluationPlan.device_outputs``, the same matrices
in the same order, and a division by the masses where the general path's
LU of the diagonal divides by the same pivots), so both give the same
numbers. The link forces are formed first and summed at the masses after:
multiplying the two matrices out into one ``A = -M^-1 S^T T`` would be one
product fewer, but a mass between a stiff and a soft link would then carry
a coefficient ``(k_stiff + k_soft) / m`` in which the soft link's share is
lost to round-off (a spurious spring to the ground: measured on the hard
case ``stretched_1e5``, accelerations off by 1e-7 of their size and scipy
Radau's Newton iteration needing 3 times the steps). ``A`` is only built
for ``jacobian`` (the spectral bound of the up-front stiffness check).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class OdeForm:
    """``g(t, u)`` of one compiled system (see the module docstring); ``linear`` when the fast form applies."""

    def __init__(self, c):
        self.c = c
        plan = c._plan
        self.linear = (c.m == 0 and c.mf == 0 and not plan.nonlinear and c.n > 0
                       and bool(np.all(c.mass > 0)))
        self._A = None
        if self.linear:
            n = c.n
            self.n, self.n_c, self.plan = n, plan.n_c, plan
            self.size = 2 * n + c.nz
            self.ScT = c.ScT
            self.mass = c.mass

    def rhs(self, t, u):
        """``[v; -M^-1 S^T tau; dz]`` (linear form only; see the module docstring)."""
        c, plan, n, n_c = self.c, self.plan, self.n, self.n_c
        yb = plan.ybuf
        yb[c._sx] = u[:n]
        yb[c._sv] = u[n:2 * n]
        yb[c._sz] = u[2 * n:]
        out = plan.T @ yb
        out += plan.t0
        if plan.V is not None:
            left = t >= c._t_right
            for grp, start in plan.offset_slots:
                grp.offsets_into(plan.buf, start, t, left)
            out += plan.V @ plan.buf
        g = np.empty(self.size)
        g[:n] = u[n:2 * n]
        if n_c:
            f = -(self.ScT @ out[:n_c])
            g[n:2 * n] = f / self.mass
        else:
            g[n:2 * n] = 0.0
        g[2 * n:] = out[n_c:]
        return g

    def jacobian(self) -> sp.csr_matrix:
        """``dg/du`` of the linear form (exact, constant; built on first use)."""
        if self._A is None:
            c, n, n_c = self.c, self.n, self.n_c
            cols = np.concatenate([c.ix, c.iv, c.iz]).astype(np.int64)         # u = [x, v, z] in y
            Tu = sp.csr_matrix(self.plan.T)[:, cols]
            force = -(sp.diags(1.0 / c.mass) @ c.ScT) if n_c else sp.csr_matrix((n, 0))
            top = sp.hstack([sp.csr_matrix((n, n)), sp.identity(n, format="csr"), sp.csr_matrix((n, c.nz))])
            self._A = sp.vstack([top, force @ Tu[:n_c], Tu[n_c:]]).tocsr()
        return self._A


def ode_form(c) -> OdeForm:
    """The ``OdeForm`` of a compiled system, built once (it reads only constant matrices of ``c``)."""
    form = c.__dict__.get("_ode_form")
    if form is None:
        form = c._ode_form = OdeForm(c)
    return form
