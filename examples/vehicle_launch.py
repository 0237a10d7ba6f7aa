"""Vehicle launch: a car pulls away from standstill through a slipping clutch.

    python examples/vehicle_launch.py [--out DIR]     (DIR: $REGMECH_EXAMPLES_OUT, else out/)

The library scene ``vehicle_launch``: engine (full-load map x throttle 0.6)
and flywheel -> dry clutch closing over 1 s from 0.2 s -> first gear 3.6 ->
elastic drive shaft -> open differential 4.1 -> two ``Wheel``s with tyre
compliance and stick/slip road contact -> car body 1300 kg with road load.

Sign convention (MSL's): a two-flange device's ``tau`` is the torque at its
``flange_b``, ``w_rel = w_b - w_a``. The engine drives from ``flange_a``, so
the slipping clutch reads *Backward* (``w_rel < 0``) and the torques it and
the drive shaft pass on are negative; the figure plots ``-tau``, the drive
torque with traction positive. Writes ``vehicle_launch.png``.
"""

import argparse
import os
from pathlib import Path

import matplotlib.pyplot as plt

from regmech.library import vehicle_launch

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default=os.environ.get("REGMECH_EXAMPLES_OUT", "out"), help="folder for the figure")
out = Path(parser.parse_args().out)
out.mkdir(parents=True, exist_ok=True)

model = vehicle_launch()
res = model.simulate(3.0, dt_out=2e-3)
for ev in res.events:
    print(ev)
lock = next(ev.t for ev in res.events if ev.component == "clutch" and ev.new_mode == 0)
print(f"clutch locks at {lock:.3f} s at {res.at('body.v', lock, unit='km/h'):.1f} km/h; "
      f"heat in the clutch {res.final('clutch.heat') / 1e3:.1f} kJ")

fig, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 7))
for name in ("flywheel.w", "gearbox_in.w", "wheel_left.J.w"):
    axes[0].plot(res.t, res.get(name, unit="rpm"), label=name)
axes[0].set_ylabel("speed [rpm]")
axes[1].plot(res.t, res.get("body.v", unit="km/h"), label="body.v")
axes[1].set_ylabel("vehicle speed [km/h]")
axes[2].plot(res.t, -res["clutch.tau"], label="-clutch.tau (transmitted)")
axes[2].plot(res.t, -res["driveshaft.tau"], label="-driveshaft.tau")
axes[2].plot(res.t, res["engine.tau"], label="engine.tau", linestyle="--")
axes[2].set_ylabel("drive torque [N m]")
axes[2].set_xlabel("time [s]")
for ax in axes:
    ax.axvline(lock, color="grey", linewidth=0.8, linestyle=":")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
axes[0].set_title(f"Vehicle launch: clutch slips (Backward) until it locks at {lock:.2f} s")
fig.tight_layout()
fig.savefig(out / "vehicle_launch.png", dpi=100)
