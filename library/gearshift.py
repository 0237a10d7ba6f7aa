"""A 1-2 upshift of a planetary automatic transmission: brake released, clutch applied.

One simple planetary set does both gears::

    engine torque -> input (engine + turbine + sun, J_in)
      sun --- Planetary (ratio = ring teeth / sun teeth) --- carrier (J_out) -> output shaft
      ring (J_ring) --- brake B1 to the housing   (1st gear: ring held)
      ring (J_ring) --- clutch C2 to the input      (2nd gear: sun locked to ring -> direct)
    output shaft (elastic, damped) -> vehicle (reflected to the gearbox output, J_veh)

Kinematics (Willis): ``(1 + r) w_carrier = w_sun + r w_ring``. Ring held:
``w_in / w_out = 1 + r`` (1st); sun locked to ring: ``w_in = w_ring = w_out`` (2nd).

Quasi-static torques with the brake still holding and the clutch slipping
(``w_sun > w_ring = 0``) with torque ``T_c``, engine torque ``T_e``::

    output torque    T_out   = (1 + r) (T_e - T_c)
    brake reaction   T_brake = r T_e - (1 + r) T_c

so as the clutch picks up torque the output torque falls from the 1st-gear
level ``(1 + r) T_e`` towards (and past) the 2nd-gear level ``T_e``: the
*torque phase*. When the brake's falling capacity can no longer hold the ring,
the brake breaks away, the ring speeds up and the engine is pulled down to the
output speed: the *inertia phase*, during which the clutch torque exceeds what
the engine delivers (the engine's inertia gives up energy) and the output
torque rises above the 2nd-gear level, until the clutch locks and the box is in
direct drive. Both friction devices have real masses on both sides (the input,
the ring, the housing), as regularity requires; the ring's own inertia is what
lets the brake and the clutch each change mode on their own.

Default parameters (a mid-size car with a 200 N m engine; SI units):

* ``r = 2`` (sun 40, ring 80 teeth): 1st 3:1, 2nd direct;
* ``J_in = 0.25 kg m^2`` (engine, locked converter, sun), ``J_ring = 0.03``,
  ``J_out = 0.05`` (carrier and output shaft flange);
* vehicle 1500 kg, wheel radius 0.3 m, final drive 3.5: reflected to the gearbox
  output ``J_veh = 1500 * 0.3^2 / 3.5^2 = 11 kg m^2``;
* output shaft (propeller shaft, final drive and half shafts reflected to the
  gearbox output) ``c = 5000 N m/rad``, ``d = 20 N m s/rad``: about 7 Hz in 1st;
* wet multi-plate friction ``mu = 0.12``, peak 1.2 (static over kinetic); the
  capacities are given as torques (``clutch_capacity`` = ``1.5 T_e`` reaches
  well beyond the ``r/(1+r) T_e`` the clutch must carry in the torque phase,
  ``brake_capacity`` = ``2.5 T_e``, 1.25 times the ``r T_e`` it holds in 1st, so
  with ``peak`` it holds 1st gear with a margin of 1.5);
* the shift at ``t_shift = 0.2 s``: the clutch pressure rises linearly over
  ``clutch_time = 0.3 s``, the brake is released linearly over
  ``brake_time = 0.2 s``;
* start in 1st gear with the engine at 300 rad/s and the output shaft twisted
  to the quasi-static torque of 1st gear, so the run starts without a jerk.

Simulate about 1 s. What happens (IDA at default settings): the clutch engages
slipping at 0.2 s, the brake breaks away at 0.367 s and is free at 0.4 s, the
clutch locks at 0.646 s. The output torque (``-output_shaft.tau``; MSL sign,
``tau = c (phi_vehicle - phi_output)``) is 496 N m in 1st, dips to ~100 N m in
the torque phase, rises to ~428 N m in the inertia phase and, after a shock at
the lock, settles at the direct-drive value 194 N m. The clutch turns ~18 kJ of
the engine's (and the input inertia's) energy into heat.
"""

