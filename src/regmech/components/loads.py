"""Loads users reach for: speed-dependent torques and forces (pumps, fans, brakes, winders), a
longitudinal ``VehicleLoad`` with a time-varying grade and wind, and a translational
``LinearBrake``.

**Speed-dependent loads** act between ``flange`` and ``support`` (grounded when free), with
``w = w_flange - w_support`` and the load ``tau = flange.tau`` [N m] (the flange receives
``-tau``; power absorbed ``tau * w``)::

    LinearSpeedDependentTorque      tau = tau_nominal * w / w_nominal
    QuadraticSpeedDependentTorque   tau = tau_nominal * w |w| / w_nominal^2
    SignTorque                      tau = tau_nominal * tanh(w / w_eps)             (Coulomb, smoothed)
    InverseSpeedDependentTorque     tau = tau_nominal * w_nominal * w / max(w^2, w_eps^2)

``tau_nominal`` [N m] is the load at the nominal speed ``w_nominal`` [rad/s] > 0. With
``tau_nominal >= 0`` every one of them opposes the motion and only dissipates (``tau * w >= 0``);
a negative ``tau_nominal`` makes it drive. The inverse law (constant power
``tau_nominal * w_nominal``, a winder or a power-limited brake) is linear below ``w_eps`` so it
stays finite at rest. The translational versions (``LinearSpeedDependentForce``, ...) take
``f_nominal`` [N] and ``v_nominal`` [m/s].

``SignTorque`` smooths the sign as ``RoadLoad`` does (``tanh``): it does not *hold* a load at
rest. A Coulomb friction that sticks is a friction device (``Brake``, ``BearingFriction``).
"""

from __future__ import annotations

import math

import sympy

from ..component import Device, Param
from ..errors import ParameterError
from ..ports import ROTATIONAL, TRANSLATIONAL
from ._symbolic import SpeedAbove
from .friction import Clutch
from .powertrain import STANDARD_GRAVITY


class _SpeedLoad(Device):
    kind = "compliant"
    flanges = (("flange", ROTATIONAL), ("support", ROTATIONAL, True))
    rel_names = {ROTATIONAL: ("phi_rel", "w_rel", "a_rel", "tau")}
    #: names of the nominal load and speed parameters (rotational or translational)
    _names = ("tau_nominal", "w_nominal")

    def rows(self):
        return [{"flange": 1.0, "support": -1.0}]

    def shape(self, w, w_nom, w_eps):
        raise NotImplementedError

    def law(self, rel, rel_dot):
        load, speed = self._names
        return getattr(self, load) * self.shape(rel_dot, getattr(self, speed), self.w_eps)


def _shapes():
    return {
        "Linear": ("tau = tau_nominal * w / w_nominal", lambda w, wn, we: w / wn),
        "Quadratic": ("tau = tau_nominal * w |w| / w_nominal^2", lambda w, wn, we: w * sympy.Abs(w) / wn ** 2),
        "Sign": ("tau = tau_nominal * tanh(w / w_eps)", lambda w, wn, we: sympy.tanh(w / we)),
        # max(w^2, w_eps^2) as SpeedAbove(w, w_eps)^2, not a Piecewise with w / w^2: numpy evaluates both branches
        # of a Piecewise, and the inverse one at w = 0 (a load starting at rest) divided by zero on the output rows
        # there (a RuntimeWarning from inside the kernels, fuzz seed 80263; the value taken was the other branch's)
        "Inverse": ("tau = tau_nominal * w_nominal * w / max(w^2, w_eps^2)",
                    lambda w, wn, we: wn * w / SpeedAbove(w, we) ** 2),
    }


