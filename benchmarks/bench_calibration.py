"""Calibration of the accuracy contract: achieved global error of every solver against the accuracy asked for.

    python benchmarks/bench_calibration.py [--cases KEY ...] [--solvers NAME ...] [--time-limit S]
                                           [--cache DIR] [--fresh]

Every solver at accuracies 1e-2 .. 1e-6 (a subset per solver, ``regmech.bench.calibration.levels_for``) on
the library scenes and the hard cases at CI size, ``solver="auto"`` included; each returned run's error
against the case's reference in the contract's measure. Writes ``benchmarks/results/calibration.md``,
``calibration.png`` and ``benchmarks/results/wp/calibration.csv`` (a rerun resumes from the CSV unless
``--fresh``); ``python benchmarks/run_benchmarks.py --assemble`` puts the section into BENCHMARKS.md.
The same campaign: ``regmech bench --calibration --out DIR``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


def main(argv=None) -> int:
    from regmech.bench import calibration as C
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--cases", nargs="+", help="case keys (default: all)")
    p.add_argument("--solvers", nargs="+", help=f"solvers (default: {' '.join(C.SOLVERS)})")
    p.add_argument("--time-limit", type=float, default=30.0, help="wall-clock limit per run [s] (default 30)")
    p.add_argument("--cache", default=None, help="reference cache folder (default ~/.cache/regmech/ref)")
    p.add_argument("--fresh", action="store_true", help="ignore the records of an earlier run")
    args = p.parse_args(argv)
    cases = C.all_cases()
    if args.cases:
        unknown = set(args.cases) - {c.key for c in cases}
        if unknown:
            p.error(f"unknown cases {sorted(unknown)}; choose from {[c.key for c in cases]}")
        cases = [c for c in cases if c.key in args.cases]
    command = "python benchmarks/bench_calibration.py " + " ".join(sys.argv[1:] if argv is None else argv)
    path = C.run_all(RESULTS, csv_path=RESULTS / "wp" / "calibration.csv", cases=cases, solvers=args.solvers,
                     limit=args.time_limit, cache_dir=args.cache, merge=not args.fresh, command=command.strip(),
                     log=lambda m: print(m, flush=True))
    print(f"calibration report: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
