"""Work-precision of the ODE-form solvers on torsional chains of 10 and 100 masses.

Scene: n inertias (J = 1 kg m^2) in a row, joined by spring-dampers
(c = 1e4 N m/rad, d = 1 N m s/rad) and anchored to the ground at the far end
by another one; a torque 10 sin(2 pi 2 t) N m drives the first inertia;
everything starts at rest; 1 s, output every 10 ms. Highest natural
frequency about 2 sqrt(c/J) = 200 rad/s, lightly damped.

Error: max over the output grid and over all masses of |w - w_ref|,
divided by max |w_ref|; the reference is IDA at rtol 1e-11 (atol 1e-13).
Time: wall time of ``simulate`` without compilation (the compiled system is
cached on the model), median of ``--repeats`` runs; IDA is run side by side
in the same process, and every time is also given as a ratio to
``scipy:RK45`` at rtol 1e-6 of the same n.

    python benchmarks/bench_solvers_ode.py            # writes benchmarks/results/solvers_ode.md
    python benchmarks/bench_solvers_ode.py --sizes 10 --repeats 1 --out -   # quick look, to stdout
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
from regmech.components import Fixed, Inertia, SpringDamper, Torque
from regmech.signals import Sine

T_END, DT_OUT = 1.0, 0.01

#: (solver, options) per chain size; fixed steps chosen inside each method's stability range, run with tol=None
#: (the bare method: no companion run of the error estimate, regmech.solvers.richardson, in the timings)
SETTINGS = {
    "ida": [{"rtol": r} for r in (1e-4, 1e-6, 1e-8)],
    "scipy:RK45": [{"rtol": r} for r in (1e-4, 1e-6, 1e-8)],
    "scipy:RK23": [{"rtol": r} for r in (1e-4, 1e-6)],
    "scipy:DOP853": [{"rtol": r} for r in (1e-4, 1e-6, 1e-8)],
    "scipy:Radau": [{"rtol": r} for r in (1e-4, 1e-6, 1e-8)],
    "scipy:BDF": [{"rtol": r} for r in (1e-4, 1e-6)],
    "scipy:LSODA": [{"rtol": r} for r in (1e-4, 1e-6, 1e-8)],
    "euler": [{"h": 2e-5, "tol": None}],
    "rk4": [{"h": h, "tol": None} for h in (1e-2 / 1, 1e-2 / 2, 1e-2 / 8)],
    "abm": [{"h": h, "tol": None} for h in (1e-2 / 2, 1e-2 / 4, 1e-2 / 16)],
    "convolution": [{"rtol": r} for r in (1e-4, 1e-6)] + [{"h": 1e-3}],
}


def chain(n: int, J: float = 1.0, c: float = 1e4, d: float = 1.0) -> rm.Model:
    m = rm.Model(f"chain{n}")
    fixed = m.add(Fixed("fixed"))
    drive = m.add(Torque("drive", tau=Sine(amplitude=10.0, freq_hz=2.0)))
    masses = [m.add(Inertia(f"J{k + 1}", J=J, phi0=0.0, w0=0.0)) for k in range(n)]
    m.connect(drive.support, fixed.flange)
    m.connect(drive.flange, masses[0].flange_a)
    for k in range(n - 1):
        link = m.add(SpringDamper(f"link{k + 1}", c=c, d=d))
        m.connect(masses[k].flange_b, link.flange_a)
        m.connect(link.flange_b, masses[k + 1].flange_a)
    anchor = m.add(SpringDamper("anchor", c=c, d=d))
    m.connect(masses[-1].flange_b, anchor.flange_a)
    m.connect(anchor.flange_b, fixed.flange)
    return m


def speeds(res, n):
    return np.column_stack([res[f"J{k + 1}.w"] for k in range(n)])


def run(model, solver, opts, repeats):
    times, res = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = model.simulate(T_END, DT_OUT, solver=solver, **opts)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), res


def label(opts):
    return ", ".join(f"{k}={v:g}" for k, v in opts.items() if v is not None)


def bench(n, repeats, only=None):
    model = chain(n)
    model.compile()
    ref = model.simulate(T_END, DT_OUT, solver="ida", rtol=1e-11, atol=1e-13)
    W = speeds(ref, n)
    scale = np.max(np.abs(W))
    rows = []
    for solver, settings in SETTINGS.items():
        if only and solver not in only:
            continue
        for opts in settings:
            try:
                t, res = run(model, solver, opts, repeats)
            except rm.SimulationError as exc:
                rows.append(dict(solver=solver, opts=label(opts), error=np.nan, time=np.nan, steps=0, rhs=0,
                                 jac=0, note=str(exc).split(".")[0]))
                print(f"n={n:4d} {solver:13s} {label(opts):12s} failed: {exc}", file=sys.stderr)
                continue
            err = float(np.max(np.abs(speeds(res, n) - W)) / scale)
            st = res.stats
            rows.append(dict(solver=solver, opts=label(opts), error=err, time=t, steps=st.steps, rhs=st.rhs_calls,
                             jac=st.jac_calls, note=""))
            print(f"n={n:4d} {solver:13s} {label(opts):12s} err {err:9.2e}  {t * 1e3:9.1f} ms  steps {st.steps:6d}  "
                  f"rhs {st.rhs_calls:7d}", file=sys.stderr)
    yard = [r["time"] for r in rows if r["solver"] == "scipy:RK45" and r["opts"] == "rtol=1e-06"]
    yard = yard[0] if yard else np.nan
    return model, rows, yard


def rhs_cost(model, repeats=200):
    """Median wall time of one ODE right-hand side and of one DAE residual (IDA's unit of work)."""
    c = model.compile()
    y, yp = c.initial_y(0.0)
    u = c.ode_state(y)
    res = np.zeros(c.N)
    t_rhs, t_res = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        c.ode_rhs(0.1, u, c.modes0)
        t_rhs.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        c.residual(0.1, y, yp, res, c.modes0)
        t_res.append(time.perf_counter() - t0)
    return statistics.median(t_rhs), statistics.median(t_res)


def best_within(rows, tol):
    ok = [r for r in rows if np.isfinite(r["error"]) and r["error"] <= tol]
    return min(ok, key=lambda r: r["time"]) if ok else None


def markdown(results, repeats):
    out = ["# ODE-form solvers: work-precision on torsional chains", "",
           f"Generated by `benchmarks/bench_solvers_ode.py` on {platform.node() or 'unknown host'} "
           f"({platform.processor() or platform.machine()}, {os.cpu_count()} logical CPUs shared with other jobs), "
           f"Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
           f"{time.strftime('%Y-%m-%d')}.", "",
           "Scene: n inertias J = 1 kg m^2 joined (and anchored at the far end) by spring-dampers c = 1e4 N m/rad, "
           "d = 1 N m s/rad; torque 10 sin(2 pi 2 t) N m on the first; 1 s, output every 10 ms; highest natural "
           "frequency about 200 rad/s, lightly damped.", "",
           "Error: max over outputs and masses of |w - w_ref| / max|w_ref|, reference IDA at rtol 1e-11. "
           f"Time: median of {repeats} runs of `simulate` (compilation excluded), recording of the outputs "
           "included. `ratio` = time / time of scipy:RK45 at rtol 1e-6 in the same run. Fixed-step methods: "
           "`h` is the requested step (steps land exactly on the output instants).", ""]
    for n, (model, rows, yard), (t_rhs, t_res) in results:
        out += [f"## n = {n} masses ({model.compile().ode_size()} ODE states)", "",
                f"One ODE right-hand side (`ode_rhs`, KKT solve included): {t_rhs * 1e6:.0f} us; one DAE residual "
                f"(IDA): {t_res * 1e6:.0f} us.", "",
                "| solver | setting | error | time [ms] | ratio | steps | RHS calls | Jacobians |",
                "|---|---|---|---|---|---|---|---|"]
        for r in rows:
            if not np.isfinite(r["error"]):
                out.append(f"| {r['solver']} | {r['opts']} | failed: {r['note']} | | | | | |")
                continue
            out.append(f"| {r['solver']} | {r['opts']} | {r['error']:.2e} | {r['time'] * 1e3:.1f} | "
                       f"{r['time'] / yard:.2f} | {r['steps']} | {r['rhs']} | {r['jac']} |")
        out.append("")
        out.append("Fastest run reaching an error of at most:")
        out.append("")
        for tol in (1e-2, 1e-4, 1e-6):
            b = best_within(rows, tol)
            line = f"- {tol:g}: " + (f"{b['solver']} ({b['opts']}), {b['time'] * 1e3:.1f} ms" if b else "none")
            for what, pick in (("best ODE-form", lambda r: r["solver"] != "ida"),
                               ("convolution", lambda r: r["solver"] == "convolution")):
                o = best_within([r for r in rows if pick(r)], tol)
                if o and b and o is not b:
                    line += f"; {what}: {o['solver']} ({o['opts']}) {o['time'] * 1e3:.1f} ms " \
                            f"({o['time'] / b['time']:.1f}x)"
            out.append(line)
        out.append("")
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 100])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--only", nargs="*", help="run only these solvers")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "solvers_ode.md"),
                    help="output Markdown file ('-' for stdout)")
    args = ap.parse_args(argv)
    results = []
    for n in args.sizes:
        model, rows, yard = bench(n, args.repeats, args.only)
        results.append((n, (model, rows, yard), rhs_cost(model)))
    text = markdown(results, args.repeats)
    if args.out == "-":
        print(text)
    else:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text + "\n")
        print(f"wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
