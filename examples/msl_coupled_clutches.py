"""MSL CoupledClutches: four inertias, three clutches, stick and slip.

    python examples/msl_coupled_clutches.py [--out DIR]     (DIR: $REGMECH_EXAMPLES_OUT, else out/)

The Modelica Standard Library's ``Rotational.Examples.CoupledClutches``: a
sinusoidal torque drives J1 (starting at 10 rad/s); clutch1's normal force
follows ``cos(2 pi 0.2 t)`` (it opens when that turns negative), clutch2 and
clutch3 close by steps at 0.4 s and 0.9 s. Every lock-up and break-away is an
event located by the solver and listed in ``res.events``. Writes
``msl_coupled_clutches.png``: speeds, clutch torques, a mode strip per clutch
and every mode change numbered and listed under the plot.
"""

import argparse
import os
from pathlib import Path

from regmech.library import coupled_clutches

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default=os.environ.get("REGMECH_EXAMPLES_OUT", "out"), help="folder for the figure")
out = Path(parser.parse_args().out)
out.mkdir(parents=True, exist_ok=True)

model = coupled_clutches()
res = model.simulate(1.5, dt_out=1e-3)
for ev in res.events:                            # time, device, old mode -> new mode
    print(ev)
res.plot(["J1.w", "J2.w", "J3.w", "J4.w", "clutch1.tau", "clutch2.tau", "clutch3.tau"], events="annotate",
         title="MSL CoupledClutches", path=out / "msl_coupled_clutches.png")
