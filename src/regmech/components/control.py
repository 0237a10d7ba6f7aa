"""Closed-loop control: controllers that read sensors and drive actuators.

Design (how a loop stays an acausal DAE of a regular mechanical system):
a controller is one massless *device*. Each **sensor** is a row of the
device between a sensed flange and its reference flange (grounded when left
free), ``e_s = phi(sensor) - phi(sensor_ref)``: the controller reads the
angle ``e_s`` and the speed ``de_s`` and exerts *no force* there (the row's
law is 0, so a sensor absorbs no power and changes no motion). Each
**actuator** is a row like a ``Torque`` source's, ``e_a = phi(support) -
phi(actuator)``, whose law is the controller's output (a torque or force,
positive driving the actuated flange forward). The controller's states
(integrators, filters) are the device's internal ``states`` with their
start parameters, so they join the DAE like a DC motor's current; signals
(a reference speed) are signal parameters. Everything a controller computes
is a law of its own rows and states, so the layers are kept: the compiler,
the hybrid layer and the solvers see one more compliant device with states
and never know it controls anything.

Sensing: ``phi`` and ``w`` of any flange (leave ``<sensor>_ref`` free, the
ground), the relative angle and speed of two flanges (connect
``<sensor>_ref`` to the other one), a translational ``s``/``v``; the torque
of a compliant device is read from its law (``c * phi_rel + d * w_rel`` of a
sensor spanning the device's flanges). What a controller drives: its own
actuator rows, with any law of the output and the actuated speed (a torque
source, an engine's ``throttle * T_full(w)``, an electric machine's
``command * T_env(w)``, a smoothed brake). The normal force of a
stick/slip ``Clutch``, ``Brake`` or ``FrictionContact`` is driven by a
*command*: a named output (``commands = {"u": "1"}``) that exerts nothing
itself; ``Clutch(..., f_normalized=ctl.command("u"))`` makes the clutch's
normal force that value, evaluated from the state wherever the hybrid layer
reads it (residual, Jacobian, event functions, mode logic:
``compile.friction_inputs``), so stick, slip, break-away and engagement
follow the loop.

User controllers are a small class: declare ``sensors`` and ``actuators``
(name -> ``"rotational"``/``"translational"``), ``states`` with their start
parameters, ``Param`` attributes, and write ``outputs(m)`` (actuator name ->
output) and ``rates(m)`` (one expression per state) from the measurements
``m`` (``m.phi[s]``, ``m.w[s]`` of the sensors, ``m.w_act[a]`` the speed of
an actuated flange, ``self.<state>``, ``self.<param>``, ``self.time``)
with arithmetic and sympy functions. ``clip``, ``positive_part`` and
``smooth_sign`` below are kink-free-at-rest helpers that lambdify to numpy
without a 1/0 in an unused branch. ``signals(m)`` (optional) names
expressions exported after the run as ``<controller>.<name>``.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import sympy

from ..component import Device, Param
from ..errors import ModelError, ParameterError
from ..ports import ROTATIONAL, TRANSLATIONAL
from .electric import envelope, signal_series


def clip(x, lo, hi):
    """``min(max(x, lo), hi)`` for ``lo <= hi`` as ``(|x - lo| - |x - hi| + lo + hi) / 2``: continuous,
    with a finite derivative everywhere (``Min``/``Max`` do not lambdify to plain numpy)."""
    return (abs(x - lo) - abs(x - hi) + lo + hi) / 2


def positive_part(x):
    """``max(x, 0) = (x + |x|) / 2``."""
    return (x + abs(x)) / 2


def smooth_sign(x, eps):
    """``tanh(x / eps)``: the sign of a speed, smoothed below ``eps`` (a brake that opposes motion
    without an event; it does not hold a body at rest)."""
    return sympy.tanh(x / eps)


class Measurements:
    """What a controller reads: ``phi``/``w`` of each sensor (``s``/``v`` for translational ones, same
    dictionaries) and ``w_act`` the speed of each actuated flange relative to its support."""

    def __init__(self, phi: dict, w: dict, w_act: dict):
        self.phi, self.w, self.w_act = phi, w, w_act


def _domain(cls, what, name, dom):
    if dom not in (ROTATIONAL, TRANSLATIONAL):
        raise ModelError(f"{cls.__name__}: {what} '{name}' must be 'rotational' or 'translational', got {dom!r}")
    return dom


def _class_name(obj) -> str:
    """The controller class's name, also while its laws are written symbolically (``self`` a proxy)."""
    return getattr(obj, "_cls", type(obj)).__name__


