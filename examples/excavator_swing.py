"""Excavator swing drive: two DC motors on one armature circuit, backlash, dry friction.

    python examples/excavator_swing.py [--out DIR]     (DIR: $REGMECH_EXAMPLES_OUT, else out/)

The library scene ``excavator_swing``: the upper structure of a mining
excavator is swung by two DC motors fed in series (``SeriesDCMotors``: one
armature current, a state of the DAE), each through a shaft with backlash to
the turntable, which dry friction (``BearingFriction``) holds until the
shafts' torques break it away. The supply voltage rises over 0.5 s to reach
a tenth of the nominal speed. Writes ``excavator_swing.png``: motor and
turntable speeds, shaft torques and the friction's mode.
"""

import argparse
import os
from pathlib import Path

from regmech.library import excavator_swing

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default=os.environ.get("REGMECH_EXAMPLES_OUT", "out"), help="folder for the figure")
out = Path(parser.parse_args().out)
out.mkdir(parents=True, exist_ok=True)

model = excavator_swing()
res = model.simulate(3.0, dt_out=1e-3)
for ev in res.events:
    print(ev)
res.plot(["motor_1.w", "motor_2.w", "turntable.w", "backlash_1.tau", "backlash_2.tau"],
         title="Excavator swing drive: two motors in series, backlash, stick/slip",
         path=out / "excavator_swing.png")
