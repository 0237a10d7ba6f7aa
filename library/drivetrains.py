"""Car drivetrains with stepped transmissions: a 6-speed automatic with torque converter and a
dual-clutch car.

Both share the driveline behind the box (SI units)::

    gearbox output ── propeller shaft (elastic, damped) ── final drive inertia ── Differential(final_drive)
        ── two driven Wheels (r 0.31 m, J 1.1 kg m^2, stick/slip road contact) ── body Mass + VehicleLoad

``six_speed_car``: engine (full-load map x throttle, flywheel) -> ``TorqueConverter`` (stall at
``K(0) sqrt(T)``, lock-up from ``t_lockup``) -> 6-speed ``Gearbox`` shifting up on a time
schedule. The car launches from rest through the converter (the engine runs up towards its
stall speed while the car is held by its inertia), shifts 1-2-3-4 with torque interruption, slip
and lock-up of each shift element, and the lock-up clutch closes in 3rd.

``dct_car``: engine -> ``DualClutchTransmission`` (7 ratios), launch from rest on clutch K1
closing over 1 s, then pre-selected clutch-to-clutch upshifts 1-2-3-4 without torque interruption.
"""

from __future__ import annotations

import regmech as rm
from regmech.components import (Damper, Differential, DualClutchTransmission, Engine, Fixed, Gearbox, Inertia, Mass,
                                 Shaft, TorqueConverter, VehicleLoad, Wheel)
from regmech.signals import Ramp

G = 9.80665

#: full-load torque of a 2.0 l petrol engine [(rad/s, N m)], cut off above 680 rad/s (6,500 rpm)
ENGINE_MAP = [(70.0, 150.0), (200.0, 190.0), (400.0, 200.0), (600.0, 170.0), (680.0, 0.0)]
#: a 6-speed automatic (first to sixth)
SIX_SPEED = [4.17, 2.34, 1.52, 1.14, 0.87, 0.69]
#: a 7-speed dual-clutch box
SEVEN_SPEED_DCT = [3.75, 2.27, 1.53, 1.12, 0.89, 0.74, 0.63]


def _driveline(m, box_out, *, final_drive, m_vehicle, grade, mu_road=0.9):
    """Propeller shaft, final drive, two wheels, body and road load behind ``box_out``."""
    shaft = m.add(Shaft("propshaft", stiffness=6000.0, damping=15.0))
    fd_in = m.add(Inertia("final_drive_in", J=0.03))
    diff = m.add(Differential("differential", ratio=final_drive))
    fn = 0.3 * m_vehicle * G
    wl = m.add(Wheel("wheel_left", radius=0.31, J=1.1, fn=fn, mu=mu_road, peak=1.1, w0=0.0, v0=0.0))
    wr = m.add(Wheel("wheel_right", radius=0.31, J=1.1, fn=fn, mu=mu_road, peak=1.1))
    body = m.add(Mass("body", m=m_vehicle))
    road = m.add(VehicleLoad.for_vehicle("road_load", m=m_vehicle, c_r=0.012, c_d=0.30, area=2.2, grade=grade))
    m.connect(box_out, shaft.flange_a)
    m.connect(shaft.flange_b, fd_in.flange_a)
    m.connect(fd_in.flange_b, diff.carrier)
    m.connect(diff.left, wl.hub)
    m.connect(diff.right, wr.hub)
    m.connect(wl.axle, body.flange_a)
    m.connect(wr.axle, body.flange_a)
    m.connect(body.flange_b, road.flange)


def _engine(m, throttle, w_engine0):
    engine = m.add(Engine("engine", torque_map=ENGINE_MAP, throttle=throttle))
    fly = m.add(Inertia("flywheel", J=0.18, phi0=0.0, w0=w_engine0))
    # pumping and friction losses, ~10 N m at 330 rad/s, at every throttle. Engine(drag_map=...) would blend
    # a drag by 1 - throttle instead (zero at full load, where the full-load map is the net torque); kept as a
    # Damper so that the scenes' tests and work-precision runs keep the model they were made with
    drag = m.add(Damper("engine_drag", d=0.03))
    ground = m.add(Fixed("ground"))
    m.connect(engine.flange, fly.flange_a)
    m.connect(fly.flange_a, drag.flange_a)
    m.connect(drag.flange_b, ground.flange)
    return fly


def six_speed_car(throttle=None, shifts=((0.0, 1), (3.0, 2), (6.0, 3), (9.5, 4)), t_lockup: float = 7.5,
                  final_drive: float = 3.2, m_vehicle: float = 1500.0, grade=0.0, w_engine0: float = 80.0) -> rm.Model:
    """Automatic car: engine -> torque converter -> 6-speed Gearbox -> driveline (simulate ~12 s).

    ``throttle``: signal (default: a ramp from 0.2 to 0.7 over the first 0.5 s); ``shifts``: the gear
    schedule [(t, gear)]; ``t_lockup`` [s]: the converter's lock-up clutch closes over 0.5 s from then;
    ``grade`` [rad] number or signal. Shift elements: 500 N m (1st 700 N m), release 0.1 s, engagement
    0.35 s after a 0.15 s pause (the torque interruption).
    """
    m = rm.Model("six_speed_car")
    fly = _engine(m, Ramp(height=0.5, duration=0.5, offset=0.2) if throttle is None else throttle, w_engine0)
    tc = m.add(TorqueConverter("converter", lockup=Ramp(height=1.0, duration=0.5, start_time=t_lockup),
                               lockup_capacity=450.0))
    gb = m.add(Gearbox("gearbox", ratios=SIX_SPEED, gear=list(shifts), capacity=[700.0] + [500.0] * 5,
                       efficiency=None, J_in=0.02, J_gear=0.004, J_out=0.03, release_time=0.1, engage_time=0.35,
                       shift_delay=0.15))
    m.connect(fly.flange_b, tc.pump)
    m.connect(tc.turbine, gb.flange_a)
    _driveline(m, gb.flange_b, final_drive=final_drive, m_vehicle=m_vehicle, grade=grade)
    return m


def dct_car(throttle: float = 0.6, shifts=((0.0, 1), (2.5, 2), (5.0, 3), (8.0, 4)), final_drive: float = 3.9,
            m_vehicle: float = 1400.0, grade=0.0, w_engine0: float = 160.0) -> rm.Model:
    """Dual-clutch car: engine -> DualClutchTransmission (7 speeds) -> driveline (simulate ~10 s).

    Launch from rest on K1 closing over 1 s (``launch_time``), then upshifts by ``shifts`` with
    pre-selection (synchronisers 0.1 s) and a 0.3 s clutch-to-clutch handover.
    """
    m = rm.Model("dct_car")
    fly = _engine(m, throttle, w_engine0)
    dct = m.add(DualClutchTransmission("dct", ratios=SEVEN_SPEED_DCT, gear=list(shifts), capacity=280.0,
                                       sync_capacity=80.0, sync_time=0.1, handover_time=0.3, launch_time=1.0))
    m.connect(fly.flange_b, dct.flange_a)
    _driveline(m, dct.flange_b, final_drive=final_drive, m_vehicle=m_vehicle, grade=grade)
    return m


__all__ = ["six_speed_car", "dct_car", "ENGINE_MAP", "SIX_SPEED", "SEVEN_SPEED_DCT"]
