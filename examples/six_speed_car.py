"""Six-speed automatic: torque converter launch, four upshifts, lock-up.

    python examples/six_speed_car.py [--out DIR]     (DIR: $REGMECH_EXAMPLES_OUT, else out/)

The library scene ``six_speed_car``: engine -> ``TorqueConverter`` (pump,
turbine, lock-up clutch closing from 7.5 s) -> six-speed ``Gearbox`` (one shift
clutch per gear: release, torque interruption, slip, lock-up) shifting
1-2-3-4 at 3, 6 and 9.5 s -> propeller shaft, ``Differential``, two ``Wheel``s,
body. Writes ``six_speed_car.png``: engine, turbine and output speeds in rpm,
the vehicle speed in km/h, and a mode strip per shift element.
"""

import argparse
import os
from pathlib import Path

from regmech.library import six_speed_car

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default=os.environ.get("REGMECH_EXAMPLES_OUT", "out"), help="folder for the figure")
out = Path(parser.parse_args().out)
out.mkdir(parents=True, exist_ok=True)

model = six_speed_car()
res = model.simulate(12.0, dt_out=1e-2)
print(res.stats)
friction = ["converter.lockup"] + [f"gearbox.shift{k}" for k in (1, 2, 3, 4)]     # the elements that act
res.plot(["flywheel.w", "converter.turbine.w", "body.v"], units={"w": "rpm", "v": "km/h"}, modes=friction,
         title="Six-speed automatic: converter launch and upshifts", path=out / "six_speed_car.png")