def _make(prefix: str, translational: bool):
    text, fn = _shapes()[prefix]
    if translational:
        name = f"{prefix}SpeedDependentForce" if prefix != "Sign" else "SignForce"
        load, speed = "f_nominal", "v_nominal"
        text = text.replace("tau_nominal", "f_nominal").replace("w_nominal", "v_nominal").replace(
            "tau =", "f =").replace("w_eps", "v_eps").replace("w", "v").replace("v_nominal", "v_nominal")
        body = {
            "default_domain": TRANSLATIONAL,
            "flanges": (("flange", TRANSLATIONAL), ("support", TRANSLATIONAL, True)),
            "rel_names": {TRANSLATIONAL: ("s_rel", "v_rel", "a_rel", "f")},
            "f_nominal": Param(check="real", unit="N", doc="load force at the nominal speed (>= 0: opposes motion)"),
            "v_nominal": Param(1.0, check="positive", unit="m/s", doc="nominal speed"),
            "w_eps": Param(1e-3, check="positive", unit="m/s", doc="smoothing speed (sign, inverse laws)"),
        }
        unit_note = "f [N], v [m/s]"
    else:
        name = f"{prefix}SpeedDependentTorque" if prefix != "Sign" else "SignTorque"
        load, speed = "tau_nominal", "w_nominal"
        body = {
            "tau_nominal": Param(check="real", unit="N m", doc="load torque at the nominal speed (>= 0: opposes motion)"),
            "w_nominal": Param(1.0, check="positive", unit="rad/s", doc="nominal speed"),
            "w_eps": Param(1e-3, check="positive", unit="rad/s", doc="smoothing speed (sign, inverse laws)"),
        }
        unit_note = "tau [N m], w [rad/s]"
    body["_names"] = (load, speed)
    body["shape"] = lambda self, w, wn, we: fn(w, wn, we)
    body["__doc__"] = (f"Speed-dependent load (module docstring): ``{text}`` ({unit_note}); the flange "
                       f"receives ``-load``, the support (grounded when free) the reaction.")
    body["__module__"] = __name__
    cls = type(name, (_SpeedLoad,), body)
    cls.__qualname__ = name
    return cls


LinearSpeedDependentTorque = _make("Linear", False)
QuadraticSpeedDependentTorque = _make("Quadratic", False)
SignTorque = _make("Sign", False)
InverseSpeedDependentTorque = _make("Inverse", False)
LinearSpeedDependentForce = _make("Linear", True)
QuadraticSpeedDependentForce = _make("Quadratic", True)
SignForce = _make("Sign", True)
InverseSpeedDependentForce = _make("Inverse", True)


