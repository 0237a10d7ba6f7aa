"""Hydrodynamic torque converter: ``ConverterFluid`` (the fluid path) and ``TorqueConverter``
(pump and turbine inertias, the fluid path and a lock-up clutch).

The standard description by the speed ratio ``nu = w_t / w_p`` [-] of turbine to pump speed:

* capacity factor ``K(nu)`` [rad/s / sqrt(N m)]: the pump absorbs ``tau_p = (w_p / K(nu))^2``;
* torque ratio ``TR(nu)`` [-]: the turbine delivers ``tau_t = TR(nu) tau_p`` (torque
  multiplication, ``TR(0)`` at stall, ``TR = 1`` from the coupling point on).

Traction (``|w_t| <= |w_p|``, the engine drives)::

    tau_p = w_p |w_p| c(nu),   tau_t = TR(nu) tau_p,   c(nu) = 1 / K(nu)^2

Overrun (``|w_t| > |w_p|``, the vehicle drives the engine): the roles swap, the stator
freewheels and the converter works as a coupling (torque ratio 1)::

    tau_t = w_t |w_t| c(w_p / w_t),   tau_p = tau_t       (the pump is driven)

``c`` is interpolated linearly between the table points (``K`` given at speed ratios in
[0, 1)) and falls linearly to zero at ``nu = 1`` (pump and turbine at one speed transmit no
torque), so the law is continuous where traction meets overrun. A turbine turning backwards
(``nu < 0``, a car rolling back at idle) is deep stall: ``c`` is held at ``c(0)`` and the torque
ratio goes linearly from ``TR(0)`` to 1 at ``nu = -1``, where traction meets overrun a second
time (``w_t = -w_p``), so the law is continuous in every quadrant (the line is written in
``q = w_p (w_p + w_t) / (w_p^2 - w_eps^2)``, ``TR = 1 + (TR(0) - 1) q``, exactly 1 at ``w_t = -w_p``;
``ConverterFluid._deep_stall_tr``). Its slope jumps there: that crossing is a switching surface
(``Event`` kind "flow").
The speed ratio is regularised as ``nu = (w_t w_p + w_eps^2) / (w_p^2 + w_eps^2)`` (overrun:
``(w_p w_t + w_eps^2) / (w_t^2 + w_eps^2)``) so that it is defined at standstill (zero torque
there) and is exactly 1 whenever ``w_t = w_p``: there both branches give zero torque with the
same slope, so a locked lock-up clutch (which holds ``w_t = w_p`` to round-off) sits on a smooth
law. (``w_t w_p / (w_p^2 + w_eps^2)``, the form before, is ``1 - w_eps^2 / w^2`` at equal speeds:
traction and overrun then gave ``+-c'(1) w_eps^2``, a jump of 1.6e-7 N m at any speed that the
round-off of a locked clutch's slip flipped at every Newton iterate, and IDA failed at rtol 1e-8.)
``w_eps`` (1e-3 rad/s) changes nothing at running speeds.

Power: the fluid absorbs ``tau_p w_p - tau_t w_t = tau_p w_p (1 - TR(nu) nu) >= 0`` in traction
(the efficiency ``TR nu`` must not exceed 1, which the tables are checked for) and
``tau_t (w_t - w_p) >= 0`` in overrun: it only dissipates (heat in the oil).

The law is odd (all speeds reversed give all torques reversed). Counter-rotation dissipates
too: ``1 - TR nu > 0`` for ``nu < 0``.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import sympy

from ..component import Device, Param, Subsystem, refuse_positional
from ..errors import ParameterError
from ..ports import ROTATIONAL
from .friction import Clutch
from .inertial import Inertia
from .powertrain import piecewise_linear

#: a representative converter (about a 2.0 l petrol engine): speed ratio -> K [rad/s / sqrt(N m)],
#: stall K(0) = 14 (stall speed 14 sqrt(200) = 198 rad/s = 1890 rpm at 200 N m), torque ratio 2.0 at
#: stall falling to 1 at the coupling point nu = 0.85
K_TABLE = ((0.0, 14.0), (0.4, 14.3), (0.6, 15.0), (0.75, 16.5), (0.85, 19.0), (0.95, 30.0))
TR_TABLE = ((0.0, 2.0), (0.4, 1.55), (0.6, 1.3), (0.75, 1.12), (0.85, 1.0), (1.0, 1.0))


class _FixedTable(Param):
    """A table that selects the class's law: it cannot change after creation."""

    def __set__(self, obj, value):
        raise ParameterError(f"{type(obj).__name__} '{obj.name}': parameter '{self.name}' selects the compiled law "
                             f"and cannot be changed; create a new {type(obj).__name__}")


