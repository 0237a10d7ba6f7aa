"""Report of a work-precision run: CSV, Markdown tables, log-log plots.

*Time to reach an error level E* of a solver on a scene is the smallest
median wall time among its runs whose ``err_max_rel <= E`` (and, with
stick/slip, whose mode changes all matched the reference's). The *ratio* of
a solver at E is that time over the same quantity of the best scipy method
at E (measured in the same run); below 1 the solver is faster than every
scipy method at that accuracy.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

from .metrics import Errors
from .runner import CHEAP_BELOW_S, CHEAP_REPEATS, REPEAT_ABOVE_S

#: error levels of the matched-accuracy tables
LEVELS = (1e-2, 1e-4, 1e-6, 1e-8)
#: errors above this are drawn at it (a run that went unstable without raising)
PLOT_CEILING = 1e2


# --------------------------------------------------------------------------- numbers
def _fmt_time(s: float) -> str:
    if not math.isfinite(s):
        return "-"
    return f"{s * 1e3:.3g} ms" if s < 1.0 else f"{s:.3g} s"


def _fmt_err(e: float) -> str:
    return "-" if e is None or not math.isfinite(e) else f"{e:.1e}"


def accurate_enough(rec, level: float, stick_slip: bool) -> bool:
    if not rec.ok or not (rec.err_max_rel <= level):
        return False
    return not (stick_slip and rec.events_unmatched)


def time_to_reach(records, solver: str, level: float, stick_slip: bool) -> tuple[float, object]:
    """(time, record) of the fastest run of ``solver`` with error <= level; (inf, None) if none."""
    best = (math.inf, None)
    for r in records:
        if r.solver == solver and accurate_enough(r, level, stick_slip) and r.wall_s < best[0]:
            best = (r.wall_s, r)
    return best


def best_scipy(records, level: float, stick_slip: bool) -> tuple[float, str]:
    solvers = sorted({r.solver for r in records if r.solver.startswith("scipy:")})
    best = (math.inf, "")
    for s in solvers:
        t, _ = time_to_reach(records, s, level, stick_slip)
        if t < best[0]:
            best = (t, s)
    return best


def matched_accuracy(records, stick_slip: bool, levels=LEVELS) -> tuple[list[dict], list[float]]:
    """Rows ``{solver, level: (time, ratio, setting)}`` for the levels some scipy method reached."""
    solvers = list(dict.fromkeys(r.solver for r in records))
    used = [lv for lv in levels if math.isfinite(best_scipy(records, lv, stick_slip)[0])]
    rows = []
    for s in solvers:
        row = {"solver": s}
        for lv in used:
            t, rec = time_to_reach(records, s, lv, stick_slip)
            ref_t, _ = best_scipy(records, lv, stick_slip)
            row[lv] = (t, t / ref_t if math.isfinite(t) else math.inf, rec.option + "=" + f"{rec.value:g}" if rec else "")
        rows.append(row)
    return rows, used


# --------------------------------------------------------------------------- files
def write_csv(records, path: Path) -> None:
    rows = [r.row() for r in records]
    if not rows:
        return
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for row in rows:
            w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in row.items()})


def read_csv(path: Path) -> list:
    """``RunRecord``s back from a CSV written by ``write_csv`` (to merge a partial re-run)."""
    import dataclasses
    from .runner import RunRecord
    kinds = {f.name: f.type for f in dataclasses.fields(RunRecord)}
    out = []
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            vals = {}
            for k, v in row.items():
                kind = kinds.get(k, "str")
                if kind in ("float", "int") and v in ("", "None"):
                    continue                      # not recorded: the field's default
                vals[k] = float(v) if kind == "float" else int(float(v)) if kind == "int" else v
            out.append(RunRecord(**vals))
    return out


def plot_scene(records, scene, reference, path: Path) -> bool:
    """Error vs median wall time, log-log, one line per solver; False when matplotlib is missing."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig, ax = plt.subplots(figsize=(8, 5.5))
    markers = "os^vD<>phX*P"
    colors = list(plt.cm.tab10.colors) + ["black", "darkgoldenrod"]     # 12 distinct: one per solver
    solvers = list(dict.fromkeys(r.solver for r in records))
    clipped = False
    for i, s in enumerate(solvers):
        pts = sorted((r.wall_s, r.err_max_rel) for r in records
                     if r.solver == s and r.ok and r.err_max_rel > 0 and math.isfinite(r.err_max_rel))
        if not pts:
            continue
        if any(p[1] > PLOT_CEILING for p in pts):
            clipped = True      # a run that went unstable without an error: drawn at the ceiling
            pts = [(p[0], min(p[1], PLOT_CEILING)) for p in pts]
        style = "-" if s.startswith("scipy:") else "--" if s in ("euler", "rk4", "abm") else "-"
        lw = 1.0 if s.startswith("scipy:") else 2.0
        ax.loglog([p[0] for p in pts], [p[1] for p in pts], style, marker=markers[i % len(markers)], lw=lw,
                  ms=5, label=s, color=colors[i % len(colors)])
    if reference is not None and reference.cross is not None and reference.cross.max_rel > 0:
        ax.axhline(reference.cross.max_rel, color="0.5", ls=":", lw=1,
                   label="reference cross-check (bound)")
    if clipped:
        ax.axhline(PLOT_CEILING, color="r", ls="--", lw=0.8, label=f"errors above {PLOT_CEILING:g} drawn here")
    ax.set_xlabel("wall time after compile, median [s]")
    ax.set_ylabel("max error relative to signal range")
    ax.set_title(f"{scene.key}: {scene.title}", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)   # beside: not over curves
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return True


