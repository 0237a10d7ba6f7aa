"""``Result``: the outcome of any solver, with one interface.

``res.t`` (output times; an event instant appears twice, before and after),
``res["J1.w"]`` any named signal (``res.names``), ``res.events`` the mode
changes, ``res.stats`` (solver, wall time, steps, residual/RHS calls,
Jacobians, the estimated global error of a fixed-step run, ...),
``res.to_dataframe()``, ``res.to_csv(path)``, ``res.plot()``.

Units: every signal is SI; ``res.unit(name)`` says which unit, and
``res.get(name, unit="rpm")``, ``res.at``, ``res.final``, ``to_dataframe``,
``to_csv`` and ``plot`` take display units (``regmech.units``). Values at an
instant are methods, name first: ``res.at(name, t)`` (linear interpolation,
t a number or an array; after the event at an event instant) and
``res.final(name)`` (the last output point; ``res.final()`` all signals).
"""

from __future__ import annotations

import csv
import difflib
from dataclasses import dataclass, field

import numpy as np

from . import units as units_mod
from ._numbers import describe
from .errors import ParameterError, RegmechError, UnknownSignalError
from .modes import MODE_NAMES


DRIVING_NAMES = {1: "flange_a drives", -1: "flange_b drives"}
CONTACT_NAMES = {0: "open", 1: "contact +", -1: "contact -"}
LIMIT_NAMES = {0: "within limits", 1: "at upper limit", -1: "at lower limit"}
FLOW_NAMES = {1: "w_p + w_t > 0", 0: "w_p + w_t < 0"}


@dataclass(frozen=True)
class Event:
    """A mode change of a variable-structure device.

    ``kind`` "mode": ``old_mode`` and ``new_mode`` are modes (``MODE_NAMES``). ``kind`` "driving
    side": a lossy gear (``LossyGear``, ``LossyPlanetary``) rolls on but the power now flows the
    other way, so its other efficiency applies; ``old_mode`` and ``new_mode`` are then the driving
    flange, +1 flange_a (the sun of a planetary set), -1 flange_b (the ring). ``kind`` "contact": a
    device with a piecewise law (``Backlash``, ``ElastoGap``, ``EndStop``, ``HardStop``) changed its
    contact state (``Device.switching_surfaces``): 0 open, +1 in contact on the positive side (the
    upper stop, ``phi_rel - phi_rel0 >= b/2``), -1 on the negative side. ``kind`` "limit": a
    controller's output (``PI``, ``PICommand``, ``Driver``) reached or left a limit: +1 at the upper
    limit, -1 at the lower one, 0 between them. ``kind`` "flow": a torque converter's fluid path
    (``ConverterFluid``) crossed ``w_t = -w_p``, the kink of its law in counter-rotation (+1 the side
    ``w_p + w_t > 0``, 0 the other). ``kind`` "switch": a block whose output jumps (``blocks.Compare``,
    ``blocks.Switch``) saw its input cross its level: 1 above it, 0 below. ``kind`` "latch": a block with memory
    (``blocks.Hysteresis``, ``blocks.ShiftSchedule``) switched up (``new_mode`` +1) or down (-1). Filter on ``kind`` to compare mode
    sequences.
    """

    t: float
    component: str
    old_mode: int
    new_mode: int
    kind: str = "mode"
    #: estimated error of ``t`` [s] (runs made with ``accuracy=``: the difference of the switch times of the
    #: companion runs, ``regmech.solvers.accuracy``); None: not estimated
    t_error: float | None = None
    #: ``kind`` "impact" (a ``HardStop`` reaching a limit, ``new_mode`` +1 upper / -1 lower): the kinetic energy
    #: the impact dissipated [J], booked in the stop's ``heat``; None otherwise
    value: float | None = None
    #: ``kind`` "impact": ``((device, J), ...)``, the work the impulse of a motion source on the stop's path did on
    #: the masses at the instant (it keeps its speed through the impulse; ``Result.impulse_work``); None: none
    work: tuple | None = None

    def __str__(self):
        err = "" if self.t_error is None else f" (+-{self.t_error:.2g} s)"
        if self.kind == "contact":
            return (f"t={self.t:.6g}{err}: {self.component} contact: {CONTACT_NAMES.get(self.old_mode, self.old_mode)} "
                    f"-> {CONTACT_NAMES.get(self.new_mode, self.new_mode)}")
        if self.kind == "impact":
            where = "upper" if self.new_mode > 0 else "lower"
            lost = "" if self.value is None else f", {self.value:.6g} J dissipated"
            return f"t={self.t:.6g}{err}: {self.component} impact at the {where} limit{lost}"
        if self.kind == "limit":
            return (f"t={self.t:.6g}{err}: {self.component} output: {LIMIT_NAMES.get(self.old_mode, self.old_mode)} "
                    f"-> {LIMIT_NAMES.get(self.new_mode, self.new_mode)}")
        if self.kind == "latch":
            return f"t={self.t:.6g}{err}: {self.component} latch: {'up' if self.new_mode > 0 else 'down'}"
        if self.kind == "switch":
            side = {1: "above", 0: "below"}
            return (f"t={self.t:.6g}{err}: {self.component} switch: input {side.get(self.old_mode, self.old_mode)} -> "
                    f"{side.get(self.new_mode, self.new_mode)} its level")
        if self.kind == "flow":
            return (f"t={self.t:.6g}{err}: {self.component} {FLOW_NAMES.get(self.old_mode, self.old_mode)} -> "
                    f"{FLOW_NAMES.get(self.new_mode, self.new_mode)}")
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
    #: integration steps; IDA: step attempts (accepted and rejected), counted from the times of its residual
    #: calls because scikit-sundae reports only residual and Jacobian counts (``extra["steps_are_attempts"]``);
    #: None: the solver does not report it
    steps: int | None = 0
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

    def load_time(self) -> float:
        """Seconds the call spent loading numba's compiled kernels (``extra["native_load_s"]``), 0 below 0.05 s."""
        load = self.extra.get("native_load_s") or 0.0
        return load if load >= 0.05 else 0.0

    def __str__(self):
        steps = "? steps" if self.steps is None else \
            f"{self.steps} step{' attempts' if self.extra.get('steps_are_attempts') else 's'}"
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
                if x.get("rtol_cap"):
                    est += f"; {x['rtol_cap']}"
                if x.get("event_time_error") is not None:
                    est += f"; switch times +-{x['event_time_error']:.2g} s"
        auto = f" [auto: {self.extra['auto_reason']}]" if self.extra.get("auto_reason") else ""
        # the first compiled IDA run of a process loads numba and the kernels (the first time on a machine, compiles
        # them): a one-off, not the run's own cost
        load = self.load_time()
        loaded = f" (+ {load:.1f} s loading the compiled kernels, once per process)" if load else ""
        return (f"{self.solver}: {self.wall_time * 1e3:.1f} ms{loaded}, {steps}, {self.rhs_calls} residual/RHS "
                f"calls, {self.jac_calls} Jacobians, {self.segments} segments, {self.events} events{est}{auto}")


