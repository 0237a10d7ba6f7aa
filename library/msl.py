"""Examples of the Modelica Standard Library (Mechanics.Rotational.Examples), rebuilt with regmech."""

from __future__ import annotations

import regmech as rm
from regmech.components import Brake, Clutch, Damper, Fixed, IdealGear, Inertia, OneWayClutch, Spring, SpringDamper, Torque
from regmech.signals import Constant, Pulse, Sine, Step


def first(amplitude: float = 10.0, freq_hz: float = 5.0, j_motor: float = 0.1, j_load: float = 2.0,
          ratio: float = 10.0, damping: float = 10.0) -> rm.Model:
    """MSL ``Rotational.Examples.First``: a motor drives a load through a gear and an elastic shaft.

    torque ``amplitude*sin(2 pi freq_hz t)`` [N m] -> inertia1 (J = ``j_motor``) -> ideal gear
    (``ratio``) -> inertia2 (J = 2, starts at rest at phi = 0) -> spring (c = 1e4 N m/rad)
    -> inertia3 (J = ``j_load``, starts at rest); a damper (d = ``damping``) from inertia2 to
    the ground. Simulate 1 s (the reference covers 0..1 s).
    """
    m = rm.Model("First")
    fixed = m.add(Fixed("fixed"))
    torque = m.add(Torque("torque", tau=Sine(amplitude=amplitude, freq_hz=freq_hz)))
    inertia1 = m.add(Inertia("inertia1", J=j_motor))
    gear = m.add(IdealGear("idealGear", ratio=ratio))
    inertia2 = m.add(Inertia("inertia2", J=2.0, phi0=0.0, w0=0.0))
    spring = m.add(Spring("spring", c=1e4))
    inertia3 = m.add(Inertia("inertia3", J=j_load, w0=0.0))
    damper = m.add(Damper("damper", d=damping))
    m.connect(torque.support, fixed.flange)
    m.connect(torque.flange, inertia1.flange_a)
    m.connect(inertia1.flange_b, gear.flange_a)
    m.connect(gear.support, fixed.flange)
    m.connect(gear.flange_b, inertia2.flange_a)
    m.connect(inertia2.flange_b, spring.flange_a)
    m.connect(spring.flange_b, inertia3.flange_a)
    m.connect(damper.flange_a, inertia2.flange_b)
    m.connect(damper.flange_b, fixed.flange)
    return m


def coupled_clutches(fn_max: float = 20.0, peak: float = 1.1, mu: float = 0.5, t2: float = 0.4,
                     t3: float = 0.9, freq_hz: float = 5.0, amplitude: float = 10.0, w0: float = 10.0) -> rm.Model:
    """MSL ``Rotational.Examples.CoupledClutches``: four inertias coupled by three clutches.

    torque ``amplitude*sin(2 pi freq_hz t)`` -> J1 (J = 1, starts at phi = 0, w = ``w0``)
    -> clutch1 -> J2 -> clutch2 -> J3 -> clutch3 -> J4 (all J = 1). Clutches: mu = ``mu``,
    ``peak``, ``fn_max`` [N], cgeo = 1; normal forces: clutch1 ``cos(2 pi 0.2 t)`` (a sine with
    phase pi/2), clutch2 a unit step at ``t2``, clutch3 a unit step at ``t3``. Simulate 1.5 s.
    """
    import math
    m = rm.Model("CoupledClutches")
    fixed = m.add(Fixed("fixed"))
    torque = m.add(Torque("torque", tau=Sine(amplitude=amplitude, freq_hz=freq_hz)))
    J = [m.add(Inertia("J1", J=1.0, phi0=0.0, w0=w0))] + [m.add(Inertia(f"J{k}", J=1.0)) for k in (2, 3, 4)]
    signals = [Sine(amplitude=1.0, freq_hz=0.2, phase=math.pi / 2), Step(start_time=t2), Step(start_time=t3)]
    clutches = [m.add(Clutch(f"clutch{k + 1}", mu=mu, peak=peak, cgeo=1.0, fn_max=fn_max, f_normalized=s))
                for k, s in enumerate(signals)]
    m.connect(torque.support, fixed.flange)
    m.connect(torque.flange, J[0].flange_a)
    for k, cl in enumerate(clutches):
        m.connect(J[k].flange_b, cl.flange_a)
        m.connect(cl.flange_b, J[k + 1].flange_a)
    return m


def one_way_clutch(engaged: bool = True) -> rm.Model:
    """MSL ``Rotational.Examples.OneWayClutch`` (``engaged=True``) and ``OneWayClutchDisengaged``.

    torque -> inertiaIn (J = 1, starts at w = -0.5) -> one-way clutch (peak 25, fn_max 3 N)
    -> inertiaOut (J = 1, at rest). Engaged: torque ``10 sin(2 pi 3 t)``, engagement pulses
    (width 50 %, period 1.3 s, from 0.3 s). Disengaged: torque ``0.3 + 10 sin(2 pi 2 t)``,
    engagement 0, and a constant load torque -0.3 N m on inertiaOut. Simulate 2 s.
    """
    m = rm.Model("OneWayClutch" if engaged else "OneWayClutchDisengaged")
    torque = m.add(Torque("torque", tau=Sine(amplitude=10.0, freq_hz=3.0) if engaged
                          else Sine(amplitude=10.0, freq_hz=2.0, offset=0.3)))
    j_in = m.add(Inertia("inertiaIn", J=1.0, phi0=0.0, w0=-0.5))
    owc = m.add(OneWayClutch("oneWayClutch", peak=25.0, fn_max=3.0,
                             f_normalized=Pulse(amplitude=1.0, width=50.0, period=1.3, start_time=0.3)
                             if engaged else Constant(0.0)))
    j_out = m.add(Inertia("inertiaOut", J=1.0, phi0=0.0, w0=0.0))
    m.connect(torque.flange, j_in.flange_a)
    m.connect(j_in.flange_b, owc.flange_a)
    m.connect(owc.flange_b, j_out.flange_a)
    if not engaged:
        load = m.add(Torque("torqueLoad", tau=-0.3))
        m.connect(j_out.flange_b, load.flange)
    return m


