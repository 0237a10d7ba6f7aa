"""Clutch capacity study: how strong and how fast should a launch clutch engage?

    python examples/clutch_capacity_study.py [--executor serial|process|dask] [--out DIR]
    (DIR: $REGMECH_EXAMPLES_OUT, else out/)

The library scene ``vehicle_launch`` is simulated for a grid of clutch
capacities (``clutch_fn_max``, the maximum normal force [N]) and engagement
ramp durations (``engage_time`` [s]) with ``rm.sweep``. Each run keeps the peak
drive-shaft torque, the heat the clutch turned the slip into
(``clutch.heat`` [J], the integral of ``tau * w_rel``) and the instant the
clutch locks. The table goes to ``clutch_capacity_study.csv`` as the runs
finish (a rerun resumes: finished rows are skipped) and the figure to
``clutch_capacity_study.png``.

``executor="process"`` (the default) runs on every core, ``"dask"`` on a Dask
cluster (``pip install "regmech[dask]"``). Both start worker processes that
import this file, so the study runs under ``if __name__ == "__main__":``.

Physics to expect: a weak or slowly closing clutch slips long (much heat, a
low torque peak); a strong, fast one locks early (little heat, a torque peak
that shakes the driveline).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

import regmech as rm
from regmech.library import vehicle_launch

CAPACITIES = [4000.0, 7000.0, 10000.0]           # clutch_fn_max [N]
ENGAGE_TIMES = [0.3, 0.8, 1.5]                    # engage_time [s]


def launch_outputs(res) -> dict:
    """Peak drive-shaft torque [N m], clutch heat [J], lock time [s] (NaN: the clutch never locked)."""
    locks = [ev.t for ev in res.events if ev.component == "clutch" and ev.new_mode == 0]
    return {"peak_torque": float(np.max(np.abs(res["driveshaft.tau"]))),
            "heat": res.final("clutch.heat"),
            "lock_time": locks[0] if locks else float("nan")}


def plot(table, path: Path) -> None:
    import matplotlib.pyplot as plt
    ok = table[table["status"] == "ok"]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for value, rows in ok.groupby("engage_time"):
        ax1.plot(rows["clutch_fn_max"], rows["peak_torque"], "o-", label=f"{value:g} s")
        ax2.plot(rows["clutch_fn_max"], rows["heat"] / 1e3, "o-", label=f"{value:g} s")
    ax1.set_ylabel("peak |driveshaft.tau| [N m]")
    ax2.set_ylabel("heat in the clutch [kJ]")
    for ax in (ax1, ax2):
        ax.set_xlabel("clutch capacity clutch_fn_max [N]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, title="engage_time", title_fontsize=8)
    fig.suptitle(f"vehicle_launch: clutch capacity and engagement time ({len(ok)} runs)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--executor", default="process", help="serial, process (default) or dask")
    ap.add_argument("--out", default=os.environ.get("REGMECH_EXAMPLES_OUT", "out"), help="folder for the results")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    table = rm.sweep(vehicle_launch, {"clutch_fn_max": CAPACITIES, "engage_time": ENGAGE_TIMES}, launch_outputs,
                     executor=args.executor, out=out / "clutch_capacity_study.csv", progress=False,
                     t_end=3.0, dt_out=5e-3, solver="ida", rtol=1e-6)
    print(table.drop(columns=["error"]).to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    for _, row in table[table["status"] != "ok"].iterrows():
        print(f"run {row['run_id']} failed: {row['error']}")
    plot(table, out / "clutch_capacity_study.png")
    print(f"{len(table)} runs in {table.attrs['elapsed']:.1f} s ({table.attrs['executor']} x{table.attrs['workers']})")
    return 0 if (table["status"] == "ok").all() else 1


if __name__ == "__main__":                        # worker processes import this file: run the study only here
    raise SystemExit(main())