from __future__ import annotations

import regmech as rm
from regmech.components import Brake, Clutch, Damper, Fixed, Inertia, Planetary, Shaft, Torque
from regmech.signals import Ramp

#: friction coefficient of the wet plates and the effective radius x faces [m]
MU_WET = 0.12
CGEO_CLUTCH = 0.08 * 8
CGEO_BRAKE = 0.10 * 8


def gear_shift(torque: float = 200.0, ratio: float = 2.0, w_in0: float = 300.0, j_in: float = 0.25,
               j_ring: float = 0.03, j_out: float = 0.05, j_vehicle: float = 11.0,
               shaft_stiffness: float = 5000.0, shaft_damping: float = 20.0, clutch_capacity: float = 300.0,
               brake_capacity: float = 500.0, peak: float = 1.2, t_shift: float = 0.2,
               clutch_time: float = 0.3, brake_time: float = 0.2) -> rm.Model:
    """Planetary 1-2 upshift (see the module docstring for the physics and defaults).

    ``torque`` [N m] constant engine torque on the input; ``ratio`` ring/sun teeth;
    ``w_in0`` [rad/s] start speed of the input in 1st gear; inertias [kg m^2];
    ``shaft_stiffness`` [N m/rad], ``shaft_damping`` [N m s/rad] of the output shaft;
    ``clutch_capacity``, ``brake_capacity`` [N m] kinetic torques at full pressure
    (static: ``peak`` times that); at ``t_shift`` [s] the clutch is applied over
    ``clutch_time`` [s] and the brake released over ``brake_time`` [s] (linear ramps).
    """
    m = rm.Model("gear_shift")
    housing = m.add(Fixed("housing"))
    engine = m.add(Torque("engine", tau=torque))
    w_out0 = w_in0 / (1.0 + ratio)
    # quasi-static 1st gear: all masses accelerate together, the shaft carries the vehicle's share
    j_first = j_in * (1.0 + ratio) ** 2 + j_out + j_vehicle
    shaft_torque = j_vehicle * (1.0 + ratio) * torque / j_first
    inp = m.add(Inertia("input", J=j_in, phi0=0.0, w0=w_in0))
    ring = m.add(Inertia("ring", J=j_ring, phi0=0.0, w0=0.0))
    out = m.add(Inertia("output", J=j_out))
    vehicle = m.add(Inertia("vehicle", J=j_vehicle, phi0=-shaft_torque / shaft_stiffness, w0=w_out0))
    gearset = m.add(Planetary("planetary", ratio=ratio))
    clutch = m.add(Clutch("clutch", mu=MU_WET, peak=peak, cgeo=CGEO_CLUTCH,
                          fn_max=clutch_capacity / (MU_WET * CGEO_CLUTCH),
                          f_normalized=Ramp(height=1.0, duration=clutch_time, start_time=t_shift)))
    brake = m.add(Brake("brake", mu=MU_WET, peak=peak, cgeo=CGEO_BRAKE,
                        fn_max=brake_capacity / (MU_WET * CGEO_BRAKE),
                        f_normalized=Ramp(height=-1.0, duration=brake_time, start_time=t_shift, offset=1.0)))
    shaft = m.add(Shaft("output_shaft", stiffness=shaft_stiffness, damping=shaft_damping))
    m.connect(engine.flange, inp.flange_a)
    m.connect(engine.support, housing.flange)
    m.connect(inp.flange_b, gearset.sun)
    m.connect(gearset.ring, ring.flange_a)
    m.connect(gearset.carrier, out.flange_a)
    m.connect(inp.flange_b, clutch.flange_a)
    m.connect(clutch.flange_b, ring.flange_b)
    m.connect(ring.flange_b, brake.flange)
    m.connect(brake.support, housing.flange)
    m.connect(out.flange_b, shaft.flange_a)
    m.connect(shaft.flange_b, vehicle.flange_a)
    return m


__all__ = ["gear_shift"]
