"""Vibration analysis of a car's driveline: modes, forced response, Campbell diagram.

    python examples/modal_analysis.py [--out DIR]     (DIR: $REGMECH_EXAMPLES_OUT, else out/)

The library scene ``vehicle_launch`` is simulated to 2 s (the clutch has
locked at 0.88 s) and linearised there: ``m.linearize(at=res, t=2.0)`` takes
the run's positions, speeds and friction modes at that instant and gives the
structural-matrix form ``M q'' + B q' + C q = W u``. ``modal`` gives the
natural frequencies, damping ratios and mode shapes; ``harmonic_response``
the drive-shaft torque per N m of engine torque; ``campbell`` where the
engine orders 1, 2 and 4 meet the natural frequencies between 800 and
6000 rpm. Writes ``modal_analysis.png`` (the frequency response) and
``modal_analysis_campbell.png``.
"""

import argparse
import os
from pathlib import Path

import numpy as np

from regmech.analysis import harmonic_response, modal
from regmech.library import vehicle_launch

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default=os.environ.get("REGMECH_EXAMPLES_OUT", "out"), help="folder for the figure")
out = Path(parser.parse_args().out)
out.mkdir(parents=True, exist_ok=True)

car = vehicle_launch()
run = car.simulate(2.0, dt_out=1e-2)
lin = car.linearize(at=run, t=2.0)                    # the clutch Stuck, the tyres gripping, as in the run
modes = modal(lin)
print(modes.frequency_table())                        # natural frequencies [Hz] and mode shapes
print(modes.damped.table())                           # damping ratios

freqs = np.linspace(0.5, 80.0, 400)                   # Hz
resp = harmonic_response(lin, ["flywheel.w", "driveshaft.tau"], freqs, inputs="engine.tau")
k = int(np.argmax(resp.amplitude("driveshaft.tau")))
print(f"drive-shaft torque peaks at {freqs[k]:.1f} Hz: {resp.amplitude('driveshaft.tau')[k]:.1f} N m per N m")
resp.plot(out / "modal_analysis.png", units={"w": "rpm"})

diagram = modes.campbell(orders=[1, 2, 4], speed_rpm=(800, 6000))
print(diagram.table())                                # resonance speeds [rpm]
diagram.plot(out / "modal_analysis_campbell.png")
