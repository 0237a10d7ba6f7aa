"""What every solver shares: the output grid, time events, recording."""

from __future__ import annotations

import math

import numpy as np

from ..errors import ParameterError, SimulationError


def check_times(t_start, t_end, dt_out):
    for name, v in (("t_start", t_start), ("t_end", t_end)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ParameterError(f"simulate(): {name} must be a finite number, got {v!r}")
    if t_end <= t_start:
        raise ParameterError(f"simulate(): t_end ({t_end}) must be greater than t_start ({t_start})")
    if dt_out is None:
        dt_out = (t_end - t_start) / 500.0
    if not (isinstance(dt_out, (int, float)) and math.isfinite(dt_out) and dt_out > 0):
        raise ParameterError(f"simulate(): dt_out must be a positive number, got {dt_out!r}")
    return float(t_start), float(t_end), float(dt_out)


def output_grid(t_start, t_end, dt_out):
    n = int(math.floor((t_end - t_start) / dt_out + 1e-9))
    grid = t_start + dt_out * np.arange(n + 1)
    if t_end - grid[-1] > 1e-12 * max(1.0, abs(t_end)):
        grid = np.append(grid, t_end)
    grid[-1] = min(grid[-1], t_end)
    return grid


def signal_breakpoints(model, t_start, t_end):
    """Instants in (t_start, t_end) where some signal of the model is not smooth."""
    from ..signals import Signal
    pts = set()
    for comp in model.components.values():
        for val in comp._values.values():
            if isinstance(val, Signal):
                pts.update(b for b in val.breakpoints(t_start, t_end) if t_start < b < t_end)
    return sorted(pts)


class Recorder:
    """Collects output rows (t, y, yp, left flag, modes)."""

    def __init__(self, modes_width: int):
        self.t, self.y, self.yp, self.left, self.modes = [], [], [], [], []
        self.mw = modes_width

    def add(self, t, y, yp, modes, left=False):
        self.t.append(float(t))
        self.y.append(np.array(y, float))
        self.yp.append(np.array(yp, float))
        self.left.append(bool(left))
        self.modes.append(np.array(modes, int).copy())

    def arrays(self):
        Y = np.array(self.y)
        YP = np.array(self.yp)
        if not (np.all(np.isfinite(Y)) and np.all(np.isfinite(YP))):
            k = int(np.nonzero(~np.all(np.isfinite(Y), axis=1) | ~np.all(np.isfinite(YP), axis=1))[0][0])
            raise SimulationError(f"the solution became non-finite (NaN/inf) at t={self.t[k]:.6g}; the model or the "
                                  f"solver settings are unstable there (try a tighter tolerance or a stable solver)")
        modes = np.array(self.modes).reshape(len(self.t), self.mw)
        return np.array(self.t), Y, YP, np.array(self.left), modes
