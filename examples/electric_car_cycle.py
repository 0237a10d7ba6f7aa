"""Electric car following a drive cycle: a driver model in the loop.

    python examples/electric_car_cycle.py [--out DIR]     (DIR: $REGMECH_EXAMPLES_OUT, else out/)

The library scene ``driver_cycle``: a ``Driver`` (PI controller) reads the car's
speed and works the accelerator (an ``ElectricMotor`` with a torque envelope
and efficiency maps, single-speed reduction 9.0) and the brake pedal (70 %
regenerative, the rest by a friction brake on the wheels) to follow the first
two hills of the ECE-15 urban cycle. Writes ``electric_car_cycle.png``: the
reference and actual speed, the pedals, and the torques of the machine (negative while
regenerating) and of the friction brake.
"""

import argparse
import os
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from regmech.library import driver_cycle
from regmech.library.electric import CYCLE_KMH

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default=os.environ.get("REGMECH_EXAMPLES_OUT", "out"), help="folder for the figure")
out = Path(parser.parse_args().out)
out.mkdir(parents=True, exist_ok=True)

model = driver_cycle()
res = model.simulate(70.0, dt_out=5e-2)
t_ref, v_ref = np.array(CYCLE_KMH).T
err = np.max(np.abs(res.get("body.v", unit="km/h") - np.interp(res.t, t_ref, v_ref)))
print(f"largest speed error {err:.2f} km/h; {res.stats}")

fig, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 7))
axes[0].plot(t_ref, v_ref, "k--", linewidth=1, label="cycle")
axes[0].plot(res.t, res.get("body.v", unit="km/h"), label="body.v")
axes[0].set_ylabel("vehicle speed [km/h]")
axes[1].plot(res.t, res["driver.throttle"], label="driver.throttle")
axes[1].plot(res.t, res["driver.pedal_brake"], label="driver.pedal_brake")
axes[1].set_ylabel("pedal [1]")
axes[2].plot(res.t, res["driver.drive.tau"], label="driver.drive.tau (machine)")
axes[2].plot(res.t, res["driver.brake.tau"], label="driver.brake.tau (friction brake)")
axes[2].set_ylabel("torque [N m]")
axes[2].set_xlabel("time [s]")
for ax in axes:
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
axes[0].set_title("Electric car, driver following two ECE-15 hills")
fig.tight_layout()
fig.savefig(out / "electric_car_cycle.png", dpi=100)
