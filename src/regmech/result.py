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
    #: estimated error of ``t`` [s] (runs made with ``accuracy=``: the difference of the switch times of the
    #: companion runs, ``regmech.solvers.accuracy``); None: not estimated
    t_error: float | None = None

    def __str__(self):
        err = "" if self.t_error is None else f" (+-{self.t_error:.2g} s)"
        if self.kind == "driving side":
            return (f"t={self.t:.6g}{err}: {self.component} driving side: "
                    f"{DRIVING_NAMES.get(self.old_mode, self.old_mode)} -> {DRIVING_NAMES.get(self.new_mode, self.new_mode)}")
        return (f"t={self.t:.6g}{err}: {self.component} {MODE_NAMES.get(self.old_mode, self.old_mode)} -> "
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
    #: the estimated global error of the run, max over the state signals (positions and speeds of every
    #: mass, internal states) and the output instants of |error| / (range of the signals of that kind):
    #: every run made with ``accuracy=`` (``regmech.solvers.accuracy``; which signal, component and when,
    #: the accuracy, the settings the run ended with, attempts and the cost of the estimate in ``extra``)
    #: and fixed-step runs with ``tol`` set (``regmech.solvers.richardson``); None: not estimated
    error_estimate: float | None = None
    extra: dict = field(default_factory=dict)

    def __str__(self):
        steps = "? steps" if self.steps is None else f"{self.steps} steps"
        est = ""
        if self.error_estimate is not None:
            x = self.extra
            est = f", estimated error {self.error_estimate:.2g}"
            if x.get("accuracy") is not None:
                where = ""
                if x.get("error_signal"):
                    where = f", worst {x['error_signal']} at t={x.get('error_t', float('nan')):.4g} s"
                settings = ", ".join(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}"
                                     for k, v in (x.get("settings") or {}).items())
                est += (f" <= accuracy {x['accuracy']:g}{where}; {settings}; {x.get('attempts', 1)} attempt(s), "
                        f"estimate {x.get('estimate_time', 0.0) * 1e3:.1f} ms")
                if x.get("event_time_error") is not None:
                    est += f"; switch times +-{x['event_time_error']:.2g} s"
        auto = f" [auto: {self.extra['auto_reason']}]" if self.extra.get("auto_reason") else ""
        return (f"{self.solver}: {self.wall_time * 1e3:.1f} ms, {steps}, {self.rhs_calls} residual/RHS "
                f"calls, {self.jac_calls} Jacobians, {self.segments} segments, {self.events} events{est}{auto}")


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
        return isinstance(name, str) and self._traj.has(name)

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
