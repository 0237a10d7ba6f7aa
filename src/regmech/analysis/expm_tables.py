"""The tables of REFERENCES.md [002] (matrix numerical-analytical integration), recomputed.

``optimal_split_table()``
    The paper's optimal split between Taylor order r and doublings m. Error
    model: the Taylor start of order r at ``theta = nu h / 2^m`` has relative
    remainder ``theta^(r+1)/(r+1)!``; m doublings add up 2^m such errors, so
    the per-step relative error is ``eps = 2^m theta^(r+1)/(r+1)!``, and the
    work is about ``m + r`` matrix products. Trading one doubling for one
    more Taylor term costs nothing, so at the optimal theta of order r the
    pair (r, theta) and (r + 1, 2 theta) give the same error:

        theta^r / (r+1)! = (2 theta)^(r+1) / (r+2)!   =>   theta_r = (r + 2) / 2^(r+1),

    which is found here numerically (``brentq``) and checked against the
    closed form. ``eps`` is per unit of ``nu h`` (``2^m theta = 1``):
    ``eps_r = theta_r^r / (r+1)!``. Below ``theta_r`` the order r + 1 is
    cheaper, above it the order r - 1.

``roundoff_check(ratio)``
    The claim "any step, error down to round-off": a chain whose natural
    frequencies spread over ``ratio`` (1e3, 1e5), driven by a quadratic
    torque (a polynomial of the degree the solver fits, ``order_p = 3``),
    simulated with steps from 1e-2 to 10 lowest periods and compared with the
    modal solution computed in 40-digit arithmetic (mpmath) from the same
    binary parameters. ``floor`` is the conditioning of the problem itself:
    ``w_max t_end * 2^-53`` (a relative change of the data by one rounding
    moves the phase of the fastest mode by that much at ``t_end``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

#: the paper's table (REFERENCES.md [002]): r -> (theta, eps)
PAPER_TABLE = {1: (0.75, 4e-1), 2: (0.50, 4e-2), 3: (0.31, 1e-3), 4: (0.19, 1e-5), 5: (0.11, 2e-8),
               6: (0.06, 1e-11)}


def taylor_error_per_unit(r: int, theta: float) -> float:
    """``eps = 2^m theta^(r+1)/(r+1)!`` with ``2^m theta = 1``: ``theta^r / (r+1)!``."""
    return theta ** r / math.factorial(r + 1)


def optimal_theta(r: int) -> float:
    """Theta at which order r and order r + 1 at twice theta (same cost m + r) give the same error."""
    f = lambda lt: math.log(taylor_error_per_unit(r, math.exp(lt))) - \
        math.log(taylor_error_per_unit(r + 1, 2 * math.exp(lt)))  # noqa: E731
    return math.exp(brentq(f, math.log(1e-6), math.log(10.0), xtol=1e-14))


def optimal_split_table(orders=range(1, 7)) -> list[dict]:
    """Rows ``{r, theta, theta_closed_form, eps, paper_theta, paper_eps}`` (see the module docstring)."""
    rows = []
    for r in orders:
        theta = optimal_theta(r)
        paper = PAPER_TABLE.get(r, (None, None))
        rows.append({"r": r, "theta": theta, "theta_closed_form": (r + 2) / 2.0 ** (r + 1),
                     "eps": taylor_error_per_unit(r, theta), "paper_theta": paper[0], "paper_eps": paper[1]})
    return rows


# ------------------------------------------------------------------ round-off check
def graded_chain(ratio: float, n: int = 5, J: float = 1.0):
    """Stiffnesses (fixed - k0 - J - k1 - J ... - J) with natural frequencies spread over ``ratio``.

    The stiffness grows geometrically along the chain; its growth factor is
    solved for so that ``w_max / w_min = ratio``. Returns (masses, stiffnesses).
    """
    def spread(log_g):
        k = 1e2 * math.exp(log_g) ** np.arange(n)
        om = np.sqrt(np.linalg.eigvalsh(_stiffness(k) / J))
        return math.log(om.max() / om.min()) - math.log(ratio)

    g = math.exp(brentq(spread, math.log(1.0001), 3 * math.log(ratio) / max(1, n - 1), xtol=1e-14))
    return np.full(n, float(J)), 1e2 * g ** np.arange(n)


def _stiffness(k):
    n = len(k)
    K = np.zeros((n, n))
    for i in range(n):
        K[i, i] += k[i]
        if i > 0:
            K[i - 1, i - 1] += k[i]
            K[i - 1, i] -= k[i]
            K[i, i - 1] -= k[i]
    return K


def chain_model(masses, stiffnesses, force_coefs):
    """fixed - k0 - J0 - k1 - J1 ... with the torque sum c_k t^k on the last inertia, at rest."""
    import regmech as rm
    from regmech.components import Fixed, Inertia, Spring, Torque

    poly = np.polynomial.Polynomial(force_coefs)
    m = rm.Model(f"graded_chain_{len(masses)}")
    fixed = m.add(Fixed("fixed"))
    prev = fixed.flange
    bodies = []
    for i, (J, k) in enumerate(zip(masses, stiffnesses)):
        s = m.add(Spring(f"k{i}", c=float(k)))
        b = m.add(Inertia(f"J{i}", J=float(J), phi0=0.0, w0=0.0))
        m.connect(prev, s.flange_a)
        m.connect(s.flange_b, b.flange_a)
        prev = b.flange_b
        bodies.append(b)
    drive = m.add(Torque("drive", tau=lambda t: float(poly(t))))
    m.connect(drive.flange, prev)
    m.connect(drive.support, fixed.flange)
    return m


def modal_solution_mp(masses, stiffness, force_coefs, times, dps: int = 40):
    """Positions and velocities (len(times) x n) from rest under the polynomial torque on the last
    inertia, by modal superposition in ``dps``-digit arithmetic (mpmath).

    ``stiffness``: the link stiffnesses (a 1-D sequence: the matrix is assembled exactly in mpmath)
    or an assembled n x n matrix (its binary entries are taken as exact).
    """
    import mpmath as mp

    with mp.workdps(dps):
        n = len(masses)
        stiffness = np.asarray(stiffness, float)
        if stiffness.ndim == 1:
            K = _mp_stiffness(stiffness)
        else:
            K = mp.matrix([[mp.mpf(float(x)) for x in row] for row in stiffness])
        s = [1 / mp.sqrt(mp.mpf(float(J))) for J in masses]
        Kh = mp.matrix(n, n)
        for i in range(n):
            for j in range(n):
                Kh[i, j] = s[i] * K[i, j] * s[j]
        lam, Q = mp.eigsy(Kh)
        coefs = [mp.mpf(float(c)) for c in force_coefs]
        Y = np.zeros((len(times), n))
        V = np.zeros((len(times), n))
        for mode in range(n):
            om2 = lam[mode]
            om = mp.sqrt(om2)
            load = Q[n - 1, mode] * s[n - 1]            # modal force per unit torque on the last inertia
            g = [c * load for c in coefs]                # g(t) = sum g_k t^k
            part = _particular(g, om2)                   # polynomial coefficients
            dpart = [(k + 1) * part[k + 1] for k in range(len(part) - 1)] or [mp.mpf(0)]
            a, b = -part[0], -(dpart[0] if dpart else 0)
            for it, t in enumerate(times):
                tt = mp.mpf(float(t))
                eta = _peval(part, tt) + a * mp.cos(om * tt) + b / om * mp.sin(om * tt)
                deta = _peval(dpart, tt) - a * om * mp.sin(om * tt) + b * mp.cos(om * tt)
                for i in range(n):
                    Y[it, i] += float(s[i] * Q[i, mode] * eta)
                    V[it, i] += float(s[i] * Q[i, mode] * deta)
        return Y, V, [float(mp.sqrt(x)) for x in lam]


def _mp_stiffness(stiffnesses):
    import mpmath as mp
    n = len(stiffnesses)
    k = [mp.mpf(float(x)) for x in stiffnesses]
    K = mp.matrix(n, n)
    for i in range(n):
        K[i, i] += k[i]
        if i > 0:
            K[i - 1, i - 1] += k[i]
            K[i - 1, i] -= k[i]
            K[i, i - 1] -= k[i]
    return K


def _particular(g, om2):
    """Coefficients of the polynomial solution of eta'' + om2 eta = g (``sum (-1)^j g^(2j) / om2^(j+1)``)."""
    import mpmath as mp
    out = [mp.mpf(0)] * max(1, len(g))
    term, factor = list(g), 1 / om2
    while any(c != 0 for c in term):
        for k, c in enumerate(term):
            out[k] += factor * c
        term = [(k + 2) * (k + 1) * term[k + 2] for k in range(len(term) - 2)]
        factor = -factor / om2
    return out


def _peval(coefs, t):
    acc = 0
    for c in reversed(coefs):
        acc = acc * t + c
    return acc


def roundoff_check(ratio: float, n: int = 5, periods=(0.01, 0.1, 1.0, 10.0), n_steps: int = 4,
                   force_coefs=(1.0, -0.5, 0.3), scaling: str | None = None) -> list[dict]:
    """Error of ``solver="expm"`` (order_p = 3) against the 40-digit modal solution (see the module docstring).

    For each step ``h = periods * 2 pi / w_min`` the run covers ``n_steps`` steps.
    Rows: ``{ratio, h_periods, nu_h, taylor_r, doublings_m, err_phi, err_w, floor}`` (errors relative to
    the largest value of each kind).
    """
    masses, stiff = graded_chain(ratio, n)
    m = chain_model(masses, stiff, force_coefs)
    K = _stiffness(stiff)
    om = np.sqrt(np.linalg.eigvalsh(K / masses[0]))
    C_assembled = np.asarray(m.linearize().C, float)        # the matrix the solver works with, rounded
    rows = []
    for per in periods:
        h = per * 2 * math.pi / om.min()
        res = m.simulate(n_steps * h, dt_out=h, solver="expm", order_p=3, scaling=scaling)
        got_y = np.column_stack([res[f"J{i}.phi"] for i in range(n)])
        got_v = np.column_stack([res[f"J{i}.w"] for i in range(n)])
        ex = res.stats.extra
        row = {"ratio": float(om.max() / om.min()), "scaling": ex["scaling"], "h_periods": per,
               "nu_h": float(ex["nu_h"]), "taylor_r": int(ex["taylor_r"]), "doublings_m": int(ex["doublings_m"]),
               "floor": float(om.max() * res.t[-1] * 2.0 ** -53)}
        for tag, stiffness in (("", C_assembled), ("_parameters", stiff)):
            Y, V, _ = modal_solution_mp(masses, stiffness, force_coefs, res.t)
            row["err_phi" + tag] = float(np.abs(got_y - Y).max() / np.abs(Y).max())
            row["err_w" + tag] = float(np.abs(got_v - V).max() / np.abs(V).max())
        # the same problem by scipy.linalg.expm of the augmented matrix (Pade 13, scaling and squaring)
        ys, vs = _scipy_expm_solution(masses, C_assembled, force_coefs, res.t)
        row["err_w_scipy_expm"] = float(np.abs(vs - V).max() / np.abs(V).max())
        rows.append(row)
    return rows


def _scipy_expm_solution(masses, K, force_coefs, times):
    """From rest: z = [y, y', 1, t, t^2/2, ...], z(t) = expm(A t) z(0) with scipy."""
    import scipy.linalg as la
    n, p = len(masses), len(force_coefs)
    A = np.zeros((2 * n + p, 2 * n + p))
    A[:n, n:2 * n] = np.eye(n)
    A[n:2 * n, :n] = -np.asarray(K) / np.asarray(masses)[:, None]
    for k, c in enumerate(force_coefs):            # t^k = k! * (t^k / k!)
        A[2 * n - 1, 2 * n + k] = c * math.factorial(k) / masses[-1]
    for k in range(1, p):
        A[2 * n + k, 2 * n + k - 1] = 1.0
    z0 = np.zeros(2 * n + p)
    z0[2 * n] = 1.0
    Z = np.array([la.expm(A * t) @ z0 for t in times])
    return Z[:, :n], Z[:, n:2 * n]


def markdown(rows: list[dict], columns: list[str], formats: dict | None = None) -> str:
    """A Markdown table of ``rows`` (used by benchmarks/bench_expm.py)."""
    formats = formats or {}
    out = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for row in rows:
        cells = []
        for col in columns:
            val = row.get(col)
            fmt = formats.get(col)
            cells.append("" if val is None else (format(val, fmt) if fmt else str(val)))
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out)


__all__ = ["optimal_split_table", "optimal_theta", "roundoff_check", "graded_chain", "modal_solution_mp",
           "PAPER_TABLE", "markdown"]
