"""``Result``: the outcome of any solver, with one interface.

``res.t`` (output times; an event instant appears twice, before and after),
``res["J1.w"]`` any named signal (``res.names``), ``res.events`` the mode
changes, ``res.stats`` (solver, wall time, steps, residual/RHS calls,
Jacobians, the estimated global error of a fixed-step run, ...),
``res.to_dataframe()``, ``res.to_csv(path)``, ``res.plot()``.
"""

from __future__ import annotations

import csv
import difflib
from dataclasses import dataclass, field

import numpy as np

from ._numbers import describe
from .errors import RegmechError, UnknownSignalError

MODE_NAMES = {-1: "Backward", 0: "Stuck", 1: "Forward", 2: "Free", 3: "Held"}


DRIVING_NAMES = {1: "flange_a drives", -1: "flange_b drives"}


@dataclass(frozen=True)
class Event:
    """A mode change of a variable-structure device.

    ``kind`` "mode": ``old_mode`` and ``new_mode`` are modes (``MODE_NAMES``). ``kind`` "driving
    side": a lossy gear (``LossyGear``, ``LossyPlanetary``) rolls on but the power now flows the
    other way, so its other efficiency applies; ``old_mode`` and ``new_mode`` are then the driving
    flange, +1 flange_a (the sun of a planetary set), -1 flange_b (the ring). Filter on ``kind``
    to compare mode sequences.
    """

    t: float
    component: str
    old_mode: int
    new_mode: int
    kind: str = "mode"

    def __str__(self):
        if self.kind == "driving side":
            return (f"t={self.t:.6g}: {self.component} driving side: {DRIVING_NAMES.get(self.old_mode, self.old_mode)}"
                    f" -> {DRIVING_NAMES.get(self.new_mode, self.new_mode)}")
        return (f"t={self.t:.6g}: {self.component} {MODE_NAMES.get(self.old_mode, self.old_mode)} -> "
                f"{MODE_NAMES.get(self.new_mode, self.new_mode)}")


@dataclass
class Stats:
    solver: str = ""
    wall_time: float = 0.0
    compile_time: float = 0.0
    steps: int | None = 0       # None: the solver does not report it (IDA through scikit-sundae)
    rhs_calls: int = 0
    jac_calls: int = 0
    segments: int = 0
    events: int = 0
    #: fixed-step solvers (euler, rk4, abm, expm) with ``tol`` set: the estimated global error of the run,
    #: max over the ODE-form states and output instants of |error| / (range of the states of that kind)
    #: (``regmech.solvers.richardson``; which state and when in ``extra``); None: not estimated
    error_estimate: float | None = None
    extra: dict = field(default_factory=dict)

    def __str__(self):
        steps = "? steps" if self.steps is None else f"{self.steps} steps"
        est = "" if self.error_estimate is None else f", estimated error {self.error_estimate:.2g}"
        return (f"{self.solver}: {self.wall_time * 1e3:.1f} ms, {steps}, {self.rhs_calls} residual/RHS "
                f"calls, {self.jac_calls} Jacobians, {self.segments} segments, {self.events} events{est}")


class Result:
    def __init__(self, trajectory, events=(), stats: Stats | None = None, model_name: str = ""):
        self._traj = trajectory
        self.t = trajectory.t
        self.events: list[Event] = list(events)
        self.stats = stats or Stats()
        self.model_name = model_name
        self._cache: dict = {}

    def __getstate__(self):
        # the signal cache is derived from the trajectory (which keeps t, y, y', modes and the compiled
        # system): left out to keep the pickle small
        state = self.__dict__.copy()
        state["_cache"] = {}
        return state

    @property
    def names(self) -> list[str]:
        return self._traj.names()

    def __contains__(self, name: str) -> bool:
        return isinstance(name, str) and name in self._traj._index

    def __getitem__(self, name: str) -> np.ndarray:
        if not isinstance(name, str):
            raise UnknownSignalError(
                f"res[{describe(name)}]: the signals of a result are looked up by name, e.g. res['J1.w'] (res.t "
                f"is the time axis); the result of model '{self.model_name}' has {len(self.names)} signals, "
                f"listed by res.names")
        if name in self._cache:
            return self._cache[name]
        val = self._traj.get(name)
        if val is None:
            raise UnknownSignalError(self._unknown(name))
        self._cache[name] = val
        return val

    def _unknown(self, name: str) -> str:
        """The message for a signal name that is not in the result: the closest names and the signals of
        the component it names, if any."""
        names = self.names
        msg = f"no signal '{name}' in the result of model '{self.model_name}'"
        close = difflib.get_close_matches(name, names, n=3, cutoff=0.6)
        if close:
            msg += "; did you mean " + " or ".join(f"'{n}'" for n in close) + "?"
        owner = name.rpartition(".")[0] or name
        same = [n for n in names if n.rpartition(".")[0] == owner]
        if same:
            msg += f" '{owner}' has {', '.join(same)}"
        return msg + f" (res.names lists all {len(names)} signals)"

    def at(self, name: str, t: float) -> float:
        """Linear interpolation of a signal at time t (after the event at t, if any)."""
        tt = self.t
        k = int(np.searchsorted(tt, t, side="right"))
        return float(np.interp(t, tt[:k] if k else tt, self[name][:k] if k else self[name]))

    def final(self, name: str) -> float:
        return float(self[name][-1])

    def to_dataframe(self, names=None):
        try:
            import pandas as pd
        except ImportError as exc:  # pragma: no cover - optional
            raise RegmechError("to_dataframe() needs pandas: pip install 'regmech[pandas]'") from exc
        names = names or self.names
        return pd.DataFrame({"time": self.t, **{n: self[n] for n in names}})

    def to_csv(self, path, names=None) -> None:
        names = names or self.names
        cols = [self.t] + [self[n] for n in names]
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["time"] + list(names))
            for row in zip(*cols):
                w.writerow([repr(float(v)) for v in row])

    def plot(self, names=None, ax=None, path=None, title=None, mark_events=True):
        """Plot signals against time; mode changes are marked by vertical lines."""
        try:
            import matplotlib
            if path is not None and ax is None:
                matplotlib.use("Agg", force=False)
            import matplotlib.pyplot as plt
        except ImportError as exc:  # pragma: no cover - optional
            raise RegmechError("plot() needs matplotlib: pip install 'regmech[plot]'") from exc
        if names is None:
            names = [n for n in self.names if n.endswith((".w", ".v"))][:8]
        if isinstance(names, str):
            names = [names]
        fig = None
        if ax is None:
            fig, ax = plt.subplots(figsize=(9, 5))
        for n in names:
            ax.plot(self.t, self[n], label=n)
        if mark_events:
            for i, ev in enumerate(self.events):
                ax.axvline(ev.t, color="0.6", lw=0.7, ls="--", label="mode change" if i == 0 else None)
        ax.set_xlabel("time [s]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=8)
        ax.set_title(title or self.model_name)
        if path is not None:
            (fig or ax.figure).savefig(path, dpi=120, bbox_inches="tight")
            if fig is not None:
                plt.close(fig)
        return ax

    def __repr__(self):
        return f"<Result {self.model_name}: {len(self.t)} points, {len(self.events)} events, {self.stats}>"