class Controller(Device):
    """Base of closed-loop controllers (see the module docstring for the design).

    Rows: one per sensor, ``e_s = phi(s) - phi(s_ref)`` with law 0 (reads, exerts nothing); one per
    actuator, ``e_a = phi(a_support) - phi(a)`` with law ``outputs(m)[a]`` (flange ``a`` receives
    the output, its support the reaction, as MSL ``Torque``). States: ``states`` (name -> start
    parameter), rates from ``rates(m)``. Flanges: ``<s>``, ``<s>_ref`` (grounded when free) per
    sensor, ``<a>``, ``<a>_support`` (grounded when free) per actuator.
    """

    kind = "compliant"
    is_source = True
    sensors: ClassVar[dict[str, str]] = {}
    actuators: ClassVar[dict[str, str]] = {}
    #: named outputs read by other devices (a clutch's normal force), name -> unit; no flange, no force
    commands: ClassVar[dict[str, str]] = {}
    rel_names = {ROTATIONAL: (None, None, None, None), TRANSLATIONAL: (None, None, None, None)}
    derived_units: ClassVar[dict[str, str]] = {}
    #: units of the names ``signals`` returns
    signal_units: ClassVar[dict[str, str]] = {}

    def __init_subclass__(cls, **kwargs):
        flanges = []
        for s, dom in cls.sensors.items():
            dom = _domain(cls, "sensor", s, dom)
            flanges += [(s, dom), (f"{s}_ref", dom, True)]
        for a, dom in cls.actuators.items():
            dom = _domain(cls, "actuator", a, dom)
            flanges += [(a, dom), (f"{a}_support", dom, True)]
        cls.flanges = tuple(flanges)
        cls.derived_units = {**{a: ("N m" if d == ROTATIONAL else "N") for a, d in cls.actuators.items()},
                             **cls.commands, **cls.signal_units}
        super().__init_subclass__(**kwargs)

    def command(self, key: str):
        """A ``Command`` reading this controller's output ``key`` (declared in ``commands``), to drive a
        ``Clutch``'s or ``Brake``'s ``f_normalized`` or a ``FrictionContact``'s ``fn``."""
        from ..component import Command
        if key not in self.commands:
            raise ModelError(f"{type(self).__name__} '{self.name}' has no command {key!r}; its commands are "
                             f"{sorted(self.commands)} (declare commands = {{'{key}': 'unit'}} on the class and "
                             f"return it from outputs())")
        return Command(self, key)

    def command_law(self, e, de, key):
        """The expression of command ``key`` (``outputs(m)[key]``), written symbolically by the compiler."""
        out = self.outputs(self._measure(e, de))
        if key not in out:
            raise ModelError(f"{_class_name(self)}: outputs() gave no value for command '{key}'; return a dict "
                             f"with one entry per actuator and per command")
        return self._checked("outputs()", [(key, out[key])])[0]

    # -- what a subclass writes ------------------------------------------------------------------
    def outputs(self, m: Measurements) -> dict:
        """Actuator or command name -> torque [N m] or force [N], or the command's value (sympy-compatible)."""
        raise NotImplementedError(f"{type(self).__name__} must define outputs(m)")

    def rates(self, m: Measurements) -> list:
        """Time derivatives of ``states``, in their order (sympy-compatible)."""
        return []

    def signals(self, m: Measurements) -> dict:
        """Named expressions exported after the run (units in ``signal_units``)."""
        return {}

    # -- the device ------------------------------------------------------------------------------
    def rows(self):
        rows = [{s: 1.0, f"{s}_ref": -1.0} for s in self.sensors]
        return rows + [{f"{a}_support": 1.0, a: -1.0} for a in self.actuators]

    def _measure(self, e, de) -> Measurements:
        ns = len(self.sensors)
        names = list(self.sensors)
        return Measurements({s: e[i] for i, s in enumerate(names)}, {s: de[i] for i, s in enumerate(names)},
                            {a: -de[ns + j] for j, a in enumerate(self.actuators)})

    def __init__(self, name: str, **params):
        if not self.sensors and not self.actuators:
            raise ModelError(f"{type(self).__name__} '{name}': a controller needs at least one sensor or actuator; "
                             f"declare sensors = {{'name': 'rotational'}} and/or actuators = {{...}} on the class")
        super().__init__(name, **params)

    def _checked(self, what, values):
        """Expressions of ``outputs``/``rates`` as sympy (a str or another object would reach the kernel
        as an unknown name and fail there, far from the cause)."""
        out = []
        for key, val in values:
            if isinstance(val, bool) or not isinstance(val, (int, float, np.floating, np.integer, sympy.Basic)):
                raise ModelError(f"{_class_name(self)}: {what} gave {val!r} for '{key}'; it must be a number or "
                                 f"an expression of the measurements, states and parameters (arithmetic and "
                                 f"sympy functions)")
            out.append(val)
        return out

    def laws(self, e, de):
        out = self.outputs(self._measure(e, de))
        missing = set(self.actuators) - set(out)
        if missing:
            raise ModelError(f"{_class_name(self)}: outputs() gave no value for actuator(s) {sorted(missing)}; "
                             f"return a dict with one entry per actuator")
        return [0] * len(self.sensors) + self._checked("outputs()", [(a, out[a]) for a in self.actuators])

    #: a controller's switching surfaces are its output limits (``limit_surfaces``)
    switching_kind = "limit"

    def limit_surfaces(self, v, lo, hi):
        """The switching surfaces of ``clip(v, lo, hi)``: ``[(v - hi, +1), (lo - v, -1)]`` (state +1 at the
        upper limit, -1 at the lower one, 0 between them). A controller with limits returns them from
        ``switching_surfaces(e, de)`` (through ``self._measure(e, de)``, as ``PI`` does), so every solver
        stops at the kink the limit puts in the law instead of stepping across it: DOP853's error estimate
        misses such a step (fuzz seed 30124: a PI leaving its limit, 4.4e-3 of the speed's range off at
        rtol 1e-10 while the energy books of its own signals failed); each change is an ``Event`` of
        kind "limit" in ``Result.events``."""
        return [(v - hi, 1), (lo - v, -1)]

    def derivatives(self, e, de):
        rates = list(self.rates(self._measure(e, de)))
        return self._checked("rates()", zip(list(self.states) + ["?"] * len(rates), rates))

    def derived(self, t, left, e, de, tau, z):
        ns = len(self.sensors)
        out = {a: tau[ns + j] for j, a in enumerate(self.actuators)}
        if self.signal_units or self.commands:
            out.update(self._evaluate_signals(t, left, e, de, z))
        return out

    def _evaluate_signals(self, t, left, e, de, z) -> dict:
        """``signals(m)`` over the output instants: written symbolically (as the laws are), then
        lambdified once per class and evaluated on the arrays."""
        cls = type(self)
        cache = cls.__dict__.get("_signals_fn")
        k = len(self.rows())
        names = [n for n, p in cls.param_specs().items() if p.check in ("real", "positive", "nonnegative",
                                                                          "nonzero", "signal")]
        if cache is None:
            es = sympy.symbols(f"_e0:{k}", real=True)
            des = sympy.symbols(f"_de0:{k}", real=True)
            zs = [sympy.Symbol(f"_z_{s}", real=True) for s in cls.states]
            ts = sympy.Symbol("_t", real=True)
            ps = [sympy.Symbol(n, real=True) for n in names]
            proxy = _Symbols(cls, dict(zip(names, ps)) | dict(zip(cls.states, zs)) | {"time": ts})
            measured = cls._measure(proxy, list(es), list(des))
            exprs = dict(cls.signals(proxy, measured))
            if cls.commands:
                outs = cls.outputs(proxy, measured)
                exprs.update({key: outs[key] for key in cls.commands})
            keys = list(cls.commands) + list(cls.signal_units)
            fn = sympy.lambdify(list(es) + list(des) + zs + ps + [ts], [sympy.sympify(exprs[n]) for n in keys],
                                modules="numpy")
            cache = (keys, fn)
            type.__setattr__(cls, "_signals_fn", cache)
        keys, fn = cache
        values = []
        for n in names:
            val = self._values[n]
            values.append(signal_series(val, t, left) if hasattr(val, "value") else val)
        res = fn(*e, *de, *[z[s] for s in cls.states], *values, t)
        return {n: np.broadcast_to(np.asarray(r, float), np.shape(t)) for n, r in zip(keys, res)}


