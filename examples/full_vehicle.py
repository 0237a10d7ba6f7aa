"""A full vehicle from components: open differential and wheels on a split-mu road.

    python examples/full_vehicle.py [--out DIR]     (DIR: $REGMECH_EXAMPLES_OUT, else out/)

Every part is a component wired by hand (no library scene): engine and
flywheel -> clutch -> gear -> elastic drive shaft -> ``Differential`` -> two
wheels -> car body with road load. Each wheel is built from its parts as the
``Wheel`` subsystem builds it: wheel inertia ``J``, ``Rolling`` (the rigid
kinematics ``s_tread = s_axle - r phi_hub``), a tread mass, the tyre's
tangential ``SpringDamper``, a contact-patch mass and a ``FrictionContact`` to
the road (stick: the tyre grips; slide: the wheel spins). The left wheel runs
on ice (mu 0.15), the right one on asphalt (mu 0.9): the open differential
passes the same torque to both, so the left wheel spins up and the right one
can only get what the left one's slipping contact holds. Writes
``full_vehicle.png``.
"""

import argparse
import os
from pathlib import Path

import regmech as rm
from regmech.components import (Clutch, Differential, Engine, Fixed, FrictionContact, IdealGear, Inertia, Mass,
                                 RoadLoad, Rolling, Shaft, SpringDamper)
from regmech.signals import Ramp

G = 9.80665                                              # m/s^2
M_CAR = 1300.0                                           # kg

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default=os.environ.get("REGMECH_EXAMPLES_OUT", "out"), help="folder for the figure")
out = Path(parser.parse_args().out)
out.mkdir(parents=True, exist_ok=True)


def wheel(m: rm.Model, name: str, mu: float, fn: float, radius: float = 0.3):
    """Add a wheel's parts to ``m``; returns (hub inertia, axle mass) to connect the drive and the body."""
    hub = m.add(Inertia(f"{name}_J", J=1.2, w0=0.0))                 # wheel, tyre and brake disc [kg m^2]
    axle = m.add(Mass(f"{name}_axle", m=20.0, v0=0.0))               # unsprung mass [kg]
    rolling = m.add(Rolling(f"{name}_rolling", radius=radius))      # s_tread = s_axle - radius phi_hub
    tread = m.add(Mass(f"{name}_tread", m=2.0))
    tyre = m.add(SpringDamper(f"{name}_tyre", c=2e5, d=500.0, domain="translational"))   # N/m, N s/m
    patch = m.add(Mass(f"{name}_patch", m=0.5))
    contact = m.add(FrictionContact(f"{name}_road", mu=mu, peak=1.1, fn=fn))               # fn: normal load [N]
    road = m.add(Fixed(f"{name}_ground", domain="translational"))
    m.connect(hub.flange_b, rolling.hub)
    m.connect(axle.flange_b, rolling.axle)
    m.connect(rolling.tread, tread.flange_a)
    m.connect(tread.flange_b, tyre.flange_a)
    m.connect(tyre.flange_b, patch.flange_a)
    m.connect(patch.flange_b, contact.flange_a)
    m.connect(contact.flange_b, road.flange)
    return hub, axle


m = rm.Model("split_mu_launch")
engine = m.add(Engine("engine", torque_map=[(80.0, 110.0), (200.0, 150.0), (400.0, 160.0), (600.0, 130.0),
                                             (680.0, 0.0)], throttle=0.5))          # (rad/s, N m) full load
flywheel = m.add(Inertia("flywheel", J=0.15, phi0=0.0, w0=150.0))
clutch = m.add(Clutch("clutch", mu=0.3, peak=1.2, cgeo=0.12, fn_max=8000.0,
                      f_normalized=Ramp(height=1.0, duration=1.0, start_time=0.2)))
gearbox_in = m.add(Inertia("gearbox_in", J=0.01, phi0=0.0, w0=0.0))
gear = m.add(IdealGear("gear", ratio=3.6))                                 # phi_a = 3.6 phi_b
gearbox_out = m.add(Inertia("gearbox_out", J=0.02))
driveshaft = m.add(Shaft("driveshaft", stiffness=8000.0, damping=10.0))   # N m/rad, N m s/rad
final_drive_in = m.add(Inertia("final_drive_in", J=0.02))
diff = m.add(Differential("differential", ratio=4.1))                     # carrier = ratio x mean of the sides
left_hub, left_axle = wheel(m, "left", mu=0.15, fn=0.3 * M_CAR * G)
right_hub, right_axle = wheel(m, "right", mu=0.9, fn=0.3 * M_CAR * G)
body = m.add(Mass("body", m=M_CAR))
road_load = m.add(RoadLoad.for_vehicle("road_load", m=M_CAR, c_r=0.012, c_d=0.32, area=2.2))

m.connect(engine.flange, flywheel.flange_a)
m.connect(flywheel.flange_b, clutch.flange_a)
m.connect(clutch.flange_b, gearbox_in.flange_a)
m.connect(gearbox_in.flange_b, gear.flange_a)
m.connect(gear.flange_b, gearbox_out.flange_a)
m.connect(gearbox_out.flange_b, driveshaft.flange_a)
m.connect(driveshaft.flange_b, final_drive_in.flange_a)
m.connect(final_drive_in.flange_b, diff.carrier)
m.connect(diff.left, left_hub.flange_a)
m.connect(diff.right, right_hub.flange_a)
m.connect(left_axle.flange_a, body.flange_a)          # both axles carry the body
m.connect(right_axle.flange_a, body.flange_a)
m.connect(body.flange_b, road_load.flange)

print(m.check())
res = m.simulate(3.0, dt_out=2e-3)
for ev in res.events:
    print(ev)
res.plot(["flywheel.w", "left_J.w", "right_J.w", "body.v", "left_road.f", "right_road.f"],
         units={"w": "rpm", "v": "km/h"}, modes=["clutch", "left_road", "right_road"],
         title="Split-mu launch: the open differential lets the wheel on ice spin",
         path=out / "full_vehicle.png")
