"""Component classes (names and parameters follow the Modelica Standard Library)."""

from .backlash import Backlash, ElastoBacklash
from .electric import DCMotor, ElectricMotor, SeriesDCMotors
from .control import PI, Controller, Driver, PICommand
from .elastic import Damper, Shaft, Spring, SpringDamper, TwoFlangeCompliant
from .friction import BearingFriction, Brake, Clutch, FrictionContact, FrictionDevice, LossyGear, OneWayClutch
from .gears import IdealGear
from .gearing import Differential, LimitedSlipDifferential, LossyDifferential, LossyPlanetary, Planetary
from .inertial import Fixed, Inertia, Mass
from .powertrain import Engine, RoadLoad
from .wheel import MagicFormulaTyre, MagicFormulaWheel, Rolling, Wheel
from .sources import Force, LinearPosition, LinearSpeed, Position, Speed, Torque
from .gearbox import DualClutchTransmission, Gearbox
from .converter import ConverterFluid, TorqueConverter
from .stops import ElastoGap, EndStop, HardStop, LinearHardStop, MassWithStopAndFriction
from .laws import Stribeck
from .heat import ThermalMass  # noqa: F401  (a law object like Stribeck: importable here, not a component)
from .accel import Accelerate, LinearAccelerate
from .loads import (InverseSpeedDependentForce, InverseSpeedDependentTorque, LinearBrake, LinearSpeedDependentForce,
                    LinearSpeedDependentTorque, QuadraticSpeedDependentForce, QuadraticSpeedDependentTorque, SignForce,
                    SignTorque, VehicleLoad)

__all__ = [
    "Fixed", "Inertia", "Mass",
    "Spring", "Damper", "SpringDamper", "Shaft", "TwoFlangeCompliant",
    "IdealGear", "Differential", "Planetary", "LossyPlanetary", "LimitedSlipDifferential", "LossyDifferential",
    "Backlash", "ElastoBacklash",
    "Engine", "RoadLoad",
    "Clutch", "OneWayClutch", "LossyGear", "Brake", "FrictionContact", "BearingFriction", "FrictionDevice",
    "Rolling", "Wheel", "MagicFormulaTyre", "MagicFormulaWheel",
    "Torque", "Force", "Position", "Speed", "LinearPosition", "LinearSpeed",
    "DCMotor", "SeriesDCMotors", "ElectricMotor", "Controller", "PI", "PICommand", "Driver",
    "Gearbox", "DualClutchTransmission", "TorqueConverter", "ConverterFluid",
    "EndStop", "ElastoGap", "HardStop", "LinearHardStop", "MassWithStopAndFriction", "LinearBrake", "VehicleLoad", "Accelerate", "LinearAccelerate",
    "LinearSpeedDependentTorque", "QuadraticSpeedDependentTorque", "SignTorque", "InverseSpeedDependentTorque",
    "LinearSpeedDependentForce", "QuadraticSpeedDependentForce", "SignForce", "InverseSpeedDependentForce",
]
