"""The work-precision runner: scenes x solvers x settings, timed, compared, recorded.

For every scene and solver a fresh model is built and compiled (both timed:
``build_s``, ``compile_s``; no compiled cache is shared between solvers).
Then for every *setting* -- a tolerance ``rtol`` of an adaptive solver
(``atol = rtol * 1e-2``, the solvers' default) or a step ``h`` of a
fixed-step one (``scenes.FIXED_STEP``, run with ``tol=None``: the bare
method, without the companion run of its error estimate) -- the scene is simulated
``repeats`` times on that compiled model (at least ``CHEAP_REPEATS`` times
when a run takes less than ``CHEAP_BELOW_S``, once when it takes more than
``REPEAT_ABOVE_S``):

* ``wall_s``: the median wall time of ``model.simulate(...)`` (compile
  excluded, the named-result construction included: what a user waits for);
  ``first_s`` the first (cold) run, which also pays the solver's own lazy
  set-up (Jacobian patterns, matrix exponentials); ``solver_s`` the median
  of the solver's own clock (``Result.stats.wall_time``);
* the errors of the last run against the scene's reference (``metrics``)
  and, for the MSL scenes, against the MSL file (``msl``).

A run that raises is recorded, not fatal: ``error`` (a regmech error, with
its message), ``crash`` (any other exception: a bug), ``timeout`` (the
per-run limit, ``guard.time_limit``). Along a ladder (coarse to fine) a
timeout skips the finer settings, and a fixed-step setting whose predicted
time (last time x step ratio) exceeds the limit is skipped; runs slower
than ``REPEAT_ABOVE_S`` are not repeated.
"""

from __future__ import annotations

import statistics
import time
from dataclasses import asdict, dataclass, field

from .guard import RunTimeout, classify_error, time_limit
from .metrics import compare, trace_of
from .scenes import FIXED_STEP

#: a run longer than this [s] is not repeated (its median is its single time)
REPEAT_ABOVE_S = 15.0
#: a run shorter than this [s] is repeated at least CHEAP_REPEATS times (short runs suffer most from a shared machine)
CHEAP_BELOW_S = 0.5
CHEAP_REPEATS = 5


@dataclass(frozen=True)
class Setting:
    solver: str
    option: str          # "rtol" or "h"
    value: float

    @property
    def options(self) -> dict:
        if self.solver in FIXED_STEP:
            # the bare method: no Richardson companion run (regmech.solvers.richardson) in the timings; the
            # errors are measured against the reference instead
            return {self.option: self.value, "tol": None}
        return {self.option: self.value}

    @property
    def label(self) -> str:
        return f"{self.option}={self.value:g}"


def settings_for(scene, solver: str) -> list[Setting]:
    """The ladder of one solver on one scene, coarse to fine."""
    if solver in FIXED_STEP:
        return [Setting(solver, "h", h) for h in scene.steps]
    return [Setting(solver, "rtol", r) for r in scene.tolerances]


def solvers_for(scene, solvers) -> list[str]:
    return [s for s in solvers if scene.solvers is None or s in scene.solvers]


@dataclass
class RunRecord:
    scene: str
    solver: str
    option: str
    value: float
    status: str = "ok"             # ok | error | crash | timeout | skipped
    reason: str = ""
    wall_s: float = float("nan")
    first_s: float = float("nan")
    solver_s: float = float("nan")
    runs: int = 0
    build_s: float = float("nan")
    compile_s: float = float("nan")
    steps: int = 0
    rhs_calls: int = 0
    jac_calls: int = 0
    events: int = 0
    err_max_rel: float = float("nan")
    worst_signal: str = ""
    err_final: float = float("nan")
    err_switch_s: float = float("nan")
    events_matched: int = 0
    events_unmatched: int = 0
    msl_max_rel: float = float("nan")
    msl_worst: str = ""
    msl_switch_s: float = float("nan")
    msl_unmatched: int = 0
    extra: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def row(self) -> dict:
        d = asdict(self)
        d.pop("extra")
        return d


def _simulate_once(model, scene, setting, limit):
    t0 = time.perf_counter()
    with time_limit(limit):
        res = model.simulate(scene.t_end, dt_out=scene.dt_out, solver=setting.solver, **setting.options)
    return res, time.perf_counter() - t0