class _Symbols:
    """``self`` of a controller while its ``signals`` are written symbolically."""

    def __init__(self, cls, symbols):
        object.__setattr__(self, "_cls", cls)
        object.__setattr__(self, "_syms", symbols)

    def __getattr__(self, name):
        syms = object.__getattribute__(self, "_syms")
        if name in syms:
            return syms[name]
        attr = getattr(object.__getattribute__(self, "_cls"), name)
        return attr.__get__(self) if hasattr(attr, "__get__") and callable(attr) else attr


class PI(Controller):
    """PI speed controller with output limits and anti-windup (back-calculation)::

        r = w_ref(t) - w                      speed error [rad/s] (w: the sensor's speed)
        v = k r + I                           unlimited output [N m]
        u = clip(v, u_min, u_max)             output, the torque on ``flange`` [N m]
        dI/dt = (k / T_i) r + (u - v) / T_t   integral part; while limited, I is pulled back so
                                              that v tracks u with time constant T_t (no windup)

    Flanges: ``sensor`` (the measured inertia; ``sensor_ref`` grounded when free, or on another
    flange for a relative speed), ``flange`` (the driven inertia; ``flange_support`` grounded when
    free). ``k`` [N m s/rad] > 0 the gain, ``T_i`` [s] > 0 the integral time, ``T_t`` [s] > 0 the
    tracking time (``T_i`` when not given), ``u_min`` < ``u_max`` [N m] the limits, ``I0`` [N m] the
    start of the integral part. Exports the state ``I``, derived ``flange`` (the applied torque u),
    ``v`` (unlimited) [N m] and ``error`` [rad/s].

    Unlimited, on a plant ``J w' = u - d w`` with ``w_ref`` a step, the loop is the second-order
    system ``J w'' + (d + k) w' + (k / T_i) w = (k / T_i) w_ref + k w_ref'``.
    """

    sensors = {"sensor": ROTATIONAL}
    actuators = {"flange": ROTATIONAL}
    states = {"I": "I0"}
    signal_units = {"v": "N m", "error": "rad/s"}
    w_ref = Param(check="signal", unit="rad/s", doc="reference speed")
    k = Param(check="positive", unit="N m s/rad", doc="proportional gain")
    T_i = Param(check="positive", unit="s", doc="integral time")
    T_t = Param(None, check="positive", optional=True, unit="s", doc="anti-windup tracking time (default T_i)")
    u_max = Param(check="real", unit="N m", doc="upper output limit")
    u_min = Param(check="real", unit="N m", doc="lower output limit")
    I0 = Param(0.0, unit="N m", doc="start of the integral part")

    def validate(self):
        unit = self.param_unit("u_max")
        if not self.u_min < self.u_max:
            raise ParameterError(f"{type(self).__name__} '{self.name}': needs u_min < u_max, got u_min={self.u_min}, "
                                 f"u_max={self.u_max} [{unit}]")
        if self.T_t is None:
            self._values["T_t"] = self.T_i
        if not self.u_min <= self.I0 <= self.u_max:
            raise ParameterError(f"{type(self).__name__} '{self.name}': the start I0={self.I0} [{unit}] lies outside "
                                 f"the output limits [{self.u_min}, {self.u_max}]; start the integral part inside them")

    def _parts(self, m):
        r = self.w_ref - m.w["sensor"]
        v = self.k * r + self.I
        return r, v, clip(v, self.u_min, self.u_max)

    def outputs(self, m):
        return {"flange": self._parts(m)[2]}

    def switching_surfaces(self, e, de):
        return self.limit_surfaces(self._parts(self._measure(e, de))[1], self.u_min, self.u_max)

    def rates(self, m):
        r, v, u = self._parts(m)
        return [self.k / self.T_i * r + (u - v) / self.T_t]

    def signals(self, m):
        r, v, _ = self._parts(m)
        return {"v": v, "error": r}


