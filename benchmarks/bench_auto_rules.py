"""solver="auto" on the benchmark chains: its choice against ida, expm and scipy:DOP853 under accuracy=.

For chains of 10, 100 and 1000 inertias (``bench_foundation.chain``: a 5 Hz
sine torque on the first inertia, spring-dampers, a grounding spring), 1 s,
at accuracies 1e-2, 1e-4, 1e-6 and output intervals 1e-2 and 1e-3 s, every
solver runs with ``accuracy=`` (the contract's runs included in its time),
interleaved, medians of ``--repeats``. A run that refuses or exceeds
``--timeout`` seconds is shown as such. The last columns: the solver auto
chose, and auto's time over the fastest solver that met the accuracy (the
issue-14 target is <= 1.5).

    python benchmarks/bench_auto_rules.py [--sizes 10 100 1000] [--repeats 3] [--out results/auto_rules.md]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from bench_foundation import chain  # noqa: E402

SOLVERS = ["auto", "ida", "expm", "scipy:DOP853"]
ACCURACIES = [1e-2, 1e-4, 1e-6]
DT_OUTS = [1e-2, 1e-3]


def one(m, solver, acc, dt, timeout):
    t0 = time.perf_counter()
    try:
        r = m.simulate(1.0, dt, solver=solver, accuracy=acc, timeout_s=timeout)
    except Exception as exc:        # noqa: BLE001 - a refusal or a timeout is a table entry
        return None, type(exc).__name__, None
    dt_run = time.perf_counter() - t0
    ok = r.stats.error_estimate is not None and r.stats.error_estimate <= acc
    return (dt_run if ok else None), r.stats.solver, r.stats.error_estimate


def main(argv=None):
    p = argparse.ArgumentParser()
    p.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 1000])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--timeout", type=float, default=30.0)
    p.add_argument("--out", default=str(Path(__file__).parent / "results" / "auto_rules.md"))
    a = p.parse_args(argv)
    rows = []
    load0 = os.getloadavg()
    for n in a.sizes:
        m = chain(n)
        m.compile()
        for dt in DT_OUTS:
            for acc in ACCURACIES:
                times = {s: [] for s in SOLVERS}
                picked = set()
                for _ in range(a.repeats):
                    for s in SOLVERS:       # interleaved
                        if times[s] and times[s][-1] is None and s != "auto":
                            continue        # refused or timed out once: not again
                        t, used, est = one(m, s, acc, dt, a.timeout)
                        times[s].append(t)
                        if s == "auto":
                            picked.add(used)
                med = {s: (statistics.median(v) if v and all(x is not None for x in v) else None)
                       for s, v in times.items()}
                best = min((v for s, v in med.items() if s != "auto" and v is not None), default=None)
                ratio = med["auto"] / best if med["auto"] is not None and best else None
                rows.append((n, dt, acc, med, "/".join(sorted(picked)), ratio))
                print(n, dt, acc, {k: (round(v, 3) if v else v) for k, v in med.items()}, picked,
                      ratio and round(ratio, 2), flush=True)
    load1 = os.getloadavg()
    fmt = lambda v: "-" if v is None else f"{v * 1e3:.0f}"  # noqa: E731
    lines = ["# solver=\"auto\" on the benchmark chains", "",
             "`python benchmarks/bench_auto_rules.py` (the rules: `regmech.solvers.auto`). Chain of n inertias "
             "(`bench_foundation.chain`, 5 Hz sine drive), 1 s, every solver with `accuracy=` (all contract runs "
             f"counted), interleaved, medians of {a.repeats}, wall ms; '-': refused, estimate above the accuracy "
             f"or over {a.timeout:g} s. Load average {load0[0]:.1f} at the start, {load1[0]:.1f} at the end "
             "(2 cores, shared).", "",
             "| n | dt_out | accuracy | auto | ida | expm | scipy:DOP853 | auto chose | auto / fastest |",
             "|---|---|---|---|---|---|---|---|---|"]
    for n, dt, acc, med, picked, ratio in rows:
        lines.append(f"| {n} | {dt:g} | {acc:g} | {fmt(med['auto'])} | {fmt(med['ida'])} | {fmt(med['expm'])} | "
                     f"{fmt(med['scipy:DOP853'])} | {picked} | {'-' if ratio is None else f'{ratio:.2f}'} |")
    Path(a.out).write_text("\n".join(lines) + "\n")
    print("->", a.out)


if __name__ == "__main__":
    main()
