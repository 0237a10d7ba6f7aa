"""Clutch capacity study: how strong and how fast should a clutch engage?

    python examples/clutch_capacity_study.py [--executor serial|process|dask] [--out out]

A launch-like scene is simulated for a grid of clutch capacities (maximum
normal force) and engagement times with ``rm.sweep``; for each run the study
keeps the peak driveline torque, the slip energy turned into heat in the
clutch, ``E_slip = integral of clutch.power dt`` [J] (``power`` is the power
the clutch absorbs, ``tau * w_rel``), and the time the clutch locks. The
results go to ``out/clutch_capacity_study.csv`` as they arrive (rerunning
resumes) and to a plot ``out/clutch_capacity_study.png``.

Scene: ``vehicle_launch`` from ``regmech.library.SCENES`` when the library has
it (engine, clutch, gearbox, drive shaft, wheels, car; parameters
``clutch_fn_max``, ``engage_time``; driveline torque = drive shaft torque),
else MSL's ``coupled_clutches`` (parameters ``fn_max`` and ``t2``, the
instant clutch 2 closes; driveline torque = clutch 2 torque).

Physics to expect: a weak or slowly closing clutch slips long (much heat,
low torque peak); a strong, fast one locks early (little heat, a torque peak
that shakes the driveline).
"""

from __future__ import annotations

import argparse
import inspect
from functools import partial
from pathlib import Path

import numpy as np

import regmech as rm
from regmech.library import SCENES

STUDIES = {
    # scene: capacity parameter, its values [N]; timing parameter, its values [s]; clutch; torque signal; t_end
    "vehicle_launch": dict(capacity=("clutch_fn_max", [4000.0, 6000.0, 8000.0, 10000.0]),
                           timing=("engage_time", [0.3, 0.6, 1.0, 1.5]),
                           clutch="clutch", torque="driveshaft.tau", t_end=3.0,
                           timing_label="engagement ramp duration [s]"),
    "coupled_clutches": dict(capacity=("fn_max", [10.0, 20.0, 30.0, 40.0]),
                             timing=("t2", [0.2, 0.4, 0.6, 0.8]),
                             clutch="clutch2", torque="clutch2.tau", t_end=1.5,
                             timing_label="clutch 2 closes at [s]"),
}


def choose_scene() -> str:
    """vehicle_launch when the library has it with the expected parameters, else coupled_clutches."""
    build = SCENES.get("vehicle_launch")
    if build is not None:
        wanted = {STUDIES["vehicle_launch"][k][0] for k in ("capacity", "timing")}
        if wanted <= set(inspect.signature(build).parameters):
            return "vehicle_launch"
    return "coupled_clutches"


def launch_outputs(res, clutch: str, torque: str) -> dict:
    """Peak driveline torque [N m], slip energy [J], lock time [s] (NaN: the clutch never locked)."""
    mode = res[f"{clutch}.mode"]
    stuck = np.nonzero(mode == 0)[0]
    return {
        "peak_torque": float(np.max(np.abs(res[torque]))),
        "slip_energy": float(np.trapezoid(res[f"{clutch}.power"], res.t)),
        "lock_time": float(res.t[stuck[0]]) if len(stuck) else float("nan"),
    }


def plot(table, study: dict, path: Path, scene: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    cap, timing = study["capacity"][0], study["timing"][0]
    ok = table[table["status"] == "ok"]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for value, rows in ok.groupby(timing):
        label = f"{timing} = {value:g}"
        ax1.plot(rows[cap], rows["peak_torque"], "o-", label=label)
        ax2.plot(rows[cap], rows["slip_energy"], "o-", label=label)
    ax1.set_ylabel(f"peak |{study['torque']}| [N m]")
    ax2.set_ylabel(f"slip energy in {study['clutch']} [J]")
    for ax in (ax1, ax2):
        ax.set_xlabel(f"clutch capacity {cap} [N]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, title=study["timing_label"], title_fontsize=8)
    fig.suptitle(f"{scene}: clutch capacity and engagement timing ({len(ok)} runs)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="clutch capacity / engagement time study")
    ap.add_argument("--executor", default="process", help="serial, process (default) or dask")
    ap.add_argument("--out", default="out", help="output folder (default: out)")
    args = ap.parse_args(argv)
    scene = choose_scene()
    study = STUDIES[scene]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (cap, cap_values), (timing, timing_values) = study["capacity"], study["timing"]
    table = rm.sweep(SCENES[scene], {cap: cap_values, timing: timing_values},
                     partial(launch_outputs, clutch=study["clutch"], torque=study["torque"]),
                     executor=args.executor, out=out / "clutch_capacity_study.csv",
                     t_end=study["t_end"], dt_out=study["t_end"] / 1000, solver="ida", rtol=1e-6, atol=1e-8)
    print(table.drop(columns=["error"]).to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    failed = table[table["status"] != "ok"]
    for _, row in failed.iterrows():
        print(f"run {row['run_id']} failed: {row['error']}")
    png = out / "clutch_capacity_study.png"
    plot(table, study, png, scene)
    print(f"{len(table)} runs in {table.attrs['elapsed']:.1f} s ({table.attrs['executor']} x{table.attrs['workers']}); "
          f"table: {out / 'clutch_capacity_study.csv'}, plot: {png}")
    return 0 if failed.empty else 1


if __name__ == "__main__":
    raise SystemExit(main())
