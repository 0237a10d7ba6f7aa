"""Where the runs of a study execute: in this process, in local worker processes, or on Dask.

Every backend takes batches of runs ``[(run_id, params), ...]`` and yields
``(batch, rows)`` as runs finish (any order; the study sorts by run id),
or ``(batch, exception)`` when a whole batch was lost (a worker died, the
recipe could not be loaded there).

The time limit per run (``timeout_s``) reaches every backend: the solvers
check it in their loops (cooperative, see ``solvers.common.time_limit``).
Only the study's own processes (``pool.ProcessBackend``) can also stop a run
that never reaches a check, by killing its worker; in this process
(``serial``), in a given ``concurrent.futures`` executor and on Dask the
limit is cooperative only. Batches, not single runs, go to the
workers: one task per batch amortises the scheduling and pickling cost, and
consecutive runs in one worker reuse its warm kernel-template cache.

``cancel()`` drops the batches not yet started (Ctrl-C); ``harvest()`` then
returns the batches that finished but were not yet yielded, so nothing that
was computed is lost.
"""

from __future__ import annotations

import ast
import os
import sys
from concurrent.futures import Executor, as_completed

from ..errors import ParameterError
from .pool import ProcessBackend
from .worker import StudySpec, run_batch, run_batch_payload

DASK_ADDRESS_SCHEMES = ("tcp://", "tls://", "inproc://", "ucx://", "ws://", "wss://")


def make_backend(executor, spec: StudySpec, workers: int | None, timeout_s: float | None = None):
    """The backend for ``sweep(executor=...)``: None or "process", "serial", "dask", a Dask
    scheduler address, a ``dask.distributed.Client`` or any ``concurrent.futures.Executor``."""
    if executor == "serial":
        return SerialBackend(spec, timeout_s)
    if executor is None or executor == "process":
        return ProcessBackend(spec, workers or default_workers(), timeout_s)
    if isinstance(executor, Executor):
        return FuturesBackend(spec, executor, workers, timeout_s)
    if executor == "dask" or (isinstance(executor, str) and executor.startswith(DASK_ADDRESS_SCHEMES)) \
            or type(executor).__name__ == "Client":
        return DaskBackend(spec, executor, workers, timeout_s)
    raise ParameterError(f"sweep: unknown executor {executor!r}; use 'serial', 'process' (default), 'dask', a Dask "
                         f"scheduler address ('tcp://host:port'), a dask.distributed.Client or a "
                         f"concurrent.futures.Executor")


def default_workers() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


class SerialBackend:
    """Runs in this process, one batch after the other (no pickling: lambdas are fine)."""

    name = "serial"
    workers = 1

    def __init__(self, spec: StudySpec, timeout_s: float | None = None):
        self.spec = spec
        self.timeout_s = timeout_s

    def run(self, batches):
        for batch in batches:
            yield batch, run_batch(self.spec, batch, self.timeout_s)

    def cancel(self):
        pass

    def harvest(self):
        return []

    def close(self):
        pass


class FuturesBackend:
    """A ``concurrent.futures`` executor given by the user (left running at the end: it is theirs).
    The study's own processes are ``pool.ProcessBackend``."""

    def __init__(self, spec: StudySpec, executor: Executor, workers: int | None, timeout_s: float | None = None):
        self.timeout_s = timeout_s
        self.payload = spec.dumps()
        self.workers = workers or getattr(executor, "_max_workers", 1)
        self.name = type(executor).__name__
        self.pool = executor
        self._futures: dict = {}
        self._yielded: set = set()

    def run(self, batches):
        self._futures = {self.pool.submit(run_batch_payload, self.payload, b, self.timeout_s): b for b in batches}
        for fut in as_completed(self._futures):
            self._yielded.add(fut)
            yield self._futures[fut], _outcome(fut)

    def cancel(self):
        for fut in self._futures:
            fut.cancel()

    def harvest(self):
        done = [f for f in self._futures if f.done() and not f.cancelled() and f not in self._yielded]
        self._yielded.update(done)
        return [(self._futures[f], _outcome(f)) for f in done]

    def close(self):
        pass


