"""Electric-vehicle scenes: an electric car with a single-speed reduction and regenerative braking, and a
driver following a drive-cycle segment (closed loop).

The car (both scenes)::

    traction machine -> rotor (J_rotor) -> single-speed reduction (ratio) -> reduction output (J_out)
      -> half shafts (c_shaft, d_shaft; rigid when c_shaft is None) -> wheels (J_wheels, radius r)
      -> rigid rolling -> body (m) with road load (rolling c_r m g, drag 0.5 rho c_d A v|v|)

Data of a compact electric car (stated so they can be checked): m = 1600 kg, r = 0.31 m, a 150 kW /
310 N m machine (base speed 484 rad/s = 4620 rpm) with a 0.04 kg m^2 rotor, reduction 9.0 (the
rotor's 12,000 rpm is 156 km/h; the envelope's power limit holds above 60 km/h), J_out = 0.02 kg m^2,
both wheels with hubs and brake discs 2.4 kg m^2, c_r = 0.009, c_d A = 0.29 * 2.3 m^2; the half
shafts 12,000 N m/rad both together, damped by 60 N m s/rad (the shuffle mode of the reduction side
against the car: sqrt(12000 (1/(J_out + 81 J_rotor) + 1/(J_wheels + m r^2))) / 2 pi = 9.8 Hz).
The efficiency maps are typical shapes of a permanent-magnet machine with its inverter (95 % at
the best point, low at light load and low speed), not a measured machine.
"""

from __future__ import annotations

import regmech as rm
from regmech.components import ElectricMotor, Fixed, IdealGear, Inertia, Mass, Rolling, Shaft
from regmech.components.control import Driver
from regmech.components.powertrain import RoadLoad
from regmech.signals import Table

G = 9.80665
KMH = 1.0 / 3.6

#: efficiency of the traction machine over speed [rad/s] (rows) and |torque| [N m] (columns)
ETA_SPEEDS = [0.0, 100.0, 300.0, 600.0, 1300.0]
ETA_TORQUES = [0.0, 50.0, 150.0, 310.0]
ETA_MOTOR = [[0.70, 0.80, 0.78, 0.72],
             [0.80, 0.90, 0.91, 0.88],
             [0.84, 0.94, 0.95, 0.93],
             [0.84, 0.94, 0.95, 0.93],
             [0.80, 0.91, 0.92, 0.90]]
#: the generator quadrants: a little lower than motoring (iron and inverter losses at the same torque)
ETA_GENERATOR = [[0.68, 0.78, 0.76, 0.70],
                 [0.78, 0.88, 0.89, 0.86],
                 [0.82, 0.92, 0.93, 0.91],
                 [0.82, 0.92, 0.93, 0.91],
                 [0.78, 0.89, 0.90, 0.88]]

#: accelerate at full command, ease off, cruise, then brake regeneratively (t [s], command [1])
EV_COMMAND = [(0.0, 0.0), (0.2, 1.0), (6.0, 1.0), (6.5, 0.15), (9.0, 0.15), (9.5, -0.6), (16.0, -0.6),
              (16.5, 0.0)]

#: drive-cycle segment (t [s], v [km/h]): the first two hills of the ECE-15 urban cycle, idle shortened
#: to 2 s before each launch
CYCLE_KMH = [(0.0, 0.0), (2.0, 0.0), (6.0, 15.0), (14.0, 15.0), (19.0, 0.0), (21.0, 0.0), (33.0, 32.0),
             (57.0, 32.0), (68.0, 0.0), (70.0, 0.0)]


