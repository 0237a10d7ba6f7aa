"""Powertrain ends: the ``Engine`` torque source and the vehicle's ``RoadLoad``.

``Engine`` is a torque source whose torque depends on its own speed through a
full-load torque map, scaled by a throttle signal. ``RoadLoad`` is the sum of
the driving resistances of a vehicle (rolling resistance, aerodynamic drag,
grade), a translational device between the vehicle's ``Mass`` and the ground.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
import sympy

from .._numbers import as_real
from ..component import Device, Param, refuse_positional
from ..errors import ParameterError
from ..ports import ROTATIONAL, TRANSLATIONAL

STANDARD_GRAVITY = 9.80665  # m/s^2


def piecewise_linear(x, points: np.ndarray):
    """Linear interpolation of ``points`` (rows ``(x_k, y_k)``, x increasing) as a
    ``sympy.Piecewise`` in ``x``, held constant beyond the first and last points."""
    xs, ys = points[:, 0], points[:, 1]
    pieces = [(float(ys[0]), x <= float(xs[0]))]
    for k in range(1, len(xs)):
        slope = (ys[k] - ys[k - 1]) / (xs[k] - xs[k - 1])
        pieces.append((float(ys[k - 1]) + float(slope) * (x - float(xs[k - 1])), x <= float(xs[k])))
    pieces.append((float(ys[-1]), True))
    return sympy.Piecewise(*pieces)


def _as_points(value):
    """The map as a float (n, 2) array, or None when it is malformed (then the
    parameter check of the instance raises the proper error)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None
    if arr.ndim != 2 or arr.shape[1] != 2 or len(arr) < 1:
        return None
    return arr


class _MapParam(Param):
    """A map of the engine (``torque_map``, ``drag_map``): setting it moves the instance to the class of
    the new pair of maps."""

    def __set__(self, obj, value):
        points = self.validate(obj, value)
        maps = {"torque_map": obj._values.get("torque_map"), "drag_map": obj._values.get("drag_map")}
        maps[self.name] = points
        obj.__class__ = type(obj)._public._class_for(maps["torque_map"], maps["drag_map"])
        super().__set__(obj, points)


def _engine_shell(public_cls, points, drag=None):
    """For unpickling: an empty instance of the class of the maps."""
    return object.__new__(public_cls._class_for(points, drag))


