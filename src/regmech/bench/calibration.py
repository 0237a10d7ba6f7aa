"""Calibration of the accuracy contract: the global error each solver achieves against the accuracy asked for.

For every *case* (the library scenes at benchmark size, the 1000- and
10000-car trains left out, and every hard case at CI size), every solver and
every accuracy ``a`` of ``LEVELS`` (a subset per solver, ``levels_for``), one
run ``model.simulate(t_end, dt_out, solver=s, accuracy=a)``. Its outcome:

* ``met``: it returned and its *achieved* error is at most ``a``;
* ``broken``: it returned and the achieved error exceeds ``a`` by more than the
  reference's resolution (a broken promise);
* ``unresolved``: the achieved error exceeds ``a`` but not by the reference's
  resolution (the two references' difference): the reference cannot judge it
  (fuzz seed 72: a model whose rotational speeds stay at rest, 1e-17 rad/s of
  round-off against the measure's floor of 1e-12, where the references
  differ by 1.1e-4 of that floor);
* ``refused``: it raised a regmech error (``AccuracyError`` or another refusal that
  names the component);
* ``limit``: it hit the time limit per run; ``crash``: anything else (a bug).

Achieved error: the contract's own measure (``solvers.accuracy``): max over
the output instants and the state signals (position and speed of every mass,
internal states) of ``|run - reference|`` over the range of the reference's
signals of that kind. References: the closed form of the linear chains of
the hard cases (``linear_ref``, 30 digits on stretched spectra) and of the
other cases whose answer covers every state; otherwise the first of
``REFERENCE_METHODS`` that succeeds, cross-checked by the next one (their
difference, in the same measure, is the reference's resolution, reported per
case). References are cached in ``<cache>/cal-<case>-<hash>.npz``.

Times: ``stats.wall_time`` of the run (every run of the contract, compile
excluded) and ``stats.extra["wall_time_main"]`` (the returned run alone:
what the same settings cost without the check).

``auto``: also run at every level, and compared per cell with the fastest
solver that met the accuracy in the same campaign (``auto_cells``); cells
where auto takes more than ``AUTO_TARGET`` times that are re-timed by
alternating runs (``retime``), medians of ``RETIME_RUNS``.
"""

from __future__ import annotations

import csv
import hashlib
import json
import math
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from .guard import RunTimeout, classify_error, first_line, names_a_component, time_limit

LEVELS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
#: solvers run at every level; the others at 1e-2, 1e-4, 1e-6 (the low-order ones at fewer, ``LOW_ORDER``)
CORE = ("ida", "scipy:DOP853", "scipy:Radau", "scipy:LSODA", "auto")
SOLVERS = ("auto", "ida", "expm", "rk4", "abm", "euler", "convolution", "scipy:RK45", "scipy:RK23", "scipy:DOP853",
           "scipy:Radau", "scipy:BDF", "scipy:LSODA", "dopri5", "dop853")
#: the auto choice's time over the fastest solver that met the accuracy: the target
AUTO_TARGET = 1.5
AUTO_LEVELS = (1e-2, 1e-4, 1e-6)
RETIME_RUNS = 3
#: (solver, options) of the numerical references, in order of preference
REFERENCE_METHODS = (("scipy:DOP853", {"rtol": 1e-12, "atol": 1e-14}),
                     ("scipy:Radau", {"rtol": 1e-11, "atol": 1e-13}),
                     ("ida", {"rtol": 1e-11, "atol": 1e-13, "native": False}))     # not the compiled path under test


#: low-order methods: only where they can finish within the time limit (euler, order 1; convolution and RK23,
#: order 2 and 3, need 10^4-10^5 steps per second of motion at 1e-6)
LOW_ORDER = {"euler": (1e-2,), "convolution": (1e-2, 1e-4), "scipy:RK23": (1e-2, 1e-4)}


def levels_for(solver: str) -> tuple:
    if solver in LOW_ORDER:
        return LOW_ORDER[solver]
    return LEVELS if solver in CORE else (1e-2, 1e-4, 1e-6)


@dataclass
class CalCase:
    key: str
    group: str                       # "library" or "hard"
    title: str
    build: Callable                  # () -> model
    t_end: float
    dt_out: float
    exact: Callable | None = None    # grid -> {signal: values} covering every state signal, or None

    def grid(self):
        from regmech.solvers.common import output_grid
        return output_grid(0.0, self.t_end, self.dt_out)


def library_cases() -> list[CalCase]:
    from regmech.library import chain_drive
    from .scenes import all_scenes
    out = []
    for sc in all_scenes():
        if sc.key in ("train_1000", "train_10000"):
            continue
        out.append(CalCase(sc.key, "library", sc.title, sc.build, sc.t_end, sc.dt_out))
    out.append(CalCase("chain_drive_5", "library", "roller chain span, 5 links (6 coordinates each), polygonal action",
                       lambda: chain_drive(n_links=5), 0.02, 1e-4))
    return out


def hard_cases() -> list[CalCase]:
    from . import hard_models as H
    from .hard import CI, all_cases
    makers = {"stretched_1e3": lambda: H.stretched_chain(1e3), "stretched_1e5": lambda: H.stretched_chain(1e5),
              "stretched_1e7": lambda: H.stretched_chain(1e7), "near_rigid_shaft": H.near_rigid_chain,
              "inertia_ratio_1e8": H.inertia_ratio_chain, "tiny_mass": H.tiny_mass_chain}
    out = []
    for hc in all_cases():
        exact = None
        if hc.key in makers:
            exact = _chain_exact(makers[hc.key])
        elif hc.key == "gear_1_1000":
            exact = _answer_exact(H.gear_1_1000)
        out.append(CalCase(hc.key, "hard", hc.title, lambda hc=hc: hc.build(CI)[0], hc.t_end[CI], hc.dt_out[CI],
                           exact))
    return out


