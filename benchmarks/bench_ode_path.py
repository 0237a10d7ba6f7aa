"""regmech's ODE-form path against the same scipy method written by hand on the same equations.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_ode_path.py [--repeat 5] [--sizes 10 1000 10000]
                                                             [--solvers scipy:DOP853 ...] [--old /work/main/src]
                                                             [--out benchmarks/results/ode_path.md]

Each model is built once per process; for each solver ``repeat`` rounds are run, and in
each round the regmech call (``model.simulate(..., solver=...)`` on the compiled model, the
whole call timed) and the hand-written version run back to back, so both see the same
machine load; the table gives the medians and their ratio. With ``--old SRC`` the same
regmech calls run right after in a subprocess with ``PYTHONPATH=SRC`` (another checkout,
e.g. main before the change): before/after in one run (an old case stops repeating
after ``--old-limit`` seconds, and its process is stopped after ``--old-timeout``).

Models (the hand versions are written out below, a few numpy lines each):

* ``chain{n}``: n inertias (J_i = 1 + 0.01 (i mod 7)) joined by spring-dampers (c = 1e4,
  d = 1), the first driven by ``10 sin(2 pi 5 t)``, the last grounded by a spring (c = 1e3);
  the chain of ``bench_foundation.py``. 1 s, output every 0.01 s.
* ``first``: MSL Rotational.Examples.First (a gear: the reduced ODE has 4 states). 1 s.

Solvers and their hand versions: ``scipy:DOP853``, ``scipy:RK45``, ``scipy:Radau`` (and regmech's own
``dop853`` and ``dopri5``, which take the steps of scipy's DOP853 and RK45) against
``scipy.integrate.solve_ivp`` with the same method, rtol, ``atol = rtol 1e-2`` and
``t_eval`` = the output grid (Radau gets the sparsity pattern of the Jacobian, as regmech
gives it); ``rk4`` (``tol=None``, h = dt_out) against a loop of classical RK4 steps;
``expm`` (``tol=None``, h = dt_out) against ``scipy.linalg.expm`` of the system matrix
augmented by the two states that generate the sine (``expm_multiply`` above 2,000 states).
regmech's runs record every named output; the hand versions keep the state at the grid.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")      # before numpy: no BLAS thread thrashing

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

T_END, DT_OUT, RTOL = 1.0, 0.01, 1e-6
AMP, FREQ, C, D, C_GROUND = 10.0, 5.0, 1e4, 1.0, 1e3
SOLVERS = ("scipy:DOP853", "scipy:RK45", "scipy:Radau", "rk4", "expm", "dop853", "dopri5")
#: regmech's own Dormand-Prince integrators (``solvers.dopri``) and the scipy method they take the steps of
OWN = {"dop853": "DOP853", "dopri5": "RK45"}


# ------------------------------------------------------------------------------- models
def chain_model(n):
    import regmech as rm
    from regmech.components import Fixed, Inertia, Spring, SpringDamper, Torque
    from regmech.signals import Sine
    m = rm.Model(f"chain{n}")
    fixed = m.add(Fixed("fixed"))
    drive = m.add(Torque("drive", tau=Sine(amplitude=AMP, freq_hz=FREQ)))
    J = [m.add(Inertia(f"J{i}", J=1.0 + 0.01 * (i % 7), phi0=0.0, w0=0.0)) for i in range(n)]
    m.connect(drive.flange, J[0].flange_a)
    for i in range(n - 1):
        sd = m.add(SpringDamper(f"sd{i}", c=C, d=D))
        m.connect(J[i].flange_b, sd.flange_a)
        m.connect(sd.flange_b, J[i + 1].flange_a)
    end = m.add(Spring("ground_spring", c=C_GROUND))
    m.connect(J[-1].flange_b, end.flange_a)
    m.connect(end.flange_b, fixed.flange)
    return m


def chain_hand(n):
    """(rhs, u0, jac_sparsity, A, speeds of u, names) of the chain: u = [phi_0..n-1, w_0..n-1]."""
    import scipy.sparse as sp
    inv_j = 1.0 / (1.0 + 0.01 * (np.arange(n) % 7))

    def rhs(t, u):
        x, v = u[:n], u[n:]
        f = C * (x[:-1] - x[1:]) + D * (v[:-1] - v[1:])      # torque of link i on inertia i+1
        a = np.zeros(n)
        a[:-1] -= f
        a[1:] += f
        a[0] += AMP * math.sin(2 * math.pi * FREQ * t)
        a[-1] -= C_GROUND * x[-1]
        a *= inv_j
        return np.concatenate([v, a])

    lap = sp.diags([np.r_[1.0, 2 * np.ones(n - 2), 1.0], -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1])
    K = C * lap + sp.diags(np.r_[np.zeros(n - 1), C_GROUND])
    Dm = D * lap
    Minv = sp.diags(inv_j)
    A = sp.bmat([[None, sp.identity(n)], [-Minv @ K, -Minv @ Dm]]).tocsr()
    force = np.zeros(2 * n)
    force[n] = AMP * inv_j[0]
    return rhs, np.zeros(2 * n), (A != 0).astype(float), A, force, [f"J{i}.w" for i in range(n)], slice(n, 2 * n)


def first_model():
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from library import first
    return first()


def first_hand():
    """MSL First reduced by hand: u = [phi2, phi3, w2, w3]; the gear folds inertia1 into J2 + r^2 J1."""
    r, j1, j2, j3, c, d = 10.0, 0.1, 2.0, 2.0, 1e4, 10.0
    je = j2 + r * r * j1

    def rhs(t, u):
        p2, p3, w2, w3 = u
        fs = c * (p2 - p3)
        return np.array([w2, w3, (r * AMP * math.sin(2 * math.pi * FREQ * t) - fs - d * w2) / je, fs / j3])

    A = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [-c / je, c / je, -d / je, 0], [c / j3, -c / j3, 0, 0]])
    force = np.array([0, 0, r * AMP / je, 0])
    return rhs, np.zeros(4), (A != 0).astype(float), A, force, ["inertia2.w", "inertia3.w"], slice(2, 4)


MODELS = {"first": (first_model, first_hand)}


def model_pair(name):
    if name.startswith("chain"):
        n = int(name[5:])
        return chain_model(n), chain_hand(n)
    build, hand = MODELS[name]
    return build(), hand()


# ------------------------------------------------------------------------ hand methods
def hand_run(solver, hand, grid):
    """The hand-written version of ``solver``: the states at the grid, (len(grid), size)."""
    from scipy.integrate import solve_ivp
    rhs, u0, pattern, A, force, _, _ = hand
    if solver.startswith("scipy:") or solver in OWN:
        method = OWN.get(solver) or solver.split(":")[1]
        kw = {"jac_sparsity": pattern} if method in ("Radau", "BDF") else {}
        sol = solve_ivp(rhs, (grid[0], grid[-1]), u0, method=method, t_eval=grid, rtol=RTOL, atol=RTOL * 1e-2, **kw)
        return sol.y.T, sol.nfev
    h = grid[1] - grid[0]
    if solver == "rk4":
        u, out, t = u0.copy(), [u0], grid[0]
        for t1 in grid[1:]:
            k1 = rhs(t, u)
            k2 = rhs(t + h / 2, u + h / 2 * k1)
            k3 = rhs(t + h / 2, u + h / 2 * k2)
            k4 = rhs(t1, u + h * k3)
            u = u + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            out.append(u)
            t = t1
        return np.array(out), 4 * (len(grid) - 1)
    if solver == "expm":
        # q = [u, sin(wt), cos(wt)]: q' = [[A, f, 0], [0, 0, w], [0, -w, 0]] q, exact for the sine forcing
        import scipy.sparse as sp
        w = 2 * math.pi * FREQ
        gen = sp.csr_matrix(np.array([[0.0, w], [-w, 0.0]]))
        f = sp.csr_matrix(np.column_stack([force, np.zeros(len(force))]))
        B = sp.bmat([[sp.csr_matrix(A), f], [None, gen]]).tocsr()
        q = np.r_[u0, 0.0, 1.0]
        out = [u0]
        if B.shape[0] <= 2002:
            import scipy.linalg as la
            E = la.expm(B.toarray() * h)
            for _ in grid[1:]:
                q = E @ q
                out.append(q[:-2])
        else:
            from scipy.sparse.linalg import expm_multiply
            Q = expm_multiply(B, q, start=grid[0], stop=grid[-1], num=len(grid), endpoint=True)
            out = list(Q[:, :-2])
        return np.array(out), 0
    raise ValueError(solver)


def regmech_run(solver, model):
    opts = {"rtol": RTOL} if solver.startswith("scipy:") or solver in OWN else {"tol": None}
    return model.simulate(T_END, DT_OUT, solver=solver, **opts)


# ----------------------------------------------------------------------------- worker
def worker(cases, repeat, hand_too):
    """Times of every (model, solver) case, regmech and hand interleaved; prints one JSON line per case."""
    import warnings
    warnings.simplefilter("ignore")
    grid = np.linspace(0.0, T_END, int(round(T_END / DT_OUT)) + 1)
    built = {}
    for name, solver, limit in cases:
        if name not in built:
            model, hand = model_pair(name)
            model.compile()
            built[name] = (model, hand)
        model, hand = built[name]
        reg, hnd, err, info = [], [], None, {}
        for k in range(repeat):
            t0 = time.perf_counter()
            try:
                res = regmech_run(solver, model)
            except Exception as exc:            # a refusal is a result too
                info["error"] = f"{type(exc).__name__}: {str(exc)[:120]}"
                reg.append(time.perf_counter() - t0)
                break
            reg.append(time.perf_counter() - t0)
            info.update(steps=res.stats.steps, rhs=res.stats.rhs_calls)
            if hand_too:
                t0 = time.perf_counter()
                U, nfev = hand_run(solver, hand, grid)
                hnd.append(time.perf_counter() - t0)
                info["hand_rhs"] = nfev
                if err is None:          # the same equations: regmech's speeds against the hand ones on the grid
                    W = np.column_stack([res[s] for s in hand[5]])
                    keep = np.r_[np.diff(res.t) != 0, True]          # breakpoints are recorded twice
                    W = W[keep]
                    Wh = U[:, hand[6]]
                    err = float(np.abs(W - Wh).max() / max(np.abs(Wh).max(), 1e-300)) if W.shape == Wh.shape \
                        else None
            if limit and sum(reg) > limit:
                break
        print(json.dumps({"model": name, "solver": solver, "regmech": reg, "hand": hnd, "diff": err, **info}),
              flush=True)


def run_worker(src, cases, repeat, hand_too, timeout=3600):
    env = dict(os.environ, PYTHONPATH=src, OPENBLAS_NUM_THREADS="1")
    arg = json.dumps({"cases": cases, "repeat": repeat, "hand": hand_too})
    try:
        out = subprocess.run([sys.executable, __file__, "--worker", arg], env=env, capture_output=True, text=True,
                             timeout=timeout)
    except subprocess.TimeoutExpired:
        return [{"model": n, "solver": s, "regmech": [], "error": f"no result within {timeout:g} s (stopped)"}
                for n, s, _ in cases]
    if out.returncode:
        sys.stderr.write(out.stderr[-3000:])
    return [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--worker")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--sizes", type=int, nargs="*", default=[10, 1000, 10000])
    ap.add_argument("--models", nargs="*", default=["first"])
    ap.add_argument("--solvers", nargs="*", default=list(SOLVERS))
    ap.add_argument("--old", help="src folder of another regmech checkout, timed in the same run (before)")
    ap.add_argument("--old-limit", type=float, default=60.0, help="stop repeating an old case beyond this [s]")
    ap.add_argument("--old-timeout", type=float, default=300.0, help="stop an old case's process after this [s]")
    ap.add_argument("--out")
    args = ap.parse_args()
    if args.worker:
        spec = json.loads(args.worker)
        worker([tuple(c) for c in spec["cases"]], spec["repeat"], spec["hand"])
        return
    new_src = str(Path(__file__).resolve().parents[1] / "src")
    names = [f"chain{n}" for n in args.sizes] + args.models
    rows = []
    for name in names:
        cases = [(name, s, 0) for s in args.solvers if not (s == "expm" and name == "chain10000")]
        # one process per model and version: regmech and hand interleaved inside it, round by round
        new = {r["solver"]: r for r in run_worker(new_src, cases, args.repeat, True)}
        old = {}
        if args.old:
            for case in cases:      # one process per case, so that one that never ends is stopped alone
                old.update({r["solver"]: r for r in run_worker(args.old, [(case[0], case[1], args.old_limit)],
                                                              args.repeat, False, timeout=args.old_timeout)})
        for _, solver, _ in cases:
            r, o = new.get(solver, {}), old.get(solver, {})
            med = {key: statistics.median(r[key]) for key in ("regmech", "hand") if r.get(key)}
            row = {"model": name, "solver": solver, "new": med.get("regmech"), "hand": med.get("hand"),
                   "old": statistics.median(o["regmech"]) if o.get("regmech") else None,
                   "n_new": len(r.get("regmech", [])), "n_old": len(o.get("regmech", [])),
                   "steps": r.get("steps"), "rhs": r.get("rhs"), "hand_rhs": r.get("hand_rhs"),
                   "diff": r.get("diff"), "error": r.get("error"), "old_error": o.get("error")}
            rows.append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)
    text = report(rows, args)
    print(text)
    if args.out:
        Path(args.out).write_text(text)


def report(rows, args):
    def ms(x):
        return "-" if x is None else f"{x * 1e3:.1f}"
    uptime = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else ["?"]
    out = [f"ODE-form path against scipy by hand (medians of {args.repeat}, interleaved; load {' '.join(uptime)})",
           "",
           "| model | solver | regmech ms | hand ms | ratio | old ms | old/new | steps | rhs calls (hand) | "
           "max diff | note |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ratio = f"{r['new'] / r['hand']:.2f}" if r["new"] and r["hand"] else "-"
        speed = f"{r['old'] / r['new']:.1f}" if r["old"] and r["new"] else "-"
        old = ms(r["old"]) + (f" ({r['n_old']}x)" if r["old"] and r["n_old"] < args.repeat else "")
        diff = f"{r['diff']:.1e}" if r["diff"] is not None else "-"
        note = r["error"] or (f"old: {r['old_error']}" if r.get("old_error") else "")
        out.append(f"| {r['model']} | {r['solver']} | {ms(r['new'])} | {ms(r['hand'])} | {ratio} | {old} | {speed} | "
                   f"{r['steps']} | {r['rhs']} ({r['hand_rhs']}) | {diff} | {note} |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    main()