class PICommand(PI):
    """PI loop whose output is a *command* ``u`` instead of a torque: it drives a friction device's
    normal force (``Clutch(..., f_normalized=pi.command("u"))``, ``Brake``, ``FrictionContact``'s ``fn``)::

        r = w_ref(t) - w                      error [rad/s] (w: the sensor's speed, relative to sensor_ref)
        v = k r + I                           unlimited output [1]
        u = clip(v, u_min, u_max)             the command [1] (default limits 0 and 1: f_normalized's range)
        dI/dt = (k / T_i) r + (u - v) / T_t   integral part with anti-windup

    ``k`` [s/rad] != 0: negative for a reverse-acting loop, e.g. a clutch holding its slip speed: with
    ``sensor`` on the input inertia and ``sensor_ref`` on the output one, ``w`` is the slip
    ``w_a - w_b``, and more slip than ``w_ref`` must raise the normal force (``k < 0``). At a steady
    slip the clutch transmits the load's torque ``tau_L``, so ``u = tau_L / (mu cgeo fn_max)`` and the
    error is zero (integral action). ``T_i``, ``T_t`` [s], ``u_min`` < ``u_max`` [1], ``I0`` [1] as ``PI``.
    Exports ``u`` (the command), the state ``I``, ``v`` and ``error``.
    """

    actuators = {}
    commands = {"u": "1"}
    signal_units = {"v": "1", "error": "rad/s"}
    k = Param(check="nonzero", unit="s/rad", doc="gain per rad/s of error (negative: reverse acting)")
    u_max = Param(1.0, check="real", unit="1", doc="upper output limit")
    u_min = Param(0.0, check="real", unit="1", doc="lower output limit")
    I0 = Param(0.0, unit="1", doc="start of the integral part")

    def outputs(self, m):
        return {"u": self._parts(m)[2]}


