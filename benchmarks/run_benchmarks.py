"""Full-size benchmark runs behind BENCHMARKS.md.

    python benchmarks/run_benchmarks.py --wp        # work-precision of every solver on every scene
    python benchmarks/run_benchmarks.py --hard      # hard cases at full size, every solver
    python benchmarks/run_benchmarks.py --peers     # regmech against its peers (bench_peers.py)
    python benchmarks/run_benchmarks.py --rewrite   # the work-precision report again from its CSV
    python benchmarks/run_benchmarks.py --all       # --wp and --hard in turn

Outputs: ``benchmarks/results/work_precision.md`` (with ``results/wp/``: CSV
and one log-log plot per scene), ``benchmarks/results/hard_cases.md`` (and
``results/wp/hard_cases.csv``), ``benchmarks/results/peers.md``. Every other
script in ``benchmarks/`` writes its own report into ``benchmarks/results/``;
``BENCHMARKS.md`` at the top of the repository summarises the latest figures
of each report by hand, with the command that regenerates it.

Options: ``--scenes``, ``--solvers``, ``--repeats`` (3), ``--time-limit`` per
run [s] (120 for work-precision, 60 for hard cases), ``--cache`` (reference
cache folder), ``--cases`` (hard-case keys), ``--merge`` (re-run some scenes or
hard cases and keep the others' records of the previous run in the report; with
``--hard`` and no ``--cases``: run only the cases not yet recorded, which resumes
an interrupted run).
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from dataclasses import asdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
WP_DIR = RESULTS / "wp"


def run_wp(args) -> None:
    from regmech.bench.report import write_report
    from regmech.bench.runner import available_solvers
    from regmech.bench.scenes import select
    from regmech.bench.workprecision import run_work_precision
    scenes = select(args.scenes)
    solvers = args.solvers or available_solvers()
    cmd = "python benchmarks/run_benchmarks.py --wp" + (" --scenes " + " ".join(args.scenes) if args.scenes else "")
    run = run_work_precision(scenes, solvers, repeats=args.repeats, limit=args.time_limit or 120.0,
                             cache_dir=Path(args.cache) if args.cache else None, command=cmd,
                             log=lambda m: print(m, file=sys.stderr))
    if args.merge and (WP_DIR / "work_precision.csv").exists():
        from regmech.bench.report import write_csv
        WP_DIR.mkdir(parents=True, exist_ok=True)
        write_csv(run.records, WP_DIR / "work_precision.partial.csv")   # kept if the merge fails
        _merge_previous(run, args)
    md = write_report(run, WP_DIR)
    text = md.read_text().replace("](wp_", "](wp/wp_")      # the Markdown lives one folder up
    (RESULTS / "work_precision.md").write_text(text)
    print(f"work-precision: {len(run.records)} runs in {run.wall_total / 60:.1f} min -> {RESULTS / 'work_precision.md'}")


def rewrite_wp(args) -> None:
    """The work-precision report again from the stored CSV and metadata (no runs; references from the cache)."""
    import json
    from regmech.bench.reference import ReferenceUnavailable, get_reference
    from regmech.bench.report import read_csv, write_report
    from regmech.bench.scenes import all_scenes
    from regmech.bench.workprecision import BenchRun
    meta = json.loads((WP_DIR / "work_precision.meta.json").read_text())
    records = read_csv(WP_DIR / "work_precision.csv")
    keys = {r.scene for r in records}
    run = BenchRun([sc for sc in all_scenes() if sc.key in keys], meta["solvers"], records, machine=meta["machine"],
                   repeats=meta["repeats"], limit=meta["limit"], command=meta["command"],
                   wall_total=meta["wall_total"])
    for sc in run.scenes:
        try:
            run.references[sc.key] = get_reference(sc, Path(args.cache) if args.cache else None)
        except ReferenceUnavailable as exc:
            run.references[sc.key], run.reference_errors[sc.key] = None, str(exc)
    md = write_report(run, WP_DIR)
    (RESULTS / "work_precision.md").write_text(md.read_text().replace("](wp_", "](wp/wp_"))
    print(f"rewrote {RESULTS / 'work_precision.md'} from {len(records)} stored runs")


def _merge_previous(run, args) -> None:
    """Keep the previous run's records of the scenes not re-run (their references come from the cache)."""
    from regmech.bench.reference import ReferenceUnavailable, get_reference
    from regmech.bench.report import read_csv
    from regmech.bench.scenes import all_scenes
    redone = {sc.key for sc in run.scenes}
    kept = [r for r in read_csv(WP_DIR / "work_precision.csv") if r.scene not in redone]
    run.records = kept + run.records
    order = [sc for sc in all_scenes() if sc.key in {r.scene for r in run.records}]
    for sc in order:
        if sc.key not in run.references:
            try:
                run.references[sc.key] = get_reference(sc, Path(args.cache) if args.cache else None)
            except ReferenceUnavailable as exc:
                run.references[sc.key], run.reference_errors[sc.key] = None, str(exc)
    run.scenes = order
    run.command += f" (merged with the previous run's records of {sorted({r.scene for r in kept})})"
    meta_path = WP_DIR / "work_precision.meta.json"
    if meta_path.exists():
        import json
        run.wall_total += json.loads(meta_path.read_text()).get("wall_total", 0.0)


