"""MSL OneWayClutch: a freewheel that transmits torque one way only.

    python examples/msl_one_way_clutch.py [--out DIR]     (DIR: $REGMECH_EXAMPLES_OUT, else out/)

The Modelica Standard Library's ``Rotational.Examples.OneWayClutch``: a
sinusoidal torque (10 N m at 3 Hz) drives inertiaIn, which drives inertiaOut
through a one-way clutch (a freewheel in parallel with a clutch engaged by
pulses). While the freewheel runs free the output coasts; when the input
overtakes it, the freewheel locks. Writes ``msl_one_way_clutch.png``.
"""

import argparse
import os
from pathlib import Path

from regmech.library import one_way_clutch

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default=os.environ.get("REGMECH_EXAMPLES_OUT", "out"), help="folder for the figure")
out = Path(parser.parse_args().out)
out.mkdir(parents=True, exist_ok=True)

model = one_way_clutch(engaged=True)
res = model.simulate(2.0, dt_out=1e-3)
print(f"{len(res.events)} mode changes; {res.stats}")
res.plot(["inertiaIn.w", "inertiaOut.w", "oneWayClutch.tau"], title="MSL OneWayClutch",
         path=out / "msl_one_way_clutch.png")