def _chain_exact(maker):
    def exact(grid):
        chain, _ = maker()
        w = chain.frequencies()
        spread = w[-1] / w[w > 1e-9 * w[-1]].min()
        x, v = chain.exact(grid, digits=30 if spread > 1e4 else None)
        pos, vel = ("s", "v") if chain.translational else ("phi", "w")
        out = {f"{nm}.{pos}": x[:, i] for i, nm in enumerate(chain.names)}
        out.update({f"{nm}.{vel}": v[:, i] for i, nm in enumerate(chain.names)})
        return out
    return exact


def _answer_exact(maker):
    def exact(grid):
        _, answer = maker()
        return answer(grid)
    return exact


def all_cases() -> list[CalCase]:
    return hard_cases() + library_cases()


# ------------------------------------------------------------------------------ references
@dataclass
class Reference:
    key: str
    signals: list
    values: np.ndarray               # (grid, signals)
    method: str
    resolution: float                # cross-check difference in the contract's measure (nan: none)
    events: list = field(default_factory=list)   # (t, component, old, new) of the primary


def _labels(model):
    from regmech.solvers.accuracy import result_state_labels
    return result_state_labels(model.compile())


def _measure(values, ref_values, labels):
    """The contract's measure of a run against the reference: largest scaled difference, a kind at rest in both
    left out where they agree (``richardson.clear_at_rest``, as the contract's own estimate does)."""
    from regmech.solvers.richardson import kind_scales, largest_difference
    value, _, i, _ = largest_difference(values, ref_values, kind_scales(labels, ref_values), labels)
    if not math.isfinite(value):
        return math.inf, ""
    return value, labels[i].signal


def _cache_path(case, cache_dir, methods=REFERENCE_METHODS) -> Path:
    import regmech
    spec = json.dumps({"key": case.key, "t_end": case.t_end, "dt_out": case.dt_out, "exact": case.exact is not None,
                       "methods": [[s, sorted(o.items())] for s, o in methods],
                       "regmech": regmech.__version__}, sort_keys=True)
    return Path(cache_dir) / f"cal-{case.key}-{hashlib.sha256(spec.encode()).hexdigest()[:16]}.npz"


def reference(case: CalCase, cache_dir=None, limit: float = 300.0, log=print, methods=REFERENCE_METHODS) -> Reference:
    from regmech.solvers.accuracy import state_matrix
    from .reference import default_cache_dir
    cache_dir = default_cache_dir() if cache_dir is None else Path(cache_dir)
    path = _cache_path(case, cache_dir, methods)
    if path.exists():
        with np.load(path, allow_pickle=False) as d:
            meta = json.loads(str(d["meta"]))
            return Reference(case.key, meta["signals"], np.asarray(d["values"]), meta["method"],
                             meta["resolution"], [tuple(e) for e in meta["events"]])
    model = case.build()
    labels = _labels(model)
    grid = case.grid()
    signals = [lab.signal for lab in labels]
    ref = None
    if case.exact is not None:
        ans = case.exact(grid)
        if all(s in ans for s in signals):
            ref = Reference(case.key, signals, np.column_stack([ans[s] for s in signals]), "closed form", 0.0)
    if ref is None:
        got = []
        for solver, opts in methods:
            if len(got) == 2:
                break
            t0 = time.perf_counter()
            try:
                with time_limit(limit):
                    res = case.build().simulate(case.t_end, dt_out=case.dt_out, solver=solver, **opts)
                got.append((f"{solver} " + " ".join(f"{k}={v:g}" for k, v in opts.items()),
                            state_matrix(res, labels, grid),
                            [(float(e.t), e.component, int(e.old_mode), int(e.new_mode)) for e in res.events]))
                log(f"  reference {case.key}: {solver} {time.perf_counter() - t0:.1f} s")
            except (Exception, RunTimeout) as exc:       # noqa: BLE001 - the next method is tried
                log(f"  reference {case.key}: {solver} failed: {first_line(exc, 160)}")
        if not got:
            raise RuntimeError(f"no reference for calibration case {case.key}")
        res_m = _measure(got[1][1], got[0][1], labels)[0] if len(got) > 1 else math.nan
        ref = Reference(case.key, signals, got[0][1], got[0][0], res_m, got[0][2])
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, values=ref.values, meta=np.array(json.dumps({"signals": ref.signals, "method": ref.method,
                                                               "resolution": ref.resolution,
                                                               "events": ref.events})))
    os.replace(tmp, path)
    return ref


# ------------------------------------------------------------------------------ runs
@dataclass
class CalRecord:
    case: str
    group: str
    solver: str
    accuracy: float
    status: str                      # met | broken | unresolved | refused | limit | crash
    used: str = ""                   # the solver actually used (auto's choice)
    wall: float = math.nan           # stats.wall_time: every run of the contract
    main: float = math.nan           # the returned run alone
    estimate: float = math.nan
    achieved: float = math.nan
    worst: str = ""
    same_path: str = ""              # events: same path as the reference ("yes"/"no"/"" without events)
    attempts: int = 0
    settings: str = ""
    reason: str = ""


