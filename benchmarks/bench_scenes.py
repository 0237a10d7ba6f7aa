"""Cost per IDA step on the models users build, against MSL First, side by side in one process.

Every library scene (the MSL examples, the cars, the excavator, the slip controller, the drive cycles) and a
random nonlinear drivetrain of 50 bodies are run with the default call (``model.simulate(t_end, dt_out)``,
solver ``auto``) and with ``solver="ida"`` at rtol 1e-6 on both IDA paths: compiled callbacks (the default,
``native=True``) and Python callbacks (``native=False``). The runs are interleaved: each repetition runs
every case once, so all see the same load. Reported per scene: the median wall time of each call, IDA's
steps, the wall time per step and its ratio to First's on the same path, and the reason a scene stays on the
Python path. A second table times the first call in a fresh process (numba's kernels loaded from the disk
cache, and compiled from nothing with an empty cache).

    python benchmarks/bench_scenes.py [--repeats 5] [--out benchmarks/results/scenes.md] [--no-fresh]
"""

from __future__ import annotations

import argparse
import os
import platform
import random
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import regmech as rm
from regmech.components import (Clutch, Damper, ElastoBacklash, Fixed, IdealGear, Inertia, SpringDamper, Torque,
                                TwoFlangeCompliant)
from regmech.library import SCENES
from regmech.signals import Ramp, Sine, Table

ROOT = Path(__file__).resolve().parents[1]
#: simulated time [s] and output interval [s] of each scene (the examples' and the issue's durations)
RUNS = {"first": (1.0, 1e-3), "coupled_clutches": (1.5, 1e-3), "one_way_clutch": (2.0, 2e-3),
        "vehicle_launch": (3.0, 5e-3), "excavator_swing": (2.0, 2e-3), "gear_shift": (1.0, 1e-3),
        "electric_car": (12.0, 1e-2), "driver_cycle": (21.0, 1e-2), "six_speed_car": (10.0, 1e-2),
        "dct_car": (10.0, 1e-2), "slip_control": (8.0, 1e-2), "random_drivetrain_50": (2.0, 2e-3)}


class HardeningSpring(TwoFlangeCompliant):
    """A user's nonlinear spring: tau = c phi (1 + (phi / phi_h)^2) + d w (the guide's way: a symbolic law)."""

    c = rm.Param(check="positive", unit="N m/rad", doc="stiffness at small twist")
    phi_h = rm.Param(check="positive", unit="rad", doc="twist at which the stiffness doubles")
    d = rm.Param(check="nonnegative", unit="N m s/rad", doc="damping")

    def law(self, rel, rel_dot):
        return self.c * rel * (1 + (rel / self.phi_h) ** 2) + self.d * rel_dot


