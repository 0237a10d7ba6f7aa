"""The study's own worker processes (``executor="process"``, the default).

Why not a ``concurrent.futures.ProcessPoolExecutor``: it cannot stop one task.
A run that never comes back (a hang in user code, a call into C that does not
return) would hold its worker for good, and killing that worker breaks the
whole pool, with the batches of every other worker. Here the parent knows
which run each worker is on and since when:

* a worker takes one batch at a time, reports ``("start", run_id)`` before
  each run and ``("row", row)`` after it, so a finished run is never lost;
* the time limit of a run (``timeout_s``) is first *cooperative*: the
  solvers check it in their loops (``solvers.common.time_limit``) and the
  run becomes a failed row in its worker. A run that does not come back by
  ``hard_stop(timeout_s)`` (``HARD_STOP_FACTOR * timeout_s +
  HARD_STOP_GRACE``) never reached a check: its worker is killed, the run is
  recorded as timed out, a new worker takes the rest of the batch;
* a worker that dies (a crash, ``os._exit``) loses only the run it was on
  (recorded as lost: run again on resume); the rest of its batch goes to a
  new worker. Every death uses up a run, so restarts are bounded;
* workers exit with the study's process, even when it is killed with
  SIGKILL and cannot clean up: on Linux the kernel kills them
  (``prctl(PR_SET_PDEATHSIG, SIGKILL)``); everywhere a thread in each
  worker checks every ``PARENT_POLL`` seconds that its parent is still
  there (POSIX: the parent pid; elsewhere ``multiprocessing.parent_process``).

The workers are started with the default ``multiprocessing`` context (fork on
Linux), so the recipe's functions need not be importable by name.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import pickle
import signal
import sys
import threading
import time
from collections import deque
from multiprocessing.connection import wait

from .worker import TIMEOUT_ORIGIN, StudySpec, describe_error, ignore_sigint, run_one, warm_up

#: a run not back from its worker after ``HARD_STOP_FACTOR * timeout_s + HARD_STOP_GRACE`` seconds is killed
HARD_STOP_FACTOR = 1.25
HARD_STOP_GRACE = 2.0
#: how often [s] a worker checks that the study's process is still alive (where the kernel does not do it)
PARENT_POLL = 0.5
#: on Linux, ask the kernel to kill a worker when its parent dies (False: the polling thread alone does it;
#: the tests run both ways)
KERNEL_PARENT_DEATH = True


def hard_stop(timeout_s: float | None) -> float | None:
    """Seconds after its start when a run that has not come back is stopped by killing its worker.

    Beyond ``timeout_s``: the cooperative stop needs the current step or
    residual evaluation to finish and the row to travel back, and a loaded
    machine can delay both; killing earlier would only replace the solver's
    message by a coarser one (and cost a new worker)."""
    return None if timeout_s is None else HARD_STOP_FACTOR * timeout_s + HARD_STOP_GRACE


# -- worker side -----------------------------------------------------------------------------------
def exit_with_parent(parent_pid: int) -> None:
    """Make this process end when the process ``parent_pid`` (its parent) ends, however that ends."""
    if KERNEL_PARENT_DEATH and sys.platform.startswith("linux"):
        try:
            import ctypes
            libc = ctypes.CDLL(None, use_errno=True)
            PR_SET_PDEATHSIG = 1
            libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):     # no prctl (an unusual libc): the thread below does it
            pass
    if not _parent_alive(parent_pid):         # it died before the line above took effect
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent_pid,), name="regmech-parent-watch", daemon=True).start()


def _parent_alive(parent_pid: int) -> bool:
    if os.name == "posix":
        return os.getppid() == parent_pid     # an orphan is adopted by another process
    parent = multiprocessing.parent_process()
    return parent is None or parent.is_alive()


def _watch_parent(parent_pid: int) -> None:
    while True:
        time.sleep(PARENT_POLL)
        if not _parent_alive(parent_pid):
            os._exit(1)


def worker_main(conn, payload: bytes, parent_pid: int) -> None:
    """A worker: batches ``(timeout_s, [(run_id, params), ...])`` in, ``start``/``row``/``done`` messages out."""
    exit_with_parent(parent_pid)
    ignore_sigint()
    try:
        spec: StudySpec = pickle.loads(payload)     # cloudpickle output loads with plain pickle
        warm_up()
    except BaseException as exc:                    # reported with the first run handed to this worker
        spec, broken = None, describe_error(exc)
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):                  # the parent closed the pipe
            return
        if msg is None:
            return
        timeout_s, batch = msg
        for run_id, params in batch:
            conn.send(("start", run_id))
            if spec is None:
                row = {"run_id": run_id, **params, "status": "failed", "wall_time": math.nan,
                       "error": f"the recipe could not be loaded in the worker process: {broken}"}
            else:
                row = run_one(spec, run_id, params, timeout_s)
            conn.send(("row", row))
        conn.send(("done", None))


# -- parent side -----------------------------------------------------------------------------------
class _Worker:
    def __init__(self, ctx, payload: bytes):
        self.conn, child = ctx.Pipe(duplex=True)
        self.proc = ctx.Process(target=worker_main, args=(child, payload, os.getpid()), daemon=True,
                                name="regmech-sweep-worker")
        self.proc.start()
        child.close()
        self.batch: list | None = None      # runs handed over and not yet back
        self.rows: list[dict] = []          # rows back, not yet passed on
        self.current = None                 # (run_id, params) of the run under way
        self.since = 0.0                    # when it started (parent's monotonic clock)

    @property
    def busy(self) -> bool:
        return self.batch is not None

    def give(self, batch, timeout_s) -> None:
        """Hand over a batch. When the worker has just died, the batch stays with it as if it had died during
        its first run (``ProcessBackend.run`` sees the death); so every death uses up a run."""
        self.batch, self.rows, self.current = list(batch), [], None
        try:
            self.conn.send((timeout_s, self.batch))
        except (OSError, ValueError):
            pass

    def receive(self) -> bool:
        """Take the messages waiting in the pipe; True when the batch is complete."""
        done = False
        while self.conn.poll():
            try:
                kind, value = self.conn.recv()
            except (EOFError, OSError):
                break
            if kind == "start":
                self.current = next(r for r in self.batch if r[0] == value)
                self.since = time.monotonic()
            elif kind == "row":
                self.rows.append(value)
                self.batch = [r for r in self.batch if r[0] != value["run_id"]]
                self.current = None
            elif kind == "done":
                done = True
        return done

    def take_rows(self) -> list[dict]:
        rows, self.rows = self.rows, []
        return rows

    def kill(self) -> None:
        if self.proc.is_alive():
            self.proc.kill()
        self.proc.join(5.0)
        self.conn.close()


class ProcessBackend:
    """``workers`` processes of this study (default: the CPUs this process may use); see the module docstring."""

    name = "process"

    def __init__(self, spec: StudySpec, workers: int, timeout_s: float | None):
        self.payload = spec.dumps()
        warm_up()                  # imported here once, inherited by forked workers
        self.workers = workers
        self.timeout_s = timeout_s
        self.hard = hard_stop(timeout_s)
        self._ctx = multiprocessing.get_context()
        self._pool: list[_Worker] = []
        self._pending: deque = deque()
        self._cancelled = False

    def _start_worker(self) -> _Worker:
        w = _Worker(self._ctx, self.payload)
        self._pool.append(w)
        return w

    def run(self, batches):
        self._pending = deque(batches)
        while self._pending or any(w.busy for w in self._pool):
            self._dispatch()
            busy = [w for w in self._pool if w.busy]
            timeout = None
            if self.hard is not None and busy:
                ends = [w.since + self.hard for w in busy if w.current is not None]
                timeout = max(0.0, min(ends) - time.monotonic()) if ends else PARENT_POLL
            wait([w.conn for w in busy] + [w.proc.sentinel for w in busy], timeout)
            for w in busy:
                done = w.receive()
                if done:
                    rows, sub = w.take_rows(), w.batch
                    w.batch = None
                    if rows:
                        yield [(r["run_id"], None) for r in rows], rows
                elif not w.proc.is_alive():
                    w.receive()                         # the last rows it sent before dying
                    yield from self._replace(w, self._lost_row(w) if w.batch else None)
                elif self.hard is not None and w.current is not None and \
                        time.monotonic() - w.since > self.hard:
                    yield from self._replace(w, self._stopped_row(w))

    def _dispatch(self) -> None:
        """Hand pending batches to idle workers (starting workers up to ``self.workers``)."""
        if self._cancelled:
            return
        for w in list(self._pool):
            if not w.busy and not w.proc.is_alive():     # gone while idle (not a run's doing): replaced below
                w.kill()
                self._pool.remove(w)
        for w in self._pool:
            if self._pending and not w.busy:
                w.give(self._pending.popleft(), self.timeout_s)
        while self._pending and len(self._pool) < self.workers:
            self._start_worker().give(self._pending.popleft(), self.timeout_s)

    def _replace(self, w: _Worker, last_row: dict | None):
        """Retire worker ``w`` (killed or dead): its rows, the row of the run it was on, the rest back in line
        (``_dispatch`` starts a new worker for it)."""
        w.kill()
        self._pool.remove(w)
        rows = w.take_rows() + ([last_row] if last_row is not None else [])
        rest = [r for r in w.batch if last_row is None or r[0] != last_row["run_id"]]
        if rest and not self._cancelled:
            self._pending.appendleft(rest)
        w.batch = None
        if rows:
            yield [(r["run_id"], None) for r in rows], rows

    def _lost_row(self, w: _Worker) -> dict:
        from .run import LOST
        run_id, params = w.current if w.current is not None else w.batch[0]
        code = w.proc.exitcode
        why = f"signal {-code}" if code is not None and code < 0 else f"exit code {code}"
        return {"run_id": run_id, **params, "status": "failed", "wall_time": math.nan,
                "error": f"{LOST}: its worker process died ({why}) during this run"}

    def _stopped_row(self, w: _Worker) -> dict:
        run_id, params = w.current
        elapsed = time.monotonic() - w.since
        return {"run_id": run_id, **params, "status": "failed", "wall_time": elapsed,
                "error": f"SimulationTimeout: timed out after {self.timeout_s:g} s ({TIMEOUT_ORIGIN}): the run did "
                         f"not come back to a time check (it was in the build or outputs function, a signal or "
                         f"other user code, or a call that does not return), so its worker process was stopped "
                         f"after {elapsed:.3g} s"}

    def cancel(self) -> None:
        self._cancelled = True
        self._pending.clear()

    def harvest(self):
        """Rows that came back but were not passed on yet (after Ctrl-C)."""
        out = []
        for w in self._pool:
            if w.busy and w.proc.is_alive():
                w.receive()
            rows = w.take_rows()
            if rows:
                out.append(([(r["run_id"], None) for r in rows], rows))
        return out

    def close(self) -> None:
        """Idle workers are told to go, busy ones (after Ctrl-C) are killed: nothing outlives the study."""
        for w in self._pool:
            if not w.busy:
                try:
                    w.conn.send(None)
                except (OSError, ValueError):
                    pass
        deadline = time.monotonic() + 2.0
        for w in self._pool:
            if not w.busy:
                w.proc.join(max(0.0, deadline - time.monotonic()))
            w.kill()
        self._pool = []