def run_cell(case: CalCase, ref: Reference, solver: str, accuracy: float, limit: float) -> CalRecord:
    from regmech.solvers.accuracy import state_matrix
    from regmech.solvers.common import output_grid  # noqa: F401 (grid via the case)
    rec = CalRecord(case.key, case.group, solver, accuracy, "crash")
    model = case.build()
    t0 = time.perf_counter()
    try:
        with time_limit(limit):
            res = model.simulate(case.t_end, dt_out=case.dt_out, solver=solver, accuracy=accuracy)
    except (Exception, RunTimeout) as exc:      # noqa: BLE001 - classified
        rec.wall = time.perf_counter() - t0
        status, reason = classify_error(exc, model)
        if status == "error":
            rec.status = "refused"
            if not names_a_component(str(exc), model):
                reason = "(names no component) " + reason
        elif status == "timeout":
            rec.status = "limit"
        rec.reason = reason
        return rec
    st = res.stats
    rec.used = st.solver
    rec.wall = st.wall_time
    rec.main = st.extra.get("wall_time_main", st.wall_time)
    rec.estimate = st.error_estimate if st.error_estimate is not None else math.nan
    rec.attempts = int(st.extra.get("attempts", 0))
    rec.settings = ", ".join(f"{k}={v:.3g}" for k, v in (st.extra.get("settings") or {}).items())
    if st.extra.get("auto_reason"):
        rec.reason = st.extra["auto_reason"]
    labels = _labels(model)
    if [lab.signal for lab in labels] != ref.signals:
        rec.status, rec.reason = "crash", "state signals differ from the reference's"
        return rec
    rec.achieved, rec.worst = _measure(state_matrix(res, labels, case.grid()), ref.values, labels)
    if ref.events or res.events:
        from regmech.result import Event
        from regmech.solvers.accuracy import match_events
        m = match_events([Event(*e) for e in ref.events], res.events)
        rec.same_path = "yes" if m.same_path else "no"
    rec.status = verdict(rec.achieved, accuracy, ref.resolution)
    return rec


#: the outcomes of a returned run
RETURNED = ("met", "broken", "unresolved")
#: every outcome (the columns of the reports)
OUTCOMES = RETURNED + ("refused", "limit", "crash")
#: the outcomes the reports list run by run
LISTED = ("broken", "crash", "unresolved")


def verdict(achieved: float, accuracy: float, resolution: float) -> str:
    """``met`` (achieved <= accuracy), ``broken`` (beyond it by more than the reference's resolution) or
    ``unresolved`` (beyond it by no more than what the reference itself is uncertain by)."""
    if achieved <= accuracy:
        return "met"
    if math.isfinite(resolution) and achieved - resolution <= accuracy:
        return "unresolved"
    return "broken"


def _fields():
    return [f for f in CalRecord.__dataclass_fields__]


def load_records(path: Path) -> list[CalRecord]:
    if not Path(path).exists():
        return []
    out = []
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            kw = {}
            for name, f in CalRecord.__dataclass_fields__.items():
                val = row.get(name, "")
                if f.type in ("float",):
                    kw[name] = float(val) if val not in ("", "nan") else math.nan
                elif f.type in ("int",):
                    kw[name] = int(float(val)) if val else 0
                else:
                    kw[name] = val
            out.append(CalRecord(**kw))
    return out


def save_records(records, path: Path) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    with open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=_fields())
        w.writeheader()
        for r in records:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in asdict(r).items()})
    os.replace(tmp, path)


def run_calibration(cases, solvers, csv_path: Path, limit: float = 30.0, levels=None, cache_dir=None,
                    log=print, merge=True) -> list[CalRecord]:
    """Every (case, solver, level) not yet in ``csv_path`` (with ``merge``); the CSV is rewritten after each."""
    records = load_records(csv_path) if merge else []
    done = {(r.case, r.solver, r.accuracy) for r in records}
    for case in cases:
        ref = reference(case, cache_dir, log=log)
        for solver in solvers:
            for acc in (levels or levels_for(solver)):
                if acc not in levels_for(solver) or (case.key, solver, acc) in done:
                    continue
                rec = run_cell(case, ref, solver, acc, limit)
                log(f"{case.key:24s} {solver:14s} {acc:7.0e} {rec.status:8s} wall {rec.wall:7.3f} s  est "
                    f"{rec.estimate:8.2g} achieved {rec.achieved:8.2g} {rec.used} {rec.settings} "
                    f"{first_line(rec.reason, 120) if rec.status != 'met' else ''}")
                records = [r for r in records if (r.case, r.solver, r.accuracy) != (case.key, solver, acc)]
                records.append(rec)
                save_records(records, csv_path)
    return records


# ------------------------------------------------------------------------------ auto against the fastest
def auto_cells(records) -> list[dict]:
    """Per (case, level of ``AUTO_LEVELS``): auto's outcome and time against the fastest solver that met
    the accuracy (named solvers only)."""
    by = {}
    for r in records:
        by.setdefault((r.case, r.accuracy), []).append(r)
    out = []
    for (case, acc), rs in sorted(by.items()):
        if acc not in AUTO_LEVELS:
            continue
        auto = next((r for r in rs if r.solver == "auto"), None)
        met = [r for r in rs if r.solver != "auto" and r.status == "met"]
        best = min(met, key=lambda r: r.wall) if met else None
        ratio = auto.wall / best.wall if (auto is not None and best is not None and auto.status == "met") else math.nan
        out.append({"case": case, "accuracy": acc, "auto": auto, "best": best, "ratio": ratio})
    return out