def random_drivetrain(n_bodies: int = 50, seed: int = 50) -> rm.Model:
    """A seeded random nonlinear drivetrain: a line of ``n_bodies`` inertias from an engine-like torque table to
    a damped load, joined by linear and hardening springs, elastic backlash and gears, with two clutches that
    engage on ramps of their normal force (stick/slip) and branches to the ground through dampers."""
    rng = random.Random(seed)
    m = rm.Model(f"random_drivetrain_{n_bodies}")
    ground = m.add(Fixed("ground"))
    bodies = [m.add(Inertia(f"J{i}", J=10 ** rng.uniform(-2, 0), w0=0.0)) for i in range(n_bodies)]
    drive = m.add(Torque("drive", tau=Table([(0.0, 0.0), (0.2, 80.0), (1.0, 120.0), (1.5, 40.0), (2.0, 60.0)])))
    m.connect(drive.flange, bodies[0].flange_a)
    clutch_at = set(rng.sample(range(2, n_bodies - 2), 2))
    for i in range(n_bodies - 1):
        a, b = bodies[i].flange_b, bodies[i + 1].flange_a
        if i in clutch_at:
            dev = m.add(Clutch(f"clutch{i}", fn_max=2000.0, mu=0.4, peak=1.1,
                               f_normalized=Ramp(height=1.0, duration=0.3, start_time=rng.uniform(0.2, 1.0))))
        else:
            kind = rng.choice(["spring", "spring", "hardening", "backlash", "gear"])
            c = 10 ** rng.uniform(3, 4)
            if kind == "spring":
                dev = m.add(SpringDamper(f"link{i}", c=c, d=rng.uniform(1.0, 5.0)))
            elif kind == "hardening":
                dev = m.add(HardeningSpring(f"link{i}", c=c, phi_h=rng.uniform(0.05, 0.2), d=rng.uniform(1.0, 5.0)))
            elif kind == "backlash":
                dev = m.add(ElastoBacklash(f"link{i}", c=c, d=rng.uniform(2.0, 8.0), b=rng.uniform(0.005, 0.02)))
            else:
                dev = m.add(IdealGear(f"link{i}", ratio=rng.choice([0.8, 1.25, 1.5])))
                m.connect(dev.support, ground.flange)
        m.connect(a, dev.flange_a)
        m.connect(dev.flange_b, b)
        if rng.random() < 0.2:
            loss = m.add(Damper(f"loss{i}", d=rng.uniform(0.05, 0.5)))
            m.connect(bodies[i + 1].flange_b, loss.flange_a)
            m.connect(loss.flange_b, ground.flange)
    load = m.add(Damper("load", d=5.0))
    m.connect(bodies[-1].flange_b, load.flange_a)
    m.connect(load.flange_b, ground.flange)
    wobble = m.add(Torque("wobble", tau=Sine(amplitude=5.0, freq_hz=7.0)))
    m.connect(wobble.flange, bodies[n_bodies // 2].flange_b)
    return m


def build(name: str) -> rm.Model:
    return random_drivetrain() if name == "random_drivetrain_50" else SCENES[name]()


def _steps(res) -> int:
    return int(res.stats.steps)


def run_case(model, name, kind):
    """One timed call: ``kind`` is ``default``, ``native`` or ``python``; returns (wall s, result)."""
    t_end, dt_out = RUNS[name]
    opts = {} if kind == "default" else {"solver": "ida", "rtol": 1e-6, "native": kind == "native"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        res = model.simulate(t_end, dt_out=dt_out, **opts)
        return time.perf_counter() - t0, res


def measure(names, repeats):
    """Interleaved medians: {(name, kind): (median wall, result of the last run)}."""
    models = {n: build(n) for n in names}
    kinds = ("default", "native", "python")
    walls = {(n, k): [] for n in names for k in kinds}
    last = {}
    for n in names:                 # untimed: compile, load the kernels, fill the caches
        for k in kinds:
            last[(n, k)] = run_case(models[n], n, k)[1]
    for _ in range(repeats):
        for n in names:
            for k in kinds:
                wall, res = run_case(models[n], n, k)
                walls[(n, k)].append(wall)
                last[(n, k)] = res
    return {key: (float(np.median(v)), last[key]) for key, v in walls.items()}


FRESH = """
import time, warnings
t0 = time.perf_counter()
import regmech
from regmech.library import six_speed_car
m = six_speed_car()
t1 = time.perf_counter()
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    res = m.simulate(10.0, dt_out=1e-2)
t2 = time.perf_counter()
res = m.simulate(10.0, dt_out=1e-2)
t3 = time.perf_counter()
print(t1 - t0, t2 - t1, t3 - t2, res.stats.extra.get("native"))
"""


def fresh_process(cache_dir):
    """(import + build, first default call, second default call) [s] of six_speed_car in a new process."""
    env = dict(os.environ, REGMECH_CACHE_DIR=cache_dir)
    out = subprocess.run([sys.executable, "-c", FRESH], env=env, capture_output=True, text=True, timeout=900)
    if out.returncode:
        raise RuntimeError(out.stderr[-2000:])
    parts = out.stdout.split()
    return float(parts[0]), float(parts[1]), float(parts[2])


def report(names, got, fresh, repeats):
    first_native = got[("first", "native")][0] / max(_steps(got[("first", "native")][1]), 1)
    first_python = got[("first", "python")][0] / max(_steps(got[("first", "python")][1]), 1)
    load = os.getloadavg()
    lines = ["# Cost per IDA step on the library scenes", "",
             f"`python benchmarks/bench_scenes.py --repeats {repeats}`, {time.strftime('%Y-%m-%d')}, "
             f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
             f"{platform.python_version()}, numpy {np.__version__}, regmech {rm.__version__}; load average at "
             f"the end {load[0]:.1f}. Medians of {repeats} interleaved repetitions (wall time); steps are IDA's "
             "own step count on the compiled path and step attempts on the Python path.", "",
             "| scene | simulated [s] | default call: solver | wall [ms] | ida rtol 1e-6, compiled: wall [ms] | "
             "steps | us/step | x First | Python callbacks: wall [ms] | us/step | x First | compiled path |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for n in names:
        wall_d, res_d = got[(n, "default")]
        wall_n, res_n = got[(n, "native")]
        wall_p, res_p = got[(n, "python")]
        sn, sp = max(_steps(res_n), 1), max(_steps(res_p), 1)
        note = res_n.stats.extra.get("native")
        path = "yes" if note is True else str(note).replace("not used: ", "no: ").replace("|", "/")
        lines.append(f"| {n} | {RUNS[n][0]:g} | {res_d.stats.solver} | {1e3 * wall_d:.1f} | {1e3 * wall_n:.1f} | "
                     f"{sn} | {1e6 * wall_n / sn:.1f} | {wall_n / sn / first_native:.1f} | {1e3 * wall_p:.1f} | "
                     f"{1e6 * wall_p / sp:.1f} | {wall_p / sp / first_python:.1f} | {path} |")
    if fresh:
        lines += ["", "First call in a fresh process (six_speed_car, 10 s, default call): import and build, the "
                  "first call (numba's machine code loaded from the disk cache, or compiled with an empty cache), "
                  "and a second call in the same process.", "",
                  "| kernel cache | import + build [s] | first call [s] | second call [s] |", "|---|---|---|---|"]
        for label, (a, b, c) in fresh:
            lines.append(f"| {label} | {a:.2f} | {b:.2f} | {c:.3f} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "scenes.md")
    ap.add_argument("--no-fresh", action="store_true", help="skip the fresh-process timings")
    ap.add_argument("--scenes", default=",".join(RUNS), help="comma-separated scene names")
    args = ap.parse_args(argv)
    names = [n for n in args.scenes.split(",") if n]
    got = measure(names, args.repeats)
    fresh = []
    if not args.no_fresh:
        from regmech.compile.codegen import cache_dir
        warm = os.path.dirname(cache_dir())
        fresh.append(("warm (kernels on disk)", fresh_process(warm)))
        with tempfile.TemporaryDirectory() as empty:
            fresh.append(("empty (compiled from nothing)", fresh_process(empty)))
    text = report(names, got, fresh, args.repeats)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