def run_setting(model, scene, setting, reference, repeats, limit, build_s, compile_s) -> RunRecord:
    """All repeats of one setting; never raises except KeyboardInterrupt."""
    rec = RunRecord(scene.key, setting.solver, setting.option, setting.value, build_s=build_s, compile_s=compile_s)
    walls, solver_walls, res = [], [], None
    try:
        wanted = max(1, repeats)
        while len(walls) < wanted:
            res, wall = _simulate_once(model, scene, setting, limit)
            walls.append(wall)
            solver_walls.append(res.stats.wall_time)
            if wall > REPEAT_ABOVE_S:
                break
            if len(walls) == 1 and wall < CHEAP_BELOW_S and repeats > 1:
                wanted = max(wanted, CHEAP_REPEATS)
    except (Exception, RunTimeout) as exc:     # recorded; KeyboardInterrupt stops the benchmark
        rec.status, rec.reason = classify_error(exc, model)
        if walls:       # a later repeat failed where the first passed: flaky, say so
            rec.reason = f"repeat {len(walls) + 1} of {repeats}: {rec.reason}"
        return rec
    rec.wall_s = statistics.median(walls)
    rec.first_s = walls[0]
    rec.solver_s = statistics.median(solver_walls)
    rec.runs = len(walls)
    st = res.stats
    # a solver may leave a counter unset (None): recorded as 0
    rec.steps, rec.rhs_calls, rec.jac_calls = st.steps or 0, st.rhs_calls or 0, st.jac_calls or 0
    rec.events = len(res.events)
    rec.extra = dict(st.extra)
    if reference is not None:
        try:
            errs = compare(trace_of(res, scene.signal_names(), reference.trace.grid), reference.trace,
                           with_switches=scene.stick_slip)
            for k, v in errs.as_row().items():
                setattr(rec, k, v)
        except (KeyError, ValueError) as exc:
            rec.reason = f"errors not computed: {exc}"
    if scene.msl is not None:
        from .msl import msl_errors
        m = msl_errors(res, scene.msl)
        if m:
            for k, v in m.items():
                setattr(rec, k, v)
    return rec


def run_solver(scene, solver, reference, repeats=3, limit=120.0, on_setting=None) -> list[RunRecord]:
    """One solver's ladder on one scene (fresh model, compile timed once)."""
    settings = settings_for(scene, solver)
    records: list[RunRecord] = []

    def done(rec):
        records.append(rec)
        if on_setting is not None:
            on_setting(rec)

    t0 = time.perf_counter()
    try:
        model = scene.build()
        build_s = time.perf_counter() - t0
        t1 = time.perf_counter()
        with time_limit(limit):
            model.compile()
        compile_s = time.perf_counter() - t1
    except (Exception, RunTimeout) as exc:
        status, reason = classify_error(exc, model if "model" in locals() else _Empty())
        for s in settings:
            done(RunRecord(scene.key, solver, s.option, s.value, status=status, reason=f"build/compile: {reason}"))
        return records
    skip_reason = ""
    for i, s in enumerate(settings):
        if skip_reason:
            done(RunRecord(scene.key, solver, s.option, s.value, status="skipped", reason=skip_reason,
                           build_s=build_s, compile_s=compile_s))
            continue
        rec = run_setting(model, scene, s, reference, repeats, limit, build_s, compile_s)
        done(rec)
        if rec.status == "timeout":
            skip_reason = f"a coarser setting ({s.label}) reached the time limit"
        elif rec.ok and s.option == "h" and i + 1 < len(settings):
            predicted = rec.first_s * s.value / settings[i + 1].value
            if predicted > limit:
                skip_reason = (f"predicted {predicted:.0f} s from {s.label} ({rec.first_s:.1f} s) exceeds the "
                               f"time limit {limit:g} s")
    return records


class _Empty:
    components: dict = {}


def planned_runs(scenes, solvers) -> int:
    return sum(len(settings_for(sc, s)) for sc in scenes for s in solvers_for(sc, solvers))


def available_solvers() -> list[str]:
    """Every registered solver, in a fixed order (regmech's own first, then scipy's)."""
    from regmech.solvers import SOLVERS, _load
    _load()
    order = ["ida", "expm", "convolution", "rk4", "abm", "euler", "scipy:RK45", "scipy:RK23", "scipy:DOP853",
             "scipy:Radau", "scipy:BDF", "scipy:LSODA"]
    known = [s for s in order if s in SOLVERS]
    return known + sorted(s for s in SOLVERS if s not in order)
