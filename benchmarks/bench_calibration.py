"""Calibration of the accuracy contract: achieved global error of every solver against the accuracy asked for.

    python benchmarks/bench_calibration.py [--cases KEY ...] [--solvers NAME ...] [--time-limit S]
                                           [--cache DIR] [--fresh]
    python benchmarks/bench_calibration.py --random 100 [--first-seed 0]

Every solver at accuracies 1e-2 .. 1e-6 (a subset per solver, ``regmech.bench.calibration.levels_for``) on
the library scenes and the hard cases at CI size, ``solver="auto"`` included; each returned run's error
against the case's reference in the contract's measure. Writes ``benchmarks/results/calibration.md``,
``calibration.png`` and ``benchmarks/results/wp/calibration.csv`` (a rerun resumes from the CSV unless
``--fresh``); BENCHMARKS.md summarises it.
The same runs: ``regmech bench --calibration --out DIR``.

``--random N`` calibrates instead on N random drivetrains of the fuzz generator (``auto``, ``ida`` and
``scipy:DOP853`` at 1e-2 and 1e-4, the default call at 1e-3): ``benchmarks/results/calibration_random.md``
(CSV ``benchmarks/results/wp/calibration_random.csv``).
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
    p.add_argument("--random", type=int, metavar="N",
                   help="instead: N random drivetrains of the fuzz generator (auto, ida, scipy:DOP853 at 1e-2 and "
                        "1e-4, the default call at 1e-3) -> benchmarks/results/calibration_random.md")
    p.add_argument("--first-seed", type=int, default=0, help="with --random: the first fuzz seed (default 0)")
    args = p.parse_args(argv)
    if args.random:
        return random_main(args, argv)
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


def random_main(args, argv) -> int:
    """The random part (``--random N``): resumes from its CSV unless ``--fresh``."""
    import json
    import time
    from regmech.bench import calibration as C
    from regmech.bench.machine import machine_info
    cases = C.random_cases(args.random, args.first_seed)
    csv_path = RESULTS / "wp" / "calibration_random.csv"
    meta_path = csv_path.with_suffix(".meta.json")
    meta = json.loads(meta_path.read_text()) if meta_path.exists() and not args.fresh else {}
    t0 = time.perf_counter()
    records = C.run_random(cases, csv_path, limit=args.time_limit, cache_dir=args.cache, merge=not args.fresh,
                           log=lambda m: print(m, flush=True))
    wall = float(meta.get("wall_total", 0.0)) + time.perf_counter() - t0
    meta_path.write_text(json.dumps({"wall_total": wall, "limit": args.time_limit,
                                     "machine": meta.get("machine") or machine_info()}))
    command = "python benchmarks/bench_calibration.py " + " ".join(sys.argv[1:] if argv is None else argv)
    md = C.random_markdown(records, cases, meta.get("machine") or machine_info(), args.time_limit, wall,
                           command.strip(), cache_dir=args.cache)
    out = RESULTS / "calibration_random.md"
    out.write_text(md)
    print(f"random calibration report: {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
