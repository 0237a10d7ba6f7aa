"""Sensors: blocks whose output is a flange's motion (no force, no power).

Each has one row ``e = x(flange) - x(flange_ref)`` (``flange_ref`` grounded when left free; connect it to
another flange for a relative measurement) with the law 0, and one algebraic output::

    AngleSensor      y = e        [rad]      (rotational; PositionSensor [m] translational)
    SpeedSensor      y = de       [rad/s]    (rotational; VelocitySensor [m/s] translational)
    RelSpeedSensor   y = de       [rad/s]    between flange_a and flange_b (y = w_b - w_a)
    RelAngleSensor   y = e        [rad]      between flange_a and flange_b (y = phi_b - phi_a)
    PowerSensor      y = tau * w  is not offered: read a device's ``power`` from the result instead

A sensor's flange must be connected to a mass (or a node with one): a sensor alone on a node leaves its
motion undetermined, which the structure check refuses.
"""

from __future__ import annotations

from ..ports import ROTATIONAL, TRANSLATIONAL
from .base import Block, Sensor


class AngleSensor(Sensor):
    """``y = phi(flange) - phi(flange_ref)`` [rad] (``flange_ref`` grounded when free)."""

    flanges = (("flange", ROTATIONAL), ("flange_ref", ROTATIONAL, True))
    outputs = {"y": "rad"}

    def output_laws(self, e, de):
        return {"y": e[0]}


class SpeedSensor(Sensor):
    """``y = w(flange) - w(flange_ref)`` [rad/s] (``flange_ref`` grounded when free)."""

    flanges = (("flange", ROTATIONAL), ("flange_ref", ROTATIONAL, True))
    outputs = {"y": "rad/s"}

    def output_laws(self, e, de):
        return {"y": de[0]}


class PositionSensor(Sensor):
    """``y = s(flange) - s(flange_ref)`` [m] (translational; ``flange_ref`` grounded when free)."""

    default_domain = TRANSLATIONAL
    flanges = (("flange", TRANSLATIONAL), ("flange_ref", TRANSLATIONAL, True))
    outputs = {"y": "m"}

    def output_laws(self, e, de):
        return {"y": e[0]}


class VelocitySensor(Sensor):
    """``y = v(flange) - v(flange_ref)`` [m/s] (translational; ``flange_ref`` grounded when free)."""

    default_domain = TRANSLATIONAL
    flanges = (("flange", TRANSLATIONAL), ("flange_ref", TRANSLATIONAL, True))
    outputs = {"y": "m/s"}

    def output_laws(self, e, de):
        return {"y": de[0]}


class _Relative(Block):
    flanges = (("flange_a", ROTATIONAL), ("flange_b", ROTATIONAL))

    def rows(self):
        return [{"flange_b": 1.0, "flange_a": -1.0}]


class RelSpeedSensor(_Relative):
    """``y = w(flange_b) - w(flange_a)`` [rad/s]: a relative speed, e.g. a clutch's slip."""

    outputs = {"y": "rad/s"}

    def output_laws(self, e, de):
        return {"y": de[0]}


class RelAngleSensor(_Relative):
    """``y = phi(flange_b) - phi(flange_a)`` [rad]: a relative angle, e.g. a shaft's twist."""

    outputs = {"y": "rad"}

    def output_laws(self, e, de):
        return {"y": e[0]}


__all__ = ["AngleSensor", "SpeedSensor", "PositionSensor", "VelocitySensor", "RelSpeedSensor", "RelAngleSensor"]
