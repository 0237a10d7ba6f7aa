"""Stability and accuracy per fixed step on the excavator swing drive: rk4, convolution (PECE), convolution (implicit).

Scene: ``regmech.library.SCENES["excavator_swing"]()`` (SOURCES.md 004, the
paper's test case), simulated 3 s with ``simulate(3.0, dt_out=h, solver=...,
h=h)``. Reference: IDA at rtol 1e-9 with output every 5 ms (every h below is
a multiple, so the compared instants coincide). Error: max over the output
instants of |turntable.w - reference| [rad/s] (the target speed is 7.85
rad/s), and the same at t = 3 s.

A run "diverges" when the driver stops it with ``SimulationError``
(``regmech.solvers.divergence``). The largest stable step is the largest h
below which no step of the grid diverged, refined by bisection between the
last completed and the first diverged step.

The linear analysis beside it: the amplification matrix of one step of
each method for ``u' = J u``, J the ODE Jacobian at two states of the
reference run (turntable held by friction, t = 0.15 s; turntable sliding,
play closed, t = 0.5 s); the step at which its spectral radius first exceeds 1.

    python benchmarks/bench_convolution_stability.py            # appends/replaces its section
    python benchmarks/bench_convolution_stability.py --out -    # to stdout
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import scipy

import regmech as rm
from regmech.library import SCENES
from regmech.solvers.convolution import lag_rates, phi_functions
from regmech.solvers.ode_driver import OdeProblem

T_END = 3.0
REF_DT = 0.005
STEPS = [0.005, 0.01, 0.015, 0.02, 0.025, 0.03, 0.035, 0.04, 0.045, 0.05, 0.055, 0.06, 0.07, 0.08, 0.1, 0.125,
         0.15, 0.2, 0.25, 0.3, 0.5, 0.75, 1.0, 1.5, 3.0]
METHODS = [("rk4", "rk4", {}), ("convolution (pece)", "convolution", {"corrector": "pece"}),
           ("convolution (implicit)", "convolution", {"corrector": "implicit"})]
MARK = "<!-- bench_convolution_stability -->"


def errors(res, ref):
    """Max |w - w_ref| over the result's output instants, and at the end."""
    t_ref, w_ref = ref.t, ref["turntable.w"]
    worst = 0.0
    for t, w in zip(res.t, res["turntable.w"]):
        k = np.searchsorted(t_ref, t - 1e-9)
        if k < len(t_ref) and abs(t_ref[k] - t) < 1e-9:
            worst = max(worst, abs(w - w_ref[k]))
    return worst, abs(res["turntable.w"][-1] - w_ref[-1])


def attempt(model, solver, opts, h, ref, repeats):
    times = []
    try:
        for _ in range(repeats):
            t0 = time.perf_counter()
            res = model.simulate(T_END, dt_out=h, solver=solver, h=h, **opts)
            times.append(time.perf_counter() - t0)
    except rm.SimulationError as exc:
        msg = str(exc)
        at = msg.split(" diverged at ")[1].split(" s ")[0] if " diverged at " in msg else "?"
        return {"ok": False, "note": f"diverged at {at} s" if at != "?" else msg[:80]}
    err, err_end = errors(res, ref)
    ex = res.stats.extra
    return {"ok": True, "err": err, "err_end": err_end, "time": statistics.median(times), "steps": res.stats.steps,
            "rhs": res.stats.rhs_calls, "jac": res.stats.jac_calls, "newton": ex.get("newton_iterations"),
            "failures": ex.get("newton_failures"), "subdivided": ex.get("subdivided"),
            "growth": ex.get("state_growth", 0.0)}


def largest_stable(model, solver, opts, rows, ref):
    """(last completed h, first diverged h) after bisection, or (largest h, None) when none diverged."""
    ok_h = [h for h in STEPS if rows[h]["ok"]]
    bad = [h for h in STEPS if not rows[h]["ok"]]
    if not bad:
        return max(ok_h), None
    hi = min(bad)
    lo = max([h for h in ok_h if h < hi], default=None)
    if lo is None:
        return None, hi
    for _ in range(7):
        mid = 0.5 * (lo + hi)
        if attempt(model, solver, opts, mid, ref, 1)["ok"]:
            lo = mid
        else:
            hi = mid
    return lo, hi


# ------------------------------------------------------------------ linear analysis
def amplification(method, J, h):
    """One step of ``method`` on u' = J u as a matrix (pece: the 2-step companion of (u_i, u_{i-1}))."""
    n = J.shape[0]
    eye = np.eye(n)
    if method == "rk4":
        hJ = h * J
        return eye + hJ @ (eye + hJ @ (eye / 2 + hJ @ (eye / 6 + hJ / 24)))
    rate = lag_rates(np.diag(J))
    p1, p2 = phi_functions(h * rate)
    B = h * p1[:, None] * J                        # h phi1 J
    C = h * p2[:, None] * (J + np.diag(rate))      # h phi2 (J + r)
    if method == "implicit":
        return eye + np.linalg.solve(eye - C, B)
    top = np.hstack([eye + B + C @ B + C @ C, -C @ C])
    return np.vstack([top, np.hstack([eye, np.zeros((n, n))])])


def linear_limit(method, J, h_max=10.0):
    """Smallest h (log grid, 0.5 % resolution) with spectral radius of the amplification above 1 + 1e-6.

    (1e-6, not less: a double zero eigenvalue of J (a held mass: x' = v, v' = 0) is a Jordan block whose
    eigenvalue 1 of the amplification comes out as 1 + O(sqrt(eps)) in floating point.)"""
    for h in np.geomspace(1e-3, h_max, 1900):
        if np.max(np.abs(np.linalg.eigvals(amplification(method, J, h)))) > 1 + 1e-6:
            return h
    return None


