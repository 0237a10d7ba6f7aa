"""Per-call overhead of the IDA path on small models, before and after, interleaved in one run.

Two worker processes, one importing the baseline regmech (``--base``: a source tree, by default the
merge base of this branch with ``main`` extracted into a temporary folder) and one importing this
checkout's, build the same models (MSL First and CoupledClutches from ``library/msl.py``, the chains
of ``bench_foundation.chain``), run each once untimed, and then take turns: every repetition runs
each case once in the baseline and once here, so both see the same load. Reported per case: the
median wall and CPU (process) time of ``model.simulate(..., solver="ida", rtol=...)`` (1 ms output
grid) on each side, their ratios (CPU time is the steadier under load), and the residual calls of each (before and after
must agree: same steps, same answer). A third column runs this checkout with ``native=True``
(``regmech.solvers.ida_native``; the same method, a residual summed in another order, so its step
counts differ a little).

    python benchmarks/bench_ida_overhead.py [--repeats 9] [--base PATH] [--out FILE.md]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CASES = [("First", 1e-6), ("First", 1e-9), ("chain10", 1e-6), ("chain10", 1e-9), ("chain100", 1e-6),
         ("chain100", 1e-9), ("CoupledClutches", 1e-6), ("CoupledClutches", 1e-9)]


# ------------------------------------------------------------------------------------ worker side
def _load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _build(name: str):
    """(model, t_end) of a case, built with the public API of whichever regmech is imported."""
    msl = _load(ROOT / "library" / "msl.py", "_bench_msl")
    if name == "First":
        return msl.first(), 1.0
    if name == "CoupledClutches":
        return msl.coupled_clutches(), 1.5
    foundation = _load(ROOT / "benchmarks" / "bench_foundation.py", "_bench_foundation")
    return foundation.chain(int(name[len("chain"):])), 1.0


def worker() -> None:
    """Answer one JSON request per line: {"case": name, "rtol": r[, "native": true]} -> {"wall": s, "rhs": n, ...}."""
    import regmech
    models = {}
    print(json.dumps({"ready": str(Path(regmech.__file__).parent)}), flush=True)
    for line in sys.stdin:
        req = json.loads(line)
        name, rtol = req["case"], req["rtol"]
        opts = {"native": True} if req.get("native") else {}
        if name not in models:
            models[name] = _build(name)
        m, t_end = models[name]
        if req.get("warm"):
            m.simulate(t_end, dt_out=1e-3, solver="ida", rtol=rtol, **opts)      # compile, first call: untimed
        c0, t0 = time.process_time(), time.perf_counter()
        res = m.simulate(t_end, dt_out=1e-3, solver="ida", rtol=rtol, **opts)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        print(json.dumps({"wall": wall, "cpu": cpu, "rhs": res.stats.rhs_calls, "segments": res.stats.segments,
                          "native": res.stats.extra.get("native")}), flush=True)


# ------------------------------------------------------------------------------------ driver side
def _baseline_tree() -> Path:
    """The merge base of HEAD and main, its ``src`` extracted into a temporary folder."""
    base = subprocess.run(["git", "-C", str(ROOT), "merge-base", "HEAD", "main"], capture_output=True, text=True,
                          check=True).stdout.strip()
    tmp = Path(tempfile.mkdtemp(prefix="regmech_base_"))
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", base, "src"], capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", str(tmp)], input=archive.stdout, check=True)
    return tmp / "src"


class Worker:
    def __init__(self, src: Path):
        env = dict(os.environ, PYTHONPATH=str(src))
        self.proc = subprocess.Popen([sys.executable, __file__, "--worker"], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, text=True, env=env, cwd=str(ROOT))
        self.where = json.loads(self.proc.stdout.readline())["ready"]

    def run(self, case: str, rtol: float, native: bool = False, warm: bool = False) -> dict:
        self.proc.stdin.write(json.dumps({"case": case, "rtol": rtol, "native": native, "warm": warm}) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the worker importing {self.where} stopped")
        return json.loads(line)

    def close(self):
        self.proc.stdin.close()
        self.proc.wait(timeout=60)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--base", type=Path, default=None, help="source folder of the baseline regmech "
                    "(default: the merge base with main, extracted)")
    ap.add_argument("--out", type=Path, default=None, help="also write the table to this markdown file")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker()
        return
    base = args.base or _baseline_tree()
    old, new = Worker(base), Worker(ROOT / "src")
    load0 = os.getloadavg()
    times = {c: ([], [], []) for c in CASES}
    cpu = {c: ([], [], []) for c in CASES}
    calls, native_note = {}, {}
    try:
        for c in CASES:          # first calls (compile, numba's start-up) outside the timing
            old.run(*c, warm=True)
            new.run(*c, warm=True)
            native_note[c] = new.run(*c, native=True, warm=True)["native"]
        for _ in range(args.repeats):
            for c in CASES:
                runs = (old.run(*c), new.run(*c), new.run(*c, native=True))
                for k, r in enumerate(runs):
                    times[c][k].append(r["wall"])
                    cpu[c][k].append(r["cpu"])
                calls[c] = tuple(r["rhs"] for r in runs) + (runs[0]["segments"],)
    finally:
        old.close()
        new.close()
    load1 = os.getloadavg()
    lines = ["# IDA per-call overhead", "",
             f"IDA overhead, before ({old.where}) and after ({new.where}; native: solver='ida', native=True), "
             f"interleaved; medians of {args.repeats}; {platform.processor() or platform.machine()}, "
             f"{os.cpu_count()} cores, load {load0[0]:.2f} -> {load1[0]:.2f}", "",
             "| case | rtol | wall before [ms] | after | native | CPU before [ms] | after | native | "
             "CPU after/before | native/before | residual calls before / after / native | segments |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for c in CASES:
        a, b, n = (1e3 * float(np.median(v)) for v in times[c])
        ca, cb, cn = (1e3 * float(np.median(v)) for v in cpu[c])
        ra, rb, rn, sa = calls[c]
        note = "" if native_note[c] is True else " (native: " + str(native_note[c]).replace("not used: ", "") + ")"
        lines.append(f"| {c[0]} | {c[1]:g} | {a:.1f} | {b:.1f} | {n:.1f} | {ca:.1f} | {cb:.1f} | {cn:.1f} | "
                     f"{cb / ca:.2f} | {cn / ca:.2f} | {ra} / {rb} / {rn}{note} | {sa} |")
    text = "\n".join(lines)
    print(text)
    if args.out:
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