def _shell(public, key):
    return object.__new__(public._class_for(*key))


class ConverterFluid(Device):
    """The fluid path of a torque converter between ``pump`` and ``turbine`` (equations in the
    module docstring); ``support`` is the housing (grounded when free).

    Rows ``e0 = phi_pump - phi_support``, ``e1 = phi_turbine - phi_support``; the forces are
    ``tau_p`` (absorbed by the pump) and ``-tau_t`` (the turbine is driven): the pump inertia
    receives ``-tau_p``, the turbine ``+tau_t``. Exports ``tau`` = ``tau_p`` (row 0) [N m].

    Each pair of tables gets its own (cached) subclass whose law holds them as
    ``sympy.Piecewise`` (laws are compiled once per class, as ``Engine`` does for its map).
    """

    kind = "compliant"
    K_table = _FixedTable(K_TABLE, check="table", unit="(1, rad/s/sqrt(N m))",
                          doc="(speed ratio in [0, 1), capacity factor K > 0) points")
    TR_table = _FixedTable(TR_TABLE, check="table", unit="(1, 1)", doc="(speed ratio, torque ratio > 0) points")
    w_eps = Param(1e-3, check="positive", unit="rad/s", doc="regularisation of the speed ratio at standstill")
    flanges = (("pump", ROTATIONAL), ("turbine", ROTATIONAL), ("support", ROTATIONAL, True))
    rel_names = {ROTATIONAL: (None, None, None, "tau")}

    _c_points: ClassVar[np.ndarray | None] = None
    _tr_points: ClassVar[np.ndarray | None] = None
    _public: ClassVar[type | None] = None
    _classes: ClassVar[dict] = {}

    def __new__(cls, name=None, *args, **params):
        public = cls._public or cls
        refuse_positional(public, (name, *args))
        try:
            k = np.asarray(params.get("K_table", K_TABLE), dtype=float)
            tr = np.asarray(params.get("TR_table", TR_TABLE), dtype=float)
        except (TypeError, ValueError):
            return object.__new__(public)     # __init__ reports the malformed table
        if k.ndim != 2 or tr.ndim != 2 or k.shape[1:] != (2,) or tr.shape[1:] != (2,):
            return object.__new__(public)
        return object.__new__(public._class_for(k, tr))

    @classmethod
    def _class_for(cls, k, tr):
        public = cls._public or cls
        k, tr = np.asarray(k, dtype=float), np.asarray(tr, dtype=float)
        key = (public, k.shape, k.tobytes(), tr.shape, tr.tobytes())
        sub = ConverterFluid._classes.get(key)
        if sub is None:
            c = np.vstack([np.column_stack([k[:, 0], 1.0 / k[:, 1] ** 2]), [[1.0, 0.0]]]) \
                if np.all(k[:, 1] > 0) and k[-1, 0] < 1.0 else None
            # the table itself: counter-rotation (nu < 0) has its own line, ``_deep_stall_tr``
            trp = tr.copy()
            sub = type(public.__name__, (public,), {
                "_c_points": c, "_tr_points": trp, "_public": public, "__module__": public.__module__,
                "__qualname__": public.__qualname__, "__doc__": public.__doc__})
            ConverterFluid._classes[key] = sub
        return sub

    def __reduce_ex__(self, protocol):
        return _shell, (type(self)._public or type(self), (self.K_table, self.TR_table)), self.__dict__

    def validate(self):
        where = f"{type(self).__name__} '{self.name}'"
        k, tr = self.K_table, self.TR_table
        if k[0, 0] != 0.0 or k[-1, 0] >= 1.0 or np.any(k[:, 1] <= 0):
            raise ParameterError(f"{where}: K_table needs speed ratios from 0 (stall) up to below 1 and capacity "
                                 f"factors K > 0 [rad/s/sqrt(N m)]; the torque falls to zero at nu = 1 by itself")
        if tr[0, 0] != 0.0 or np.any(tr[:, 1] <= 0):
            raise ParameterError(f"{where}: TR_table needs speed ratios from 0 (stall) and torque ratios > 0")
        nu = np.linspace(0.0, 1.0, 2001)
        eff = nu * np.interp(nu, tr[:, 0], tr[:, 1])
        if np.any(eff > 1.0 + 1e-12):
            j = int(np.argmax(eff))
            raise ParameterError(f"{where}: the efficiency nu * TR(nu) reaches {eff[j]:.4g} > 1 at nu = {nu[j]:.4g}; "
                                 f"the converter would create energy. Lower the torque ratio there (TR <= 1/nu)")
        if type(self)._c_points is None:
            raise ParameterError(f"{where}: internal table class mismatch; create it with "
                                 f"ConverterFluid(name, K_table=..., TR_table=...)")

    def rows(self):
        return [{"pump": 1.0, "support": -1.0}, {"turbine": 1.0, "support": -1.0}]

    def laws(self, e, de):
        wp, wt = de
        eps2 = self.w_eps ** 2
        nu = (wt * wp + eps2) / (wp ** 2 + eps2)          # traction: w_t / w_p, exactly 1 at w_t = w_p
        nu_o = (wp * wt + eps2) / (wt ** 2 + eps2)        # overrun: w_p / w_t
        c_pts = self._c_points
        tau_p = wp * sympy.Abs(wp) * piecewise_linear(nu, c_pts)
        tau_o = wt * sympy.Abs(wt) * piecewise_linear(nu_o, c_pts)
        tr = sympy.Piecewise((self._deep_stall_tr(wp, wt, eps2), nu < 0), (piecewise_linear(nu, self._tr_points), True))
        traction = wp ** 2 >= wt ** 2
        return [sympy.Piecewise((tau_p, traction), (-tau_o, True)),
                sympy.Piecewise((-tr * tau_p, traction), (tau_o, True))]

    def _deep_stall_tr(self, wp, wt, eps2):
        """The torque ratio in counter-rotation (``nu < 0``): ``1 + (TR(0) - 1) q`` with
        ``q = w_p (w_p + w_t) / (w_p^2 - w_eps^2)``, i.e. ``1 + nu`` at running speeds (linear from TR(0) at
        ``nu = 0`` to 1 at ``nu = -1``), written so that it is *exactly* TR(0) where the regularised ``nu`` is 0
        (``w_t w_p = -w_eps^2``) and exactly 1 at ``w_t = -w_p``, where traction meets overrun (coupling, TR = 1).
        As a function of the regularised ``nu`` the line reached only ``1 + (TR(0) - 1) 2 w_eps^2 / (w_p^2 +
        w_eps^2)`` there: the turbine torque jumped by ``(TR(0) - 1) 2 w_eps^2 c(0)`` (7e-8 N m on fuzz seed
        60009), and IDA, whose error test sees a jump of an algebraic force at every step size, took 50,000 steps
        at rtol 1e-10 without passing it. Used where ``nu < 0`` and ``|w_t| <= |w_p|``, so ``w_p^2 > w_eps^2``
        there; the floor of the denominator only keeps the unused branch finite."""
        tr0 = float(self._tr_points[0, 1])          # TR(0): the table starts at nu = 0 (``validate``)
        den = wp ** 2 - eps2
        floor = 1e-12 * eps2
        den = (den + floor + sympy.Abs(den - floor)) / 2          # max(den, floor) as arithmetic
        return 1 + (tr0 - 1) * wp * (wp + wt) / den

    #: a crossing of ``w_t = -w_p`` (a turbine turning backwards overtakes the pump's speed) is an ``Event`` of
    #: kind "flow": +1 ``w_p + w_t > 0``, 0 ``w_p + w_t < 0``
    switching_kind = "flow"

    def switching_surfaces(self, e, de):
        """The kink of the law where traction meets overrun in counter-rotation: ``w_t = -w_p`` (state +1 on the
        side ``w_p + w_t > 0``, 0 on the other).

        There the law is continuous but its slope jumps (the torque ratio and the capacity factor change
        branch). Unwatched, IDA at rtol 1e-10 took a step of 1.3e-22 s at that crossing and failed (fuzz seed
        60009: a turbine pulled backwards through the pump's speed); watched, no step straddles it. One
        surface, not the pair ``+-(w_p + w_t)``: the two cross at the same root, and a crossing reported for
        one of them only left the other on its old side (fuzz seed 60005: the state read 0 and IDA
        failed its error test at the restart). The other meeting of traction and overrun, ``w_t = w_p``, is
        smooth by construction (see the module docstring) and is not watched: a locked lock-up clutch holds
        the speeds there to round-off, where a surface would be zero and flip sign at every step."""
        wp, wt = de
        return [(wp + wt, 1)]


