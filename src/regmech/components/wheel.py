"""Wheels: rolling kinematics, a wheel with tyre compliance and stick/slip
road contact (REFERENCES.md [003]), and a Magic-Formula tyre.

``Wheel`` (a ``Subsystem``) is the translational-rotational wheel of the
regular-system paper::

    hub ── J (wheel inertia) ══ Rolling(radius) ══ tread mass ── tyre spring-damper
                                    ║                                  │
    axle ── axle mass ══════════════╝                           contact mass
                                                                       │
                                                       FrictionContact(mu, peak, fn) ── road

``Rolling`` is the rigid branching device: the tread point moves at
``v_tread = v_axle - radius * w`` (zero for rolling without slip), so the
drive torque becomes a pair of forces on the axle and the tread. The tyre's
tangential compliance (elastic slip) sits between the tread and the contact
mass; the contact mass sticks to the road or slides on it (inelastic slip),
with a mass on each side in every state (Position 3).
"""

from __future__ import annotations

import numpy as np
import sympy

from ..component import Device, Param, Subsystem
from ..ports import ROTATIONAL, TRANSLATIONAL
from .elastic import SpringDamper
from .friction import FrictionContact
from .inertial import Fixed, Inertia, Mass


class Rolling(Device):
    """Rigid rolling: ``s_tread = s_axle - radius * phi_hub`` (contact point of a wheel).

    Constraint force ``tau`` = force on the tread side; the hub receives ``radius``
    times it as torque, the axle the opposite force."""

    kind = "rigid"
    radius = Param(check="positive", unit="m", doc="rolling radius")
    flanges = (("hub", ROTATIONAL), ("axle", TRANSLATIONAL), ("tread", TRANSLATIONAL))
    rel_names = {ROTATIONAL: (None, None, None, "f"), TRANSLATIONAL: (None, None, None, "f")}

    def rows(self):
        return [{"tread": 1.0, "axle": -1.0, "hub": self.radius}]


class Wheel(Subsystem):
    """Wheel with tyre compliance and stick/slip road contact (see module docstring).

    Ports: ``hub`` (rotational, the wheel inertia: connect the drive shaft),
    ``axle`` (translational, the axle mass: connect the vehicle body).
    ``fn`` is the normal load [N] (number, signal or callable). Parts:
    ``J``, ``rolling``, ``tread``, ``tyre``, ``contact``, ``road_contact``, ``road``.
    Signals: ``<wheel>.J.w``, ``<wheel>.tyre.f`` (tyre force), ``<wheel>.road_contact.mode``
    (0: gripping, elastic slip only; +-1: sliding), ``<wheel>.road_contact.v_rel``.
    """

    radius = Param(0.3, check="positive", unit="m", doc="rolling radius")
    J = Param(1.0, check="positive", unit="kg m^2", doc="wheel inertia")
    m_axle = Param(20.0, check="positive", unit="kg", doc="axle (unsprung) mass")
    m_tread = Param(2.0, check="positive", unit="kg", doc="tread ring mass")
    m_contact = Param(0.5, check="positive", unit="kg", doc="contact patch mass (tyre and dragged road)")
    c_tyre = Param(2e5, check="positive", unit="N/m", doc="tangential tyre stiffness")
    d_tyre = Param(500.0, check="nonnegative", unit="N s/m", doc="tangential tyre damping")
    mu = Param(0.9, check="nonnegative", unit="1", doc="sliding friction coefficient")
    peak = Param(1.1, check="positive", unit="1", doc="static over sliding friction")
    fn = Param(check="signal", unit="N", doc="normal load")
    w0 = Param(None, optional=True, unit="rad/s", doc="start speed of the wheel (fixed when given)")
    v0 = Param(None, optional=True, unit="m/s", doc="start speed of the axle (fixed when given)")
    ports = {"hub": "J.flange_a", "axle": "axle.flange_a"}

    def build(self):
        J = self.part(Inertia("J", J=self.J, w0=self.w0))
        axle = self.part(Mass("axle", m=self.m_axle, v0=self.v0))
        roll = self.part(Rolling("rolling", radius=self.radius))
        tread = self.part(Mass("tread", m=self.m_tread))
        tyre = self.part(SpringDamper("tyre", c=self.c_tyre, d=self.d_tyre, domain=TRANSLATIONAL))
        contact = self.part(Mass("contact", m=self.m_contact))
        fric = self.part(FrictionContact("road_contact", mu=self.mu, peak=self.peak, fn=self.fn))
        road = self.part(Fixed("road", domain=TRANSLATIONAL))
        self.link(J.flange_b, roll.hub)
        self.link(axle.flange_b, roll.axle)
        self.link(roll.tread, tread.flange_a)
        self.link(tread.flange_b, tyre.flange_a)
        self.link(tyre.flange_b, contact.flange_a)
        self.link(contact.flange_b, fric.flange_a)
        self.link(fric.flange_b, road.flange)


