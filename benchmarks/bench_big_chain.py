"""Large chains end to end: build, compile, simulate and read named results, each size in a
fresh Python process, with the wall time of every phase, the resident memory after it, and the whole
process's wall time and peak memory (as ``/usr/bin/time -v`` reports them: interpreter start, imports and
exit included).

    python benchmarks/bench_big_chain.py [--sizes 1000 10000 100000] [--dt-out 0.01] [--repeat 1]
                                         [--baseline /work/main/src] [--out benchmarks/results/big_chain.md]

The model is ``bench_foundation.chain(n)``: n inertias (J_i = 1 + 0.01 (i mod 7) kg m^2) joined by
spring-dampers (c = 1e4 N m/rad, d = 1 N m s/rad), driven at the first by ``Torque`` ``10 sin(2 pi 5 t)``
N m, the last grounded through a spring (1e3 N m/rad). It runs 1 s with ``solver="ida", rtol=1e-6``
and ``dt_out`` (default 0.01 s: 101 output points; ``--dt-out 0`` takes simulate's default of 500
intervals), then reads ``res.t`` and six named signals (speeds and angles of the first, middle and last
inertia, the torque of the first spring-damper and of the end spring).

``--baseline SRC`` runs the same worker with ``PYTHONPATH=SRC`` (e.g. the main checkout's ``src``),
interleaved with the current code, so before/after numbers come from the same machine state. The
machine is shared: read the ratios, and the load printed with them.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
T_END, RTOL = 1.0, 1e-6
PHASES = ("import", "build", "compile", "simulate", "read")


# --------------------------------------------------------------------------- worker (fresh process)
def worker(n: int, dt_out: float | None) -> dict:
    t_proc = time.perf_counter()
    import resource

    def rss_mb() -> float:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmRSS"):
                    return int(line.split()[1]) / 1024
        return float("nan")

    out = {"n": n, "phases": {}, "rss_mb": {}}
    t = time.perf_counter()
    import regmech as rm                                      # noqa: F401  (import time is a phase)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_foundation import chain
    out["regmech"] = str(Path(rm.__file__).resolve().parent)

    def mark(phase, t0):
        out["phases"][phase] = time.perf_counter() - t0
        out["rss_mb"][phase] = rss_mb()
        return time.perf_counter()

    t = mark("import", t)
    m = chain(n)
    t = mark("build", t)
    c = m.compile()
    t = mark("compile", t)
    res = m.simulate(T_END, dt_out, solver="ida", rtol=RTOL)
    t = mark("simulate", t)
    names = ["J0.w", f"J{n // 2}.phi", f"J{n // 2}.w", f"J{n - 1}.w", "sd0.tau", "ground_spring.tau"]
    vals = [res.t] + [res[nm] for nm in names]
    t = mark("read", t)
    out["points"] = len(vals[0])
    out["N"] = int(c.N)
    out["ida_wall_s"] = res.stats.wall_time
    out["residual_calls"] = res.stats.rhs_calls
    out["atol_rescaled"] = "atol_rescaled" in res.stats.extra
    out["final_J_last_w"] = float(vals[4][-1])
    out["in_process_s"] = time.perf_counter() - t_proc
    out["peak_in_process_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return out


def run_worker(n: int, dt_out: float | None, src: str | None) -> dict:
    """One fresh process; wall time and max RSS of the whole process (``os.wait4``)."""
    env = dict(os.environ)
    if src:
        env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    with tempfile.TemporaryFile("w+") as fh:
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, __file__, "--worker", str(n), str(dt_out or 0)], stdout=fh,
                                stderr=subprocess.PIPE, env=env, text=True)
        err = proc.stderr.read()
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        fh.seek(0)
        text = fh.read()
    if proc.returncode != 0:
        raise RuntimeError(f"worker n={n} src={src} failed ({proc.returncode}): {err[-2000:]}")
    out = json.loads(text.strip().splitlines()[-1])
    out["process_wall_s"] = wall
    out["process_peak_mb"] = usage.ru_maxrss / 1024
    out["exit_s"] = wall - out["in_process_s"]
    return out


# --------------------------------------------------------------------------- report
def load() -> str:
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return "?"


def row(label, r):
    ph = r["phases"]
    return (f"| {label} | {r['n']:,} | {r['points']} | " + " | ".join(f"{ph[p]:.2f}" for p in PHASES) +
            f" | {r['exit_s']:.2f} | **{r['process_wall_s']:.1f}** | {r['rss_mb']['compile']:.0f} | "
            f"**{r['process_peak_mb']:.0f}** | {r['ida_wall_s']:.2f} ({2 if r['atol_rescaled'] else 1}) |")


def markdown(rows, args, loads) -> str:
    import numpy as np
    import scipy
    head = ("| code | n | points | import [s] | build [s] | compile [s] | simulate [s] | read [s] | start + exit [s] | "
            "process [s] | RSS after compile [MB] | peak RSS [MB] | IDA wall (stats) [s] (runs) |\n" + "|---" * 13 + "|")
    lines = [
        "# Large chains end to end (`benchmarks/bench_big_chain.py`)",
        "",
        f"Chain of n inertias and spring-dampers (`bench_foundation.chain`), 1 s, `solver=\"ida\", rtol={RTOL:g}`, "
        f"dt_out {args.dt_out or 'default (500 intervals)'}; each run a fresh process; `process` is its whole "
        f"wall time and `peak RSS` its maximum resident set (as `/usr/bin/time -v`), the phases are timed inside "
        f"it (`start + exit`: the rest, interpreter start-up and shutdown); IDA's wall time is the sum over its "
        f"runs (2: the motion was small for the scalar atol and the run was repeated with scaled tolerances). Machine: {platform.machine()}, Python {platform.python_version()}, "
        f"numpy {np.__version__}, scipy {scipy.__version__}; load average {', '.join(loads)} (2 cores shared with "
        f"other work: read the before/after ratios of the same run).",
        "",
        head,
    ]
    lines += [row(label, r) for label, r in rows]
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000])
    ap.add_argument("--dt-out", type=float, default=0.01, help="output interval [s]; 0: simulate's default")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--baseline", default=None, help="a src folder to compare with (PYTHONPATH), interleaved")
    ap.add_argument("--out", default=None)
    ap.add_argument("--worker", nargs=2, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        n, dt = int(args.worker[0]), float(args.worker[1])
        print(json.dumps(worker(n, dt or None)))
        return
    rows, loads = [], []
    for n in args.sizes:
        for _ in range(args.repeat):
            for label, src in ([("before", args.baseline)] if args.baseline else []) + [("after", None)]:
                loads.append(load())
                r = run_worker(n, args.dt_out or None, src)
                rows.append((label, r))
                print(row(label, r), flush=True)
    text = markdown(rows, args, sorted(set(loads)))
    print(text)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text)


if __name__ == "__main__":
    main()
