"""Vehicle scenes: a launch from standstill through a friction clutch."""

from __future__ import annotations

import regmech as rm
from regmech.components import Clutch, IdealGear, Inertia, Mass, Shaft, Wheel
from regmech.components.gearing import Differential
from regmech.components.powertrain import Engine, RoadLoad
from regmech.signals import Ramp

G = 9.80665

#: full-load torque of a 1.6 l petrol engine [(rad/s, N m)], cut-off above 680 rad/s
ENGINE_MAP = [(80.0, 110.0), (200.0, 150.0), (400.0, 160.0), (600.0, 130.0), (680.0, 0.0)]


def vehicle_launch(throttle: float = 0.6, w_engine0: float = 150.0, t_engage: float = 0.2,
                   engage_time: float = 1.0, clutch_fn_max: float = 8000.0, gear_ratio: float = 3.6,
                   final_drive: float = 4.1, m_vehicle: float = 1300.0, mu_road: float = 0.9,
                   shaft_stiffness: float = 8000.0, grade: float = 0.0) -> rm.Model:
    """Front-wheel-drive car launching from standstill in first gear (simulate ~3 s).

    engine (full-load map ``ENGINE_MAP`` x ``throttle``, flywheel 0.15 kg m^2, starts at
    ``w_engine0`` rad/s) -> dry clutch (mu 0.3, cgeo 0.12 m, ``clutch_fn_max`` N, engaged by a
    ramp from ``t_engage`` over ``engage_time`` s) -> gearbox input 0.01 kg m^2 -> ideal gear
    ``gear_ratio`` -> 0.02 kg m^2 -> drive shaft (``shaft_stiffness`` N m/rad, 10 N m s/rad)
    -> 0.02 kg m^2 -> open differential (``final_drive``) -> two driven ``Wheel``s (r 0.3 m,
    J 1.2 kg m^2, each carrying 30 % of the weight, road friction ``mu_road``, peak 1.1) ->
    vehicle body ``m_vehicle`` kg with road load (rolling 0.012 m g, drag 0.5*1.2*0.32*2.2
    kg/m, ``grade`` rad). Physics: the clutch slips while the engine pulls the car away,
    then locks; a low ``mu_road`` with high torque makes the driven wheels spin (sliding
    road contact) instead.
    """
    m = rm.Model("vehicle_launch")
    engine = m.add(Engine("engine", torque_map=ENGINE_MAP, throttle=throttle))
    flywheel = m.add(Inertia("flywheel", J=0.15, phi0=0.0, w0=w_engine0))
    clutch = m.add(Clutch("clutch", mu=0.3, peak=1.2, cgeo=0.12, fn_max=clutch_fn_max,
                          f_normalized=Ramp(height=1.0, duration=engage_time, start_time=t_engage)))
    gb_in = m.add(Inertia("gearbox_in", J=0.01, phi0=0.0, w0=0.0))
    gear = m.add(IdealGear("gear", ratio=gear_ratio))
    gb_out = m.add(Inertia("gearbox_out", J=0.02))
    shaft = m.add(Shaft("driveshaft", stiffness=shaft_stiffness, damping=10.0))
    fd_in = m.add(Inertia("final_drive_in", J=0.02))
    diff = m.add(Differential("differential", ratio=final_drive))
    fn = 0.3 * m_vehicle * G
    wl = m.add(Wheel("wheel_left", radius=0.3, J=1.2, fn=fn, mu=mu_road, peak=1.1, w0=0.0, v0=0.0))
    wr = m.add(Wheel("wheel_right", radius=0.3, J=1.2, fn=fn, mu=mu_road, peak=1.1))
    body = m.add(Mass("body", m=m_vehicle))
    road = m.add(RoadLoad.for_vehicle("road_load", m=m_vehicle, c_r=0.012, c_d=0.32, area=2.2, grade=grade))
    m.connect(engine.flange, flywheel.flange_a)
    m.connect(flywheel.flange_b, clutch.flange_a)
    m.connect(clutch.flange_b, gb_in.flange_a)
    m.connect(gb_in.flange_b, gear.flange_a)
    m.connect(gear.flange_b, gb_out.flange_a)
    m.connect(gb_out.flange_b, shaft.flange_a)
    m.connect(shaft.flange_b, fd_in.flange_a)
    m.connect(fd_in.flange_b, diff.carrier)
    m.connect(diff.left, wl.hub)
    m.connect(diff.right, wr.hub)
    m.connect(wl.axle, body.flange_a)
    m.connect(wr.axle, body.flange_a)
    m.connect(body.flange_b, road.flange)
    return m