class Engine(Device):
    """Combustion engine as a torque source with a full-load map and an optional drag map::

        tau = throttle(t) * T_full(w) + (1 - throttle(t)) * T_drag(w),   w = w_flange - w_support  [rad/s]

    ``torque_map``: rows ``(w_k [rad/s], T_k [N m])`` with strictly increasing
    speeds, interpolated linearly and held at the end values outside the
    table (below idle and above the governed speed the torque does not keep
    rising or falling; add an explicit point, e.g. ``(w_max + 10, 0)``, for a
    governor cut-off). ``throttle``: number, signal or callable of t, the
    fraction of full load (normally 0..1; 1 by default). The torque acts on
    ``flange`` and its reaction on ``support`` (grounded when free), as MSL
    ``Torque``: ``flange.tau = -tau``. Exports ``tau``; the engine speed is
    the speed of the inertia on its flange.

    ``drag_map``: rows ``(w_k [rad/s], T_k [N m])``, the drag (motoring) torque
    at closed throttle -- friction and pumping losses, what a vehicle feels as
    engine braking on overrun -- interpolated as the full-load map; it opposes
    the rotation (``T_k <= 0`` at ``w_k >= 0``, ``T_k >= 0`` at ``w_k < 0``).
    Between closed and full throttle the torque is blended linearly (a common
    map-based engine model). Without it, a closed throttle gives no torque at
    all, as before.

    How the map reaches the class kernel: laws are written once per *class*
    with parameters as symbols, and a table is not a scalar parameter. So each
    distinct map gets its own (cached) subclass of ``Engine`` whose law holds
    the map as a ``sympy.Piecewise`` of linear segments; all engines with the
    same map share one subclass and one compiled kernel, and ``isinstance(e,
    Engine)`` holds for all of them. Assigning ``engine.torque_map`` moves the
    instance to the class of the new map.
    """

    kind = "compliant"
    is_source = True
    torque_map = _MapParam(check="table", unit="(rad/s, N m)", doc="full-load torque vs speed")
    drag_map = _MapParam(None, check="table", optional=True, unit="(rad/s, N m)",
                         doc="drag (motoring) torque at closed throttle vs speed, opposing the rotation")
    throttle = Param(1.0, check="signal", unit="1", doc="fraction of full load (0..1)")
    drag_map = _MapParam(None, check="table", optional=True, unit="(rad/s, N m)",
                         doc="drag (motoring) torque <= 0 at closed throttle vs speed")
    flanges = (("flange", ROTATIONAL), ("support", ROTATIONAL, True))
    rel_names = {ROTATIONAL: (None, None, None, "tau")}

    #: on the per-map subclasses: the maps ((n, 2); the drag map None when not given) and the public class
    #: they derive from
    _points: ClassVar[np.ndarray | None] = None
    _drag: ClassVar[np.ndarray | None] = None
    _public: ClassVar[type | None] = None
    _map_classes: ClassVar[dict] = {}

    def __new__(cls, name=None, *args, **params):
        public = cls._public or cls
        refuse_positional(public, (name, *args))
        points = _as_points(params.get("torque_map"))
        drag = params.get("drag_map")
        drag = None if drag is None else _as_points(drag)
        if points is None or (params.get("drag_map") is not None and drag is None):
            return object.__new__(public)      # __init__ reports the malformed map
        return object.__new__(public._class_for(points, drag))

    @classmethod
    def _class_for(cls, points: np.ndarray, drag: np.ndarray | None = None) -> type:
        public = cls._public or cls
        key = (public, points.shape, points.tobytes(), None if drag is None else (drag.shape, drag.tobytes()))
        sub = Engine._map_classes.get(key)
        if sub is None:
            sub = type(public.__name__, (public,), {
                "_points": points.copy(), "_drag": None if drag is None else drag.copy(), "_public": public,
                "__module__": public.__module__, "__qualname__": public.__qualname__, "__doc__": public.__doc__})
            Engine._map_classes[key] = sub
        return sub

    def __reduce_ex__(self, protocol):
        return _engine_shell, (type(self)._public or type(self), self.torque_map, self.drag_map), self.__dict__

    def validate(self):
        drag = self.drag_map
        cls = type(self)
        if cls._points is None or not np.array_equal(cls._points, self.torque_map) \
                or (drag is None) != (cls._drag is None) or (drag is not None and not np.array_equal(cls._drag, drag)):
            raise ParameterError(f"Engine '{self.name}': internal map class mismatch; create the Engine with "
                                 f"Engine(name, torque_map=..., drag_map=..., throttle=...)")
        if drag is not None:
            w, T = drag[:, 0], drag[:, 1]
            if np.any(np.diff(w) <= 0):
                raise ParameterError(f"Engine '{self.name}': drag_map speeds must increase strictly, got {w.tolist()}")
            bad = np.nonzero(((w >= 0) & (T > 0)) | ((w < 0) & (T < 0)))[0]
            if bad.size:
                k = int(bad[0])
                raise ParameterError(
                    f"Engine '{self.name}': drag_map must oppose the rotation (T <= 0 at w >= 0, T >= 0 at w < 0); "
                    f"row {k} is (w={w[k]:g} rad/s, T={T[k]:g} N m). Give the drag torque with its sign, e.g. "
                    f"[(0, 0), (100, -15), (600, -60)]")

    def rows(self):
        # e = phi_support - phi_flange: flange.tau = -tau, power absorbed = -tau * w
        return [{"support": 1.0, "flange": -1.0}]

    def law(self, rel, rel_dot):
        full = piecewise_linear(-rel_dot, self._points)
        if self._drag is None:
            return self.throttle * full
        return self.throttle * full + (1 - self.throttle) * piecewise_linear(-rel_dot, self._drag)