def _car(m: rm.Model, drive_flange_owner, *, ratio, m_vehicle, radius, j_rotor, j_out, j_wheels, c_shaft,
         d_shaft, c_r, cd_a):
    """The driveline from the rotor to the road; returns (rotor, wheels, body)."""
    rotor = m.add(Inertia("rotor", J=j_rotor, phi0=0.0, w0=0.0))
    gear = m.add(IdealGear("reduction", ratio=ratio))
    out = m.add(Inertia("reduction_out", J=j_out))
    wheels = m.add(Inertia("wheels", J=j_wheels))
    rolling = m.add(Rolling("rolling", radius=radius))
    road = m.add(Fixed("road", domain="translational"))
    body = m.add(Mass("body", m=m_vehicle, s0=0.0, v0=0.0))
    load = m.add(RoadLoad.for_vehicle("road_load", m=m_vehicle, c_r=c_r, c_d=cd_a, area=1.0))
    m.connect(drive_flange_owner, rotor.flange_a)
    m.connect(rotor.flange_b, gear.flange_a)
    m.connect(gear.flange_b, out.flange_a)
    if c_shaft is None:
        link = m.add(IdealGear("half_shafts", ratio=1.0))
    else:
        link = m.add(Shaft("half_shafts", stiffness=c_shaft, damping=d_shaft))
    m.connect(out.flange_b, link.flange_a)
    m.connect(link.flange_b, wheels.flange_a)
    m.connect(wheels.flange_b, rolling.hub)
    m.connect(rolling.axle, body.flange_a)
    m.connect(rolling.tread, road.flange)
    m.connect(body.flange_b, load.flange)
    return rotor, wheels, body


CAR = dict(ratio=9.0, m_vehicle=1600.0, radius=0.31, j_rotor=0.04, j_out=0.02, j_wheels=2.4, c_shaft=12000.0,
           d_shaft=60.0, c_r=0.009, cd_a=0.29 * 2.3)


def electric_car(command=None, tau_max: float = 310.0, p_max: float = 150e3, **car) -> rm.Model:
    """Electric car with a single-speed reduction driven by a map-based ``ElectricMotor`` (simulate ~17 s).

    ``command``: the machine's torque demand in [-1, 1] (default ``EV_COMMAND``: full torque from rest,
    cruise, then regenerative braking at 60 % of the envelope); ``tau_max`` [N m], ``p_max`` [W]; the
    car data (``CAR``) may be overridden by keyword. Read ``motor.p_el`` (battery side, negative while
    regenerating), ``motor.efficiency``, ``body.v``.
    """
    params = CAR | car
    m = rm.Model("electric_car")
    cmd = Table(EV_COMMAND) if command is None else command
    motor = m.add(ElectricMotor("motor", command=cmd, tau_max=tau_max, p_max=p_max, eta_speeds=ETA_SPEEDS,
                                eta_torques=ETA_TORQUES, eta=ETA_MOTOR, eta_gen=ETA_GENERATOR))
    _car(m, motor.flange, **params)
    return m


def driver_cycle(cycle=None, k: float = 1.0, T_i: float = 2.0, tau_max: float = 310.0, p_max: float = 150e3,
                 tau_brake: float = 2500.0, regen: float = 0.7, **car) -> rm.Model:
    """A driver launches the electric car and follows a drive-cycle segment (closed loop; simulate 70 s).

    ``cycle``: (t [s], v [km/h]) points (default ``CYCLE_KMH``, the first two ECE-15 hills); a
    ``Driver`` reads the body's speed and works the traction machine (``tau_max``, ``p_max``) and,
    for ``1 - regen`` of the brake pedal, a friction brake on the wheels (``tau_brake`` [N m] at full
    pedal); ``k`` [s/m] and ``T_i`` [s] its PI gains. Read ``driver.throttle``, ``driver.pedal_brake``,
    ``driver.error`` [m/s], ``body.v``.
    """
    params = CAR | car
    pts = CYCLE_KMH if cycle is None else cycle
    m = rm.Model("driver_cycle")
    driver = m.add(Driver("driver", v_ref=Table([(t, v * KMH) for t, v in pts]), k=k, T_i=T_i, tau_max=tau_max,
                          p_max=p_max, tau_brake=tau_brake, regen=regen))
    _, wheels, body = _car(m, driver.drive, **params)
    m.connect(driver.vehicle, body.flange_b)
    m.connect(driver.brake, wheels.flange_b)
    return m


__all__ = ["electric_car", "driver_cycle", "CAR", "EV_COMMAND", "CYCLE_KMH", "ETA_SPEEDS", "ETA_TORQUES",
           "ETA_MOTOR", "ETA_GENERATOR"]
