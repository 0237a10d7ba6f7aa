"""The hard-case suite: models that break naive solvers, each with its stated tolerance.

A ``HardCase`` has a model builder per *size* (``"ci"``: small enough for the
test suite, ``"full"``: the benchmark), the horizon and output interval, the
solver settings it is run with (``rtol`` for adaptive solvers, a step ``h``
for fixed-step ones) and a ``check`` that compares the result with an
analytic or independent answer (``hard_models``, ``linear_ref``) and
returns the measured deviation and the tolerance it must meet.

A run ends in one of these *verdicts*:

* ``pass``: it finished and the check holds;
* ``refuse``: it stopped with a regmech error whose message names a
  component of the model (a clear refusal is an acceptable outcome);
* ``fail``: anything else, with the reason -- a wrong answer beyond the
  tolerance (``inaccurate`` for fixed-step methods, run with ``tol`` =
  ``ANSWER_TOL`` for their Richardson error estimate), a NaN, a regmech error that names no component, another
  exception (a bug), or the time limit (a run that would hang).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .guard import (RunTimeout, WorkBudgetExceeded, classify_error, first_line, names_a_component, time_limit,
                    work_budget)
from .scenes import FIXED_STEP

CI, FULL = "ci", "full"
#: tolerance of the answers (max error relative to the range of each kind of signal) at rtol 1e-8:
#: 1e4 times the requested relative tolerance, so a failure is an answer that is plainly wrong
ANSWER_TOL = 1e-4


@dataclass
class Check:
    ok: bool
    value: float          # measured deviation (its meaning in ``what``)
    tolerance: float
    what: str             # e.g. "max rel error of positions and speeds"
    detail: str = ""


@dataclass
class HardCase:
    key: str
    group: str
    title: str
    build: Callable        # size -> (model, check) where check(result) -> Check
    t_end: dict
    dt_out: dict
    rtol: float = 1e-8
    h: dict = field(default_factory=dict)      # size -> fixed step [s] (euler, rk4, abm, expm), run with
    #                                            tol=ANSWER_TOL: each meets the answer tolerance or refuses
    note: str = ""
    limits: dict = field(default_factory=dict)  # size -> wall-clock limit per run [s], overriding the default

    def options(self, solver: str, size: str) -> dict:
        if solver in FIXED_STEP:
            # the Richardson error estimate (regmech.solvers.richardson) at the answer tolerance: a fixed-step
            # run either meets it or stops with AccuracyError naming the worst component
            return {"h": self.h.get(size, self.dt_out[size]), "tol": ANSWER_TOL}
        return {"rtol": self.rtol}


@dataclass
class HardOutcome:
    case: str
    solver: str
    size: str
    verdict: str          # pass | refuse | fail
    reason: str
    value: float = math.nan
    tolerance: float = math.nan
    what: str = ""
    wall_s: float = math.nan
    steps: int = 0
    events: int = 0


# ----------------------------------------------------------------------------- checks
def _rel_dev(res, answer: dict, grid, skip=None) -> tuple[float, str]:
    """max |res - answer| over the grid, per kind of signal relative to the largest range of that kind."""
    from .metrics import sample
    worst, name = 0.0, ""
    kinds: dict = {}
    for sig, ref in answer.items():
        kinds.setdefault(sig.rsplit(".", 1)[1], []).append((sig, ref))
    for kind, pairs in kinds.items():
        scale = max(max(float(np.ptp(r)) for _, r in pairs), 1e-300)
        for sig, ref in pairs:
            run = sample(res.t, res[sig], grid)
            keep = np.ones(len(grid), bool) if skip is None else ~skip
            d = float(np.max(np.abs(run[keep] - ref[keep]))) / scale if keep.any() else 0.0
            if not math.isfinite(d):
                return math.inf, sig
            if d > worst:
                worst, name = d, sig
    return worst, name


def _grid(case, size):
    from regmech.solvers.common import output_grid
    return output_grid(0.0, case.t_end[size], case.dt_out[size])


def linear_chain_case(key, group, title, maker, tol, t_end, dt_out, h, rtol=1e-8, note=""):
    """A case on a ``LinearChain``: positions and speeds of every mass against the exact response."""
    def build(size):
        chain, signal = maker()
        model = chain.to_model(signal)
        pos, vel = ("s", "v") if chain.translational else ("phi", "w")
        grid = _grid(case, size)
        w = chain.frequencies()
        spread = w[-1] / w[w > 1e-9 * w[-1]].min()
        # double-precision round-off of the exact solution grows like spread^2 (linear_ref): 30 digits beyond 1e4
        x, v = chain.exact(grid, digits=30 if spread > 1e4 else None)
        answer = {f"{nm}.{pos}": x[:, i] for i, nm in enumerate(chain.names)}
        answer.update({f"{nm}.{vel}": v[:, i] for i, nm in enumerate(chain.names)})

        def check(res):
            dev, sig = _rel_dev(res, answer, grid)
            return Check(dev <= tol, dev, tol, "max error of positions/speeds relative to their range",
                         f"worst {sig}; natural frequencies {w[0]:.3g}..{w[-1]:.3g} rad/s (ratio {spread:.3g})")
        return model, check

    case = HardCase(key, group, title, build, t_end, dt_out, rtol=rtol, h=h, note=note)
    return case


def _belt_case():
    from .hard_models import belt_answer, belt_oscillator

    def build(size):
        model = belt_oscillator()
        first_stick, slip, stick = belt_answer()
        t_end = case.t_end[size]
        tol = 1e-5

        def check(res):
            ev = [(e.t, e.new_mode) for e in res.events if e.component == "contact"]
            starts_slip = [t for t, m in ev if m != 0]
            starts_stick = [t for t, m in ev if m == 0]
            cycles_expected = int((t_end - first_stick) // (slip + stick))
            if len(starts_slip) < cycles_expected or not starts_slip:
                return Check(False, math.inf, tol, "max error of phase durations [s]",
                             f"{len(starts_slip)} slip phases, expected at least {cycles_expected}")
            devs = [abs(starts_slip[0] - first_stick)]
            devs += [abs((b - a) - slip) for a, b in zip(starts_slip, starts_stick)]
            devs += [abs((b - a) - stick) for a, b in zip(starts_stick, starts_slip[1:])]
            stuck = res["contact.mode"] == 0
            drift = float(np.max(np.abs(res["block.v"][stuck] - 0.2))) if stuck.any() else 0.0
            dev = max(devs)
            ok = dev <= tol and drift <= 1e-8
            return Check(ok, dev, tol, "max error of phase durations [s]",
                         f"{len(starts_slip)} cycles ({len(res.events)} mode changes); speed drift while "
                         f"stuck {drift:.1e} m/s (must be <= 1e-8)")
        return model, check

    case = HardCase("belt_limit_cycle", "stick/slip",
                    "stick-slip limit cycle of a block on a belt (hundreds of lock/unlock events)",
                    build, {CI: 20.0, FULL: 100.0}, {CI: 0.01, FULL: 0.05}, rtol=1e-8, h={CI: 1e-3, FULL: 1e-3},
                    note="closed-form slip and stick durations (limit cycle entered after the first stick phase; "
                         "full size: about 150 cycles, 300 lock/unlock events)",
                    limits={FULL: 120.0})
    return case


def _simultaneous_case():
    from .hard_models import simultaneous_lock

    def build(size):
        model = simultaneous_lock()
        tol = 1e-6

        def check(res):
            ev = [(e.t, e.component, e.old_mode, e.new_mode) for e in res.events]
            locks = [e for e in ev if e[3] == 0]
            others = [e for e in ev if e[3] != 0]
            dt = max((abs(e[0] - 2.0) for e in locks), default=math.inf)
            after = res.t > 2.0 + 1e-6
            dw = max(float(np.max(np.abs(res[n][after] - 6.0))) for n in ("hub.w", "sat1.w", "sat2.w", "sat3.w"))
            ok = len(locks) == 3 and not others and dt <= tol and dw <= tol
            return Check(ok, max(dt, dw), tol, "max of lock-time error [s] and speed error after [rad/s]",
                         f"{len(locks)} locks at {sorted(e[0] for e in locks)}; other changes {others[:3]}")
        return model, check

    return HardCase("simultaneous_lock", "stick/slip", "three clutches that lock at the same instant",
                    build, {CI: 4.0, FULL: 4.0}, {CI: 0.01, FULL: 0.01}, rtol=1e-8, h={CI: 1e-3, FULL: 1e-3},
                    note="lock at t = 2 s, then 6 rad/s (momentum)")


def _zero_speed_case():
    from .hard_models import zero_speed_engagement

    def build(size):
        model, answer = zero_speed_engagement()
        grid = _grid(case, size)
        ans = answer(grid)
        tol = 1e-7

        def check(res):
            ev = [(round(e.t, 12), e.old_mode, e.new_mode) for e in res.events]
            # locked from 0.5 s on: every change within 1e-9 s of the engagement, the last one into Stuck
            # (round-off in w_rel may give a Free -> Forward -> Stuck pair 1e-15 s apart: no visible slip)
            good_events = bool(ev) and all(abs(t - 0.5) <= 1e-9 for t, _, _ in ev) and ev[-1][2] == 0
            dev, sig = _rel_dev(res, ans, grid)
            return Check(good_events and dev <= tol, dev, tol, "max error of speeds relative to their range",
                         f"mode changes {ev[:4]}" + ("" if good_events else " (expected: Stuck from t = 0.5 on)"))
        return model, check

    case = HardCase("zero_speed_engagement", "stick/slip", "clutch engaging at exactly zero relative speed",
                    build, {CI: 1.0, FULL: 1.0}, {CI: 0.01, FULL: 0.01}, rtol=1e-8, h={CI: 1e-3, FULL: 1e-3})
    return case


def _slope_case():
    from .hard_models import slope_hold
    holds = {CI: 100.0, FULL: 10000.0}

    def build(size):
        t_hold = holds[size]
        model, t_b, answer = slope_hold(t_hold=t_hold)
        grid = _grid(case, size)
        ans = answer(grid)
        tol = ANSWER_TOL

        def check(res):
            held = res.t < t_hold
            drift = max(float(np.max(np.abs(res["vehicle.s"][held]))), float(np.max(np.abs(res["vehicle.v"][held]))))
            ev = [(e.t, e.old_mode, e.new_mode) for e in res.events]
            breaks = [e for e in ev if e[1] == 0]
            dt_b = abs(breaks[0][0] - t_b) if breaks else math.inf
            dev, sig = _rel_dev(res, ans, grid)
            ok = drift <= 1e-9 and dt_b <= 1e-6 * max(1.0, t_b) and dev <= tol
            return Check(ok, dev, tol, "max error of position/speed after break-away, relative to range",
                         f"drift while held {drift:.1e} (must be <= 1e-9); break-away at "
                         f"{breaks[0][0] if breaks else None} vs {t_b:.9g} s; changes {ev[:3]}")
        return model, check

    case = HardCase("slope_hold", "stick/slip", "brake holding a vehicle on a 15 deg slope, then breaking away",
                    build, {CI: 105.0, FULL: 10005.0}, {CI: 0.05, FULL: 1.0}, rtol=1e-8,
                    h={CI: 0.05, FULL: 0.1},
                    note="held for 100 s (CI) / 10^4 s (full), then a winch pulls down the slope")
    return case


def _long_horizon_case():
    from .hard_models import energy, undamped_chain

    def build(size):
        model, e0 = undamped_chain()
        tol = 1e-3

        def check(res):
            e = energy(res, 4)
            drift = float(np.max(np.abs(e / e0 - 1.0)))
            final = float(e[-1] / e0 - 1.0)
            ok = math.isfinite(drift) and drift <= tol
            return Check(ok, drift, tol, "max relative energy drift",
                         f"final energy change {final:+.2e}; {len(res.t)} output points")
        return model, check

    return HardCase("long_horizon", "long horizon",
                    "undamped 4-mass chain over ~32,000 periods of its highest mode (1e6 rk4 steps)",
                    build, {CI: 100.0, FULL: 1e4}, {CI: 0.1, FULL: 1.0}, rtol=1e-8, h={CI: 0.01, FULL: 0.01},
                    note="CI: 100 s (1e4 steps of h = 0.01 s); full: 1e4 s (1e6 steps)",
                    limits={FULL: 300.0})


def _torque_steps_case():
    from regmech.signals import Step
    from .hard_models import damped_inertia, piecewise_constant_answer

    def build(size):
        model = damped_inertia(Step(height=10.0, start_time=0.3), Step(height=-15.0, start_time=0.7),
                               Step(height=8.0, start_time=1.3))
        grid = _grid(case, size)
        w, phi = piecewise_constant_answer([(0.3, 10.0), (0.7, -5.0), (1.3, 3.0)], 2.0, 4.0, grid)
        ans = {"J.w": w, "J.phi": phi}
        tol = ANSWER_TOL

        def check(res):
            dev, sig = _rel_dev(res, ans, grid)
            return Check(dev <= tol, dev, tol, "max error of speed/angle relative to range", f"worst {sig}")
        return model, check

    case = HardCase("torque_steps", "discontinuous inputs", "torque steps on a damped inertia", build,
                    {CI: 2.0, FULL: 2.0}, {CI: 0.01, FULL: 0.002}, rtol=1e-8, h={CI: 1e-3, FULL: 1e-3})
    return case


def _square_wave_case():
    from regmech.signals import Pulse
    from .hard_models import damped_inertia, piecewise_constant_answer, pulse_levels

    def build(size):
        pulse = Pulse(amplitude=10.0, width=30.0, period=0.25, start_time=0.1)
        model = damped_inertia(pulse, name="square_wave_torque")
        grid = _grid(case, size)
        w, phi = piecewise_constant_answer(pulse_levels(pulse, case.t_end[size]), 2.0, 4.0, grid)
        ans = {"J.w": w, "J.phi": phi}
        tol = ANSWER_TOL

        def check(res):
            dev, sig = _rel_dev(res, ans, grid)
            return Check(dev <= tol, dev, tol, "max error of speed/angle relative to range", f"worst {sig}")
        return model, check

    case = HardCase("square_wave_torque", "discontinuous inputs", "square-wave torque (Pulse) on a damped inertia",
                    build, {CI: 2.0, FULL: 10.0}, {CI: 0.005, FULL: 0.005}, rtol=1e-8, h={CI: 1e-3, FULL: 1e-3})
    return case


def _throttle_case():
    from regmech.signals import Pulse

    def build(size):
        from regmech.library import vehicle_launch
        t_end, dt = case.t_end[size], case.dt_out[size]

        def make():
            return vehicle_launch(throttle=Pulse(amplitude=0.6, width=50.0, period=0.4, start_time=0.3, offset=0.3))
        model = make()
        names = ("flywheel.w", "gearbox_out.w", "wheel_left.J.w", "body.v")
        ref_cache: dict = {}
        tol = ANSWER_TOL

        def reference():
            if "trace" not in ref_cache:
                from .metrics import compare, trace_of
                grid = _grid(case, size)
                ref = trace_of(make().simulate(t_end, dt_out=dt, solver="scipy:DOP853", rtol=1e-11, atol=1e-13),
                               names, grid)
                chk = trace_of(make().simulate(t_end, dt_out=dt, solver="scipy:Radau", rtol=1e-10, atol=1e-12),
                               names, grid)
                ref_cache.update(trace=ref, cross=compare(chk, ref, with_switches=True))
            return ref_cache["trace"], ref_cache["cross"]

        def check(res):
            from .metrics import compare, trace_of
            ref, cross = reference()
            err = compare(trace_of(res, names, ref.grid), ref, with_switches=True)
            ok = err.max_rel <= tol and err.switch.unmatched == 0
            return Check(ok, err.max_rel, tol, "max rel error vs reference (DOP853 rtol 1e-11)",
                         f"switch err {err.switch.max_dt:.1e} s, unmatched {err.switch.unmatched}; reference "
                         f"cross-check (Radau rtol 1e-10) {cross.max_rel:.1e}")
        return model, check

    case = HardCase("square_wave_throttle", "discontinuous inputs",
                    "vehicle launch with a square-wave throttle (Pulse, 2.5 Hz)", build,
                    {CI: 1.5, FULL: 3.0}, {CI: 5e-3, FULL: 5e-3}, rtol=1e-8, h={CI: 2e-3, FULL: 2e-3},
                    note="no closed form: reference DOP853 rtol 1e-11, cross-checked by Radau rtol 1e-10")
    return case


def _gear_case():
    from .hard_models import gear_1_1000

    def build(size):
        model, answer = gear_1_1000()
        grid = _grid(case, size)
        ans = answer(grid)
        tol = ANSWER_TOL

        def check(res):
            dev, sig = _rel_dev(res, ans, grid)
            return Check(dev <= tol, dev, tol, "max error of angles/speeds relative to range", f"worst {sig}")
        return model, check

    case = HardCase("gear_1_1000", "extreme parameters", "gear ratio 1:1000 between a motor and an elastic load",
                    build, {CI: 4.0, FULL: 20.0}, {CI: 0.01, FULL: 0.01}, rtol=1e-8, h={CI: 0.01, FULL: 0.01})
    return case


def all_cases() -> list[HardCase]:
    from .hard_models import inertia_ratio_chain, near_rigid_chain, stretched_chain, tiny_mass_chain
    cases = []
    for ratio in (1e3, 1e5, 1e7):
        cases.append(linear_chain_case(
            f"stretched_{ratio:.0e}".replace("+0", ""), "stretched spectra",
            f"6-mass chain, highest/lowest natural frequency {ratio:.0e}",
            lambda ratio=ratio: stretched_chain(ratio), tol=ANSWER_TOL, t_end={CI: 10.0, FULL: 40.0},
            dt_out={CI: 0.02, FULL: 0.02}, h={CI: 0.01, FULL: 0.01}))
    cases.append(linear_chain_case(
        "near_rigid_shaft", "stretched spectra", "soft 8-mass chain with one shaft 1e6 times stiffer",
        near_rigid_chain, tol=ANSWER_TOL, t_end={CI: 2.0, FULL: 10.0}, dt_out={CI: 0.004, FULL: 0.004},
        h={CI: 1e-3, FULL: 1e-3}))
    cases.append(linear_chain_case(
        "inertia_ratio_1e8", "extreme parameters", "flywheel 1e4 kg m^2 and a 1e-4 kg m^2 inertia on one shaft",
        inertia_ratio_chain, tol=ANSWER_TOL, t_end={CI: 5.0, FULL: 20.0}, dt_out={CI: 0.01, FULL: 0.01},
        h={CI: 1e-3, FULL: 1e-3}))
    cases.append(_gear_case())
    cases.append(linear_chain_case(
        "tiny_mass", "extreme parameters", "a 1 g mass between two 10 t masses (ratio 1e7)",
        tiny_mass_chain, tol=ANSWER_TOL, t_end={CI: 3.0, FULL: 10.0}, dt_out={CI: 0.005, FULL: 0.005},
        h={CI: 1e-3, FULL: 1e-3}))
    cases += [_belt_case(), _simultaneous_case(), _zero_speed_case(), _slope_case(), _long_horizon_case(),
              _torque_steps_case(), _square_wave_case(), _throttle_case()]
    return cases


def get_case(key: str) -> HardCase:
    for c in all_cases():
        if c.key == key:
            return c
    raise KeyError(f"no hard case {key!r}; known: {[c.key for c in all_cases()]}")


# ----------------------------------------------------------------------------- running
def run_case(case: HardCase, solver: str, size: str = CI, limit: float | None = 60.0, built=None,
             max_calls: int | None = None) -> HardOutcome:
    """One solver on one hard case; never raises (except KeyboardInterrupt).

    ``limit``: wall-clock limit [s] (``guard.time_limit``); ``max_calls``: limit on the
    evaluations of the model equations (``guard.work_budget``, the same on any machine).
    """
    model, check = built if built is not None else case.build(size)
    opts = case.options(solver, size)
    out = HardOutcome(case.key, solver, size, "fail", "")
    t0 = time.perf_counter()
    try:
        with time_limit(limit), work_budget(model, max_calls):
            res = model.simulate(case.t_end[size], dt_out=case.dt_out[size], solver=solver, **opts)
    except (Exception, RunTimeout, WorkBudgetExceeded) as exc:
        out.wall_s = time.perf_counter() - t0
        if isinstance(exc, WorkBudgetExceeded):
            out.reason = f"work budget: {first_line(exc)} (a run that would go on for a long time)"
            return out
        status, reason = classify_error(exc, model)
        if status == "error" and names_a_component(str(exc), model):
            out.verdict, out.reason = "refuse", reason
        elif status == "error":
            out.reason = f"regmech error naming no component: {reason}"
        elif status == "timeout":
            out.reason = f"time limit: {reason}"
        else:
            out.reason = reason
        return out
    out.wall_s = time.perf_counter() - t0
    out.steps, out.events = res.stats.steps, len(res.events)
    try:
        chk = check(res)
    except (Exception, RunTimeout, WorkBudgetExceeded) as exc:   # a check that cannot evaluate the result: a failure
        out.reason = f"result could not be checked: {type(exc).__name__}: {first_line(exc)}"
        return out
    out.value, out.tolerance, out.what = chk.value, chk.tolerance, chk.what
    setting = ", ".join(f"{k}={v:g}" if v is not None else f"{k}=None" for k, v in opts.items())
    if chk.ok:
        out.verdict, out.reason = "pass", f"{setting}: {chk.what} {chk.value:.1e} <= {chk.tolerance:g}; {chk.detail}"
    else:
        if solver in FIXED_STEP:     # with tol: the Richardson estimate passed the run, the check did not
            label = "inaccurate (no error control)" if opts.get("tol") is None else "inaccurate (error underestimated)"
        else:
            label = "wrong answer"
        shown = "NaN" if not math.isfinite(chk.value) else f"{chk.value:.1e}"
        out.reason = f"{label} at {setting}: {chk.what} {shown} > {chk.tolerance:g}; {chk.detail}"
    return out


def run_cases(cases, solvers, size=FULL, limit=60.0, progress=True) -> list[HardOutcome]:
    bar = None
    if progress:
        try:
            from tqdm import tqdm
            bar = tqdm(total=len(cases) * len(solvers), unit="run", dynamic_ncols=True)
        except ImportError:
            bar = None
    outcomes = []
    try:
        for case in cases:
            for solver in solvers:
                if bar is not None:
                    bar.set_description(f"{case.key}: {solver}")
                outcomes.append(run_case(case, solver, size, case.limits.get(size, limit)))
                if bar is not None:
                    bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    return outcomes


# ----------------------------------------------------------------------------- report
def hard_markdown(cases, outcomes, solvers, size, machine: dict, limit: float, wall_total: float) -> str:
    from .machine import machine_line
    lines = ["# Hard cases", "",
             f"Machine: {machine_line(machine)}. Size: `{size}`; time limit {limit:g} s per run; "
             f"total {wall_total / 60:.1f} min. Reproduce: `python benchmarks/run_benchmarks.py --hard`.", "",
             "Each case is solved by every solver at the stated setting (adaptive solvers at `rtol`, atol = "
             "rtol/100; fixed-step solvers at the step `h`) and checked against an analytic or independent "
             "answer. **pass**: within the stated tolerance; **refuse**: stopped with a regmech error that names "
             "a component (acceptable); **fail**: a wrong answer (`inaccurate` for fixed-step methods, run "
             "with `tol` = the answer tolerance of their Richardson error estimate), a NaN, an error naming no "
             "component, a non-regmech exception, or the time limit (a run that would hang). The CI-sized "
             "versions run in `tests/hard/`.", ""]
    by = {(o.case, o.solver): o for o in outcomes}
    mark = {"pass": "pass", "refuse": "refuse", "fail": "**FAIL**"}
    hdr = ["case"] + [f"`{s}`" for s in solvers]
    lines += ["## Overview", "", "| " + " | ".join(hdr) + " |", "|" + "---|" * len(hdr)]
    for c in cases:
        row = [c.key]
        for s in solvers:
            o = by.get((c.key, s))
            row.append("-" if o is None else mark[o.verdict] + (" (t)" if "time limit" in o.reason else ""))
        lines.append("| " + " | ".join(row) + " |")
    lines += ["", "(t): stopped by the time limit.", ""]
    for group in dict.fromkeys(c.group for c in cases):
        lines += [f"## {group[0].upper() + group[1:]}", ""]
        for c in [c for c in cases if c.group == group]:
            lines += [f"### {c.key}: {c.title}", "",
                      f"Horizon {c.t_end[size]:g} s, output every {c.dt_out[size]:g} s; adaptive solvers at rtol "
                      f"{c.rtol:g}, fixed-step at h = {c.h.get(size, c.dt_out[size]):g} s"
                      + (f", time limit {c.limits[size]:g} s." if size in c.limits else ".")
                      + (f" {c.note}." if c.note else ""), "",
                      "| solver | verdict | time | measured | reason |", "|---|---|---|---|---|"]
            for s in solvers:
                o = by.get((c.key, s))
                if o is None:
                    continue
                meas = "-" if not math.isfinite(o.value) else f"{o.value:.1e}"
                t = f"{o.wall_s:.2f} s" if math.isfinite(o.wall_s) else "-"
                lines.append(f"| `{s}` | {mark[o.verdict]} | {t} | {meas} | {o.reason.replace('|', '/')} |")
            lines.append("")
    return "\n".join(lines)


__all__ = ["HardCase", "HardOutcome", "Check", "all_cases", "get_case", "run_case", "run_cases", "hard_markdown",
           "CI", "FULL"]
