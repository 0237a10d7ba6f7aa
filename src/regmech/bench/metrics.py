"""Error metrics of the benchmarks, defined once.

A run is compared with a reference on the scene's *output grid*
``t_k = t_start + k * dt_out`` (``regmech.solvers.common.output_grid``), for
a few chosen *signals* ``y_i`` (continuous quantities: speeds, positions,
spring torques; jumps such as friction torques at a mode change would turn a
tiny switch-time error into an O(1) value error).

``max_rel``  (the work-precision error)::

    e_max = max_i max_k |y_i(t_k) - y_i_ref(t_k)| / s_i,
    s_i   = max(max_k y_i_ref - min_k y_i_ref, 1e-6 max_k |y_i_ref|, 1e-300)

  i.e. relative to each signal's range over the run (a signal that starts at
  zero has no meaningful pointwise relative error).

``final``::

    e_final = max_i |y_i(t_end) - y_i_ref(t_end)| / s_i

``switch`` (stick/slip scenes): the mode changes ``(t, component, old, new)``
are grouped by ``(component, old, new)``; the k-th change of a group in the
run is matched with the k-th of the reference::

    e_switch = max over matched pairs |t - t_ref|   [s]

  and changes without a partner are counted (``unmatched``); a run with
  unmatched changes has taken another path through the modes, so its
  ``e_switch`` covers only the matched part (the report says so).

Values at an event instant (which a result holds twice, before and after)
are taken as right limits (after the change), the same for run and
reference.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np

#: relative floor of a signal's scale: a constant signal is compared relative to its size
SCALE_FLOOR = 1e-6


@dataclass
class Trace:
    """What the benchmarks keep of a run: the compared signals on the grid, final values, mode changes."""

    grid: np.ndarray
    values: dict[str, np.ndarray]
    final: dict[str, float]
    events: list[tuple[float, str, int, int]] = field(default_factory=list)

    @property
    def names(self) -> list[str]:
        return list(self.values)

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Plain arrays for ``np.savez`` (see ``from_arrays``)."""
        names = self.names
        comps = sorted({e[1] for e in self.events})
        return {
            "grid": self.grid,
            "names": np.array(names, dtype=str),
            "values": np.array([self.values[n] for n in names]).reshape(len(names), len(self.grid)),
            "final": np.array([self.final[n] for n in names], float),
            "event_components": np.array(comps, dtype=str),
            "events": np.array([(e[0], comps.index(e[1]), e[2], e[3]) for e in self.events], float).reshape(-1, 4),
        }

    @classmethod
    def from_arrays(cls, d) -> "Trace":
        names = [str(n) for n in d["names"]]
        comps = [str(c) for c in d["event_components"]]
        events = [(float(t), comps[int(k)], int(o), int(n)) for t, k, o, n in d["events"]]
        return cls(np.asarray(d["grid"], float), {n: np.asarray(d["values"][i], float) for i, n in enumerate(names)},
                   {n: float(d["final"][i]) for i, n in enumerate(names)}, events)


def sample(t: np.ndarray, y: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Values of a result's signal ``y(t)`` at the grid instants.

    A result's time axis holds every grid instant (solvers land on them) and
    each event instant twice; the value at a grid instant is the *last* row
    at that time (the right limit after an event), and an instant that is
    not in ``t`` (to round-off) is interpolated linearly between its
    neighbours.
    """
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    tol = 1e-11 * np.maximum(1.0, np.abs(grid))
    k = np.searchsorted(t, grid + tol, side="right") - 1
    k = np.clip(k, 0, len(t) - 1)
    out = y[k].copy()
    off = np.abs(t[k] - grid) > tol
    if np.any(off):
        kk = np.clip(k[off], 0, len(t) - 2)
        t0, t1 = t[kk], t[kk + 1]
        w = np.where(t1 > t0, (grid[off] - t0) / np.where(t1 > t0, t1 - t0, 1.0), 0.0)
        out[off] = (1 - w) * y[kk] + w * y[kk + 1]
    return out


def trace_of(result, names, grid) -> Trace:
    """The compared signals of a ``Result`` on ``grid``, its final values and mode changes."""
    values = {n: sample(result.t, result[n], grid) for n in names}
    final = {n: float(result[n][-1]) for n in names}
    events = [(float(e.t), str(e.component), int(e.old_mode), int(e.new_mode)) for e in result.events]
    return Trace(np.asarray(grid, float), values, final, events)


def scales(ref: Trace) -> dict[str, float]:
    """``s_i``: the range of each reference signal, floored (see the module docstring)."""
    out = {}
    for n, v in ref.values.items():
        rng = float(np.max(v) - np.min(v)) if len(v) else 0.0
        out[n] = max(rng, SCALE_FLOOR * float(np.max(np.abs(v), initial=0.0)), 1e-300)
    return out


@dataclass
class SwitchError:
    max_dt: float            # max |t - t_ref| over matched changes [s]; nan when none matched
    matched: int
    unmatched: int           # changes of the run or of the reference without a partner

    @property
    def consistent(self) -> bool:
        return self.unmatched == 0


def switch_time_error(events, ref_events) -> SwitchError:
    """Mode changes matched by (component, old mode, new mode) and order (module docstring)."""
    groups: dict = defaultdict(lambda: ([], []))
    for t, comp, old, new in events:
        groups[(comp, old, new)][0].append(t)
    for t, comp, old, new in ref_events:
        groups[(comp, old, new)][1].append(t)
    dts, unmatched, matched = [], 0, 0
    for run_t, ref_t in groups.values():
        m = min(len(run_t), len(ref_t))
        matched += m
        unmatched += abs(len(run_t) - len(ref_t))
        dts.extend(abs(a - b) for a, b in zip(run_t[:m], ref_t[:m]))
    return SwitchError(max(dts) if dts else float("nan"), matched, unmatched)


@dataclass
class Errors:
    """All metrics of one run against one reference."""

    max_rel: float
    worst_signal: str
    final: float
    switch: SwitchError | None

    def as_row(self) -> dict:
        row = {"err_max_rel": self.max_rel, "worst_signal": self.worst_signal, "err_final": self.final}
        if self.switch is not None:
            row.update(err_switch_s=self.switch.max_dt, events_matched=self.switch.matched,
                       events_unmatched=self.switch.unmatched)
        return row


def compare(run: Trace, ref: Trace, with_switches: bool = False) -> Errors:
    """``max_rel``, ``final`` and (for stick/slip scenes) ``switch`` errors of ``run`` against ``ref``."""
    if len(run.grid) != len(ref.grid) or np.max(np.abs(run.grid - ref.grid), initial=0.0) > 1e-9:
        raise ValueError("compare(): run and reference are not on the same output grid")
    s = scales(ref)
    worst, e_max = "", -1.0
    e_final = 0.0
    for n in ref.values:
        d = np.abs(run.values[n] - ref.values[n]) / s[n]
        e = float(np.max(d)) if np.all(np.isfinite(d)) else float("inf")
        if e > e_max:
            worst, e_max = n, e
        fe = abs(run.final[n] - ref.final[n]) / s[n]
        e_final = max(e_final, fe if np.isfinite(fe) else float("inf"))
    sw = switch_time_error(run.events, ref.events) if with_switches else None
    return Errors(e_max, worst, e_final, sw)