def retime(cases_by_key, cell, runs=RETIME_RUNS, limit=60.0) -> tuple[float, float]:
    """Medians of alternating runs of auto and of the fastest solver of a cell (noise of a loaded machine)."""
    case = cases_by_key[cell["case"]]
    ta, tb = [], []
    for _ in range(runs):
        for solver, acc_list in (("auto", ta), (cell["best"].solver, tb)):
            model = case.build()
            with time_limit(limit):
                res = model.simulate(case.t_end, dt_out=case.dt_out, solver=solver, accuracy=cell["accuracy"])
            acc_list.append(res.stats.wall_time)
    return float(np.median(ta)), float(np.median(tb))




# ------------------------------------------------------------------------------ report
def _g(x, fmt="{:.2g}"):
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else fmt.format(x)


def _median(values):
    vals = sorted(v for v in values if v is not None and math.isfinite(v))
    return float(np.median(vals)) if vals else math.nan


def summary_rows(records, solvers=SOLVERS):
    """Per solver: counts of the outcomes, and the estimate, the achieved error and the cost of the check."""
    rows = []
    for s in solvers:
        rs = [r for r in records if r.solver == s]
        if not rs:
            continue
        ok = [r for r in rs if r.status in RETURNED]
        rows.append({
            "solver": s, "runs": len(rs), **{k: sum(r.status == k for r in rs)
                                              for k in OUTCOMES},
            "est_over_acc": _median([r.estimate / r.accuracy for r in ok]),
            "achieved_over_acc_max": max((r.achieved / r.accuracy for r in ok), default=math.nan),
            # only where the error is not round-off: achieved and estimate near 1e-15 say nothing of the estimate
            "achieved_over_est_max": max((r.achieved / r.estimate for r in ok
                                          if r.estimate > 0 and r.achieved >= 1e-3 * r.accuracy), default=math.nan),
            "retried": sum(r.attempts > 1 for r in ok),
            "cost": _median([r.wall / r.main for r in ok if r.main > 0]),
            "other_path": sum(r.same_path == "no" for r in ok),
        })
    return rows


