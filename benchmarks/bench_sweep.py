"""Benchmark: throughput of a parameter study (``rm.sweep``) on each executor.

    python benchmarks/bench_sweep.py [--n 1000] [--repeat 1] [--t-end 1.5] [--out benchmarks/results/sweep.md]

N runs of the CoupledClutches scene (a Latin hypercube over clutch capacity
``fn_max`` in [10, 40] N and clutch-2 engagement time ``t2`` in [0.2, 0.6] s,
seed 1; t_end 1.5 s, IDA rtol 1e-6, atol 1e-8, dt_out 0.01 s; outputs: final
speeds and peak clutch torques), side by side in the same run:

* a bare loop ``coupled_clutches(**p).simulate(...)`` + outputs over the same
  parameter sets: the cost of the simulations alone, no study machinery;
* ``sweep(executor="serial")``, ``sweep(executor=ProcessPoolExecutor(2))`` (the
  pool ``executor="process"`` makes, created here so that its workers' CPU time
  can be counted) and ``sweep(executor=Client(LocalCluster(2 single-threaded
  worker processes)))``, each writing its CSV incrementally; the Dask
  cluster's start-up is timed apart.

The machine is shared, so wall times carry other people's load; CPU time
does not. Per-run CPU: all CPU seconds of the study (this process, plus the
pool's worker processes via ``getrusage(RUSAGE_CHILDREN)`` after the pool is
joined, plus the Dask workers via psutil) divided by N. Per-run overhead: that
minus the CPU time of a bare simulation (the bare loop): what the study
machinery costs per run (dispatch, pickling, bookkeeping, CSV, scheduler).
Every executor's table must equal the serial one.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import statistics
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

import regmech as rm
from regmech.library import coupled_clutches
from regmech.study.outputs import SignalSummary
from regmech.study.worker import ignore_sigint

OUTPUTS = SignalSummary(final=["J1.w", "J2.w", "J3.w", "J4.w"], peak=["clutch1.tau", "clutch2.tau", "clutch3.tau"])


def numbers(table):
    return table.drop(columns=["wall_time"])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000, help="runs per study (default 1000)")
    ap.add_argument("--repeat", type=int, default=1,
                    help="rounds of studies, executors interleaved; medians are reported")
    ap.add_argument("--bare", type=int, default=None,
                    help="parameter sets in the bare single-simulation loop (default: all N, the same runs)")
    ap.add_argument("--t-end", type=float, default=1.5)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "sweep.md"))
    args = ap.parse_args(argv)
    import psutil          # comes with dask.distributed
    from dask.distributed import Client, LocalCluster

    sample = rm.latin_hypercube({"fn_max": (10.0, 40.0), "t2": (0.2, 0.6)}, n=args.n, seed=1)
    sim = dict(t_end=args.t_end, dt_out=0.01, solver="ida", rtol=1e-6, atol=1e-8)
    load0 = os.getloadavg()
    # the Dask workers start first: they import regmech at the same time as this process
    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster)
    dask_start = time.perf_counter() - t0
    dask_pids = list(client.run(os.getpid).values())

    # the first compile lambdifies the kernel templates (one-off per process)
    t0 = time.perf_counter()
    coupled_clutches().compile()
    first_compile = time.perf_counter() - t0
    bare, bare_cpu = [], []
    for p in sample[:args.bare or args.n]:
        t0, c0 = time.perf_counter(), time.process_time()
        OUTPUTS(coupled_clutches(**p).simulate(**sim))
        bare.append(time.perf_counter() - t0)
        bare_cpu.append(time.process_time() - c0)
    compile_warm = statistics.median(_time(lambda: coupled_clutches().compile()) for _ in range(20))

    def children_cpu():
        ru = resource.getrusage(resource.RUSAGE_CHILDREN)
        return ru.ru_utime + ru.ru_stime

    def process_pool():
        pool = ProcessPoolExecutor(args.workers, initializer=ignore_sigint)
        return pool, lambda: pool.shutdown(wait=True)      # joined: its CPU time is in RUSAGE_CHILDREN

    executors = {   # label: (make_executor() -> (executor, finish), CPU seconds of the workers so far)
        "serial": (lambda: ("serial", lambda: None), lambda: 0.0),
        "process": (process_pool, children_cpu),
        "dask": (lambda: (client, lambda: None),
                 lambda: sum(sum(psutil.Process(pid).cpu_times()[:2]) for pid in dask_pids)),
    }
    tables = {label: [] for label in executors}
    cpus = {label: [] for label in executors}
    tmp = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    try:
        for k in range(args.repeat):      # rounds, executors interleaved: load drift hits all alike
            for label, (make_executor, worker_cpu) in executors.items():
                executor, finish = make_executor()
                w0, c0 = worker_cpu(), time.process_time()
                table = rm.sweep(coupled_clutches, sample, OUTPUTS, executor=executor,
                                 out=tmp / f"{label}_{k}.csv", progress=False, **sim)
                finish()
                cpus[label].append(time.process_time() - c0 + worker_cpu() - w0)
                tables[label].append(table)
                if not numbers(table).equals(numbers(tables["serial"][0])):
                    raise SystemExit(f"{label}: the table differs from the serial one")
                print(f"round {k + 1} {label}: {args.n} runs in {table.attrs['elapsed']:.1f} s, "
                      f"{cpus[label][-1] / args.n * 1e3:.1f} ms CPU per run")
    finally:
        client.close()
        cluster.close()
    results = {label: dict(elapsed=statistics.median(t.attrs["elapsed"] for t in tables[label]),
                           workers=tables[label][0].attrs["workers"],
                           in_run=statistics.median(float(t["wall_time"].mean()) for t in tables[label]),
                           cpu=statistics.median(cpus[label]),
                           rounds=[t.attrs["elapsed"] for t in tables[label]])
               for label in executors}
    load1 = os.getloadavg()
    write_report(args, results, bare, bare_cpu, first_compile, compile_warm, dask_start, load0, load1)
    return 0


def _time(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def write_report(args, results, bare, bare_cpu, first_compile, compile_warm, dask_start, load0, load1) -> None:
    serial = results["serial"]
    single, single_cpu = float(np.mean(bare)), float(np.mean(bare_cpu))
    how = f"median of {args.repeat} rounds (executors interleaved)" if args.repeat > 1 else "one study"
    lines = [
        "# Parameter studies: sweep throughput",
        "",
        f"{args.n} runs of CoupledClutches (Latin hypercube over `fn_max` in [10, 40] N and `t2` in [0.2, 0.6] s, "
        f"seed 1; t_end {args.t_end} s, IDA rtol 1e-6, atol 1e-8, dt_out 0.01 s; 7 outputs per run), each study "
        f"writing its CSV incrementally; {how} per executor. Machine: {platform.machine()}, {_cpu()}, "
        f"{os.cpu_count()} cores shared with other work (load average {load0[0]:.1f} at the start, {load1[0]:.1f} "
        f"at the end), Python {platform.python_version()}, numpy {np.__version__}, dask {_version('dask')}. "
        f"All three tables are identical (every number, row order by run id).",
        "",
        "| executor | workers | wall time [s] | runs/s | speed-up vs serial | mean in-run wall time [ms] | "
        "CPU per run [ms] | per-run overhead (CPU) [ms] |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for label, r in results.items():
        cpu_run = r["cpu"] / args.n
        lines.append(f"| {label} | {r['workers']} | {r['elapsed']:.1f} | {args.n / r['elapsed']:.1f} | "
                     f"{serial['elapsed'] / r['elapsed']:.2f} | {r['in_run'] * 1e3:.1f} | {cpu_run * 1e3:.1f} | "
                     f"{(cpu_run - single_cpu) * 1e3:.1f} |")
    which = "the same" if len(bare) == args.n else f"the first {len(bare)}"
    rounds = "; ".join(f"round {k + 1}: " + " / ".join(f"{r['rounds'][k]:.1f}" for r in results.values())
                       for k in range(args.repeat))
    lines += [
        "",
        f"Wall time of each study [s] ({' / '.join(results)}): {rounds}.",
        "",
        f"A single simulation (bare loop `OUTPUTS(coupled_clutches(**p).simulate(...))` over {which} "
        f"parameter sets, warm caches): mean {single * 1e3:.1f} ms wall, {single_cpu * 1e3:.1f} ms CPU; the "
        f"per-run overhead is the CPU per run of the study minus this. Compiling a CoupledClutches model costs "
        f"{first_compile * 1e3:.0f} ms the first time in a process (class templates built, first-use imports) "
        f"and {compile_warm * 1e3:.1f} ms after that (median of 20): a worker keeps its template "
        f"cache for every run it does (forked pool workers inherit it warm; Dask workers, fresh interpreters, "
        f"build it on their first run). Starting the Dask LocalCluster ({args.workers} worker processes) took "
        f"{dask_start:.1f} s (not in the Dask row; `executor=\"dask\"` pays it on every call, a kept `Client` "
        f"once).",
        "",
        "The machine is shared: wall times, throughput and speed-up include other processes' load (the in-run "
        "wall time, measured inside the worker around build + simulate + outputs, shows how much CPU each "
        "worker actually got). CPU time is not diluted by that load, so the overhead column is the cost of "
        "the study machinery itself: dispatch, pickling, bookkeeping, CSV appends, and for Dask the scheduler "
        "and worker event loops.",
        "",
    ]
    if _autogroup():
        lines += [
            "This kernel schedules by autogroup (`/proc/sys/kernel/sched_autogroup_enabled` = 1): CPU is shared "
            "fairly between sessions, not between processes, so while other sessions keep the cores busy the "
            "worker processes of one study share that session's slice, and the parallel rows cannot show a "
            "speed-up in wall time. On an idle machine the CPU per run above bounds it: about "
            "`workers x (serial CPU per run) / (parallel CPU per run)`.",
            "",
        ]
    lines += [
        f"Reproduce: `python benchmarks/bench_sweep.py --n {args.n} --repeat {args.repeat}` (options `--n`, "
        f"`--repeat`, `--t-end`, `--workers`, `--bare`).",
        "",
    ]
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text("\n".join(lines))
    print(f"written {args.out}")


def _autogroup() -> bool:
    try:
        return Path("/proc/sys/kernel/sched_autogroup_enabled").read_text().strip() == "1"
    except OSError:
        return False


def _cpu() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _version(name: str) -> str:
    try:
        from importlib.metadata import version
        return version(name)
    except Exception:
        return "not installed"


if __name__ == "__main__":
    raise SystemExit(main())
