"""``sweep``: run a model over many parameter sets and tabulate scalar outputs.

The study loop: plan the runs (run id = position in the parameter sets),
take the finished rows from ``out`` when it exists (resume), cut the rest
into batches, hand them to the executor, and record every finished batch at
once in memory, on disk and on the progress bar. Ctrl-C cancels the batches
not yet started and returns the table of what finished.
"""

from __future__ import annotations

import math
import os
import sys
import time
import warnings
from typing import Callable

from ..errors import ParameterError
from .executors import make_backend
from .outputs import SignalSummary
from .sampling import runs_from
from .store import FINISHED, ResultStore, parse_row, same_parameters
from .table import make_table
from .worker import StudySpec, describe_error

MAX_BATCH = 16
#: error text of runs whose batch was lost with its worker (rerun on resume, unlike failed runs)
LOST = "the worker lost this run's batch"


def sweep(build: Callable, params, outputs, executor=None, out=None, progress: bool = True, *,
          zipped: bool = False, workers: int | None = None, batch_size: int | None = None,
          retry_failed: bool = False, timeout_s: float | None = None, **simulate_options):
    """Simulate ``build(**p)`` for every parameter set ``p`` of ``params``; one table row per run.

    build     function returning a ``regmech.Model`` for one parameter set (keyword arguments).
    params    a grid ``{name: [values...]}`` (full factorial; ``zipped=True``: k-th values
              together), a pandas DataFrame, or an iterable of dicts (``latin_hypercube``,
              ``scatter``, ``grid``). Run ids are positions in this sequence.
    outputs   function ``Result -> {name: scalar}``, or a list of signal names: then each
              signal's final value ``"<name>.final"`` and peak ``"<name>.max_abs"``.
    executor  None/"process": local worker processes (``workers``, default: all CPUs);
              "serial"; "dask" (a LocalCluster started and stopped here), a Dask scheduler
              address "tcp://host:port", a ``dask.distributed.Client``, or any
              ``concurrent.futures.Executor``. Every executor gives the same numbers.
    out       CSV path (or ``.parquet`` with pyarrow): rows are written as they finish; when
              the file exists, its finished rows whose parameters match are reused, not rerun
              (``retry_failed=True`` reruns the failed ones; runs lost with a crashed worker
              always run again).
    progress  show a tqdm bar (throughput, time remaining).
    batch_size runs per task sent to a worker (default: up to 16, at least 4 tasks a worker).
    timeout_s wall-clock limit [s] of each run (build, simulate and outputs; default: none). A run
              past it becomes a failed row "SimulationTimeout: timed out after <timeout_s> s ..."
              and the study goes on. Every solver checks the limit in its loops and stops within
              a step; with the default executor a run that never reaches a check (a hang in user
              code) is stopped by killing its worker after ``1.25 timeout_s + 2`` s (the other
              executors rely on the solvers' checks only). Timed-out rows count as failed: rerun
              with ``retry_failed=True``.
    **simulate_options  go to every ``model.simulate``: ``t_end`` (required), ``dt_out``,
              ``solver``, ``rtol``, ``atol``, ...

    A run that fails (``ParameterError`` for a bad parameter set, ``SimulationError`` when the
    solver fails, any error in ``build`` or ``outputs``) gets ``status="failed"`` and its error
    message; the study goes on. Returns a pandas DataFrame (else a ``SweepTable``) sorted by
    run id: ``run_id``, parameters, outputs, ``status``, ``error``, ``wall_time`` [s] (build,
    simulate and outputs of that run, in its worker); ``table.attrs`` has the study's totals.
    """
    if not callable(build):
        raise ParameterError(f"sweep: build must be a function returning a regmech.Model, got {build!r}")
    if "t_end" not in simulate_options:
        raise ParameterError("sweep: give t_end=<end time [s]> (passed to every model.simulate)")
    from ..solvers import check_options
    check_options(**simulate_options)       # a misspelt option or a bad value stops the study before any run
    if not callable(outputs):
        outputs = SignalSummary(outputs)
    if batch_size is not None and (isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1):
        raise ParameterError(f"sweep: batch_size must be a positive integer, got {batch_size!r}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ParameterError(f"sweep: workers must be a positive integer (or None: all CPUs), got {workers!r}")
    from ..solvers.common import check_timeout
    timeout_s = check_timeout(timeout_s, "sweep()")
    runs = runs_from(params, zipped=zipped)
    param_names = list(dict.fromkeys(k for p in runs for k in p))
    spec = StudySpec(build, outputs, dict(simulate_options))

    store = ResultStore(out) if out is not None else None
    rows = _resumed_rows(store, runs, retry_failed) if store is not None else {}
    todo = [(i, p) for i, p in enumerate(runs) if i not in rows]
    attrs = {"executor": "none", "workers": 0, "runs": len(todo), "skipped": len(rows), "failed": 0,
             "elapsed": 0.0, "runs_per_second": math.nan, "interrupted": False}
    t0 = time.perf_counter()
    if todo:
        _execute(make_backend(executor, spec, workers, timeout_s), todo, rows, store, progress, batch_size, attrs)
    elapsed = time.perf_counter() - t0
    done_now = len(rows) - attrs["skipped"]
    attrs.update(runs=done_now, elapsed=elapsed, runs_per_second=done_now / elapsed if elapsed > 0 else math.nan)
    table = make_table([rows[i] for i in sorted(rows) if i < len(runs)], param_names, attrs)
    _warn_outcome(attrs, rows, len(runs), out)
    return table


def _execute(backend, todo: list, rows: dict, store, progress: bool, batch_size, attrs: dict) -> None:
    """Run ``todo`` on ``backend``; every finished batch goes at once into ``rows``, ``store`` and
    the progress bar. Ctrl-C: cancel what has not started, keep what finished."""
    attrs.update(executor=backend.name, workers=backend.workers)
    size = batch_size or (1 if backend.name == "serial" else
                          max(1, min(MAX_BATCH, len(todo) // (4 * backend.workers))))
    batches = [todo[k:k + size] for k in range(0, len(todo), size)]
    bar = _progress_bar(progress, len(todo), backend, len(rows))

    def record(batch, outcome):
        new = outcome if isinstance(outcome, list) else [_lost_row(i, p, outcome) for i, p in batch]
        new = [r for r in new if r["run_id"] not in rows]    # a batch may be harvested twice
        for r in new:
            rows[r["run_id"]] = r
        if store is not None:
            store.add(new)
        attrs["failed"] += sum(r["status"] != "ok" for r in new)
        if bar is not None:
            if attrs["failed"]:
                bar.set_postfix_str(f"failed={attrs['failed']}", refresh=False)
            bar.update(len(new))

    try:
        for batch, outcome in backend.run(batches):
            record(batch, outcome)
    except KeyboardInterrupt:
        attrs["interrupted"] = True
        backend.cancel()
        for batch, outcome in backend.harvest():
            record(batch, outcome)
    finally:
        backend.close()
        if bar is not None:
            bar.close()
        if store is not None:
            store.rewrite(sort=True)
            store.close()


def _resumed_rows(store: ResultStore, runs: list[dict], retry_failed: bool) -> dict:
    """Finished rows of this study found in ``store``; their parameters must match the plan."""
    stored = store.load()
    rows = {}
    for run_id, p in enumerate(runs):
        s = stored.get(run_id)
        if s is None:
            continue
        if not same_parameters(s, p):
            raise ParameterError(
                f"sweep: {store.path} holds run {run_id} with other parameter values "
                f"({ {k: s.get(k) for k in p} } instead of {p}): it belongs to another study; choose "
                f"another out path or delete the file")
        status, error = s.get("status"), str(s.get("error") or "")
        lost = error.startswith(LOST)             # the worker died, not the run: compute it again
        if status in FINISHED and not lost and not (retry_failed and status == "failed"):
            rows[run_id] = {**parse_row(s), **p, "run_id": run_id}
    return rows


def _lost_row(run_id: int, params: dict, exc: BaseException) -> dict:
    return {"run_id": run_id, **params, "status": "failed", "error": f"{LOST}: {describe_error(exc)}",
            "wall_time": math.nan}


def _progress_bar(progress: bool, total: int, backend, skipped: int):
    if not progress:
        return None
    from tqdm import tqdm
    desc = f"sweep [{backend.name} x{backend.workers}]" + (f" ({skipped} done before)" if skipped else "")
    return tqdm(total=total, desc=desc, unit="run", file=sys.stderr, dynamic_ncols=True)


def _warn_outcome(attrs: dict, rows: dict, n_runs: int, out) -> None:
    if attrs["interrupted"]:
        hint = f"; rerun with out={str(out)!r} to compute the rest" if out is not None else \
            "; give out=<file> to keep partial results and resume"
        warnings.warn(f"sweep interrupted: {len(rows)} of {n_runs} runs finished{hint}", RuntimeWarning,
                      stacklevel=_user_stacklevel())
    if attrs["runs"] and attrs["failed"] == attrs["runs"]:
        first = next((r["error"] for r in rows.values() if r.get("status") == "failed"), "")
        warnings.warn(f"sweep: all {attrs['runs']} runs failed; the first error: {first}", RuntimeWarning,
                      stacklevel=_user_stacklevel())


def _user_stacklevel() -> int:
    """Stack level of the first frame outside regmech (rm.sweep may be called through the module)."""
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    frame, level = sys._getframe(1), 1
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(here + os.sep):
        frame, level = frame.f_back, level + 1
    return level
