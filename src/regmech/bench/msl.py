"""Errors against the Modelica Standard Library reference trajectories.

The files (``First.csv``, ``CoupledClutches.csv``, ...; Dymola, DASSL,
tolerance 1e-6, see ``regmech/data/msl/README.md``) ship with the package
(``regmech.data.msl_dir``; ``$REGMECH_MSL_REFERENCE`` points elsewhere when
set). They are themselves accurate to about
1e-4 (CoupledClutches' ``J1.w`` is 6.6e-5 off the closed form), so an
error against them says whether a run reproduces MSL within the library's
own tube (2e-3), not how accurate the run is; the work-precision errors are
taken against regmech's own tight references (``reference``).

Metrics, as in ``metrics`` but on the reference file's time axis: the
largest deviation of each column relative to the column's range, and the
switch-time error of the friction modes (mode changes read from the
``<device>.mode`` columns: an event instant is a repeated time with a new mode).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..data import msl_dir
from .metrics import SCALE_FLOOR, sample, switch_time_error

_CACHE: dict = {}


def reference_dir() -> Path | None:
    """``$REGMECH_MSL_REFERENCE`` when set, else the files shipped in ``regmech/data/msl``
    (None when the folder does not exist)."""
    folder = msl_dir()
    return folder if folder.is_dir() else None


def load(file: str) -> dict[str, np.ndarray] | None:
    """Columns of a reference CSV by name (``time`` included); None when the file is not found."""
    if file in _CACHE:
        return _CACHE[file]
    folder = reference_dir()
    if folder is None or not (folder / file).exists():
        return None
    with open(folder / file, newline="") as fh:
        rows = list(csv.reader(fh))
    header = [h.strip().strip('"') for h in rows[0]]
    data = np.array([[float(v) for v in r] for r in rows[1:] if r], float)
    _CACHE[file] = {h: data[:, i] for i, h in enumerate(header)}
    return _CACHE[file]


def mode_events(cols: dict[str, np.ndarray], devices) -> list[tuple[float, str, int, int]]:
    """Mode changes ``(t, device, old, new)`` read from the ``<device>.mode`` columns."""
    events = []
    t = cols["time"]
    for dev in devices:
        m = np.rint(cols[f"{dev}.mode"]).astype(int)
        for k in np.nonzero(m[1:] != m[:-1])[0]:
            events.append((float(t[k + 1]), dev, int(m[k]), int(m[k + 1])))
    return sorted(events)


def msl_errors(result, spec) -> dict | None:
    """``{"msl_max_rel", "msl_worst", "msl_switch_s", "msl_unmatched"}`` of a result against its MSL file."""
    cols = load(spec.file)
    if cols is None:
        return None
    t_ref = cols["time"]
    keep = t_ref <= result.t[-1] + 1e-12
    worst, e_max = "", -1.0
    for ours, theirs in spec.columns:
        ref = cols[theirs][keep]
        run = sample(result.t, result[ours], t_ref[keep])
        scale = max(float(np.ptp(ref)), SCALE_FLOOR * float(np.max(np.abs(ref), initial=0.0)), 1e-300)
        e = float(np.max(np.abs(run - ref))) / scale
        if e > e_max:
            worst, e_max = ours, e
    out = {"msl_max_rel": e_max, "msl_worst": worst}
    if spec.modes:
        run_events = [(float(e.t), str(e.component), int(e.old_mode), int(e.new_mode)) for e in result.events
                      if e.kind != "contact"]
        sw = switch_time_error(run_events, mode_events(cols, spec.modes))
        out.update(msl_switch_s=sw.max_dt, msl_unmatched=sw.unmatched)
    return out
