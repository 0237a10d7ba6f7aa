"""``regmech bench``: work-precision of every solver on the benchmark scenes.

    regmech bench [--quick] [--scenes KEY ...] [--solvers NAME ...] [--out DIR]
                  [--repeats N] [--time-limit S] [--cache DIR | --no-cache] [--no-progress]
    regmech bench --calibration [--scenes CASE ...] [--solvers NAME ...] [--out DIR] [--time-limit S]

Writes ``work_precision.csv``, ``work_precision.md`` and one log-log plot
``wp_<scene>.png`` per scene into ``--out`` (default ``bench-out``).
``--quick`` runs the two MSL scenes and the 10-car train with three
tolerances and two steps per solver (a few minutes on two cores).
``--list`` prints the scenes and solvers and exits. ``--calibration`` runs the
calibration of the accuracy contract instead (``regmech.bench.calibration``;
``--scenes`` then takes its case keys).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="regmech bench", description="work-precision benchmark of regmech's solvers")
    p.add_argument("--quick", action="store_true", help="small set: MSL First, CoupledClutches, 10-car train")
    p.add_argument("--scenes", nargs="+", metavar="KEY", help="scene keys (see --list; default: all)")
    p.add_argument("--solvers", nargs="+", metavar="NAME", help="solver names (default: every registered solver)")
    p.add_argument("--out", default="bench-out", help="output folder (default: bench-out)")
    p.add_argument("--repeats", type=int, default=None, help="runs per setting, median taken (default 3; quick 2)")
    p.add_argument("--time-limit", type=float, default=None,
                   help="wall-clock limit per run in s (default 120; quick 30)")
    p.add_argument("--cache", default=None, help="reference cache folder (default ~/.cache/regmech/ref)")
    p.add_argument("--no-cache", action="store_true", help="recompute the references, do not store them")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--list", action="store_true", help="list scenes and solvers, then exit")
    p.add_argument("--calibration", action="store_true",
                   help="calibration of the accuracy contract instead: every solver's achieved error against the "
                        "accuracy asked for (1e-2..1e-6) on the library scenes and the hard cases (CI size), "
                        "calibration.md/.png/.csv in --out (an interrupted run resumes from the CSV)")
    return p


def main(argv: list[str] | None = None) -> int:
    from regmech.errors import ParameterError
    from .report import write_report
    from .runner import available_solvers
    from .scenes import all_scenes, select
    from .workprecision import run_work_precision

    args = _parser().parse_args(sys.argv[1:] if argv is None else argv)
    if args.calibration:
        return _calibration(args, argv)
    solvers_known = available_solvers()
    if args.list:
        for sc in all_scenes():
            print(f"{sc.key:18s} {sc.title}")
        print("solvers: " + ", ".join(solvers_known))
        return 0
    try:
        scenes = select(args.scenes, quick=args.quick)
    except ParameterError as exc:
        print(f"regmech bench: {exc}", file=sys.stderr)
        return 2
    solvers = args.solvers or solvers_known
    unknown = [s for s in solvers if s not in solvers_known]
    if unknown:
        print(f"regmech bench: unknown solver(s) {unknown}; choose from {solvers_known}", file=sys.stderr)
        return 2
    if args.repeats is not None and args.repeats < 1:
        print("regmech bench: --repeats must be at least 1", file=sys.stderr)
        return 2
    repeats = args.repeats or (2 if args.quick else 3)
    limit = args.time_limit or (30.0 if args.quick else 120.0)
    command = "regmech bench " + " ".join(sys.argv[1:] if argv is None else argv)
    run = run_work_precision(scenes, solvers, repeats=repeats, limit=limit,
                             cache_dir=Path(args.cache) if args.cache else None, use_cache=not args.no_cache,
                             progress=not args.no_progress, command=command.strip(),
                             log=lambda msg: print(msg, file=sys.stderr))
    path = write_report(run, Path(args.out))
    bad = sum(1 for r in run.records if r.status in ("crash",))
    print(f"{len(run.records)} runs in {run.wall_total / 60:.1f} min; report: {path}")
    if bad:
        print(f"{bad} run(s) crashed with a non-regmech exception (see the report)", file=sys.stderr)
    return 0


def _calibration(args, argv) -> int:
    from . import calibration as C
    cases = C.all_cases()
    if args.scenes:
        unknown = set(args.scenes) - {c.key for c in cases}
        if unknown:
            print(f"regmech bench --calibration: unknown case(s) {sorted(unknown)}; choose from "
                  f"{[c.key for c in cases]}", file=sys.stderr)
            return 2
        cases = [c for c in cases if c.key in args.scenes]
    command = "regmech bench " + " ".join(sys.argv[1:] if argv is None else argv)
    path = C.run_all(Path(args.out), cases=cases, solvers=args.solvers, limit=args.time_limit or 30.0,
                     cache_dir=Path(args.cache) if args.cache else None, command=command.strip(),
                     log=(lambda msg: None) if args.no_progress else (lambda msg: print(msg, file=sys.stderr)))
    print(f"calibration report: {path}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