class Driver(Controller):
    """A driver following a speed profile with accelerator and brake (longitudinal vehicle control)::

        r = v_ref(t) - v                             speed error [m/s], v of the ``vehicle`` mass
        c = clip(k r + I, -1, 1)                     pedal command: + accelerator, - brake
        dI/dt = (k / T_i) r + (c - (k r + I)) / T_t  integral part with anti-windup [1/s]
        throttle = max(c, 0),  brake = max(-c, 0)
        drive torque = (throttle - regen * brake) * T_env(w_drive)                  [N m]
        brake torque = -(1 - regen) * brake * tau_brake * tanh(w_brake / w_eps)     [N m]

    ``T_env`` is the electric machine's envelope (``tau_max`` up to ``p_max / tau_max``, then the
    power limit ``p_max / |w|``, as ``ElectricMotor``): the ``drive`` actuator is the traction
    motor (its rotor ``Inertia`` on ``drive``) and brakes regeneratively with the fraction ``regen``
    of the brake pedal; the rest goes to the friction brake on ``brake`` (a wheel or axle inertia),
    smoothed below ``w_eps`` (it opposes motion but does not hold the car at rest: the loop does).

    Parameters: ``v_ref`` [m/s] the speed profile (signal, e.g. a ``Table`` of a drive cycle),
    ``k`` [s/m] > 0 the pedal gain per m/s of error, ``T_i`` [s] > 0, ``T_t`` [s] (default ``T_i``),
    ``tau_max`` [N m] > 0, ``p_max`` [W] > 0, ``tau_brake`` [N m] >= 0 the friction brake at full
    pedal, ``regen`` [1] in [0, 1], ``w_eps`` [rad/s] > 0, ``I0`` [1] in [-1, 1].
    Exports the state ``I``, derived ``drive``, ``brake`` (the torques), ``throttle``, ``pedal_brake``,
    ``error`` [m/s].
    """

    sensors = {"vehicle": TRANSLATIONAL}
    actuators = {"drive": ROTATIONAL, "brake": ROTATIONAL}
    states = {"I": "I0"}
    signal_units = {"throttle": "1", "pedal_brake": "1", "error": "m/s"}
    v_ref = Param(check="signal", unit="m/s", doc="speed profile to follow")
    k = Param(check="positive", unit="s/m", doc="pedal command per m/s of speed error")
    T_i = Param(check="positive", unit="s", doc="integral time")
    T_t = Param(None, check="positive", optional=True, unit="s", doc="anti-windup tracking time (default T_i)")
    tau_max = Param(check="positive", unit="N m", doc="traction motor peak torque")
    p_max = Param(check="positive", unit="W", doc="traction motor peak power")
    tau_brake = Param(0.0, check="nonnegative", unit="N m", doc="friction brake torque at full pedal")
    regen = Param(1.0, check="nonnegative", unit="1", doc="share of the brake pedal taken by the motor, 0..1")
    w_eps = Param(0.5, check="positive", unit="rad/s", doc="speed scale of the smoothed friction brake")
    I0 = Param(0.0, unit="1", doc="start of the integral part")

    def validate(self):
        if self.regen > 1.0:
            raise ParameterError(f"Driver '{self.name}': regen is the share of braking done by the motor and "
                                 f"must lie in [0, 1], got {self.regen}")
        if self.T_t is None:
            self._values["T_t"] = self.T_i
        if not -1.0 <= self.I0 <= 1.0:
            raise ParameterError(f"Driver '{self.name}': the start I0={self.I0} must lie in [-1, 1] (a pedal "
                                 f"command)")

    def _parts(self, m):
        r = self.v_ref - m.w["vehicle"]
        v = self.k * r + self.I
        c = clip(v, -1.0, 1.0)
        throttle, brake = positive_part(c), positive_part(-c)
        drive = (throttle - self.regen * brake) * envelope(m.w_act["drive"], self.tau_max, self.p_max)
        fric = -(1 - self.regen) * brake * self.tau_brake * smooth_sign(m.w_act["brake"], self.w_eps)
        return r, v, c, throttle, brake, drive, fric

    def outputs(self, m):
        parts = self._parts(m)
        return {"drive": parts[5], "brake": parts[6]}

    def switching_surfaces(self, e, de):
        # the pedal limits; the switch from accelerator to brake at c = 0 is a kink of the law only with
        # regen < 1 and is not located
        return self.limit_surfaces(self._parts(self._measure(e, de))[1], -1.0, 1.0)

    def rates(self, m):
        r, v, c = self._parts(m)[:3]
        return [self.k / self.T_i * r + (c - v) / self.T_t]

    def signals(self, m):
        r, _, _, throttle, brake = self._parts(m)[:5]
        return {"throttle": throttle, "pedal_brake": brake, "error": r}


__all__ = ["Controller", "Measurements", "PI", "PICommand", "Driver", "clip", "positive_part", "smooth_sign"]