def lossy_gear_demo(number: int = 1) -> rm.Model:
    """MSL ``Rotational.Examples.LossyGearDemo1/2/3`` (simulate 0.5, 0.5 and 1 s).

    1: Inertia1 (J 1) driven by ``10 sin(2 pi t)`` -> LossyGear (ratio 2, efficiency 0.5 both ways)
       -> Inertia2 (J 1.5, at rest) loaded by a ramp from -10 to -5 N m over 2 s: the gear rolls
       forward, backward and sticks.
    2: as 1 with a BearingFriction (tau table [(0, 0.5), (1, 1)]) between the torque and Inertia1.
    3: ratio 1, loss table [0, 0.25, 0.25, 0.625, 2.5]; both inertias (J 0.001) start at 10 rad/s,
       a load step of 1 N m at 0.5 s on Inertia2: a case where the driving side is not obvious.
    """
    from regmech.components import BearingFriction, LossyGear
    from regmech.signals import Ramp
    if number not in (1, 2, 3):
        raise rm.ParameterError(f"lossy_gear_demo: number must be 1, 2 or 3, got {number!r}")
    m = rm.Model(f"LossyGearDemo{number}")
    if number in (1, 2):
        gear = m.add(LossyGear("gear", ratio=2.0, loss_table=[[0.0, 0.5, 0.5, 0.0, 0.0]]))
        j1 = m.add(Inertia("Inertia1", J=1.0))
        j2 = m.add(Inertia("Inertia2", J=1.5, phi0=0.0, w0=0.0))
        t1 = m.add(Torque("torque1", tau=Sine(amplitude=10.0, freq_hz=1.0)))
        t2 = m.add(Torque("torque2", tau=Ramp(height=5.0, duration=2.0, offset=-10.0)))
        if number == 2:
            bf = m.add(BearingFriction("bearingFriction", tau_table=[(0.0, 0.5), (1.0, 1.0)]))
            m.connect(t1.flange, bf.flange)
            m.connect(bf.flange, j1.flange_a)
        else:
            m.connect(t1.flange, j1.flange_a)
    else:
        gear = m.add(LossyGear("gear", ratio=1.0, loss_table=[[0.0, 0.25, 0.25, 0.625, 2.5]]))
        j1 = m.add(Inertia("Inertia1", J=0.001, w0=10.0))
        j2 = m.add(Inertia("Inertia2", J=0.001, phi0=0.0, w0=10.0))
        t1 = m.add(Torque("torque1", tau=0.0))
        t2 = m.add(Torque("torque2", tau=Step(height=1.0, start_time=0.5)))
        m.connect(t1.flange, j1.flange_a)
    m.connect(j1.flange_b, gear.flange_a)
    m.connect(gear.flange_b, j2.flange_a)
    m.connect(j2.flange_b, t2.flange)
    return m


def friction(start_time: float = 0.5) -> rm.Model:
    """MSL ``Rotational.Examples.Friction``: a drive train with a clutch and a brake (simulate 3 s).

    torque ``200 sin(100 t)`` [N m] until ``start_time``, 0 after (MSL's sine times a step down; here a second
    source ``-200 sin(100 t)`` from ``start_time`` on) -> inertia3 (J 1, w 100 rad/s) -> clutch (fn_max 160 N,
    f_normalized 1, mu 0.5, peak 1) -> inertia2 (J 0.05, w 90) -> SpringDamper (c 160 N m/rad, d 1 N m s/rad)
    -> inertia1 (J 1, w 90), braked to the ground by a brake (fn_max 1600 N) engaged by a unit step at
    ``start_time``. All angles start at 0.
    """
    import math
    w = 100.0                                  # 2 pi f with f = 50/pi Hz
    m = rm.Model("Friction")
    fixed = m.add(Fixed("fixed"))
    torque = m.add(Torque("torque", tau=Sine(amplitude=200.0, freq_hz=w / (2 * math.pi))))
    stop = m.add(Torque("torque_stop", tau=Sine(amplitude=-200.0, freq_hz=w / (2 * math.pi), phase=w * start_time,
                                                  start_time=start_time)))
    inertia3 = m.add(Inertia("inertia3", J=1.0, phi0=0.0, w0=100.0))
    clutch = m.add(Clutch("clutch", fn_max=160.0, f_normalized=1.0))
    inertia2 = m.add(Inertia("inertia2", J=0.05, phi0=0.0, w0=90.0))
    spring = m.add(SpringDamper("spring", c=160.0, d=1.0))
    brake = m.add(Brake("brake", fn_max=1600.0, f_normalized=Step(start_time=start_time)))
    inertia1 = m.add(Inertia("inertia1", J=1.0, phi0=0.0, w0=90.0))
    for src in (torque, stop):
        m.connect(src.support, fixed.flange)
        m.connect(src.flange, inertia3.flange_a)
    m.connect(inertia3.flange_b, clutch.flange_a)
    m.connect(clutch.flange_b, inertia2.flange_a)
    m.connect(inertia2.flange_b, spring.flange_a)
    m.connect(spring.flange_b, brake.flange)
    m.connect(brake.flange, inertia1.flange_a)
    m.connect(brake.support, fixed.flange)
    return m