HARD_CSV = WP_DIR / "hard_cases.csv"
HARD_META = WP_DIR / "hard_cases.meta.json"


def _read_hard_csv(path):
    """The outcomes stored by a previous (possibly interrupted) hard-case run."""
    from regmech.bench.hard import HardOutcome
    if not path.exists():
        return []
    out = []
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            for k in ("value", "tolerance", "wall_s"):
                row[k] = float(row[k]) if row[k] not in ("", "nan") else float("nan")
            for k in ("steps", "events"):
                row[k] = int(float(row[k])) if row[k] not in ("", "None", "nan") else 0
            out.append(HardOutcome(**row))
    return out


def _write_hard_csv(outcomes, path):
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = [asdict(o) for o in outcomes]
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def run_hard(args) -> None:
    """Every solver on every full-size hard case. The CSV is rewritten after each case, so an
    interrupted run keeps what finished; ``--merge`` re-runs only ``--cases`` (or the cases not
    yet in the CSV when ``--cases`` is not given) and keeps the other cases' outcomes."""
    import json
    from regmech.bench.hard import FULL, all_cases, hard_markdown, run_cases
    from regmech.bench.machine import machine_info
    from regmech.bench.runner import available_solvers
    everything = all_cases()
    previous = _read_hard_csv(HARD_CSV) if args.merge else []
    done = {o.case for o in previous}
    if args.cases:
        cases = [c for c in everything if c.key in args.cases]
    else:
        cases = [c for c in everything if not args.merge or c.key not in done]
    todo = {c.key for c in cases}
    solvers = args.solvers or available_solvers()
    # keep every earlier outcome except those of the (case, solver) pairs run again
    outcomes = [o for o in previous if not (o.case in todo and o.solver in solvers)]
    limit = args.time_limit or 60.0
    meta = json.loads(HARD_META.read_text()) if args.merge and HARD_META.exists() else {}
    wall = float(meta.get("wall_total", 0.0))
    for case in cases:
        t0 = time.perf_counter()
        outcomes += run_cases([case], solvers, size=FULL, limit=limit)
        wall += time.perf_counter() - t0
        _write_hard_csv(outcomes, HARD_CSV)
        HARD_META.write_text(json.dumps({"wall_total": wall, "limit": limit}))
    order = {c.key: i for i, c in enumerate(everything)}
    outcomes.sort(key=lambda o: order.get(o.case, len(order)))
    shown = [c for c in everything if c.key in {o.case for o in outcomes}]
    all_solvers = list(dict.fromkeys(solvers + [o.solver for o in outcomes]))
    (RESULTS / "hard_cases.md").write_text(hard_markdown(shown, outcomes, all_solvers, FULL, machine_info(),
                                                         limit, wall))
    print(f"hard cases: {len(outcomes)} runs, {wall / 60:.1f} min in total -> {RESULTS / 'hard_cases.md'}")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--wp", action="store_true", help="work-precision run (full size)")
    p.add_argument("--hard", action="store_true", help="hard cases (full size)")
    p.add_argument("--peers", action="store_true",
                   help="regmech against hand-written scipy and CasADi (benchmarks/bench_peers.py)")
    p.add_argument("--all", action="store_true", help="--wp and --hard")
    p.add_argument("--scenes", nargs="+")
    p.add_argument("--cases", nargs="+")
    p.add_argument("--solvers", nargs="+")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--time-limit", type=float, default=None)
    p.add_argument("--cache", default=None)
    p.add_argument("--rewrite", action="store_true",
                   help="rewrite the work-precision report from the stored CSV (no runs)")
    p.add_argument("--merge", action="store_true",
                   help="with --wp --scenes or --hard: keep the previous records of the other scenes/cases "
                        "(--hard without --cases: resume, running only the cases not yet recorded)")
    args = p.parse_args(argv)
    if not (args.wp or args.hard or args.all or args.rewrite or args.peers):
        p.error("choose --wp, --hard, --rewrite, --peers or --all")
    if args.rewrite:
        rewrite_wp(args)
    if args.wp or args.all:
        run_wp(args)
    if args.hard or args.all:
        run_hard(args)
    if args.peers:
        sys.path.insert(0, str(ROOT / "benchmarks"))
        import bench_peers
        bench_peers.main(["--repeats", str(max(args.repeats, 5))])
    return 0


if __name__ == "__main__":
    sys.exit(main())