class Result:
    def __init__(self, trajectory, events=(), stats: Stats | None = None, model_name: str = ""):
        self._traj = trajectory
        self.t = trajectory.t
        self.events: list[Event] = list(events)
        self.stats = stats or Stats()
        self.model_name = model_name
        self._cache: dict = {}
        #: ``(trajectory, names, tol) -> ({name: (values, estimate)}, counts)``: the time integrals between the rows
        #: (``integral``), set by ``simulate`` (``regmech.solvers.quadrature.cumulative``); None: a result made
        #: otherwise, whose ``heat`` is then the trapezoid over the rows of ``Device.derived``
        self.integrator = None

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
        # a stored result (``io``) keeps its heat as it was computed; a run's is integrated between the rows
        rate = self._traj.integral_rate(name) if getattr(self, "integrator", None) is not None else None
        if rate is not None:
            val = self._with_impacts(name, self.integral(rate))
            self._cache[name] = val
            return val
        val = self._traj.get(name)
        if val is None:
            raise UnknownSignalError(self._unknown(name))
        val = self._with_impacts(name, val)
        self._cache[name] = val
        return val

    def impact_losses(self, device: str):
        """The energy [J] the impacts of ``device`` (a ``HardStop``) have dissipated up to each output row, or None
        when it had none: the sum of ``Event.value`` of its "impact" events, each from the row after the impact
        on (the last row at the event's instant). Part of the device's ``heat``."""
        hits = [(ev.t, ev.value) for ev in self.events if ev.kind == "impact" and ev.component == device
                and ev.value is not None]
        return self._jumps(hits)

    def impulse_work(self, device: str):
        """The work [J] the impulses of hard stops' impacts made ``device`` (a motion source on a stop's path, which
        keeps its speed through an impulse) do on the masses up to each output row, or None when they made it do
        none: the sum of its entries in ``Event.work`` of the "impact" events, each from the row after the impact on.
        ``res.integral('<device>.power')`` includes it (as ``-`` its jumps: ``power`` is what the device absorbs),
        so the work of a source, ``-res.integral('motor.power')``, closes the books across impacts."""
        hits = [(ev.t, w) for ev in self.events if ev.kind == "impact" and ev.work
                for name, w in ev.work if name == device]
        return self._jumps(hits)

    def _jumps(self, hits):
        """``[(t, J)]`` as a cumulative sum over the output rows, each from the row after its instant on (the last
        row at the instant), or None without any."""
        if not hits:
            return None
        out = np.zeros(len(self.t))
        for t_ev, amount in hits:
            k = int(np.searchsorted(self.t, t_ev, side="right")) - 1
            if k >= 0 and self.t[k] < t_ev:
                k += 1          # no row at the event (a result thinned after the run): from the next row on
            out[max(k, 0):] += amount
        return out

    def _with_impacts(self, name: str, val):
        """A hard stop's ``heat``: its friction heat (none) plus what its impacts dissipated (``impact_losses``)."""
        if not name.endswith(".heat"):
            return val
        jumps = self.impact_losses(name[:-len(".heat")])
        return val if jumps is None else np.asarray(val, dtype=float) + jumps

    def integral(self, name: str, error: bool = False, tol: float | None = None):
        """``int_{t_0}^{t} p dt`` of signal ``name`` (a power [W] gives an energy [J]) at every output instant,
        computed from the model's laws between the output rows, not by the trapezoid over them: an interval the
        rows do not resolve (a clutch locking up inside it, an oscillation faster than ``dt_out``) is integrated
        again from its first row (``regmech.solvers.quadrature``). Its error is within the run's accuracy
        (``accuracy=``; else its ``rtol``; else 1e-6) times ``int |p| dt``, plus what the rows' own error
        carries. ``error=True`` returns ``(values, estimate)``; ``tol`` asks for another relative error than the
        run's. A device's ``heat`` is this integral of its ``heat_flow``; ``res.integrals([...])`` computes
        several at once (they share the work)."""
        hit = self.integrals([name], tol=tol)[name]
        return hit if error else hit[0]

    def _with_impulses(self, name: str, val):
        """The integral of a motion source's ``power``: minus the work its impulses did at impacts
        (``impulse_work``), as jumps."""
        if not name.endswith(".power"):
            return val
        jumps = self.impulse_work(name[:-len(".power")])
        return val if jumps is None else (np.asarray(val[0], dtype=float) - jumps, val[1])

    def integrals(self, names, tol: float | None = None) -> dict:
        """``{name: (values, estimate)}`` of ``integral`` for several signals at once (``tol``: as there)."""
        names = list(names)
        if tol is None:
            tol = self._quadrature_tol()
        elif isinstance(tol, bool) or not isinstance(tol, (int, float)) or not 0 < tol < 1:
            raise ParameterError(f"res.integrals(tol={tol!r}): tol is a relative error in (0, 1), e.g. 1e-6")
        tol = float(tol)
        for nm in names:
            if not isinstance(nm, str) or not self._traj.has(nm):
                raise UnknownSignalError(self._unknown(nm) if isinstance(nm, str) else
                                         f"res.integral({describe(nm)}): give a signal's name, e.g. "
                                         f"res.integral('drive.power')")
        todo = [nm for nm in dict.fromkeys(names) if ("integral", nm, tol) not in self._cache]
        if todo:
            # the quadrature follows the model's laws, which the solver layer knows: ``simulate`` hands it over
            cumulative = getattr(self, "integrator", None)
            if cumulative is None:
                raise RegmechError(f"res.integral({todo[0]!r}): this result of model '{self.model_name}' was not "
                                   f"made by simulate() (or was saved before integrals existed), so the laws "
                                   f"between its rows are unknown; run the model again to integrate its signals")
            got, counts = cumulative(self._traj, todo, tol)
            for nm, val in got.items():
                self._cache[("integral", nm, tol)] = val
            q = self.stats.extra.setdefault("quadrature", {"signals": 0, "intervals": 0, "reintegrated": 0,
                                                           "rhs_calls": 0})
            q["signals"] += len(todo)
            for k, v in counts.items():
                q[k] = q.get(k, 0) + v
        return {nm: self._with_impulses(nm, self._cache[("integral", nm, tol)]) for nm in names}

    def _quadrature_tol(self) -> float:
        """The relative error ``integral`` aims at: the run's accuracy, else its rtol, else 1e-6."""
        x = self.stats.extra
        for val in (x.get("accuracy"), (x.get("settings") or {}).get("rtol"), x.get("rtol")):
            if isinstance(val, (int, float)) and 0 < val < 1:
                return float(val)
        return 1e-6

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

    # values at an instant -------------------------------------------------------------------------
    # Both are methods taking the signal name first (as np.interp takes x first): ``res.at(name, t)``
    # interpolates linearly at one time or an array of times, ``res.final(name)`` is the value at the
    # last output instant, ``res.final()`` all of them; ``unit=`` converts (``res.get``).
    def at(self, name: str, t, unit: str | None = None):
        """Value of signal ``name`` at time ``t`` [s] by linear interpolation between output points; at an
        event instant (stored twice) the value just after the event. ``t`` a number gives a float, an
        array of times an array. ``unit``: a display unit (``res.get``)."""
        tt, y = self.t, self.get(name, unit=unit)
        try:
            tq = np.asarray(t, float)
        except (TypeError, ValueError):
            tq = np.array(np.nan)
        if not np.all(np.isfinite(tq)):
            raise RegmechError(f"res.at('{name}', t): t must be a finite time [s] or an array of them, got {t!r}")
        if len(tt) < 2:
            vals = np.full(tq.shape, float(y[0]))
        else:
            # i: the last output point at or before t (after an event, whose instant is stored twice);
            # times outside the run take the end values, as np.interp does
            i = np.clip(np.searchsorted(tt, tq, side="right") - 1, 0, len(tt) - 2)
            dt = tt[i + 1] - tt[i]
            w = np.clip(np.divide(tq - tt[i], dt, out=np.zeros(np.shape(dt)), where=dt > 0), 0.0, 1.0)
            vals = y[i] + w * (y[i + 1] - y[i])
        return float(vals) if tq.ndim == 0 else np.asarray(vals)

    def final(self, name: str | None = None, unit: str | None = None):
        """Value of signal ``name`` at the end of the run (a float); without a name, a dict of the final
        values of every signal (SI; ``unit`` then refused). ``unit``: a display unit (``res.get``)."""
        if name is None:
            if unit is not None:
                raise ParameterError(f"res.final(unit={unit!r}) needs a signal name: one unit does not fit every "
                                     f"signal; use res.final(name, unit=...) or res.to_dataframe(units=...)")
            return {n: float(self[n][-1]) for n in self.names}
        return float(self.get(name, unit=unit)[-1])

    # units ------------------------------------------------------------------------------------------
    def unit(self, name: str) -> str | None:
        """SI unit of signal ``name`` (``"rad/s"``, ``"N m"``, ``"1"`` for modes; None if its component
        does not declare it): from the kind of its flange or component and its parameters' units
        (``Component.signal_unit``, ``regmech.units``)."""
        if not isinstance(name, str):
            raise UnknownSignalError(f"res.unit() takes a signal name (a str), got {name!r}")
        if name not in self:
            raise UnknownSignalError(self._unknown(name))
        units = self._cache.setdefault(("units",), {})
        if name not in units:
            units[name] = self._signal_unit(name)
        return units[name]

    def _signal_unit(self, name: str) -> str | None:
        return units_mod.signal_unit(self._traj.c.model.components, name)

    def get(self, name: str, unit: str | None = None) -> np.ndarray:
        """Signal ``name`` (as ``res[name]``), in display unit ``unit`` when given (``"rpm"``, ``"deg"``,
        ``"km/h"``, ``"kN m"``, ... see ``regmech.units.DISPLAY_UNITS``); a unit that does not fit the
        signal is a ``ParameterError`` listing the ones that do."""
        values = self[name]
        if unit is None:
            return values
        return units_mod.convert(values, self.unit(name), unit, name)

    def display_unit(self, name: str, units=None) -> str | None:
        """The unit ``name`` is shown in under ``units``: a display unit (str) for every signal, or a dict
        keyed by signal name, by the variable (last part of the name, ``"w"``), or by SI unit
        (``"rad/s"``), looked up in that order; otherwise its SI unit."""
        si = self.unit(name)
        if units is None or (isinstance(units, str) and units.strip().upper() == "SI"):
            return si
        if isinstance(units, str):
            return units_mod.normalise(units)
        if not isinstance(units, dict):
            raise RegmechError(f"units must be a unit name or a dict (signal, variable or SI unit -> unit), "
                               f"got {describe(units)}")
        for key in (name, name.rpartition(".")[2], si):
            if key in units:
                return units_mod.normalise(units[key])
        return si

    def _columns(self, names, units):
        """(header, values) per signal for tables: SI with plain names when ``units`` is None; else
        ``"name [unit]"`` headers in the display units (``"SI"``: every signal in SI)."""
        names = list(self.names if names is None else ([names] if isinstance(names, str) else names))
        if units is None:
            return [("time", self.t)] + [(n, self[n]) for n in names]
        units = None if isinstance(units, str) and units.upper() == "SI" else units
        if isinstance(units, dict):
            known = set(self.names) | {n.rpartition(".")[2] for n in self.names} | \
                {u for u in (self.unit(n) for n in names) if u}
            stray = [k for k in units if k not in known]
            if stray:
                raise UnknownSignalError(f"units: {stray} name no signal, variable or SI unit of the result of "
                                         f"model '{self.model_name}' (keys: signal names such as "
                                         f"'{names[0] if names else 'J1.w'}', variables such as 'w', or SI units "
                                         f"such as 'rad/s')")
        cols = [("time [s]", self.t)]
        for n in names:
            unit = self.display_unit(n, units)
            values = self[n] if unit == self.unit(n) else units_mod.convert(self[n], self.unit(n), unit, n)
            cols.append((units_mod.label(n, unit), values))
        return cols

    def to_dataframe(self, names=None, units=None):
        """A pandas DataFrame with a ``time`` column and one per signal (SI). With ``units`` (``"SI"``, a
        display unit, or a dict as in ``display_unit``) the columns are named ``"name [unit]"``
        (``"time [s]"``) and hold the values in those units."""
        try:
            import pandas as pd
        except ImportError as exc:  # pragma: no cover - optional
            raise RegmechError("to_dataframe() needs pandas: pip install 'regmech[pandas]'") from exc
        return pd.DataFrame(dict(self._columns(names, units)))

    def to_csv(self, path, names=None, units=None) -> None:
        """Write ``time`` and the signals to a CSV file (full precision). ``units`` as in
        ``to_dataframe``: headers ``"name [unit]"`` and values in those units."""
        from .io import writing
        cols = self._columns(names, units)
        with writing(path, "res.to_csv"), open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow([h for h, _ in cols])
            for row in zip(*(v for _, v in cols)):
                w.writerow([repr(float(v)) for v in row])

    def plot(self, names=None, ax=None, path=None, title=None, mark_events=True, units=None, *, events=None,
             modes=None, logy=False, figsize=None):
        """Plot signals against time, one axis per unit shown, and a mode strip per friction device.

        ``names``: the signals (default: the masses' speeds, then the devices' and sources' torques and
        forces, in model order; ``regmech.plotting``). ``units``: display units as in ``to_dataframe``
        (``{"w": "rpm"}``, ``"SI"``); every axis is labelled with its quantity and unit
        (``speed [rpm]``). ``modes``: the devices whose mode strip is drawn (default every device with a
        ``mode`` signal; False none). ``events``: True draws the mode changes as vertical lines,
        ``"annotate"`` labels each with device and transition (``clutch: Free -> Backward``), False
        neither (``mark_events`` is the older name of the same switch). ``logy``: logarithmic y axes;
        signals <= 0 are said so in the legend. ``path``: write a PNG. ``figsize`` (inches).

        Returns the matplotlib ``Figure`` (its ``axes``: the signal axes, then the strips); with ``ax``
        given, draws every signal on that one axis (no strips) and returns it."""
        from .plotting import plot_result
        if events is None:
            events = mark_events
        return plot_result(self, names, ax=ax, path=path, title=title, events=events, units=units, modes=modes,
                           logy=logy, figsize=figsize)

    def save(self, path, names=None):
        """Write the result to a MATLAB ``.mat`` file (time, every signal in SI with its name and unit,
        events, solver statistics, model name, regmech version; layout in ``regmech.io``); read it back
        with ``regmech.load_result(path)``. ``names``: only these signals. Returns the path."""
        from .io import save_result
        return save_result(self, path, names)

    def __repr__(self):
        return f"<Result {self.model_name}: {len(self.t)} points, {len(self.events)} events, {self.stats}>"
