"""Causal signal blocks evaluated inside the DAE: sensors, static functions, dynamic blocks, controllers and
sample-and-hold (see ``blocks.base`` for how they become unknowns and rows of the DAE).

Every block's inputs are keyword signals (``u=``, ``ref=``, ``u1=``...), its outputs attributes (``.y``); any
parameter of any component that takes a signal takes a block output::

    ws = m.add(SpeedSensor("ws")); m.connect(ws.flange, J.flange_b)
    pi = m.add(PI("pi", u=ws.y, ref=100.0, k=1.0, T_i=0.1, y_min=-24.0, y_max=24.0))
    mot = m.add(DCMotor("mot", u=pi.y, R=1.0, L=1e-3, k=0.1))

The outputs are exported as result signals ``res["pi.y"]``.
"""

from .base import Block, Input, Output, Sensor
from .continuous import PI, PID, Integrator, Lag, ShiftElement
from .discrete import Hysteresis, SampleClock, SampleHold, ShiftSchedule
from .math import Compare, Constant, Feedback, Gain, Max, Min, Product, Saturation, Sum, Switch, Table1D
from .sensors import AngleSensor, PositionSensor, RelAngleSensor, RelSpeedSensor, SpeedSensor, VelocitySensor

__all__ = ["Block", "Input", "Output", "Sensor", "PI", "PID", "Integrator", "Lag", "SampleHold", "SampleClock",
           "Hysteresis", "ShiftSchedule", "ShiftElement",
           "Compare", "Constant", "Feedback", "Gain", "Max", "Min", "Product", "Saturation", "Sum", "Switch",
           "Table1D", "AngleSensor", "PositionSensor", "RelAngleSensor", "RelSpeedSensor", "SpeedSensor",
           "VelocitySensor"]