class TorqueConverter(Subsystem):
    """Torque converter with lock-up clutch (equations in the module docstring).

    ::

        pump ── pump inertia (J_pump) ── ConverterFluid ── turbine inertia (J_turbine) ── turbine
                                 └──────── lockup (Clutch) ────────┘

    Ports ``pump`` (connect the engine) and ``turbine`` (the gearbox input). Parts: ``pump``,
    ``turbine`` (``Inertia``), ``fluid`` (``ConverterFluid``, housing grounded) and ``lockup``
    (``Clutch`` with ``mu = 1``, ``cgeo = 1``, ``fn_max = lockup_capacity``: kinetic torque
    ``lockup_capacity * lockup(t)`` [N m], static ``peak`` times that; ``lockup <= 0`` leaves it
    open). Signals: ``<tc>.fluid.tau`` (pump torque ``tau_p``), ``<tc>.lockup.mode``,
    ``<tc>.pump.w``, ``<tc>.turbine.w``.

    Closed forms: with the turbine held, an engine of torque ``T`` settles at the stall speed
    ``w = K(0) sqrt(T)`` and the turbine receives ``TR(0) T``; at the coupling point ``nu_c``
    (``TR = 1``) pump and turbine torques are equal, ``(w_p / K(nu_c))^2``.
    """

    K_table = Param(K_TABLE, check="table", unit="(1, rad/s/sqrt(N m))", doc="(nu, K) points, nu in [0, 1)")
    TR_table = Param(TR_TABLE, check="table", unit="(1, 1)", doc="(nu, torque ratio) points")
    J_pump = Param(0.05, check="positive", unit="kg m^2", doc="pump (impeller and cover) inertia")
    J_turbine = Param(0.03, check="positive", unit="kg m^2", doc="turbine inertia")
    lockup = Param(0.0, check="signal", bounds=(None, 1.0), unit="1", doc="lock-up command, <= 1 (<= 0: open)")
    lockup_capacity = Param(400.0, check="positive", unit="N m", doc="kinetic torque of the lock-up clutch")
    peak = Param(1.1, check="positive", unit="1", doc="static over kinetic torque of the lock-up clutch")
    w_pump0 = Param(None, optional=True, unit="rad/s", doc="start speed of the pump (fixed when given)")
    w_turbine0 = Param(None, optional=True, unit="rad/s", doc="start speed of the turbine (fixed when given)")
    ports = {"pump": "pump.flange_a", "turbine": "turbine.flange_b"}

    def build(self):
        pump = self.part(Inertia("pump", J=self.J_pump, w0=self.w_pump0))
        turb = self.part(Inertia("turbine", J=self.J_turbine, w0=self.w_turbine0))
        fluid = self.part(ConverterFluid("fluid", K_table=self.K_table, TR_table=self.TR_table))
        lock = self.part(Clutch("lockup", mu=1.0, cgeo=1.0, fn_max=self.lockup_capacity, peak=self.peak,
                                f_normalized=self.lockup))
        self.link(pump.flange_b, fluid.pump)
        self.link(fluid.turbine, turb.flange_a)
        self.link(pump.flange_b, lock.flange_a)
        self.link(lock.flange_b, turb.flange_a)


def stall_speed(torque: float, K0: float) -> float:
    """Engine speed [rad/s] at stall (turbine held) for a constant engine torque [N m]: ``K(0) sqrt(T)``."""
    return K0 * float(np.sqrt(torque))


__all__ = ["ConverterFluid", "TorqueConverter", "K_TABLE", "TR_TABLE", "stall_speed"]