# --------------------------------------------------------------------------- markdown
def _md_table(header, rows) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return out


def _ratio_cell(t, ratio, setting):
    if not math.isfinite(t):
        return "-"
    return f"{_fmt_time(t)} (x{ratio:.2g}, {setting})"


def scene_markdown(scene, records, reference, ref_error, plot_name) -> list[str]:
    lines = [f"### {scene.key}: {scene.title}", "", f"Scene: `{scene.describe()}`; compared signals: "
             + ", ".join(f"`{s}`" for s in scene.signal_names()) + "."]
    if scene.note:
        lines += ["", scene.note]
    if reference is not None:
        lines += ["", f"Reference: {reference.summary()}" + (f" ({reference.note})" if reference.note else "")
                  + ("" if not reference.cached else " [cached]") + "."]
    else:
        lines += ["", f"Reference: unavailable ({ref_error}); runs are listed without errors."]
    comp = {}
    for r in records:
        if math.isfinite(r.compile_s):
            comp.setdefault(r.solver, (r.build_s, r.compile_s))
    if comp:
        cs = sorted(c for _, c in comp.values())
        bs = sorted(b for b, _ in comp.values())
        lines += ["", f"Model build {_fmt_time(bs[len(bs) // 2])}, compile {_fmt_time(cs[len(cs) // 2])} "
                      f"(medians over the {len(cs)} fresh builds, one per solver; not included in the times below)."]
    rows, used = matched_accuracy(records, scene.stick_slip)
    if used:
        lines += ["", "Time to reach a max relative error, and its ratio to the best scipy method at that "
                      "error (same run):", ""]
        hdr = ["solver"] + [f"err <= {lv:g}" for lv in used]
        body = [[f"`{row['solver']}`"] + [_ratio_cell(*row[lv]) for lv in used] for row in rows]
        lines += _md_table(hdr, body)
    if plot_name:
        lines += ["", f"![work-precision {scene.key}]({plot_name})"]
    lines += ["", "<details><summary>all runs</summary>", ""]
    hdr = ["solver", "setting", "status", "wall", "first run", "solver clock", "steps", "RHS/res.", "events",
           "max rel err", "final err"]
    if scene.stick_slip:
        hdr += ["switch err [s]", "unmatched"]
    if scene.msl is not None:
        hdr += ["vs MSL"] + (["MSL switch [s]"] if scene.msl.modes else [])
    body = []
    for r in records:
        row = [f"`{r.solver}`", f"{r.option}={r.value:g}", r.status if r.ok else f"**{r.status}**",
               _fmt_time(r.wall_s), _fmt_time(r.first_s), _fmt_time(r.solver_s), r.steps or "-",
               r.rhs_calls or "-", r.events, _fmt_err(r.err_max_rel), _fmt_err(r.err_final)]
        if scene.stick_slip:
            row += [_fmt_err(r.err_switch_s), r.events_unmatched]
        if scene.msl is not None:
            row += [_fmt_err(r.msl_max_rel)] + ([_fmt_err(r.msl_switch_s)] if scene.msl.modes else [])
        body.append(row)
    lines += _md_table(hdr, body)
    lines += ["", "</details>", ""]
    return lines


