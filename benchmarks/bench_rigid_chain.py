"""Build + compile time of long rigid chains.

    python benchmarks/bench_rigid_chain.py [--sizes 1000 3000 10000 30000] [--repeat 3] [--simulate]

The model: a ``Torque`` of 2 N m drives J0 (w0 = 1 rad/s); n rigid links join
n + 1 inertias of 1e-3 kg m^2 in a chain: ``Shaft(stiffness=None)``, or
``IdealGear`` with ratios 2 and 0.5 in turn. Every run is a fresh Python
process (the one-off symbolic work is included, as a user sees it); the time
is split into building the model, ``structure`` (regularity, nodes,
Pantelides, dummy derivatives) and the rest of ``compile``. Medians of
``--repeat`` runs. With ``--simulate`` each run also integrates 0.5 s by IDA
and reports the relative error of ``w`` at the far end against the closed form
of one lumped inertia ``J_eff = sum J_k (w_k / w_0)^2``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

CHILD = r"""
import json, sys, time
import numpy as np
import regmech as rm
from regmech.components import IdealGear, Inertia, Shaft, Torque
from regmech.structure.system import build_structure
from regmech.compile.system import CompiledSystem

n, kind, simulate = int(sys.argv[1]), sys.argv[2], sys.argv[3] == "1"
J, tau, w0 = 1e-3, 2.0, 1.0
t0 = time.perf_counter()
m = rm.Model(f"{kind}{n}")
drive = m.add(Torque("drive", tau=tau))
prev = m.add(Inertia("J0", J=J, w0=w0))
m.connect(drive.flange, prev.flange_a)
speed = [1.0]
for k in range(1, n + 1):
    r = 1.0 if kind == "shaft" else (2.0 if k % 2 else 0.5)
    link = m.add(Shaft(f"s{k}", stiffness=None) if kind == "shaft" else IdealGear(f"g{k}", ratio=r))
    Jk = m.add(Inertia(f"J{k}", J=J))
    m.connect(prev.flange_b, link.flange_a)
    m.connect(link.flange_b, Jk.flange_a)
    speed.append(speed[-1] / r)
    prev = Jk
t1 = time.perf_counter()
st = build_structure(m)
t2 = time.perf_counter()
c = CompiledSystem(st)
t3 = time.perf_counter()
out = {"build": t1 - t0, "structure": t2 - t1, "compile": t3 - t2}
if simulate:
    m._compiled = c
    res = m.simulate(t_end=0.5, dt_out=0.25)
    out["simulate"] = time.perf_counter() - t3
    J_eff = J * float(np.sum(np.array(speed) ** 2))
    exact = speed[-1] * (w0 + tau * res.t / J_eff)
    out["rel_error"] = float(np.max(np.abs(res[f"J{n}.w"] - exact)) / np.max(np.abs(exact)))
print(json.dumps(out))
"""


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 3000, 10000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--simulate", action="store_true")
    args = ap.parse_args(argv)
    print("| chain | links | build model [s] | structure [s] | compile [s] | build + compile [s] |"
          + (" simulate 0.5 s [s] | rel. error |" if args.simulate else ""))
    print("|---|---|---|---|---|---|" + ("---|---|" if args.simulate else ""))
    for kind in ("shaft", "gear"):
        for n in args.sizes:
            runs = []
            for _ in range(args.repeat):
                p = subprocess.run([sys.executable, "-c", CHILD, str(n), kind, "1" if args.simulate else "0"],
                                   capture_output=True, text=True, check=True)
                runs.append(json.loads(p.stdout.strip().splitlines()[-1]))
            med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
            row = (f"| {kind} | {n} | {med['build']:.3f} | {med['structure']:.3f} | {med['compile']:.3f} | "
                   f"{med['build'] + med['structure'] + med['compile']:.3f} |")
            if args.simulate:
                row += f" {med['simulate']:.2f} | {max(r['rel_error'] for r in runs):.1e} |"
            print(row, flush=True)


if __name__ == "__main__":
    main()
