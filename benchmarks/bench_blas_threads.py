"""What one BLAS thread does to the ODE-form path (``regmech.solvers.blas``), measured side by side.

    python benchmarks/bench_blas_threads.py [--repeats 7] [--sizes 1000 10000] [--load-note '...']

On the benchmark chains (``bench_foundation.chain``, 1 s, output every 10 ms, rtol 1e-6), interleaved, medians:
scipy's DOP853 by hand (``peers.scipy_models.chain``) with numpy's BLAS threads as they are, the same hand run
inside ``one_blas_thread`` (what the hand gains from the same setting), and regmech's ``scipy:DOP853`` at rtol r
and at 20 r (the peers' matched-error row, ``bench_peers.ODE_LOOSER``). Writes
``benchmarks/results/blas_threads.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_foundation import chain as regmech_chain          # noqa: E402
from peers import scipy_models as sm                          # noqa: E402

from regmech.solvers.blas import one_blas_thread              # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000])
    ap.add_argument("--load-note", default="")
    ap.add_argument("--out", default=str(HERE / "results" / "blas_threads.md"))
    args = ap.parse_args(argv)
    rtol = 1e-6
    lines = ["# One BLAS thread on the ODE-form path (`regmech.solvers.blas`)", "",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
             f"load: {os.getloadavg()[0]:.2f} at the start. {args.load_note}", "",
             f"Chain of n inertias, 1 s, dt_out 10 ms, rtol {rtol:g}; interleaved, medians of {args.repeats} "
             f"(wall ms). `hand`: scipy DOP853 by hand with numpy's BLAS threads as they are; `hand, 1 thread`: "
             f"the same inside `one_blas_thread`; regmech `scipy:DOP853` (which runs inside it) at r and at 20 r "
             f"(the peers' matched-error row).", "",
             "| n | hand | hand, 1 thread | regmech r | regmech 20 r | regmech 20 r / hand | "
             "regmech 20 r / (hand, 1 thread) |", "|---|---|---|---|---|---|---|"]
    for n in args.sizes:
        m = regmech_chain(n)
        m.compile()
        m.simulate(1.0, dt_out=1e-2, solver="scipy:DOP853", rtol=rtol)       # the stiffness check, once

        def hand():
            sm.chain(n, "DOP853", rtol=rtol)

        def hand1():
            with one_blas_thread():
                sm.chain(n, "DOP853", rtol=rtol)

        def reg():
            m.simulate(1.0, dt_out=1e-2, solver="scipy:DOP853", rtol=rtol)

        def reg20():
            m.simulate(1.0, dt_out=1e-2, solver="scipy:DOP853", rtol=20 * rtol)
        runs = {"hand": hand, "hand1": hand1, "reg": reg, "reg20": reg20}
        times = {k: [] for k in runs}
        for _ in range(args.repeats):
            for k, fn in runs.items():
                t0 = time.perf_counter()
                fn()
                times[k].append(1e3 * (time.perf_counter() - t0))
        med = {k: statistics.median(v) for k, v in times.items()}
        lines.append(f"| {n} | {med['hand']:.1f} | {med['hand1']:.1f} | {med['reg']:.1f} | {med['reg20']:.1f} | "
                     f"{med['reg20'] / med['hand']:.2f}x | {med['reg20'] / med['hand1']:.2f}x |")
        print(lines[-1], flush=True)
    lines += ["", f"Load at the end: {os.getloadavg()[0]:.2f}."]
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