def _outcome(fut):
    try:
        return fut.result()
    except Exception as exc:   # the whole batch was lost (worker died, recipe not loadable)
        return exc


class DaskBackend:
    """A ``dask.distributed`` cluster: a given ``Client``, a client to a scheduler address,
    or a ``LocalCluster`` started here (``workers`` single-threaded worker processes) and
    closed at the end. The recipe is scattered to every worker once."""

    name = "dask"

    def __init__(self, spec: StudySpec, executor, workers: int | None, timeout_s: float | None = None):
        self.timeout_s = timeout_s
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:
            raise ParameterError("sweep(executor='dask') needs dask.distributed: pip install 'regmech[dask]'") from None
        self._owned = []
        if executor == "dask":
            _refuse_unguarded_script()
            cluster = LocalCluster(n_workers=workers or default_workers(), threads_per_worker=1,
                                   processes=True, dashboard_address=None)
            self.client = Client(cluster)
            self._owned = [self.client, cluster]
        elif isinstance(executor, str):
            self.client = Client(executor)
            self._owned = [self.client]
        else:
            self.client = executor
        self.workers = max(1, sum(self.client.nthreads().values()))
        self.payload = self.client.scatter(spec.dumps(), broadcast=True)
        self._futures: dict = {}
        self._yielded: set = set()

    def run(self, batches):
        from dask.distributed import as_completed as dask_completed
        self._futures = {self.client.submit(run_batch_payload, self.payload, b, self.timeout_s, pure=False): b
                         for b in batches}
        for fut in dask_completed(list(self._futures)):
            self._yielded.add(fut)
            yield self._futures[fut], _outcome(fut)

    def cancel(self):
        pending = [f for f in self._futures if not f.done()]
        if pending:
            self.client.cancel(pending)

    def harvest(self):
        done = [f for f in self._futures if f.status == "finished" and f not in self._yielded]
        self._yielded.update(done)
        return [(self._futures[f], _outcome(f)) for f in done]

    def close(self):
        self._futures = {}          # drop the references: the cluster forgets the results
        self._yielded = set()
        self.payload = None
        for obj in self._owned:
            obj.close()


def _main_line():
    """``(script path, line)`` of the main script's top-level statement that led to this call, or None (an
    interactive session, ``python -c``, a call not made from the main script)."""
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if not path:
        return None
    frame, line = sys._getframe(1), None
    while frame is not None:
        if frame.f_globals is main.__dict__ and frame.f_code.co_name == "<module>":
            line = frame.f_lineno          # the outermost one: a function called from the top level counts too
        frame = frame.f_back
    return None if line is None else (path, line)


def _is_main_test(test) -> bool:
    """``__name__ == "__main__"`` (either way round)."""
    if not (isinstance(test, ast.Compare) and len(test.ops) == 1 and isinstance(test.ops[0], ast.Eq)):
        return False
    sides = [test.left, test.comparators[0]]
    return any(isinstance(a, ast.Name) and a.id == "__name__" for a in sides) and \
        any(isinstance(a, ast.Constant) and a.value == "__main__" for a in sides)


def _refuse_unguarded_script():
    """A LocalCluster's worker processes start by running the main script again (multiprocessing's spawn): a
    sweep called at its top level outside ``if __name__ == "__main__":`` would start again in each of them, and
    Dask reports a RuntimeError "Nanny failed to start" after 40 lines. Refused before, by name."""
    where = _main_line()
    if where is None:
        return
    path, line = where
    try:
        with open(path, encoding="utf-8") as fh:
            tree = ast.parse(fh.read())
    except (OSError, SyntaxError, ValueError):
        return
    for node in tree.body:
        if isinstance(node, ast.If) and _is_main_test(node.test) and node.lineno <= line <= node.end_lineno:
            return
    raise ParameterError(
        f"sweep(executor='dask') is called from the top level of the script '{path}' (line {line}), outside an "
        f"'if __name__ == \"__main__\":' block. Dask starts its worker processes by running the script again, "
        f"which would start the sweep again in each of them. Put the call under 'if __name__ == \"__main__\":', or "
        f"use executor='process' (the default), which needs no guard")