class RoadLoad(Device):
    """Driving resistances of a vehicle, between its ``Mass`` (``flange``) and
    the road (``support``, grounded when free)::

        f = f_roll * tanh(v / v_eps) + c_drag * v * |v| + m * g * sin(grade)   [N]

    with ``v = v_flange - v_support`` [m/s] and ``flange.f = f`` (the vehicle
    receives ``-f``). Parameters: ``f_roll`` [N] >= 0 rolling resistance
    (``c_r * m * g * cos(grade)``), ``c_drag`` [kg/m] >= 0 the drag
    coefficient ``0.5 * rho * c_d * A``, ``grade`` [rad] the road slope
    (positive uphill in the direction of positive s), ``m`` [kg] the mass
    for the grade force, ``g`` [m/s^2], ``v_eps`` [m/s] > 0.

    ``sign(v)`` of the rolling resistance is smoothed to ``tanh(v/v_eps)``:
    the law stays smooth, so no event is needed when the vehicle stops and
    IDA's Newton iteration converges through v = 0. The price: below about
    ``v_eps`` the resistance is smaller than the real one, and a vehicle at
    rest is not *held* by it (it creeps under any force). A rolling resistance
    that sticks (locked at rest until the drive force exceeds it) is a
    friction device with a mode, and belongs with the stick/slip components.
    Keep ``v_eps`` well below the speeds of interest (0.1 m/s by default).

    The grade force is conservative: its potential ``m g sin(grade) s_rel``
    (the height energy) is exported as ``<name>.potential``; rolling resistance
    and drag only dissipate.
    """

    kind = "compliant"
    default_domain = TRANSLATIONAL
    flanges = (("flange", TRANSLATIONAL), ("support", TRANSLATIONAL, True))
    rel_names = {TRANSLATIONAL: ("s_rel", "v_rel", "a_rel", "f")}
    f_roll = Param(0.0, check="nonnegative", unit="N", doc="rolling resistance force")
    c_drag = Param(0.0, check="nonnegative", unit="kg/m", doc="0.5 * air density * c_d * frontal area")
    grade = Param(0.0, unit="rad", doc="road slope angle, positive uphill")
    m = Param(0.0, check="nonnegative", unit="kg", doc="vehicle mass for the grade force")
    g = Param(STANDARD_GRAVITY, check="positive", unit="m/s^2", doc="gravity")
    v_eps = Param(0.1, check="positive", unit="m/s", doc="speed scale of the smoothed sign(v)")

    def validate(self):
        if self.grade != 0.0 and self.m == 0.0:
            raise ParameterError(f"RoadLoad '{self.name}': grade={self.grade} needs the vehicle mass m [kg] for the "
                                 f"grade force m*g*sin(grade); pass m=<vehicle mass>")
        if abs(self.grade) >= math.pi / 2:
            raise ParameterError(f"RoadLoad '{self.name}': grade is an angle in rad and must lie in (-pi/2, pi/2), "
                                 f"got {self.grade}")

    @classmethod
    def for_vehicle(cls, name: str, m: float, c_r: float, c_d: float, area: float, *, rho: float = 1.2,
                    grade: float = 0.0, v_eps: float = 0.1, g: float = STANDARD_GRAVITY) -> "RoadLoad":
        """From vehicle data: mass m [kg], rolling coefficient c_r [-], drag coefficient
        c_d [-], frontal area [m^2], air density rho [kg/m^3], grade [rad]."""
        for pname, val in (("c_r", c_r), ("c_d", c_d), ("area", area), ("rho", rho)):
            x = as_real(val)        # numpy scalars too
            if x is None or not math.isfinite(x) or x < 0:
                raise ParameterError(f"RoadLoad '{name}': {pname} must be a finite number >= 0, got {val!r}")
        c_r, c_d, area, rho = (as_real(v) for v in (c_r, c_d, area, rho))
        return cls(name, f_roll=c_r * m * g * math.cos(grade), c_drag=0.5 * rho * c_d * area,
                   grade=grade, m=m, g=g, v_eps=v_eps)

    def rows(self):
        return [{"flange": 1.0, "support": -1.0}]

    def law(self, rel, rel_dot):
        v = rel_dot
        return (self.f_roll * sympy.tanh(v / self.v_eps) + self.c_drag * v * sympy.Abs(v)
                + self.m * self.g * sympy.sin(self.grade))

    def potential(self, e):
        return self.m * self.g * sympy.sin(self.grade) * e[0]


__all__ = ["Engine", "RoadLoad", "piecewise_linear", "STANDARD_GRAVITY"]
