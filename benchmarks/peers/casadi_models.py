"""CasADi models of First and the chains, integrated by SUNDIALS CVODES and IDAS through
``casadi.integrator``: the same equations as the hand-written scipy models
(``scipy_models``; see its docstring for the physics), written as CasADi SX
expressions with time as a symbol for the sine drive.

CasADi is a benchmark-only dependency (``pip install -e ".[bench]"``); this
module imports it lazily, so ``available()`` can be asked without it.

``build_*`` returns a ``CasadiRun``: the integrator ``Function`` built once
(``build_time`` [s]: SX expressions plus ``casadi.integrator``, where CasADi
forms the sparse Jacobian symbolically), and ``run()`` integrates from the
start state over the output grid and returns ``(outputs, info)`` as the scipy
models do. Settings: ``reltol`` = rtol, ``abstol`` = rtol * 1e-2 (regmech's
default atol), CasADi's default sparse direct linear solver (CSparse) on the
exact Jacobian, and a step cap high enough never to bind.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from . import scipy_models as sm

SOLVERS = ("cvodes", "idas")


def available() -> bool:
    try:
        import casadi  # noqa: F401
    except ImportError:
        return False
    return True


def version() -> str:
    try:
        import casadi
    except ImportError:
        return "not installed"
    return casadi.__version__


@dataclass
class CasadiRun:
    solver: str
    integrator: object
    x0: np.ndarray
    outputs: dict                      # signal name -> (state index, factor)
    build_time: float
    t0: float = 0.0
    first_point: dict = field(default_factory=dict)

    def run(self):
        res = self.integrator(x0=self.x0)
        xf = np.asarray(res["xf"])                       # states x output instants (after t0)
        out = {}
        for name, (i, fac) in self.outputs.items():
            out[name] = np.concatenate(([fac * self.x0[i]], fac * xf[i]))
        stats = self.integrator.stats()
        return out, {"nfev": int(stats.get("nfevals", 0) or 0), "steps": int(stats.get("nsteps", 0) or 0)}


def _integrator(solver, t, x, ode, tg, rtol, atol):
    import casadi as ca
    opts = {"reltol": rtol, "abstol": rtol * 1e-2 if atol is None else atol, "max_num_steps": 10_000_000}
    return ca.integrator("F", solver, {"t": t, "x": x, "ode": ode}, float(tg[0]), list(tg[1:]), opts)


def build_first(solver: str = "cvodes", rtol: float = 1e-6, atol: float | None = None,
                t_end: float = 1.0, dt_out: float = 1e-3) -> CasadiRun:
    """MSL First on states (phi2, w2, phi3, w3)."""
    import casadi as ca
    t_start = time.perf_counter()
    p = sm.FIRST
    r, c, d, j3 = p["ratio"], p["c"], p["d"], p["j3"]
    je = p["j2"] + r * r * p["j1"]
    t = ca.SX.sym("t")
    x = ca.SX.sym("x", 4)
    s = c * (x[2] - x[0])
    ode = ca.vertcat(x[1], (r * p["amp"] * ca.sin(2 * math.pi * p["freq"] * t) + s - d * x[1]) / je, x[3], -s / j3)
    F = _integrator(solver, t, x, ode, sm.grid(t_end, dt_out), rtol, atol)
    outputs = {"inertia1.w": (1, r), "inertia2.w": (1, 1.0), "inertia3.w": (3, 1.0), "damper.w_rel": (1, -1.0)}
    return CasadiRun(solver, F, np.zeros(4), outputs, time.perf_counter() - t_start)


def build_chain(n: int, solver: str = "cvodes", rtol: float = 1e-6, atol: float | None = None,
                t_end: float = 1.0, dt_out: float = 1e-2) -> CasadiRun:
    """The benchmark chain of n inertias on states (phi_0..phi_n-1, w_0..w_n-1)."""
    import casadi as ca
    t_start = time.perf_counter()
    p = sm.CHAIN
    inv_j = 1.0 / sm.chain_inertias(n)
    t = ca.SX.sym("t")
    phi = ca.SX.sym("phi", n)
    w = ca.SX.sym("w", n)
    f = p["c"] * (phi[1:] - phi[:-1]) + p["d"] * (w[1:] - w[:-1])       # torque of link i on J_i, -f on J_i+1
    zero = ca.SX.zeros(1)
    acc = ca.vertcat(f, zero) - ca.vertcat(zero, f)
    drive = ca.vertcat(p["amp"] * ca.sin(2 * math.pi * p["freq"] * t), ca.SX.zeros(n - 1))
    ground = ca.vertcat(ca.SX.zeros(n - 1), -p["c_ground"] * phi[n - 1])
    ode = ca.vertcat(w, (acc + drive + ground) * ca.DM(inv_j))
    F = _integrator(solver, t, ca.vertcat(phi, w), ode, sm.grid(t_end, dt_out), rtol, atol)
    outputs = {f"J{i}.w": (n + i, 1.0) for i in sorted({0, n // 2, n - 1})}
    return CasadiRun(solver, F, np.zeros(2 * n), outputs, time.perf_counter() - t_start)