def plot_calibration(records, path, solvers=SOLVERS) -> None:
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8.5, 7))
    markers = "os^vD<>phX*P8"
    named = [s for s in solvers if any(r.solver == s for r in records)]
    for k, s in enumerate(named):
        rs = [r for r in records if r.solver == s and r.status in RETURNED]
        if not rs:
            continue
        jitter = 10 ** (0.12 * (k - len(named) / 2) / len(named))      # side by side at each level
        x = [r.accuracy * jitter for r in rs]
        y = [max(r.achieved, 1e-16) for r in rs]
        ax.scatter(x, y, s=18, marker=markers[k % len(markers)], label=s, alpha=0.75,
                   color=plt.cm.tab20(k % 20 / 20.0))
    lo, hi = 3e-7, 3e-2
    ax.plot([lo, hi], [lo, hi], "k-", lw=1.2, label="contract (achieved = requested)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("requested accuracy")
    ax.set_ylabel("achieved error (contract measure, against the reference)")
    ax.set_title("Calibration: every returned run; points above the line would be broken promises")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)   # beside: not over runs
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def calibration_markdown(records, cases, refs, machine: dict, limit: float, wall_total: float, plot_name: str,
                         retimed: dict | None = None, command: str = "regmech bench --calibration") -> str:
    from .machine import machine_line
    lines = ["# Calibration of the accuracy contract", "",
             f"Machine: {machine_line(machine)}. Command: `{command}`; time limit {limit:g} s per run; total "
             f"{wall_total / 60:.1f} min. The machine is shared (2 cores, other jobs running): absolute times vary "
             f"by up to 2x between runs, ratios within a cell less.", "",
             "Every solver is asked for `accuracy=a` on every case (library scenes at benchmark size without the "
             "1000- and 10000-car trains, hard cases at CI size) and the returned run is compared with the case's "
             "reference in the contract's own measure: max over the output instants and the state signals "
             "(position and speed of every mass, internal states) of the error over the range of the reference's "
             "signals of that kind. **met**: achieved <= a; **broken**: achieved > a by more than the reference's "
             "resolution (a broken promise); **unresolved**: achieved > a within the reference's resolution; "
             "**refused**: a regmech error (`AccuracyError`, or a solver's own refusal naming the component); "
             "**limit**: the time limit. Definitions: `regmech.bench.calibration`, `regmech.solvers.accuracy`.", "",
             f"![calibration]({plot_name})", "",
             "## Promises kept, by solver", "",
             "| solver | runs | met | broken | unresolved | refused | limit | crash | median estimate / a | "
             "max achieved / a | max achieved / estimate | retried | other path | time with / without the check |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for row in summary_rows(records):
        lines.append(f"| `{row['solver']}` | {row['runs']} | {row['met']} | **{row['broken']}** | "
                     f"{row['unresolved']} | {row['refused']} | "
                     f"{row['limit']} | {row['crash']} | {_g(row['est_over_acc'])} | "
                     f"{_g(row['achieved_over_acc_max'])} | {_g(row['achieved_over_est_max'])} | {row['retried']} | "
                     f"{row['other_path']} | {_g(row['cost'], '{:.2f}')} |")
    lines += ["", "*max achieved / estimate*: over the runs whose achieved error is at least 1e-3 a (below, both are round-off); above 1 the estimate was low, though the accuracy was met. *retried*: runs that needed more than one pair (adaptive) or step (fixed-step); *other path*: "
              "returned runs whose friction events took another path than the reference's (their states are "
              "still within a); *time with / without*: median over the returned runs of the wall time of the "
              "whole contract (every run it made) over that of the returned run alone (the same settings "
              "without the check).", ""]
    # time with and without the check, per case for the default solvers
    lines += ["## Time with and without the accuracy check", "",
              "Wall time of the contract (all its runs) and of the returned run alone, at a = 1e-4 "
              "(compile excluded).", "",
              "| case | " + " | ".join(f"`{s}` with / without" for s in ("ida", "expm", "scipy:DOP853", "rk4")) + " |",
              "|---|" + "---|" * 4]
    by = {(r.case, r.solver, r.accuracy): r for r in records}
    for case in cases:
        cells = []
        for s in ("ida", "expm", "scipy:DOP853", "rk4"):
            r = by.get((case.key, s, 1e-4))
            cells.append("-" if r is None or r.status not in RETURNED else
                         f"{r.wall * 1e3:.0f} / {r.main * 1e3:.0f} ms")
        lines.append(f"| {case.key} | " + " | ".join(cells) + " |")
    # auto
    cells = auto_cells(records)
    if cells:
        lines += ["", "## `solver=\"auto\"` against the fastest solver that met the accuracy", "",
                  f"Per case and accuracy: auto's choice and time, the fastest named solver that met the accuracy "
                  f"in the same campaign and its time, and the ratio (target <= {AUTO_TARGET:g}). Cells above the "
                  f"target were re-timed by alternating runs (median of {RETIME_RUNS}; `re-timed` column).", "",
                  "| case | a | auto | time | fastest met | time | ratio | re-timed |",
                  "|---|---|---|---|---|---|---|---|"]
        over = 0
        for cell in cells:
            a, b = cell["auto"], cell["best"]
            rt = (retimed or {}).get((cell["case"], cell["accuracy"]))
            ratio = rt[0] / rt[1] if rt else cell["ratio"]
            if math.isfinite(ratio) and ratio > AUTO_TARGET:
                over += 1
            auto_txt = "-" if a is None else (f"`{a.used}`" if a.status == "met" else f"{a.status} ({a.used or '-'})")
            lines.append(f"| {cell['case']} | {cell['accuracy']:.0e} | {auto_txt} | "
                         f"{'-' if a is None else _g(a.wall * 1e3, '{:.0f} ms')} | "
                         f"{'-' if b is None else '`' + b.solver + '`'} | "
                         f"{'-' if b is None else _g(b.wall * 1e3, '{:.0f} ms')} | {_g(cell['ratio'], '{:.2f}')} | "
                         f"{'-' if not rt else f'{rt[0] * 1e3:.0f} / {rt[1] * 1e3:.0f} ms = {ratio:.2f}'} |")
        n_auto = sum(1 for c in cells if c["auto"] is not None)
        n_met = sum(1 for c in cells if c["auto"] is not None and c["auto"].status == "met")
        reachable = sum(1 for c in cells if c["auto"] is not None and c["best"] is not None)
        lines += ["", f"auto met the accuracy in {n_met} of {n_auto} cells ({reachable} cells where some named solver "
                  f"met it; in the others every solver refused); {over} cells above {AUTO_TARGET:g}x the fastest "
                  f"(after re-timing).", ""]
    lines += _auto_rules_text(records)
    lines += ["## References", "", "| case | group | reference | resolution (cross-check, contract measure) |",
              "|---|---|---|---|"]
    for case in cases:
        ref = refs.get(case.key)
        if ref is not None:
            lines.append(f"| {case.key} | {case.group} | {ref.method} | {_g(ref.resolution)} |")
    broken = [r for r in records if r.status in LISTED]
    if broken:
        lines += ["", "## Broken promises, unresolved verdicts and crashes", "",
                  "| case | solver | a | verdict | estimate | achieved | worst | path | settings |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for r in broken:
            lines.append(f"| {r.case} | `{r.solver}` | {r.accuracy:.0e} | {r.status} | {_g(r.estimate)} | "
                         f"{_g(r.achieved)} | {r.worst} | {r.same_path} | {r.settings} {r.reason[:120]} |")
    return "\n".join(lines) + "\n"


def _auto_rules_text(records) -> list[str]:
    """The rules of ``solvers.auto`` beside the figures of this campaign they rest on."""
    by = {(r.case, r.solver, r.accuracy): r for r in records}

    def t(case, solver, acc):
        r = by.get((case, solver, acc))
        return "-" if r is None or r.status != "met" else f"{r.wall * 1e3:.0f} ms"

    def pair(case, acc):
        return f"{case} at {acc:.0e}: ida {t(case, 'ida', acc)}, expm {t(case, 'expm', acc)}"

    costs = {row["solver"]: row["cost"] for row in summary_rows(records)}

    def cost(solver):
        return costs.get(solver, math.nan)

    def dop853_wins():
        # the cells (case, accuracy of AUTO_LEVELS) where DOP853 was the fastest named solver that met the accuracy
        won = [c for c in auto_cells(records) if c["best"] is not None and c["best"].solver == "scipy:DOP853"]
        if not won:
            return "it was the fastest in no cell of the auto table"
        shown = "; ".join(f"{c['case']} at {c['accuracy']:.0e} ({c['best'].wall * 1e3:.0f} ms, ida "
                          f"{t(c['case'], 'ida', c['accuracy'])})" for c in won[:4])
        more = f" and {len(won) - 4} more" if len(won) > 4 else ""
        return f"it was the fastest in {len(won)} of the auto table's cells: {shown}{more}"
    from regmech.solvers import auto
    return [
        "## The rules of `solver=\"auto\"` and the figures they come from", "",
        f"* **ida by default.** Under the contract `ida` was the fastest solver that met the accuracy in most "
        f"cells of every nonlinear case and of the linear ones that do not oscillate long (vehicle_launch at "
        f"1e-6: ida {t('vehicle_launch', 'ida', 1e-6)}, DOP853 {t('vehicle_launch', 'scipy:DOP853', 1e-6)}; "
        f"coupled_clutches at 1e-6: ida {t('coupled_clutches', 'ida', 1e-6)}, LSODA "
        f"{t('coupled_clutches', 'scipy:LSODA', 1e-6)}; first at 1e-6: ida {t('first', 'ida', 1e-6)}, expm "
        f"{t('first', 'expm', 1e-6)}). scipy:DOP853's rule of the work-precision tables (small models at very tight "
        f"tolerance) did not survive the contract: its check costs {_g(cost('scipy:DOP853'), '{:.2f}')}x a run (median) "
        f"against ida's {_g(cost('ida'), '{:.2f}')}x, and {dop853_wins()}.",
        f"* **expm for a linear model that oscillates longer than its output steps repay** "
        f"(`expm_steps(a) <= K(a) periods(a)`, `K(a) = {auto.EXPM_STEPS_PER_PERIOD:g} + "
        f"{auto.EXPM_STEPS_PER_DECADE:g} log10(1/a)`): {pair('long_horizon', 1e-2)}; {pair('long_horizon', 1e-6)} "
        f"(undamped, 300 periods); {pair('stretched_1e3', 1e-6)} but {pair('stretched_1e3', 1e-2)}; "
        f"{pair('train_10', 1e-6)} but {pair('train_10', 1e-2)}. K grows with the accuracy because a stepping "
        f"method takes more steps per period the tighter it is asked to be; expm's steps grow only with a fast "
        f"sinusoidal input ({pair('chain_drive_5', 1e-6)}: expm's step fell to 4.4e-6 s for the 425 Hz forcing).",
        f"* **expm near the round-off bound** (bound > {auto.NEAR_ROUNDOFF:g} a, and <= a/3): ida's rtol would "
        f"sit at the link-spread limit: {pair('inertia_ratio_1e8', 1e-6)} (ida refused).",
        f"* **expm for large linear models whose steps are within the bounded periods** (more than "
        f"{auto.MODAL_MAX} coordinates, no modal traits: `expm_steps(a) <= K(a) span f_bound max(1, states / "
        f"{auto.EXPM_STATES_REF:g})`, f_bound the Gershgorin bound of the highest frequency; the chains of "
        f"auto_rules.md): {pair('train_100', 1e-4)}; {pair('train_100', 1e-6)}; {pair('train_100', 1e-2)} "
        f"(train_100's RoadLoad keeps ida on its Python callbacks). When ida runs with compiled callbacks "
        f"(`native=True`, auto's ida when numba is installed) the weight is `min(max(1, states / "
        f"{auto.EXPM_STATES_REF:g}), (states / {auto.NATIVE_EXPM_STATES:g})^{auto.NATIVE_EXPM_POWER:g})`: on the "
        f"5 Hz-driven chains of auto_rules.md native ida beat expm in every cell up to 100 inertias (the "
        f"100-inertia chain at 1e-3, dt_out 1e-2: 29 ms against 41 ms under the contract; the old weight chose "
        f"expm) and lost every cell at 1000.",
        f"* **ida's compiled callbacks** (`ida_native`): K(a) is divided by `native_gain(states)` in rule 1 where "
        f"the periods counted are all ida must resolve. The `ida` column of this campaign is ida's Python path "
        f"(`solver=\"ida\"` without `native=True`); auto's ida runs natively where the model allows, so its "
        f"cells can be well below the `ida` column's.",
        "* Misses: the cells of the auto table above the target; a rule for them would rest on one case each.", ""]


def write_calibration_report(records, cases, out_dir: Path, machine=None, limit=30.0, wall_total=0.0,
                             cache_dir=None, retimed=None, command="regmech bench --calibration") -> Path:
    from .machine import machine_info
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    refs = {}
    for case in cases:
        try:
            refs[case.key] = reference(case, cache_dir, log=lambda m: None)
        except Exception:           # noqa: BLE001 - a case without reference is reported without it
            pass
    plot_calibration(records, out_dir / "calibration.png")
    md = calibration_markdown(records, cases, refs, machine or machine_info(), limit, wall_total, "calibration.png",
                              retimed, command)
    path = out_dir / "calibration.md"
    path.write_text(md)
    return path


def run_all(out_dir, csv_path=None, cases=None, solvers=None, limit=30.0, cache_dir=None, merge=True, retime_cells=True,
            log=print, command="regmech bench --calibration") -> Path:
    """The whole campaign: every (case, solver, level) not yet in the CSV, the auto cells above the target
    re-timed, the report (``calibration.md``, ``calibration.png``) written to ``out_dir``."""
    from .machine import machine_info
    out_dir = Path(out_dir)
    csv_path = Path(csv_path) if csv_path is not None else out_dir / "calibration.csv"
    meta_path = csv_path.with_suffix(".meta.json")
    meta = json.loads(meta_path.read_text()) if merge and meta_path.exists() else {}
    cases = all_cases() if cases is None else cases
    t0 = time.perf_counter()
    records = run_calibration(cases, list(solvers or SOLVERS), csv_path, limit=limit, cache_dir=cache_dir, log=log,
                              merge=merge)
    retimed = {tuple(k): v for k, v in meta.get("retimed", [])} if merge else {}
    if retime_cells:
        by_key = {c.key: c for c in cases}
        for cell in auto_cells(records):
            key = (cell["case"], cell["accuracy"])
            if cell["case"] in by_key and math.isfinite(cell["ratio"]) and cell["ratio"] > AUTO_TARGET \
                    and key not in retimed:
                try:
                    retimed[key] = retime(by_key, cell, limit=2 * limit)
                    log(f"re-timed {key}: auto {retimed[key][0]:.3f} s, {cell['best'].solver} {retimed[key][1]:.3f} s")
                except (Exception, RunTimeout) as exc:    # noqa: BLE001 - the campaign's own times stand
                    log(f"re-timing {key} failed: {first_line(exc, 160)}")
    wall = float(meta.get("wall_total", 0.0)) + time.perf_counter() - t0
    meta_path.parent.mkdir(parents=True, exist_ok=True)
    meta_path.write_text(json.dumps({"wall_total": wall, "limit": limit, "machine": machine_info(),
                                     "retimed": [[list(k), list(v)] for k, v in retimed.items()]}))
    shown = [c for c in cases if any(r.case == c.key for r in records)]
    return write_calibration_report(records, shown, out_dir, machine=meta.get("machine") or machine_info(),
                                    limit=limit, wall_total=wall, cache_dir=cache_dir, retimed=retimed,
                                    command=command)


# ------------------------------------------------------------------------------ random drivetrains
#: the cells of the random calibration: (solver, accuracy); auto at 1e-3 is the default call
RANDOM_CELLS = (("auto", 1e-2), ("auto", 1e-3), ("auto", 1e-4), ("ida", 1e-2), ("ida", 1e-4),
                ("scipy:DOP853", 1e-2), ("scipy:DOP853", 1e-4))
#: references of the random drivetrains: two methods of different families at tolerances 1e5 below the
#: tightest accuracy asked (their difference, the resolution, is reported per case)
RANDOM_REFERENCE_METHODS = (("scipy:DOP853", {"rtol": 1e-10, "atol": 1e-12, "max_steps": 400_000}),
                            ("ida", {"rtol": 1e-10, "atol": 1e-12, "native": False}))


def random_cases(n: int = 100, first_seed: int = 0) -> list[CalCase]:
    """``n`` random regular drivetrains of the fuzz generator (``regmech.bench.fuzz.generate_seed``, seeds
    ``first_seed`` ..): every component family, parameters across decades, the fuzz campaign's t_end and
    output grid. The key carries a hash of the model's source, so a changed generator never reuses a cached
    reference."""
    from .fuzz import generate_seed
    out = []
    for seed in range(first_seed, first_seed + n):
        spec = generate_seed(seed)
        tag = hashlib.sha256("\n".join(spec.lines).encode()).hexdigest()[:8]
        out.append(CalCase(f"fuzz_{seed}_{tag}", "random", ", ".join(spec.families), spec.build, spec.t_end,
                           spec.dt_out))
    return out


def run_random(cases, csv_path: Path, limit: float = 30.0, cache_dir=None, log=print, merge=True,
               cells=RANDOM_CELLS) -> list[CalRecord]:
    """Every (case, solver, accuracy) of ``cells`` not yet in ``csv_path``; a case without a reference (both
    reference methods failed or hit the limit) is recorded as such (solver ``reference``, status ``limit``
    or ``refused``) and skipped."""
    records = load_records(csv_path) if merge else []
    done = {(r.case, r.solver, r.accuracy) for r in records}
    for case in cases:
        if all((case.key, s, a) in done for s, a in cells) or (case.key, "reference", 0.0) in done:
            continue
        try:
            ref = reference(case, cache_dir, limit=4 * limit, log=log, methods=RANDOM_REFERENCE_METHODS)
        except Exception as exc:        # noqa: BLE001 - no reference: the case is not judged
            rec = CalRecord(case.key, case.group, "reference", 0.0, "limit", reason=first_line(exc, 200))
            records.append(rec)
            save_records(records, csv_path)
            log(f"{case.key}: no reference ({rec.reason})")
            continue
        for solver, acc in cells:
            if (case.key, solver, acc) in done:
                continue
            rec = run_cell(case, ref, solver, acc, limit)
            log(f"{case.key:24s} {solver:14s} {acc:7.0e} {rec.status:8s} wall {rec.wall:7.3f} s  est "
                f"{rec.estimate:8.2g} achieved {rec.achieved:8.2g} {rec.used} {rec.settings} "
                f"{first_line(rec.reason, 120) if rec.status != 'met' else ''}")
            records.append(rec)
            save_records(records, csv_path)
    return records


def random_markdown(records, cases, machine: dict, limit: float, wall_total: float, command: str,
                    cache_dir=None) -> str:
    """The report of the random calibration (``calibration_random.md``)."""
    from .machine import machine_line
    keys = {c.key for c in cases}
    records = [r for r in records if r.case in keys]
    no_ref = [r for r in records if r.solver == "reference"]
    runs = [r for r in records if r.solver != "reference"]
    judged = sorted({r.case for r in runs})
    lines = ["# Calibration on random drivetrains", "",
             f"Machine: {machine_line(machine)}. Command: `{command}`; time limit {limit:g} s per run; total "
             f"{wall_total / 60:.1f} min (shared machine: times vary by up to 2x).", "",
             f"{len(cases)} random regular drivetrains of the fuzz generator (`regmech.bench.fuzz.generate_seed`, "
             f"seeds {min(int(k.split('_')[1]) for k in keys)} to {max(int(k.split('_')[1]) for k in keys)}: every "
             "component family, parameters across decades, friction, lossy gears, tyres, prescribed motions); each "
             "asked for `accuracy=a` with `auto` (a = 1e-3 is the default call `m.simulate(t_end, dt_out)`), `ida` and "
             "`scipy:DOP853`, and the returned run compared with a reference (scipy:DOP853 at rtol 1e-10, cross-checked "
             "by ida at rtol 1e-10) in the contract's measure (max over the output instants and the state signals "
             "of the error over the range of the reference's signals of that kind). **broken**: achieved error > a "
             "by more than the reference's resolution (the two references' difference); **unresolved**: > a within "
             "that resolution; "
             f"**refused**: a regmech error; **limit**: the time limit. {len(judged)} models judged, "
             f"{len(no_ref)} without a reference (both reference runs failed or hit their limit).", "",
             "| solver | a | runs | met | broken | unresolved | refused | limit | crash | median estimate / a | "
             "max achieved / a | median time with / without the check |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for solver, acc in RANDOM_CELLS:
        rs = [r for r in runs if r.solver == solver and r.accuracy == acc]
        if not rs:
            continue
        ok = [r for r in rs if r.status in RETURNED]
        c = {k: sum(r.status == k for r in rs) for k in OUTCOMES}
        lines.append(f"| `{solver}`{' (default call)' if solver == 'auto' and acc == 1e-3 else ''} | {acc:.0e} | "
                     f"{len(rs)} | {c['met']} | **{c['broken']}** | {c['unresolved']} | {c['refused']} | {c['limit']} | "
                     f"{c['crash']} | "
                     f"{_g(_median([r.estimate / r.accuracy for r in ok]))} | "
                     f"{_g(max((r.achieved / r.accuracy for r in ok), default=math.nan))} | "
                     f"{_g(_median([r.wall / r.main for r in ok if r.main > 0]), '{:.2f}')} |")
    used = {}
    for r in runs:
        if r.solver == "auto" and r.status in RETURNED:
            used[r.used] = used.get(r.used, 0) + 1
    lines += ["", "*time with / without*: wall time of the whole contract (every run it made) over that of the "
              "returned run alone. auto chose: " + ", ".join(f"`{k}` {v}" for k, v in sorted(used.items(),
                                                                                         key=lambda kv: -kv[1]))
              + ".", ""]
    ref_kinds = {}
    for r in runs:
        if r.status == "refused":
            kind = r.reason.split(":")[0][:40]
            ref_kinds.setdefault((r.solver, kind), []).append(r.case.split("_")[1])
    if ref_kinds:
        lines += ["## Refusals", "", "| solver | error | runs | seeds (first 8) |", "|---|---|---|---|"]
        for (solver, kind), seeds in sorted(ref_kinds.items(), key=lambda kv: -len(kv[1])):
            lines.append(f"| `{solver}` | {kind} | {len(seeds)} | {', '.join(sorted(set(seeds), key=int)[:8])} |")
        lines.append("")
    bad = [r for r in runs if r.status in LISTED]
    lines += ["## Broken promises, unresolved verdicts and crashes", ""]
    if not bad:
        lines += ["None.", ""]
    else:
        lines += ["| case | solver | a | verdict | estimate | achieved | worst | path | settings, reason |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for r in bad:
            lines.append(f"| {r.case} | `{r.solver}` | {r.accuracy:.0e} | {r.status} | {_g(r.estimate)} | "
                         f"{_g(r.achieved)} | {r.worst} | {r.same_path} | {r.settings} {r.reason[:120]} |")
        lines.append("")
    res = []
    for case in cases:
        try:
            res.append(reference(case, cache_dir, log=lambda m: None, methods=RANDOM_REFERENCE_METHODS).resolution)
        except Exception:       # noqa: BLE001 - reported as missing above
            pass
    finite = [x for x in res if math.isfinite(x)]
    if finite:
        lines += [f"Reference resolution (the two references' difference, contract measure): median "
                  f"{_g(float(np.median(finite)))}, max {_g(max(finite))} over {len(finite)} models.", ""]
    return "\n".join(lines) + "\n"


__all__ = ["LEVELS", "SOLVERS", "CalCase", "all_cases", "library_cases", "hard_cases", "reference", "run_cell",
           "run_calibration", "auto_cells", "retime", "load_records", "save_records", "write_calibration_report",
           "run_all", "random_cases", "run_random", "random_markdown", "RANDOM_CELLS"]


if __name__ == "__main__":  # pragma: no cover - ``python -m regmech.bench.calibration [options]``
    import sys

    from .cli import main
    # the same campaign as ``regmech bench --calibration [options]`` (options: --scenes, --solvers, --out, ...)
    sys.exit(main(["--calibration", *sys.argv[1:]]))
