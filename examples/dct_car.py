"""Dual-clutch car: launch on clutch K1, then clutch-to-clutch upshifts.

    python examples/dct_car.py [--out DIR]     (DIR: $REGMECH_EXAMPLES_OUT, else out/)

The library scene ``dct_car``: engine -> ``DualClutchTransmission`` (odd gears
behind K1, even gears behind K2, synchronisers pre-select the next gear) ->
driveline with ``Differential`` and two ``Wheel``s. The car launches on K1
closing over 1 s, then shifts 1-2-3-4 at 2.5, 5 and 8 s by handing the torque
from one clutch to the other in 0.3 s, without interruption. Writes
``dct_car.png`` with the speeds and the two clutches' modes.
"""

import argparse
import os
from pathlib import Path

from regmech.library import dct_car

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default=os.environ.get("REGMECH_EXAMPLES_OUT", "out"), help="folder for the figure")
out = Path(parser.parse_args().out)
out.mkdir(parents=True, exist_ok=True)

model = dct_car()
res = model.simulate(10.0, dt_out=1e-2)
print(f"{len(res.events)} mode changes; {res.stats}")
res.plot(["flywheel.w", "dct.K1.flange_b.w", "dct.K2.flange_b.w", "body.v"], units={"w": "rpm", "v": "km/h"},
         modes=["dct.K1", "dct.K2"], title="Dual-clutch car: launch and power-on upshifts",
         path=out / "dct_car.png")