def issue3_markdown(records, reference) -> list[str]:
    """CoupledClutches at rtol 1e-6: IDA (time after compile, compile time) vs the scipy ODE-form drivers."""
    sel = [r for r in records if r.scene == "coupled_clutches" and r.option == "rtol" and r.value == 1e-6
           and (r.solver == "ida" or r.solver.startswith("scipy:"))]
    if not sel:
        return []
    lines = ["## CoupledClutches at rtol 1e-6: IDA against scipy with event restarts", "",
             "IDA's hybrid loop against scipy's solvers driven by regmech's ODE-form driver (which locates each "
             "friction event on the dense output and restarts the solver there). Times are medians after "
             "compile; the compile time (one per fresh model) is listed separately. Errors against regmech's "
             "tight reference and against the MSL reference file (Dymola, tolerance 1e-6).", ""]
    hdr = ["solver", "status", "time after compile", "compile", "steps", "RHS/res.", "max rel err (ref)",
           "switch err [s]", "max rel err (MSL)", "switch err vs MSL [s]", "time / IDA"]
    ida = next((r for r in sel if r.solver == "ida" and r.ok), None)
    body = []
    for r in sorted(sel, key=lambda r: (r.solver != "ida", r.wall_s if r.ok else math.inf)):
        ratio = f"{r.wall_s / ida.wall_s:.2f}" if (ida and r.ok) else "-"
        body.append([f"`{r.solver}`", r.status, _fmt_time(r.wall_s), _fmt_time(r.compile_s), r.steps or "-",
                     r.rhs_calls or "-", _fmt_err(r.err_max_rel), _fmt_err(r.err_switch_s), _fmt_err(r.msl_max_rel),
                     _fmt_err(r.msl_switch_s), ratio])
    lines += _md_table(hdr, body)
    if reference is not None:
        lines += ["", f"Reference: {reference.summary()}."]
    return lines + [""]


def summary_markdown(scenes, records) -> list[str]:
    """Fastest solver per scene at each error level (ratio to the best scipy method)."""
    lines = ["## Fastest solver at matched accuracy", "",
             "For each scene and error level: the fastest solver that reached it, its time, and that time over "
             "the best scipy method's (same run). `-`: no run reached the level.", ""]
    hdr = ["scene"] + [f"err <= {lv:g}" for lv in LEVELS]
    body = []
    for sc in scenes:
        recs = [r for r in records if r.scene == sc.key]
        if not recs:
            continue
        row = [sc.key]
        for lv in LEVELS:
            best = (math.inf, None)
            for s in dict.fromkeys(r.solver for r in recs):
                t, rec = time_to_reach(recs, s, lv, sc.stick_slip)
                if t < best[0]:
                    best = (t, rec)
            t_sc, s_sc = best_scipy(recs, lv, sc.stick_slip)
            if best[1] is None:
                row.append("-")
            else:
                ratio = f"x{best[0] / t_sc:.2g} vs {s_sc}" if math.isfinite(t_sc) else "no scipy method"
                row.append(f"`{best[1].solver}` {_fmt_time(best[0])} ({ratio})")
        body.append(row)
    return lines + _md_table(hdr, body) + [""]


