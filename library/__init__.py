"""Ready-made models and scenes (each uses only the public API).

``regmech.library.first()`` builds MSL's Rotational.Examples.First, and so on;
``SCENES`` maps scene names to builder functions.
"""

from .chains import chain_drive, train
from .msl import coupled_clutches, first, friction, one_way_clutch
from .vehicle import vehicle_launch
from .excavator import excavator_swing
from .gearshift import gear_shift
from .electric import driver_cycle, electric_car
from .drivetrains import dct_car, six_speed_car
from .clutch_control import slip_control

SCENES = {
    "first": first,
}

SCENES["coupled_clutches"] = coupled_clutches
SCENES["one_way_clutch"] = one_way_clutch
SCENES["train"] = train
SCENES["chain_drive"] = chain_drive
SCENES["vehicle_launch"] = vehicle_launch
SCENES["excavator_swing"] = excavator_swing
SCENES["gear_shift"] = gear_shift
SCENES["electric_car"] = electric_car
SCENES["driver_cycle"] = driver_cycle
SCENES["six_speed_car"] = six_speed_car
SCENES["dct_car"] = dct_car
SCENES["slip_control"] = slip_control

__all__ = ["SCENES", "train", "chain_drive", "first", "coupled_clutches", "one_way_clutch", "friction", "vehicle_launch",
           "excavator_swing", "gear_shift", "electric_car", "driver_cycle", "six_speed_car", "dct_car",
           "slip_control"]
