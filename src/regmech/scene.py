"""``Scene``: a model, its experiment and the outputs wanted; simulated on a
model reduced to what those outputs need.

>>> sc = rm.Scene(model, t_end=1.5, outputs=["J2.w"], band_hz=50)
>>> res = sc.simulate()            # the reduced model; res["J2.w"] is there
>>> print(sc.report())             # what was removed or merged and why, sizes, error, speed-up

Passes (``structure.reduction``): ``drop_disengaged``, ``prune``,
``merge_rigid`` always; ``rigidify`` when ``band_hz`` is given;
``ground_heavy`` when ``heavy_ratio`` is given. ``passes=`` picks a subset.
``accuracy`` (optional) is the bound a user reads off the outputs: the
error of ``Scene.simulate()``'s outputs against the full model's exact
answer, relative to each output's range. It is split in two: every
simulation of the scene (reduced and full) runs under the accuracy contract
at ``SOLVER_SHARE * accuracy`` (``regmech.solvers.accuracy``; an
``accuracy=`` in the simulate options overrides it), and ``report()`` /
``verify()`` require the reduced model's outputs to lie within
``REDUCTION_SHARE * accuracy`` of the full model's; if they do not, the
riskiest pass (``ground_heavy``, then ``rigidify``) is dropped and the check
repeated. The two solver errors in that comparison (each at most
``SOLVER_SHARE * accuracy`` on the state signals) and the reduced run's own
keep the total within ``accuracy``. (The contract bounds state signals;
outputs such as device torques are checked by the comparison alone.)
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from . import units
from .errors import ModelError, ParameterError
from .result import Result
from .structure import reduction as R

#: shares of a Scene's accuracy: each simulation's contract, and the reduced-against-full check (module docstring)
SOLVER_SHARE = 0.1
REDUCTION_SHARE = 0.7

SAFE_PASSES = ("drop_disengaged", "prune", "merge_rigid")
ALL_PASSES = SAFE_PASSES + ("rigidify", "ground_heavy")


class SceneResult:
    """A reduced model's Result that also answers for the full model's requested outputs."""

    def __init__(self, result, maps, model=None):
        self._res = result
        self._maps = maps
        self._model = model          # the full model: the units of the outputs it answers for
        self.t = result.t
        self.events = result.events
        self.stats = result.stats

    def __getitem__(self, name):
        if name in self._maps:
            m = self._maps[name]
            return m.scale * self._res[m.source] if m.scale != 0.0 else np.zeros_like(self.t)
        return self._res[name]

    def __contains__(self, name):
        return name in self._maps or name in self._res

    @property
    def names(self):
        return sorted(set(self._res.names) | set(self._maps))

    def unit(self, name):
        """SI unit of ``name`` (an output of the full model or a signal of the reduced one)."""
        if name in self._maps and self._model is not None:
            return units.signal_unit(self._model.components, name)
        return self._res.unit(name)

    # the Result methods that read signals by name, reading them through this object (so the full
    # model's outputs answer too): display units, values at an instant, tables, plots
    get = Result.get
    at = Result.at
    final = Result.final
    display_unit = Result.display_unit
    _columns = Result._columns
    to_csv = Result.to_csv
    to_dataframe = Result.to_dataframe
    plot = Result.plot

    def __getattr__(self, attr):
        return getattr(self._res, attr)


@dataclass
class SceneReport:
    actions: list
    size_full: dict
    size_reduced: dict
    errors: dict = field(default_factory=dict)
    time_full: float | None = None
    time_reduced: float | None = None
    accuracy: float | None = None
    dropped_passes: list = field(default_factory=list)

    @property
    def max_error(self):
        return max(self.errors.values()) if self.errors else None

    @property
    def speedup(self):
        if self.time_full and self.time_reduced:
            return self.time_full / self.time_reduced
        return None

    def __str__(self):
        lines = ["scene reduction:"]
        applied = [a for a in self.actions if a.applied]
        refused = [a for a in self.actions if not a.applied]
        lines += [f"  {a}" for a in applied] or ["  (nothing to reduce)"]
        if refused:
            lines.append("refused:")
            lines += [f"  {a}" for a in refused]
        if self.dropped_passes:
            lines.append(f"passes dropped to meet the accuracy target: {', '.join(self.dropped_passes)}")
        f, r = self.size_full, self.size_reduced
        lines.append(f"size: {f['components']} -> {r['components']} components, {f['states']} -> {r['states']} "
                     f"states, {f['unknowns']} -> {r['unknowns']} DAE unknowns")
        if self.errors:
            lines.append("error of the reduced model against the full one (max abs, relative to each signal's range):")
            lines += [f"  {k}: {v:.3g}" for k, v in self.errors.items()]
            if self.accuracy is not None:
                ok = self.max_error <= REDUCTION_SHARE * self.accuracy
                lines.append(f"accuracy target {self.accuracy:g} (reduction share {REDUCTION_SHARE * self.accuracy:g}, "
                             f"simulations at {SOLVER_SHARE * self.accuracy:g}): {'met' if ok else 'NOT met'}")
        if self.speedup:
            lines.append(f"time: full {self.time_full * 1e3:.1f} ms, reduced {self.time_reduced * 1e3:.1f} ms "
                         f"(speed-up {self.speedup:.2f}x)")
        return "\n".join(lines)


def _size(model):
    c = model.compile()
    return {"components": len(model.components), "states": int(c.ode_size()), "unknowns": int(c.N)}


class Scene:
    def __init__(self, model, t_end, outputs, band_hz=None, accuracy=None, *, t_start=0.0, passes=None,
                 rigid_factor=10.0, heavy_ratio=None, **simulate_options):
        if not outputs:
            raise ParameterError("Scene: give the outputs you need, e.g. outputs=['J2.w']")
        self.model = model
        self.t_start, self.t_end = float(t_start), float(t_end)
        self.outputs = list(outputs)
        for name in self.outputs:
            R.output_component(model, name)        # raises for unknown components
        self.band_hz = band_hz
        if accuracy is not None:
            from .solvers.accuracy import check_accuracy
            accuracy = check_accuracy(accuracy)
        self.accuracy = accuracy
        self.rigid_factor = rigid_factor
        self.heavy_ratio = heavy_ratio
        if passes is None:
            passes = list(SAFE_PASSES)
            if band_hz is not None:
                passes.append("rigidify")
            if heavy_ratio is not None:
                passes.append("ground_heavy")
        unknown = set(passes) - set(ALL_PASSES)
        if unknown:
            raise ParameterError(f"Scene: unknown passes {sorted(unknown)}; choose from {ALL_PASSES}")
        if "rigidify" in passes and band_hz is None:
            raise ParameterError("Scene: the 'rigidify' pass needs band_hz (the frequency band of interest)")
        self.passes = list(passes)
        self.options = simulate_options
        self._reduction = None
        self._report = None

    # -- reduction ------------------------------------------------------------------
    def reduce(self, passes=None):
        passes = self.passes if passes is None else passes
        model, actions, maps = self.model, [], {}
        if "drop_disengaged" in passes:
            model, acts = R.drop_disengaged(model, self.t_start, self.t_end,
                                            keep={R.output_component(model, o) for o in self.outputs})
            actions += acts
        if "prune" in passes:
            model, acts = R.prune(model, self.outputs)
            actions += acts
        if "rigidify" in passes:
            model, acts = R.rigidify(model, self.outputs, self.band_hz, self.rigid_factor)
            actions += acts
        if "ground_heavy" in passes:
            model, acts = R.ground_heavy(model, self.outputs, self.heavy_ratio)
            actions += acts
        if "merge_rigid" in passes:
            model, acts, m = R.merge_rigid(model, self.outputs)
            actions += acts
            maps.update(m)
        model.name = f"{self.model.name} (reduced)"
        try:
            model.compile()
        except ModelError as exc:
            raise ModelError(f"the reduced model of '{self.model.name}' does not compile ({exc}); run the Scene with "
                             f"fewer passes (passes=...)") from exc
        return R.Reduction(model, actions, maps)

    @property
    def reduction(self):
        if self._reduction is None:
            self._reduction = self.reduce()
        return self._reduction

    def _options(self, options):
        opts = {**self.options, **options}
        if self.accuracy is not None and opts.get("accuracy") is None:
            opts["accuracy"] = SOLVER_SHARE * self.accuracy
        return opts

    def simulate(self, **options):
        red = self.reduction
        res = red.model.simulate(self.t_end, t_start=self.t_start, **self._options(options))
        return SceneResult(res, red.outputs, self.model)

    def simulate_full(self, **options):
        return self.model.simulate(self.t_end, t_start=self.t_start, **self._options(options))

    # -- verification -------------------------------------------------------------------
    def _compare(self, full, reduced):
        errs = {}
        for name in self.outputs:
            a = np.interp(full.t, reduced.t, reduced[name])
            b = full[name]
            scale = max(np.ptp(b), np.abs(b).max(), 1e-300)
            errs[name] = float(np.max(np.abs(a - b)) / scale)
        return errs

    def report(self, compare=True, repeats=3):
        """What was reduced and why; with ``compare``, error and speed-up against the full model."""
        if self._report is not None:
            return self._report
        dropped = []
        full_res = None
        t_full = None
        while True:
            red = self.reduction
            rep = SceneReport(red.actions, _size(self.model), _size(red.model), accuracy=self.accuracy,
                              dropped_passes=list(dropped))
            if not compare:
                break
            if full_res is None:
                full_res, t_full = _timed(lambda: self.simulate_full(), repeats)
            red_res, t_red = _timed(lambda: self.simulate(), repeats)
            rep.errors = self._compare(full_res, red_res)
            rep.time_full, rep.time_reduced = t_full, t_red
            risky = [p for p in ("ground_heavy", "rigidify") if p in self.passes]
            if self.accuracy is None or rep.max_error <= REDUCTION_SHARE * self.accuracy or not risky:
                break
            dropped.append(risky[0])
            self.passes.remove(risky[0])
            self._reduction = None
        self._report = rep
        return rep

    def verify(self):
        return self.report(compare=True)


def _timed(fn, repeats):
    times, out = [], None
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, float(np.median(times))