class VehicleLoad(Device):
    """Longitudinal driving resistances with a time-varying grade and wind, between the vehicle's
    ``Mass`` (``flange``) and the road (``support``, grounded when free)::

        f = c_r m g cos(grade(t)) tanh(v / v_eps)           rolling resistance (normal force at that grade)
          + c_drag (v - v_wind(t)) |v - v_wind(t)|           aerodynamic drag on the air speed
          + m g sin(grade(t))                                 grade force     [N]

    ``v = v_flange - v_support`` [m/s]; the vehicle receives ``-f``. ``grade`` [rad] (signal, in
    (-pi/2, pi/2), positive uphill in the direction of positive s), ``wind`` [m/s] (signal, the air
    moving in the direction of positive s: a tailwind is positive), ``m`` [kg], ``c_r`` [-],
    ``c_drag = 0.5 rho c_d A`` [kg/m] (``VehicleLoad.for_vehicle`` computes it), ``g`` [m/s^2],
    ``v_eps`` [m/s] the smoothing of the rolling resistance's sign (see ``RoadLoad``).

    Energy: rolling resistance dissipates; with a grade that changes in time the grade force has
    no potential of the position alone, so its work (negative downhill) is part of the device's
    ``power``, as is the work of the wind (a tailwind faster than the car pushes it). The books
    still close: the device's power is what it takes from the vehicle. For a constant grade and no
    wind ``RoadLoad`` exports the height energy as a potential instead.
    """

    kind = "compliant"
    default_domain = TRANSLATIONAL
    flanges = (("flange", TRANSLATIONAL), ("support", TRANSLATIONAL, True))
    rel_names = {TRANSLATIONAL: ("s_rel", "v_rel", "a_rel", "f")}
    m = Param(check="positive", unit="kg", doc="vehicle mass")
    c_r = Param(0.0, check="nonnegative", unit="1", doc="rolling resistance coefficient")
    c_drag = Param(0.0, check="nonnegative", unit="kg/m", doc="0.5 * air density * c_d * frontal area")
    grade = Param(0.0, check="signal", unit="rad", bounds=(-1.5707, 1.5707), doc="road slope, positive uphill",
                  bounds_note="; the grade is an angle in rad within (-pi/2, pi/2) (a 10 % slope is atan(0.1))")
    wind = Param(0.0, check="signal", unit="m/s", doc="wind speed along +s (tailwind > 0)")
    g = Param(STANDARD_GRAVITY, check="positive", unit="m/s^2", doc="gravity")
    v_eps = Param(0.1, check="positive", unit="m/s", doc="speed scale of the smoothed sign(v)")

    @classmethod
    def for_vehicle(cls, name: str, *, m: float, c_r: float, c_d: float, area: float, rho: float = 1.2,
                    grade=0.0, wind=0.0, v_eps: float = 0.1, g: float = STANDARD_GRAVITY) -> "VehicleLoad":
        """From vehicle data: m [kg], c_r [-], drag coefficient c_d [-], frontal area [m^2], air density
        rho [kg/m^3]; grade and wind numbers or signals."""
        for pname, val in (("c_d", c_d), ("area", area), ("rho", rho)):
            if not isinstance(val, (int, float)) or isinstance(val, bool) or not math.isfinite(val) or val < 0:
                raise ParameterError(f"VehicleLoad '{name}': {pname} must be a finite number >= 0, got {val!r}")
        return cls(name, m=m, c_r=c_r, c_drag=0.5 * rho * c_d * area, grade=grade, wind=wind, v_eps=v_eps, g=g)

    def rows(self):
        return [{"flange": 1.0, "support": -1.0}]

    def law(self, rel, rel_dot):
        v = rel_dot
        air = v - self.wind
        return (self.c_r * self.m * self.g * sympy.cos(self.grade) * sympy.tanh(v / self.v_eps)
                + self.c_drag * air * sympy.Abs(air) + self.m * self.g * sympy.sin(self.grade))


class LinearBrake(Clutch):
    """Translational brake (MSL ``Translational.Components.Brake``): friction between ``flange``
    and ``support`` (grounded when free), ``v_rel = v_flange - v_support`` [m/s]; normal force
    ``fn = fn_max * f_normalized(t)`` [N], kinetic force ``mu(|v_rel|) fn`` (``mu``, ``mu_table`` of
    (m/s, mu) points or ``mu_law``), static ``peak`` times that; free when ``f_normalized <= 0``.
    Modes as every friction device: Stuck 0, Forward 1, Backward -1, Free 2. ``cgeo`` is fixed to 1
    (a translational brake has no lever arm)."""

    default_domain = TRANSLATIONAL
    flanges = (("flange", TRANSLATIONAL), ("support", TRANSLATIONAL, True))
    rel_names = {TRANSLATIONAL: ("s_rel", "v_rel", "a_rel", "f")}
    mu_table = Param(None, check="table", optional=True, unit="(m/s, 1)", doc="(v_rel [m/s], mu) points for v_rel >= 0")

    def validate(self):
        super().validate()
        if self.cgeo != 1.0:
            raise ParameterError(f"LinearBrake '{self.name}': cgeo must stay 1 (a translational brake has no "
                                 f"lever arm); scale fn_max instead")

    def rows(self):
        return [{"support": -1.0, "flange": 1.0}]


__all__ = ["LinearSpeedDependentTorque", "QuadraticSpeedDependentTorque", "SignTorque", "InverseSpeedDependentTorque",
           "LinearSpeedDependentForce", "QuadraticSpeedDependentForce", "SignForce", "InverseSpeedDependentForce",
           "VehicleLoad", "LinearBrake"]
