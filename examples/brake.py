"""A brake stops a flywheel and a sliding mass, and holds them.

    python examples/brake.py [--out DIR]     (DIR: $REGMECH_EXAMPLES_OUT, else out/)

In the manner of MSL's Brake examples: a flywheel (J = 1 kg m^2, 20 rad/s)
and a mass (m = 1 kg, 1 m/s) each meet a brake applied at 0.1 s. ``Brake`` acts
between its ``flange`` and its ``support`` (grounded when left free), kinetic
torque ``mu cgeo fn``; ``LinearBrake`` is its translational twin. Each slides
to rest and then sticks (an event, mode Stuck): the static capacity
(``peak`` x kinetic) holds it. The kinetic energy ends up as the brakes' heat,
``J w0^2 / 2 = 200 J`` and ``m v0^2 / 2 = 0.5 J``. Writes ``brake.png``.
"""

import argparse
import os
from pathlib import Path

import matplotlib.pyplot as plt

import regmech as rm
from regmech.components import Brake, Inertia, LinearBrake, Mass
from regmech.signals import Step

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default=os.environ.get("REGMECH_EXAMPLES_OUT", "out"), help="folder for the figure")
out = Path(parser.parse_args().out)
out.mkdir(parents=True, exist_ok=True)

m = rm.Model("brakes")
flywheel = m.add(Inertia("flywheel", J=1.0, phi0=0.0, w0=20.0))
brake = m.add(Brake("brake", mu=0.5, peak=1.2, cgeo=0.1, fn_max=400.0, f_normalized=Step(start_time=0.1)))
mass = m.add(Mass("mass", m=1.0, s0=0.0, v0=1.0))
linear_brake = m.add(LinearBrake("linear_brake", mu=0.5, peak=1.2, fn_max=4.0, f_normalized=Step(start_time=0.1)))
m.connect(flywheel.flange_b, brake.flange)           # the brake's support is grounded when left free
m.connect(mass.flange_b, linear_brake.flange)

res = m.simulate(1.5, dt_out=1e-3)
for ev in res.events:
    print(ev)
print(f"heat: brake {res.final('brake.heat'):.2f} J, linear brake {res.final('linear_brake.heat'):.4f} J")

fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
ax1.plot(res.t, res["flywheel.w"], label="flywheel.w")
ax1.set_ylabel("speed [rad/s]")
ax1b = ax1.twinx()
ax1b.plot(res.t, res["mass.v"], color="C1", label="mass.v")
ax1b.set_ylabel("speed [m/s]")
ax1.legend(loc="upper right")
ax1b.legend(loc="center right")
ax2.plot(res.t, res["brake.heat"], label="brake.heat")
ax2.plot(res.t, 400 * res["linear_brake.heat"], label="linear_brake.heat x 400")
ax2.set_ylabel("heat [J]")
ax2.set_xlabel("time [s]")
ax2.legend()
fig.suptitle("Brakes applied at 0.1 s: slide to rest, then stick")
fig.tight_layout()
fig.savefig(out / "brake.png", dpi=100)
