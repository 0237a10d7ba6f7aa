"""One run of a study, and the study's recipe as shipped to worker processes.

A run: ``model = build(**params)``, ``res = model.simulate(**simulate_options)``,
``outputs(res)`` -> a dict of scalars. Whatever goes wrong in one run (a bad
parameter set raising ``ParameterError``, a solver failure raising
``SimulationError``, a bug in the outputs function) is caught and recorded in
that run's row, so the study goes on.

A time limit per run (``timeout_s``) covers build, simulate and outputs: the
solvers check it in their inner loops (``solvers.common.time_limit``), so a
run past it stops there with ``SimulationTimeout``, and a run that finished
but took longer is failed too, so every ``ok`` row kept its limit. A worker
loads the solvers before its first run, so the one-time imports of a process
are not charged to a run (the first compile of each device class still is).

Worker processes receive the recipe as bytes (cloudpickle when installed, so
lambdas and closures work, else pickle) and keep it unpickled per process,
keyed by its hash: a worker unpickles each study's recipe once, and the
per-class kernel templates that ``model.compile()`` lambdifies (the expensive
part of compiling, ``compile.kernels._TEMPLATES``) stay warm in the worker for
every later run of the same device classes.
"""

from __future__ import annotations

import hashlib
import pickle
import signal
import time
import traceback
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..errors import ParameterError, RegmechError, SimulationTimeout
from .sampling import RESERVED

#: where a study's limit comes from (in the messages of timed-out runs)
TIMEOUT_ORIGIN = "sweep(timeout_s=...)"


@dataclass
class StudySpec:
    """What every run does: build a model, simulate it, reduce the result to scalars."""

    build: Callable
    outputs: Callable
    simulate_options: dict = field(default_factory=dict)

    def dumps(self) -> bytes:
        try:
            import cloudpickle as pickler      # pickles lambdas and closures by value
        except ImportError:
            pickler = pickle
        try:
            return pickler.dumps(self)
        except Exception as exc:
            raise ParameterError(
                f"sweep: the build or outputs function cannot be sent to worker processes ({exc}); define them "
                f"at module level (not lambdas or nested functions, unless cloudpickle is installed), make "
                f"what they use picklable, or use executor='serial'") from exc


def run_one(spec: StudySpec, run_id: int, params: dict, timeout_s: float | None = None) -> dict:
    """The table row of one run: run id, parameters, outputs, status, error, wall time [s].

    ``timeout_s``: the run's wall-clock limit (build, simulate and outputs; see the module docstring).
    """
    from ..solvers.common import time_limit
    row = {"run_id": run_id, **params}
    t0 = time.perf_counter()
    try:
        with time_limit(timeout_s, TIMEOUT_ORIGIN):
            model = spec.build(**params)
            # the study's own bar tells the progress; a bar per run would scroll over it
            res = model.simulate(**{"progress": False, **spec.simulate_options})
            values = spec.outputs(res)
        elapsed = time.perf_counter() - t0
        if timeout_s is not None and elapsed > timeout_s:
            raise SimulationTimeout(f"timed out after {timeout_s:g} s ({TIMEOUT_ORIGIN}): the run finished after "
                                    f"{elapsed:.3g} s (build, simulate and outputs together)")
        row.update(_check_outputs(values, params))
        row.update(status="ok", error=None)
    except Exception as exc:   # recorded in the row: one bad run must not stop the study
        row.update(status="failed", error=describe_error(exc))
    row["wall_time"] = time.perf_counter() - t0
    return row


def run_batch(spec: StudySpec, batch: list[tuple[int, dict]], timeout_s: float | None = None) -> list[dict]:
    if timeout_s is not None:
        warm_up()
    return [run_one(spec, run_id, params, timeout_s) for run_id, params in batch]


def warm_up() -> None:
    """Import the solvers now (seconds in a fresh process), so that no run's time limit pays for it."""
    from .. import solvers
    solvers._load()


def describe_error(exc: BaseException) -> str:
    """``Type: message``; for errors outside regmech (bugs in user code) also where it happened."""
    text = f"{type(exc).__name__}: {exc}"
    if not isinstance(exc, RegmechError):
        frames = traceback.extract_tb(exc.__traceback__)
        if frames:
            f = frames[-1]
            text += f" [at {f.filename}:{f.lineno} in {f.name}]"
    return text


def _check_outputs(values, params: dict) -> dict:
    if not isinstance(values, dict):
        raise ParameterError(f"sweep: the outputs function must return a dict of scalars, got "
                             f"{type(values).__name__}")
    out = {}
    for name, v in values.items():
        name = str(name)
        if name in RESERVED or name in params:
            raise ParameterError(f"sweep: output '{name}' has the name of a parameter or of a table column "
                                 f"{RESERVED}; rename it in the outputs function")
        out[name] = _scalar(name, v)
    return out


def _scalar(name: str, v):
    if isinstance(v, (str, bool)) or v is None:
        return v
    arr = np.asarray(v)
    if arr.ndim != 0 and arr.size != 1:
        raise ParameterError(f"sweep: output '{name}' is an array of shape {arr.shape}; the outputs function must "
                             f"return scalars (e.g. float(np.max(np.abs(res['<signal>']))))")
    return arr.reshape(()).item()   # numpy scalar -> Python int/float/bool


# -- worker side ---------------------------------------------------------------------------------
_SPECS: dict[str, StudySpec] = {}


def _spec_from(payload: bytes) -> StudySpec:
    key = hashlib.sha1(payload).hexdigest()
    spec = _SPECS.get(key)
    if spec is None:
        spec = _SPECS[key] = pickle.loads(payload)   # cloudpickle output loads with plain pickle
    return spec


def run_batch_payload(payload: bytes, batch: list[tuple[int, dict]], timeout_s: float | None = None) -> list[dict]:
    """Entry point in a worker process (a ``concurrent.futures`` executor or a Dask worker)."""
    return run_batch(_spec_from(payload), batch, timeout_s)


def ignore_sigint() -> None:
    """Initializer of the study's own worker processes: Ctrl-C is the parent's business
    (it cancels pending runs and returns what finished); running batches finish cleanly."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