def failures_markdown(records) -> list[str]:
    bad = [r for r in records if not r.ok]
    if not bad:
        return ["## Failures, refusals, time-outs", "", "None: every run finished.", ""]
    groups: dict = {}
    for r in bad:
        groups.setdefault((r.scene, r.solver, r.status, r.reason), []).append(f"{r.option}={r.value:g}")
    lines = ["## Failures, refusals, time-outs", "",
             "`error`: stopped with a regmech error (the message is quoted); `crash`: any other exception (a bug); "
             "`timeout`: the run reached the per-run time limit; `skipped`: not run (reason given).", ""]
    body = [[s, f"`{sv}`", st, ", ".join(settings), reason.replace("|", "/")]
            for (s, sv, st, reason), settings in groups.items()]
    return lines + _md_table(["scene", "solver", "status", "settings", "reason"], body) + [""]


def write_report(run, out: Path) -> Path:
    """CSV, Markdown and plots of a ``workprecision.BenchRun`` into ``out``; returns the Markdown path."""
    from .machine import machine_line
    out.mkdir(parents=True, exist_ok=True)
    write_csv(run.records, out / "work_precision.csv")
    meta = {"machine": run.machine, "command": run.command, "repeats": run.repeats, "limit": run.limit,
            "wall_total": run.wall_total, "scenes": [sc.key for sc in run.scenes], "solvers": run.solvers}
    (out / "work_precision.meta.json").write_text(json.dumps(meta, indent=1))
    lines = ["# Work-precision of regmech's solvers", "",
             f"Machine: {machine_line(run.machine)}.", "",
             f"Command: `{run.command}`; {run.repeats} runs per setting, median (runs under "
             f"{_fmt_time(CHEAP_BELOW_S)} {CHEAP_REPEATS} times, runs over {_fmt_time(REPEAT_ABOVE_S)} once), "
             f"time limit {run.limit:g} s per run, total {run.wall_total / 60:.1f} min. The machine is shared with "
             f"other work: times of a few ms vary by a factor up to 2 between runs; compare ratios within a table.", "",
             "Errors: max over the output grid and the compared signals of |run - reference| / range of the "
             "reference signal (`max rel err`); the same at t_end (`final err`); for stick/slip scenes the "
             "largest switch-time difference of the mode changes matched by device, old and new mode "
             "(`switch err`, with the count of unmatched changes). Definitions: `regmech.bench.metrics`. "
             "Adaptive solvers run at rtol on a ladder (atol = rtol/100); fixed-step solvers (euler, rk4, "
             "abm, expm) on a ladder of steps h with `tol=None`: the bare method, timed without the companion "
             "run at 2h of their error estimate (which adds about half a run; `regmech.solvers.richardson`).", ""]
    lines += summary_markdown(run.scenes, run.records)
    cc_ref = run.references.get("coupled_clutches")
    lines += issue3_markdown(run.records, cc_ref)
    lines += ["## Scenes", ""]
    for sc in run.scenes:
        recs = [r for r in run.records if r.scene == sc.key]
        ref = run.references.get(sc.key)
        name = f"wp_{sc.key}.png"
        plotted = plot_scene(recs, sc, ref, out / name) if recs else False
        lines += scene_markdown(sc, recs, ref, run.reference_errors.get(sc.key, ""), name if plotted else "")
    lines += failures_markdown(run.records)
    path = out / "work_precision.md"
    path.write_text("\n".join(lines))
    return path


__all__ = ["write_report", "write_csv", "plot_scene", "matched_accuracy", "time_to_reach", "best_scipy",
           "LEVELS", "Errors"]