def jacobian_at(model, ref, t):
    """dg/du (dense) and the modes at the reference's output row nearest after t (the stored unknowns y)."""
    c = model.compile()
    k = int(np.searchsorted(ref.t, t))
    traj = ref._traj                        # the unknowns themselves: the Result keeps them on its trajectory
    c._t_right = T_END
    J = OdeProblem(c, traj.modes[k]).jacobian(ref.t[k], c.ode_state(traj.Y[k])).toarray()
    return J, traj.modes[k]


# ------------------------------------------------------------------------- report
def markdown(rows, limits, linear, repeats):
    host = (f"{platform.node() or 'unknown host'} ({platform.processor() or platform.machine()}, "
            f"{os.cpu_count()} logical CPUs shared with other jobs), Python {platform.python_version()}, "
            f"numpy {np.__version__}, scipy {scipy.__version__}, {time.strftime('%Y-%m-%d')}")
    out = [MARK, "## Excavator swing drive: stability and accuracy per fixed step (rk4, convolution PECE, "
           "convolution implicit)", "",
           f"Generated by `benchmarks/bench_convolution_stability.py` on {host}.", "",
           "Scene `excavator_swing` (SOURCES.md 004), 3 s, `simulate(3.0, dt_out=h, solver=..., h=h)`. Reference: "
           "IDA rtol 1e-9, output every 5 ms. `error` = max over the output instants of |turntable.w - ref| "
           "[rad/s] (target speed 7.85 rad/s), `at 3 s` the same at the end. `diverged` = stopped by the "
           "divergence test (`regmech.solvers.divergence`, max_growth 1e4). Time: median of "
           f"{repeats} runs (compilation excluded). Implicit corrector: `Newton` iterations, `fail` Newton "
           "failures (each followed by a fresh Jacobian or, at the last resort, a halved step: `halved`).", ""]
    head = "| h [s] | " + " | ".join(f"{name}: error / at 3 s / ms" for name, _, _ in METHODS) + \
        " | implicit: steps, RHS, Newton, fail, halved |"
    out += [head, "|---|" + "---|" * (len(METHODS) + 1)]
    for h in STEPS:
        cells = []
        for name, _, _ in METHODS:
            r = rows[name][h]
            cells.append(f"{r['err']:.2e} / {r['err_end']:.1e} / {r['time'] * 1e3:.0f}" if r["ok"]
                         else r["note"])
        r = rows[METHODS[-1][0]][h]
        extra = (f"{r['steps']}, {r['rhs']}, {r['newton']}, {r['failures']}, {r['subdivided']}" if r["ok"] else "")
        out.append(f"| {h:g} | " + " | ".join(cells) + f" | {extra} |")
    out += ["", "Largest stable step (bisection between the last completed and the first diverged step; the "
            "linear limit is the step at which the one-step amplification matrix on u' = J u first has a "
            "spectral radius above 1 + 1e-6, J at the held state t = 0.15 s / the sliding state t = 0.5 s):", "",
            "| method | measured: completes up to | diverges from | linear limit, held | linear limit, sliding |",
            "|---|---|---|---|---|"]
    for name, _, _ in METHODS:
        lo, hi = limits[name]
        lin = linear[name]
        fmt = (lambda v: "none up to 10 s" if v is None else f"{v:.4g} s")
        out.append(f"| {name} | {lo:.4g} s | {'none up to 3 s (one step)' if hi is None else f'{hi:.4g} s'} | "
                   f"{fmt(lin[0])} | {fmt(lin[1])} |")
    out.append("")
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "solvers_ode.md"),
                    help="Markdown file whose section (from the marker on) is replaced; '-' for stdout")
    args = ap.parse_args(argv)
    model = SCENES["excavator_swing"]()
    model.compile()
    ref = model.simulate(T_END, dt_out=REF_DT, solver="ida", rtol=1e-9)
    rows, limits, linear = {}, {}, {}
    kind = {"rk4": "rk4", "convolution (pece)": "pece", "convolution (implicit)": "implicit"}
    J_held, _ = jacobian_at(model, ref, 0.15)
    J_slide, _ = jacobian_at(model, ref, 0.5)
    for name, solver, opts in METHODS:
        rows[name] = {}
        for h in STEPS:
            rows[name][h] = r = attempt(model, solver, opts, h, ref, args.repeats)
            print(f"{name:24s} h={h:<6g} " + (f"err {r['err']:.3e} end {r['err_end']:.2e} {r['time'] * 1e3:.0f} ms"
                                              if r["ok"] else r["note"]), file=sys.stderr)
        limits[name] = largest_stable(model, solver, opts, rows[name], ref)
        linear[name] = (linear_limit(kind[name], J_held), linear_limit(kind[name], J_slide))
        print(f"{name}: stable up to {limits[name]}, linear {linear[name]}", file=sys.stderr)
    text = markdown(rows, limits, linear, args.repeats)
    if args.out == "-":
        print(text)
        return
    path = Path(args.out)
    old = path.read_text() if path.exists() else ""
    head = old.split(MARK)[0].rstrip("\n")
    path.write_text((head + "\n\n" if head else "") + text + "\n")
    print(f"wrote {path}", file=sys.stderr)


if __name__ == "__main__":
    main()
