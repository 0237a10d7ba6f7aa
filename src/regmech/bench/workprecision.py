"""The work-precision benchmark as a whole: references, runs, progress, report.

``run_work_precision(scenes, solvers, ...)`` gets (or computes and caches)
each scene's reference, runs every solver's ladder (``runner``) with a tqdm
progress bar over all planned runs, and returns a ``BenchRun`` that
``report.write_report`` turns into CSV, Markdown and plots.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from .machine import machine_info
from .reference import ReferenceUnavailable, get_reference
from .runner import RunRecord, planned_runs, run_solver, solvers_for


@dataclass
class BenchRun:
    scenes: list
    solvers: list[str]
    records: list[RunRecord] = field(default_factory=list)
    references: dict = field(default_factory=dict)
    reference_errors: dict = field(default_factory=dict)
    machine: dict = field(default_factory=dict)
    repeats: int = 3
    limit: float = 120.0
    command: str = "regmech bench"
    wall_total: float = 0.0


def _progress(total: int, enabled: bool):
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:      # tqdm is a dependency; a broken install still runs, silently
        return None
    return tqdm(total=total, unit="run", dynamic_ncols=True)


def run_work_precision(scenes, solvers, repeats: int = 3, limit: float = 120.0, cache_dir: Path | None = None,
                       use_cache: bool = True, progress: bool = True, command: str = "regmech bench",
                       log=print) -> BenchRun:
    t0 = time.perf_counter()
    run = BenchRun(list(scenes), list(solvers), machine=machine_info(), repeats=repeats, limit=limit,
                   command=command)
    bar = _progress(planned_runs(scenes, solvers), progress)
    try:
        for sc in scenes:
            if bar is not None:
                bar.set_description(f"{sc.key}: reference")
            try:
                ref = get_reference(sc, cache_dir, use_cache, time_limit_s=max(30 * limit, 600.0))
                run.references[sc.key] = ref
                if ref.in_doubt:
                    log(f"warning: the reference of '{sc.key}' is in doubt: {ref.summary()}")
            except ReferenceUnavailable as exc:
                run.references[sc.key] = None
                run.reference_errors[sc.key] = str(exc)
                log(f"warning: {exc}")
            for solver in solvers_for(sc, solvers):
                if bar is not None:
                    bar.set_description(f"{sc.key}: {solver}")

                def tick(rec):
                    if bar is not None:
                        bar.update(1)

                run.records.extend(run_solver(sc, solver, run.references.get(sc.key), repeats, limit, tick))
    finally:
        if bar is not None:
            bar.close()
        run.wall_total = time.perf_counter() - t0
    return run
