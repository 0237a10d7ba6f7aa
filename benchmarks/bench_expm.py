"""Benchmark: the step-doubling exponential integrator ("expm", REFERENCES.md [002]) against scipy and IDA.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_expm.py [--sizes 10 100 1000] [--repeat 3]
                                                          [--out benchmarks/results/expm.md]

Scene: ``regmech.library.train(n, c_r=0)``, a train of n cars joined by
spring-damper couplers, pulled by a force ramped up over 10 s (rolling
resistance off: that term, ``tanh(v/v_eps)``, is nonlinear). 20 s, output
every 0.1 s. A second forcing, ``traction.f = 3e5 (1 + sin(2 pi 0.5 t))/2``
(not a polynomial on a step), shows the method as an ordinary one.

Error: the largest deviation over all output instants of the car speeds
and of the coupler forces, each relative to the largest value of its kind
(the larger of the two is reported). Reference: the modal solution of the
train (``modal_reference``: identical couplers give proportional damping, so
the modes decouple; each is stepped exactly), independent of regmech.

For every solver a sweep of its accuracy setting (rtol, or the step h for
expm, run with ``tol=None``: the bare method, without the companion run of
its error estimate) is timed (median of ``--repeat`` runs, each a full ``simulate`` call
on an already compiled model, in the same process, one BLAS thread for all
so that the shared 2-core machine does not thrash); "time to 1e-6" is the
fastest run of the sweep whose error is at most 1e-6.

Round-off floor: the spread of expm results over steps h, h/2, h/4 and
over the dense/sparse paths (which round differently) estimates the error
floor at each n.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")      # before numpy: no BLAS thread thrashing

import argparse  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402

from regmech.library import train  # noqa: E402
from regmech.signals import Sine  # noqa: E402

T_END, DT_OUT = 20.0, 0.1
TARGETS = (1e-6, 1e-10)


def scene(n: int, forcing: str):
    m = train(n, c_r=0.0)
    if forcing == "sine":
        m["traction"].f = Sine(amplitude=1.5e5, freq_hz=0.5, offset=1.5e5)
    m.compile()
    return m


def signals(res, n):
    V = np.column_stack([res[f"car{i}.v"] for i in range(n)])
    F = np.column_stack([res[f"coupler{i}.f"] for i in range(n - 1)])
    return V, F


def error(res, ref, n):
    V, F = signals(res, n)
    Vr, Fr = ref
    if V.shape != Vr.shape:             # the breakpoint of the ramp is recorded twice: drop the left value
        keep = np.ones(len(res.t), bool)
        keep[np.nonzero(np.diff(res.t) == 0)[0]] = False
        V, F = V[keep], F[keep]
    return max(np.abs(V - Vr).max() / np.abs(Vr).max(), np.abs(F - Fr).max() / np.abs(Fr).max())


def timed(m, repeat, dt_out=DT_OUT, **kw):
    """(median, min) wall time of ``repeat`` full simulate calls, and the last result."""
    times, res = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        res = m.simulate(T_END, dt_out, **kw)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), min(times), res


def sweeps(n, forcing):
    """(label, solver, options) of every run of the sweep."""
    runs = []
    if forcing == "ramp":
        for h in (DT_OUT, DT_OUT / 4):
            runs.append((f"expm h={h:g}", "expm", {"h": h, "order_p": 2, "tol": None}))
    else:
        for p in (2, 3):
            for h in (DT_OUT, DT_OUT / 2, DT_OUT / 4, DT_OUT / 8):
                runs.append((f"expm p={p} h={h:g}", "expm", {"h": h, "order_p": p, "tol": None}))
    for rtol in (1e-5, 1e-7, 1e-9, 1e-11, 1e-12):
        runs.append((f"DOP853 rtol={rtol:g}", "scipy:DOP853", {"rtol": rtol, "atol": rtol * 1e-3}))
    for rtol in (1e-5, 1e-7, 1e-9):
        runs.append((f"RK45 rtol={rtol:g}", "scipy:RK45", {"rtol": rtol, "atol": rtol * 1e-3}))
    for rtol in (1e-5, 1e-7, 1e-9):
        runs.append((f"Radau rtol={rtol:g}", "scipy:Radau", {"rtol": rtol, "atol": rtol * 1e-3}))
    for rtol in (1e-5, 1e-7, 1e-9, 1e-11):
        runs.append((f"IDA rtol={rtol:g}", "ida", {"rtol": rtol, "atol": rtol * 1e-3}))
    if n >= 1000:        # the explicit low-order and implicit runs at tight tolerances take minutes there
        runs = [r for r in runs if not (r[1] in ("scipy:RK45",) and r[2]["rtol"] < 1e-7)]
    return runs


def modal_reference(n, forcing, times, m_car=60e3, c=2e7, d=5e4, force=3e5, t_ramp=10.0):
    """Car speeds and coupler forces of ``train(n, c_r=0)`` by modal superposition (independent of regmech).

    The couplers are identical spring-dampers, so the damping is stiffness-proportional and the
    free-free chain decouples in the modes of the path Laplacian,
    ``lam_k = 2 - 2 cos(k pi / n)``, ``phi_k(i) ~ cos(k pi (i + 1/2) / n)`` (k = 0: rigid motion):
    ``m eta'' + d lam_k eta' + c lam_k eta = phi_k(0) f(t)``, from rest. Each mode is stepped
    from output instant to output instant with the exponential of its small augmented matrix
    (forcing states ``[1, t]`` for the ramp, ``[1, sin, cos]`` for the sine), which is exact.
    Coupler forces ``c (s_i+1 - s_i) + d (v_i+1 - v_i)`` are summed over the elastic modes only, so
    they do not suffer from differencing large absolute positions.
    """
    import scipy.linalg as la
    k = np.arange(n)
    lam = 2.0 - 2.0 * np.cos(k * np.pi / n)
    Phi = np.cos(np.outer(np.arange(n) + 0.5, k) * np.pi / n)
    Phi /= np.linalg.norm(Phi, axis=0)
    load = Phi[0, :]
    dt = float(times[1] - times[0])
    Omega = 2 * np.pi * 0.5
    eta = np.zeros((len(times), n))
    deta = np.zeros((len(times), n))
    for j in range(n):
        a, b = d * lam[j] / m_car, c * lam[j] / m_car
        g = load[j] / m_car
        if forcing == "ramp":
            def aug(slope, const):
                A = np.zeros((4, 4))
                A[0, 1] = 1.0
                A[1, 0], A[1, 1] = -b, -a
                A[1, 2], A[1, 3] = g * const, g * slope
                A[3, 2] = 1.0
                return la.expm(A * dt)
            P_ramp, P_flat = aug(force / t_ramp, 0.0), aug(0.0, force)
            z = np.array([0.0, 0.0, 1.0, 0.0])
            for i, t in enumerate(times):
                eta[i, j], deta[i, j] = z[0], z[1]
                z = (P_ramp if t < t_ramp - 1e-9 else P_flat) @ z
        else:
            A = np.zeros((5, 5))
            A[0, 1] = 1.0
            A[1, 0], A[1, 1] = -b, -a
            A[1, 2], A[1, 3] = g * 1.5e5, g * 1.5e5
            A[3, 4], A[4, 3] = Omega, -Omega
            P = la.expm(A * dt)
            z = np.array([0.0, 0.0, 1.0, 0.0, 1.0])
            for i in range(len(times)):
                eta[i, j], deta[i, j] = z[0], z[1]
                z = P @ z
    V = deta @ Phi.T
    dPhi = np.diff(Phi, axis=0)[:, 1:]                     # (n-1) x elastic modes
    F = (c * eta[:, 1:] + d * deta[:, 1:]) @ dPhi.T
    return V, F


def bench(n, forcing, repeat):
    m = scene(n, forcing)
    times = np.round(np.arange(0.0, T_END + DT_OUT / 2, DT_OUT), 12)
    t0 = time.perf_counter()
    ref = modal_reference(n, forcing, times)
    t_ref = time.perf_counter() - t0
    rows = []
    for label, solver, opts in sweeps(n, forcing):
        try:
            t, t_min, res = timed(m, repeat, solver=solver, **opts)
        except Exception as exc:  # a failed setting is reported, not fatal
            rows.append({"n": n, "forcing": forcing, "run": label, "solver": solver, "time": math.nan,
                         "error": math.nan, "note": f"failed: {type(exc).__name__}"})
            continue
        note = ""
        if solver == "expm":
            ex = res.stats.extra
            note = (f"{'sparse' if ex['sparse'] else 'dense'}, r={ex['taylor_r']}, m={ex['doublings_m']}, "
                    f"set-up {ex['setup_time'] * 1e3:.1f} ms")
        rows.append({"n": n, "forcing": forcing, "run": label, "solver": solver, "time": t, "min": t_min,
                     "error": error(res, ref, n), "steps": res.stats.steps, "note": note})
    return rows, t_ref, ref


def scaling_rows(sizes, repeat):
    """Dense versus sparse E and large steps, ramp forcing: where does the n^3 set-up take over?"""
    rows = []
    for n in sizes:
        m = scene(n, "ramp")
        for label, dt_out, opts, reps in (
                ("DOP853 rtol=1e-9", DT_OUT, {"solver": "scipy:DOP853", "rtol": 1e-9, "atol": 1e-12}, repeat),
                ("expm sparse h=0.1", DT_OUT, {"solver": "expm", "sparse": True, "tol": None}, repeat),
                ("expm dense h=0.1", DT_OUT, {"solver": "expm", "sparse": False, "tol": None},
                 1 if n >= 1000 else repeat),
                ("expm sparse h=1, dt_out=1", 1.0, {"solver": "expm", "sparse": True, "tol": None}, repeat),
                ("expm dense h=1, dt_out=1", 1.0, {"solver": "expm", "sparse": False, "tol": None},
                 1 if n >= 1000 else repeat)):
            if opts.get("sparse") is False and n > 1000:
                continue                          # (2n)^3 products of 6000 x 6000: minutes per set-up
            t, t_min, res = timed(m, reps, dt_out=dt_out, **opts)
            times = np.round(np.arange(0.0, T_END + dt_out / 2, dt_out), 12)
            err = error(res, modal_reference(n, "ramp", times), n)
            ex = res.stats.extra
            note = "" if opts["solver"] != "expm" else (
                f"r={ex['taylor_r']}, m={ex['doublings_m']}, set-up {ex['setup_time']:.3f} s"
                + (f", E density {ex['E_density']:.3f}" if "E_density" in ex else ""))
            rows.append({"n": n, "run": label, "time": t, "min": t_min, "error": err, "note": note})
        print(f"done scaling n={n}", flush=True)
    return rows


def floor_estimate(n, repeat):
    """Spread of expm results (ramp forcing: exact for any h) over h, h/2, h/4 and dense/sparse."""
    m = scene(n, "ramp")
    outs = []
    for opts in ({"h": DT_OUT}, {"h": DT_OUT / 2}, {"h": DT_OUT / 4}, {"h": DT_OUT, "sparse": n < 200}):
        res = m.simulate(T_END, DT_OUT, solver="expm", tol=None, **opts)
        outs.append(signals(res, n))
    V0, F0 = outs[0]
    spread = max(max(np.abs(V - V0).max() / np.abs(V0).max(), np.abs(F - F0).max() / np.abs(F0).max())
                 for V, F in outs[1:])
    return spread


def time_to(rows, solver_prefix, target, key="time"):
    ok = [r[key] for r in rows if r["solver"].startswith(solver_prefix) and r["error"] <= target]
    return min(ok) if ok else math.nan


def warm_up():
    """One untimed run of every solver (imports, first-call caches) before anything is timed."""
    m = scene(10, "ramp")
    for solver in ("expm", "scipy:DOP853", "scipy:RK45", "scipy:Radau", "ida"):
        m.simulate(2.0, DT_OUT, solver=solver)


def fmt_t(t):
    return "–" if not math.isfinite(t) else (f"{t * 1e3:.0f} ms" if t < 10 else f"{t:.1f} s")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 1000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--forcings", nargs="+", default=["ramp", "sine"])
    ap.add_argument("--scaling-sizes", type=int, nargs="*", default=[100, 200, 400, 1000, 3000])
    ap.add_argument("--out", default="benchmarks/results/expm.md")
    args = ap.parse_args(argv)

    from regmech.analysis.expm_tables import markdown, optimal_split_table, roundoff_check

    all_rows, summary, refs = [], [], []
    warm_up()
    for forcing in args.forcings:
        for n in args.sizes:
            rows, t_ref, _ = bench(n, forcing, args.repeat)
            all_rows += rows
            expm_best = min((r["error"] for r in rows if r["solver"] == "expm"), default=math.nan)
            refs.append({"n": n, "forcing": forcing, "reference time": fmt_t(t_ref),
                         "expm vs reference": f"{expm_best:.1e}"})
            for target in TARGETS:
                entry = {"n": n, "forcing": forcing, "target": f"{target:g}"}
                for name, prefix in (("expm", "expm"), ("DOP853", "scipy:DOP853"), ("RK45", "scipy:RK45"),
                                     ("Radau", "scipy:Radau"), ("IDA", "ida")):
                    med, low = time_to(rows, prefix, target), time_to(rows, prefix, target, "min")
                    entry[name] = fmt_t(med) + ("" if not math.isfinite(low) else f" ({fmt_t(low)})")
                others = ("scipy:DOP853", "scipy:RK45", "scipy:Radau", "ida")
                for key, col in (("time", "speed-up (medians)"), ("min", "speed-up (mins)")):
                    best_other = min(time_to(rows, p, target, key) for p in others)
                    te = time_to(rows, "expm", target, key)
                    entry[col] = (f"{best_other / te:.1f}x" if math.isfinite(te) and math.isfinite(best_other)
                                  else "–")
                summary.append(entry)
            print(f"done n={n} {forcing}", flush=True)
    floors = [{"n": n, "spread of expm results": f"{floor_estimate(n, args.repeat):.1e}"} for n in args.sizes]
    scal = scaling_rows(args.scaling_sizes, args.repeat) if args.scaling_sizes else []

    split = optimal_split_table()
    rc = roundoff_check(1e3) + roundoff_check(1e5) + roundoff_check(1e3, scaling="frequency") + \
        roundoff_check(1e5, scaling="frequency")

    lines = [
        "# expm: the step-doubling matrix exponential (REFERENCES.md [002])",
        "",
        f"Machine: {platform.machine()}, {os.cpu_count()} cores (shared with other jobs), Python "
        f"{platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
        f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}. Medians of {args.repeat} runs, all "
        f"solvers in the same process on the same compiled model. Produced by `benchmarks/bench_expm.py`.",
        "",
        "Scene: `regmech.library.train(n, c_r=0)` (n cars, spring-damper couplers c = 2e7 N/m, d = 5e4 N s/m, "
        "60 t cars; highest frequency 36.5 rad/s; lowest non-zero 36.5 sin(pi/2n) rad/s), 20 s, output every "
        "0.1 s. `ramp`: the library's traction (0 to 300 kN over 10 s: piecewise linear, integrated exactly by "
        "expm with order_p = 2); `sine`: 150 kN (1 + sin(pi t)). Error: largest deviation of car speeds and "
        "coupler forces, relative to the largest value of each, against the modal solution (exact, independent "
        "of regmech; see `modal_reference` in the script).",
        "",
        "## Time to reach a relative error",
        "",
        "Median (min) of the repeats of the fastest run of each solver's sweep that reaches the target; "
        "speed-up = time of the best other solver / time of expm. '–': no run of the sweep reached it.",
        "",
        markdown(summary, ["n", "forcing", "target", "expm", "DOP853", "RK45", "Radau", "IDA",
                           "speed-up (medians)", "speed-up (mins)"]),
        "",
        "## Reference check",
        "",
        markdown(refs, ["n", "forcing", "reference time", "expm vs reference"]),
        "",
        "## Round-off floor of expm (train, ramp forcing)",
        "",
        "Largest relative difference between expm runs at h = 0.1, 0.05, 0.025 s and the other storage path "
        "(dense with energy scaling vs sparse with the paper's frequency scaling): each is exact for this "
        "forcing, so the spread is their round-off.",
        "",
        markdown(floors, ["n", "spread of expm results"]),
        "",
        "## Dense versus sparse E, and long steps (ramp forcing)",
        "",
        "Times in s (median and min); `dt_out=1`: 21 output instants instead of 201, so expm takes 20 steps "
        "of 1 s (nu h = 40) while DOP853's steps are set by its tolerance. Errors against the modal solution.",
        "",
        markdown(scal, ["n", "run", "time", "min", "error", "note"], {"time": ".3f", "min": ".3f", "error": ".1e"}),
        "",
        "## All runs",
        "",
        "Times in s: median and min of the repeats (the machine is shared: a median can catch a busy period).",
        "",
        markdown(all_rows, ["n", "forcing", "run", "time", "min", "error", "steps", "note"],
                 {"time": ".4f", "min": ".4f", "error": ".2e"}),
        "",
        "## The paper's optimal split (recomputed)",
        "",
        "Per-step error `eps = 2^m theta^(r+1)/(r+1)!` with `theta = nu h/2^m`, cost `m + r` products; the "
        "optimal theta of order r is where (r, theta) and (r + 1, 2 theta) cost the same and give the same "
        "error: `theta_r = (r+2)/2^(r+1)`, `eps_r = theta_r^r/(r+1)!` per unit of `nu h` "
        "(`regmech.analysis.expm_tables.optimal_split_table`).",
        "",
        markdown(split, ["r", "theta", "theta_closed_form", "eps", "paper_theta", "paper_eps"],
                 {"theta": ".4f", "theta_closed_form": ".4f", "eps": ".2e"}),
        "",
        "## 'Any step, error down to round-off'",
        "",
        "Chain of 5 inertias with geometrically graded stiffness (frequency ratio 1e3 and 1e5), quadratic torque, "
        "order_p = 3 (exact for that forcing), 4 steps of h; error of positions and speeds against the modal "
        "solution in 40-digit arithmetic, both of the exactly assembled problem (`_parameters`) and of the "
        "rounded matrix C the solver uses; `err_w_scipy_expm`: the speeds of the same problem computed with "
        "`scipy.linalg.expm` of the augmented matrix, for comparison. `floor` = w_max t_end 2^-53 "
        "(`regmech.analysis.expm_tables.roundoff_check`).",
        "",
        markdown(rc, ["ratio", "scaling", "h_periods", "nu_h", "taylor_r", "doublings_m", "err_phi", "err_w",
                      "err_phi_parameters", "err_w_parameters", "err_w_scipy_expm", "floor"],
                 {"ratio": ".0e", "nu_h": ".3g", "err_phi": ".1e", "err_w": ".1e", "err_phi_parameters": ".1e",
                  "err_w_parameters": ".1e", "err_w_scipy_expm": ".1e", "floor": ".1e"}),
        "",
    ]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
