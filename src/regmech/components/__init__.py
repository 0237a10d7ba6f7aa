"""Component classes (names and parameters follow the Modelica Standard Library)."""

from .elastic import Damper, Shaft, Spring, SpringDamper, TwoFlangeCompliant
from .friction import BearingFriction, Brake, Clutch, FrictionContact, FrictionDevice, OneWayClutch
from .gears import IdealGear
from .inertial import Fixed, Inertia, Mass
from .sources import Force, LinearPosition, LinearSpeed, Position, Speed, Torque

__all__ = [
    "Fixed", "Inertia", "Mass",
    "Spring", "Damper", "SpringDamper", "Shaft", "TwoFlangeCompliant",
    "IdealGear",
    "Clutch", "OneWayClutch", "Brake", "FrictionContact", "BearingFriction", "FrictionDevice",
    "Torque", "Force", "Position", "Speed", "LinearPosition", "LinearSpeed",
]
