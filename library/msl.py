"""Examples of the Modelica Standard Library (Mechanics.Rotational.Examples), rebuilt with regmech."""

from __future__ import annotations

import regmech as rm
from regmech.components import Damper, Fixed, IdealGear, Inertia, Spring, Torque
from regmech.signals import Sine, Step


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


def coupled_clutches(*args, **kwargs):  # defined in the stick/slip step
    raise NotImplementedError
