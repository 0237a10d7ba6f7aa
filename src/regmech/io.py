"""Results on disk: ``res.save(path)`` and ``regmech.load_result(path)`` (MATLAB ``.mat``, level 5).

Why ``.mat``: drivetrain engineers open it directly in MATLAB/Simulink and
Octave (``load``), in Python (``scipy.io.loadmat``, no regmech needed) and in
Julia (MAT.jl); scipy, already a dependency of regmech, writes it; numbers
keep full double precision. (HDF5 or Parquet would need another package.)

Layout of the file (every variable is plain: matrices, char, cell arrays,
structs)::

    format          'regmech result'         format_version  1
    regmech_version '0.1.0'                  model_name      'vehicle_launch'
    time            points x 1  [s]          (an event instant appears twice: before, after)
    data            points x signals, SI     (column j is signal names{j})
    names           1 x signals cell         ('J1.w', 'clutch.tau', 'clutch.mode', ...)
    units           1 x signals cell         ('rad/s', 'N m', '1'; '' when not declared)
    events          struct of columns: t [s], device (cell), old_mode, new_mode (codes),
                    old_name, new_name (cells: 'Free', 'Stuck', ...), kind (cell), t_error [s] (NaN: none),
                    value [J] (an impact's dissipated energy, ``Event.value``; NaN: none),
                    work_json (cell: an impact's work per motion source, ``Event.work``, as JSON
                    [["device", J], ...]; '': none)
    stats           struct: solver, wall_time, compile_time, steps (NaN: not reported), rhs_calls,
                    jac_calls, segments, events, error_estimate (NaN: none), text (one line),
                    extra_json (the solver's extra statistics as JSON)

Signal names keep their dots: they sit in the cell array ``names`` beside
the matrix ``data`` (no mangling to field names, so nothing to undo). In
MATLAB: ``r = load('run.mat'); w = r.data(:, strcmp(r.names, 'J1.w'));``.

A loaded result (``StoredResult``) answers as the result saved did:
``res[name]``, ``res.unit(name)``, ``res.names``, ``res.events``,
``res.stats``, ``res.at``, ``res.final``, ``to_dataframe``, ``to_csv``,
``plot`` and ``Model.linearize(at=res, t=...)``; it holds no model, so it
cannot continue the simulation.
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import numpy as np

from .errors import RegmechError
from .modes import MODE_NAMES
from .result import Event, Result, Stats

FORMAT = "regmech result"
FORMAT_VERSION = 1


def _version() -> str:
    try:
        from importlib.metadata import version
        return version("regmech")
    except Exception:                # pragma: no cover - not installed (source tree on sys.path)
        return "unknown"


def _cell(strings) -> np.ndarray:
    """A 1 x k cell array of strings (savemat writes object arrays as cells)."""
    out = np.empty((1, len(strings)), dtype=object)
    for i, s in enumerate(strings):
        out[0, i] = str(s)
    return out


def _nan_if_none(v) -> float:
    return float("nan") if v is None else float(v)


def _json_default(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return str(obj)


def save_result(res: Result, path, names=None) -> Path:
    """Write ``res`` to the ``.mat`` file ``path`` (layout in the module docstring); returns the path.

    ``names``: the signals to keep (default: every signal, ``res.names``). Raises ``RegmechError`` when
    the path cannot be written.
    """
    import scipy.io

    path = Path(path)
    if path.suffix.lower() != ".mat":
        raise RegmechError(f"res.save('{path}'): results are saved as MATLAB .mat files; give a path ending "
                           f"in '.mat', e.g. '{path.with_suffix('.mat')}'")
    names = list(res.names if names is None else ([names] if isinstance(names, str) else names))
    t = np.asarray(res.t, float)
    data = np.empty((len(t), len(names)))
    for j, n in enumerate(names):
        data[:, j] = res[n]
    units = [res.unit(n) or "" for n in names]
    ev = res.events
    events = {
        "t": np.array([e.t for e in ev], float).reshape(-1, 1),
        "device": _cell([e.component for e in ev]),
        "old_mode": np.array([e.old_mode for e in ev], float).reshape(-1, 1),
        "new_mode": np.array([e.new_mode for e in ev], float).reshape(-1, 1),
        "old_name": _cell([_mode_name(e, e.old_mode) for e in ev]),
        "new_name": _cell([_mode_name(e, e.new_mode) for e in ev]),
        "kind": _cell([e.kind for e in ev]),
        "t_error": np.array([_nan_if_none(e.t_error) for e in ev], float).reshape(-1, 1),
        # an impact's heat and a motion source's work through its impulse: the books of a loaded result
        # (``Result.impulse_work``, ``res.integral('<source>.power')``) read them from the events
        "value": np.array([_nan_if_none(e.value) for e in ev], float).reshape(-1, 1),
        "work_json": _cell([json.dumps([[str(d), float(w)] for d, w in e.work]) if e.work else "" for e in ev]),
    }
    s = res.stats
    stats = {
        "solver": s.solver, "wall_time": float(s.wall_time), "compile_time": float(s.compile_time),
        "steps": _nan_if_none(s.steps), "rhs_calls": float(s.rhs_calls), "jac_calls": float(s.jac_calls),
        "segments": float(s.segments), "events": float(s.events), "error_estimate": _nan_if_none(s.error_estimate),
        "text": str(s), "extra_json": json.dumps(s.extra, default=_json_default),
    }
    content = {
        "format": FORMAT, "format_version": float(FORMAT_VERSION), "regmech_version": _version(),
        "model_name": res.model_name, "time": t.reshape(-1, 1), "data": data, "names": _cell(names),
        "units": _cell(units), "events": events, "stats": stats,
    }
    with writing(path, "res.save"):
        scipy.io.savemat(path, content, do_compression=True, oned_as="column")
    return path


@contextlib.contextmanager
def writing(path, what: str):
    """Around the writing of a file to ``path`` by ``what`` (``"res.to_csv"``): an ``OSError`` (a folder that does
    not exist, no permission, a full disk) is a ``RegmechError`` naming the path and the fix, not the bare
    ``FileNotFoundError``."""
    try:
        yield
    except OSError as exc:
        folder = Path(path).expanduser().resolve().parent
        why = (f"the folder '{folder}' does not exist; create it first (os.makedirs(folder, exist_ok=True)) or "
               f"give a path in an existing folder" if not folder.is_dir()
               else "check the folder is writable and the path names a file")
        raise RegmechError(f"{what}: cannot write '{path}' ({exc.strerror or exc}): {why}") from None


def save_figure(fig, path, what: str):
    """Write the matplotlib figure ``fig`` as a PNG to ``path`` (``writing`` names a failure)."""
    with writing(path, what):
        fig.savefig(path, dpi=120, bbox_inches="tight")


def _mode_name(ev: Event, code: int) -> str:
    if ev.kind == "driving side":
        return {1: "flange_a drives", -1: "flange_b drives"}.get(code, str(code))
    return MODE_NAMES.get(code, str(code))


# ------------------------------------------------------------------------- loading
def _strings(cell) -> list[str]:
    """A cell array of strings as loadmat gives it (object array, any shape; empty: 0 x 0) -> list."""
    arr = np.asarray(cell, dtype=object).ravel()
    out = []
    for item in arr:
        item = np.asarray(item)
        out.append(str(item.item()) if item.size == 1 else ("" if item.size == 0 else str(item.ravel()[0])))
    return out


def _scalar(v) -> float:
    a = np.asarray(v, float).ravel()
    return float(a[0]) if a.size else float("nan")


def _text(v) -> str:
    a = np.asarray(v).ravel()
    return str(a[0]) if a.size else ""


def _field(struct, name):
    return struct[name] if name in struct.dtype.names else None


def _finite_or_none(v):
    """A stored number, None for NaN (none) or a column absent from the file (saved by an older regmech)."""
    return None if v is None or not np.isfinite(v) else float(v)


def _work(text):
    """``Event.work`` from its JSON column: ``((device, J), ...)``, None for '' or an absent column."""
    if not text:
        return None
    return tuple((str(d), float(w)) for d, w in json.loads(text))


class StoredTrajectory:
    """The signals of a loaded result: a name -> column map over ``data`` (the interface ``Result`` reads:
    ``t``, ``names()``, ``has(name)``, ``get(name)``)."""

    def __init__(self, t, data, names, units):
        self.t = t
        self.data = data
        self._names = list(names)
        self._index = {n: j for j, n in enumerate(self._names)}
        self.units = {n: (u or None) for n, u in zip(self._names, units)}

    def names(self) -> list[str]:
        return list(self._names)

    def has(self, name: str) -> bool:
        return name in self._index

    def get(self, name: str):
        j = self._index.get(name)
        return None if j is None else self.data[:, j]


class StoredResult(Result):
    """A ``Result`` read back from a file by ``load_result``: the same signals, units, events and
    statistics; ``path`` is where it came from. It holds no model (it cannot continue a simulation)."""

    def __init__(self, trajectory: StoredTrajectory, events, stats, model_name, path, regmech_version):
        super().__init__(trajectory, events, stats, model_name)
        self.path = str(path)
        self.regmech_version = regmech_version

    def _signal_unit(self, name: str):
        return self._traj.units.get(name)


def load_result(path) -> StoredResult:
    """Read a result written by ``res.save(path)`` (layout in the module docstring).

    A file that is not there, not a ``.mat`` file or not a regmech result is a ``RegmechError`` naming
    the path."""
    import scipy.io

    path = Path(path)
    if not path.is_file():
        raise RegmechError(f"load_result: no file '{path}'")
    try:
        raw = scipy.io.loadmat(path, squeeze_me=False, struct_as_record=True)
    except Exception as exc:          # scipy raises ValueError/TypeError/... on files it cannot parse
        raise RegmechError(f"load_result: '{path}' is not a MATLAB .mat file ({type(exc).__name__}: {exc})") \
            from None
    if _text(raw.get("format", "")) != FORMAT:
        raise RegmechError(f"load_result: '{path}' is a .mat file but not a regmech result (no "
                           f"format = '{FORMAT}'); write results with res.save(path)")
    try:
        return _read(raw, path)
    except (KeyError, IndexError, ValueError, TypeError, json.JSONDecodeError) as exc:
        raise RegmechError(f"load_result: '{path}' is a damaged regmech result ({type(exc).__name__}: {exc}); "
                           f"save the result again with res.save(path)") from None


def _read(raw: dict, path: Path):
    """The result held by a regmech .mat file's variables (``load_result``); any missing or malformed variable
    raises KeyError/IndexError/ValueError/TypeError, which ``load_result`` reports naming the file."""
    version = int(_scalar(raw["format_version"]))
    if version > FORMAT_VERSION:
        raise RegmechError(f"load_result: '{path}' has format version {version}, this regmech reads up to "
                           f"{FORMAT_VERSION}; update regmech")
    t = np.asarray(raw["time"], float).ravel()
    names = _strings(raw["names"]) if np.asarray(raw["names"]).size else []
    units = _strings(raw["units"]) if np.asarray(raw["units"]).size else []
    data = np.asarray(raw["data"], float).reshape(len(t), len(names))
    if len(units) != len(names):
        raise ValueError(f"{len(names)} signal names but {len(units)} units")
    if not (np.all(np.isfinite(t)) and np.all(np.diff(t) >= 0)):
        raise ValueError("the time vector is not finite and non-decreasing")
    traj = StoredTrajectory(t, data, names, units)

    ev = raw["events"][0, 0]
    times = np.asarray(ev["t"], float).ravel()
    k = len(times)

    def col(name, text=False):
        v = _field(ev, name)
        if v is None or k == 0:
            return [None] * k
        return _strings(v) if text else np.asarray(v, float).ravel().tolist()

    events = [Event(t=float(te), component=dev, old_mode=int(om), new_mode=int(nm), kind=kind,
                    t_error=_finite_or_none(err), value=_finite_or_none(val), work=_work(work))
              for te, dev, om, nm, kind, err, val, work in zip(times, col("device", True), col("old_mode"),
                                                               col("new_mode"), col("kind", True), col("t_error"),
                                                               col("value"), col("work_json", True))]
    st = raw["stats"][0, 0]

    def num(name, integer=True):
        v = _scalar(st[name])
        if not np.isfinite(v):
            return None
        return int(v) if integer else v

    stats = Stats(solver=_text(st["solver"]), wall_time=_scalar(st["wall_time"]),
                  compile_time=_scalar(st["compile_time"]), steps=num("steps"),
                  rhs_calls=num("rhs_calls"), jac_calls=num("jac_calls"), segments=num("segments"),
                  events=num("events"), error_estimate=num("error_estimate", integer=False),
                  extra=json.loads(_text(st["extra_json"]) or "{}"))
    return StoredResult(traj, events, stats, _text(raw["model_name"]), path, _text(raw["regmech_version"]))