class MagicFormulaTyre(Device):
    """Longitudinal Magic-Formula tyre force between a wheel hub and its axle (road grounded).

    Slip ``kappa = (radius*w - v) / sqrt(v^2 + v_eps^2)`` (smoothed at standstill),
    force on the axle ``F = fn * D * sin(C * atan(B*kappa - E*(B*kappa - atan(B*kappa))))``
    [N], reaction torque ``-radius * F`` on the hub. Coefficients B, C, D, E are the
    tyre's (Pacejka); the defaults describe a dry-road passenger tyre."""

    kind = "compliant"
    radius = Param(0.3, check="positive", unit="m")
    fn = Param(check="positive", unit="N", doc="normal load")
    B = Param(10.0, check="positive", unit="1", doc="stiffness factor")
    C = Param(1.9, check="positive", unit="1", doc="shape factor")
    D = Param(1.0, check="positive", unit="1", doc="peak factor (friction coefficient)")
    E = Param(0.97, unit="1", doc="curvature factor")
    v_eps = Param(0.5, check="positive", unit="m/s", doc="slip smoothing speed at standstill")
    flanges = (("hub", ROTATIONAL), ("axle", TRANSLATIONAL))
    rel_names = {ROTATIONAL: (None, None, None, None)}
    #: exported signals: ``slip`` the slip ratio kappa [1] of the law, ``slip_speed`` = radius w - v [m/s] (the
    #: tread's speed over the road, positive when the wheel drives), ``f`` the force on the axle [N]
    derived_units = {"slip": "1", "slip_speed": "m/s", "f": "N"}

    def rows(self):
        return [{"hub": 1.0}, {"axle": 1.0}]

    def derived(self, t, left, e, de, tau, z):
        w, v = np.asarray(de[0], float), np.asarray(de[1], float)
        slip_speed = self.radius * w - v
        return {"slip": slip_speed / np.sqrt(v ** 2 + self.v_eps ** 2), "slip_speed": slip_speed,
                "f": -np.asarray(tau[1], float)}

    def laws(self, e, de):
        w, v = de
        kappa = (self.radius * w - v) / sympy.sqrt(v**2 + self.v_eps**2)
        bk = self.B * kappa
        F = self.fn * self.D * sympy.sin(self.C * sympy.atan(bk - self.E * (bk - sympy.atan(bk))))
        # hub receives -tau_0 = -radius F, axle receives -tau_1 = F
        return [self.radius * F, -F]


class MagicFormulaWheel(Subsystem):
    """Wheel inertia plus ``MagicFormulaTyre``: ports ``hub`` (rotational) and ``axle``
    (translational; connect the vehicle mass, which carries the axle)."""

    radius = Param(0.3, check="positive", unit="m")
    J = Param(1.0, check="positive", unit="kg m^2")
    fn = Param(check="positive", unit="N")
    B = Param(10.0, check="positive", unit="1")
    C = Param(1.9, check="positive", unit="1")
    D = Param(1.0, check="positive", unit="1")
    E = Param(0.97, unit="1")
    w0 = Param(None, optional=True, unit="rad/s")
    ports = {"hub": "J.flange_a", "axle": "tyre.axle"}

    def build(self):
        J = self.part(Inertia("J", J=self.J, w0=self.w0))
        tyre = self.part(MagicFormulaTyre("tyre", radius=self.radius, fn=self.fn, B=self.B, C=self.C, D=self.D,
                                          E=self.E))
        self.link(J.flange_b, tyre.hub)
