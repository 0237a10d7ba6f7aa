"""A launch clutch under slip control, heating up: a controller's command as a clutch's normal force and
the clutch's lumped thermal mass with fade, both inside the DAE.

An engine governed at ``w_engine`` (a ``Speed`` source on its flywheel) launches a vehicle, reduced to an
inertia ``J_vehicle`` with a speed-proportional load ``d_load``, through a dry clutch. A ``PICommand``
reads the clutch slip ``w_engine - w_vehicle`` and sets the clutch's normalised normal force to follow a
slip reference that holds ``slip0`` and then ramps to zero from ``t_close`` over ``close_time``, so the
clutch slides, heats its thermal mass (``C`` [J/K], convection ``G`` [W/K]) whose friction coefficient
fades above 330 K, and finally locks (mode Stuck) with the controller holding the normal force. Signals:
``clutch.T`` [K], ``clutch.heat``, ``clutch.heat_stored``, ``clutch.heat_to_ambient`` [J], ``slip_ctl.u``.
"""

from __future__ import annotations

import regmech as rm
from regmech.components import Clutch, Damper, Fixed, Inertia, Speed
from regmech.components.control import PICommand
from regmech.components.heat import ThermalMass
from regmech.signals import Ramp

#: fade of the clutch lining: full friction to 330 K, 70 % at 530 K
FADE = [(330.0, 1.0), (530.0, 0.7)]


def slip_control(w_engine: float = 150.0, slip0: float = 40.0, t_close: float = 3.0, close_time: float = 2.0,
                 J_vehicle: float = 4.0, d_load: float = 0.4, C: float = 800.0, G: float = 4.0,
                 k: float = -0.01, T_i: float = 0.5):
    """Launch clutch under PI slip control, its lining heating into fade, then locking (simulate ~8 s).

    ``w_engine`` [rad/s] governed engine speed, ``slip0`` [rad/s] the slip held until ``t_close`` [s], then
    ramped to zero over ``close_time`` [s]; ``J_vehicle`` [kg m^2], ``d_load`` [N m s/rad]; the clutch's thermal
    mass ``C`` [J/K] with convection ``G`` [W/K]; the controller's gain ``k`` [1/(rad/s)] (negative: more slip,
    less normal force) and integral time ``T_i`` [s] (module docstring)."""
    m = rm.Model("slip_control")
    ground = m.add(Fixed("ground"))
    engine = m.add(Speed("engine", w_ref=w_engine))
    fly = m.add(Inertia("flywheel", J=0.25, w0=w_engine))
    clutch = m.add(Clutch("clutch", mu=0.35, cgeo=0.15, fn_max=6000.0,
                          thermal=ThermalMass(C=C, G=G, T_amb=300.0, fade=FADE)))
    car = m.add(Inertia("vehicle", J=J_vehicle, w0=0.0))
    load = m.add(Damper("load", d=d_load))
    ctl = m.add(PICommand("slip_ctl", w_ref=Ramp(height=-slip0, duration=close_time, start_time=t_close,
                                                  offset=slip0), k=k, T_i=T_i))
    clutch.f_normalized = ctl.command("u")
    m.connect(engine.flange, fly.flange_a)
    m.connect(fly.flange_b, clutch.flange_a)
    m.connect(clutch.flange_b, car.flange_a)
    m.connect(car.flange_b, load.flange_a)
    m.connect(load.flange_b, ground.flange)
    m.connect(ctl.sensor, fly.flange_a)          # the slip: w_flywheel - w_vehicle
    m.connect(ctl.sensor_ref, car.flange_a)
    return m


__all__ = ["slip_control", "FADE"]
