"""Gearing with two degrees of freedom: ``Differential`` and ``Planetary``.

Both are one-row rigid devices (REFERENCES.md [003]: "differential, W = 2"): three
flanges bound by one linear relation between their angles, so two of the
three stay free. The constraint force ``lam`` of the row is the only torque
unknown; the flange torques are its multiples by the row's coefficients,
which is where the torque ratios come from (``flange.tau = coef * lam``,
the torque the device exerts on itself; the bodies receive the opposite).

Losses: ``LossyPlanetary`` gives the planetary set the efficiency of its
basic (carrier-stopped) gear train, with stuck/rolling modes, through the
``LossyGear`` machinery ("efficiency with the third link stopped", REFERENCES.md
[003]); ``LimitedSlipDifferential`` adds internal friction (a preloaded clutch
between the side gears) to the open differential.
"""

from __future__ import annotations

from ..component import Device, Param, Subsystem
from ..errors import ParameterError
from ..ports import ROTATIONAL
from .friction import Clutch, LossyGear
from .inertial import Inertia


class Differential(Device):
    """Open (bevel) differential: ``phi_c - phi_s = ratio * ((phi_l + phi_r)/2 - phi_s)``.

    Flanges: ``carrier`` (input, e.g. the crown wheel with its housing),
    ``left`` and ``right`` (the side shafts), ``support`` (the axle housing,
    grounded when left unconnected). All angles in rad, torques in N m.

    ``ratio`` (dimensionless, non-zero) is the reduction from the carrier to
    the mean of the sides; 1 for the bare bevel set, the final-drive ratio
    when the carrier flange stands for the pinion shaft.

    Device coordinate (the constraint ``e = 0``)::

        e = phi_c - (ratio/2) phi_l - (ratio/2) phi_r + (ratio - 1) phi_s

    Torques (``lam`` = the exported ``tau``, the carrier torque)::

        carrier.tau = lam,  left.tau = right.tau = -(ratio/2) lam,
        support.tau = (ratio - 1) lam

    so the side torques are always equal (the open differential's defining
    property): a wheel on ice carries almost no torque, hence neither does the
    other one, and the free wheel spins at twice the mean speed.

    Ideal (no losses): ``LossyDifferential`` adds a mesh efficiency by power-flow direction,
    ``LimitedSlipDifferential`` the locking friction of a limited-slip unit.
    """

    kind = "rigid"
    ratio = Param(1.0, check="nonzero", unit="1", doc="carrier angle / mean angle of the sides")
    flanges = (("carrier", ROTATIONAL), ("left", ROTATIONAL), ("right", ROTATIONAL),
               ("support", ROTATIONAL, True))
    rel_names = {ROTATIONAL: (None, None, None, "tau")}

    def rows(self):
        half = self.ratio / 2.0
        return [{"carrier": 1.0, "left": -half, "right": -half, "support": self.ratio - 1.0}]


class Planetary(Device):
    """Ideal planetary gear set (MSL ``IdealPlanetary``), Willis' relation::

        (1 + ratio) * phi_carrier = phi_sun + ratio * phi_ring

    ``ratio`` = ring teeth / sun teeth (> 0 for a real set, e.g. 100/50 = 2).
    Flanges ``sun``, ``carrier``, ``ring``; angles in rad, torques in N m.
    The relation involves only differences of angles, so no support flange is
    needed (a rotating housing changes nothing).

    Device coordinate ``e = phi_sun + ratio*phi_ring - (1 + ratio)*phi_carrier``;
    its constraint force ``lam`` is the sun torque (exported as ``tau``)::

        sun.tau = lam,  ring.tau = ratio * lam,  carrier.tau = -(1 + ratio) * lam

    i.e. sun : ring : carrier = 1 : ratio : -(1 + ratio), as in MSL.
    With the ring held, sun in and carrier out: ``phi_sun = (1 + ratio) phi_carrier``.

    For mesh losses use ``LossyPlanetary``.
    """

    kind = "rigid"
    ratio = Param(check="positive", unit="1", doc="number of ring teeth / number of sun teeth")
    flanges = (("sun", ROTATIONAL), ("carrier", ROTATIONAL), ("ring", ROTATIONAL))
    rel_names = {ROTATIONAL: (None, None, None, "tau")}

    def rows(self):
        r = self.ratio
        return [{"sun": 1.0, "ring": r, "carrier": -(1.0 + r)}]


class LossyPlanetary(LossyGear):
    """Planetary gear set with mesh efficiency and bearing friction of its basic gear train.

    Seen from the carrier, sun and ring form an ordinary gear of ratio
    ``-ratio`` (``phi_sun - phi_c = -ratio (phi_ring - phi_c)``, Willis), so the
    set is a ``LossyGear`` between ``sun`` (flange_a) and ``ring`` (flange_b) whose
    support is the ``carrier``: the efficiency is that of the carrier-stopped
    train (REFERENCES.md [003], "efficiency with the third link stopped"), applied
    to the power flowing through the meshes in the carrier frame. ``loss_table``
    rows ``(|w_sun - w_carrier|, eta_mf1, eta_mf2, tau_bf1, tau_bf2)`` as in
    ``LossyGear`` (1: the sun drives the train, 2: the ring drives it). With the
    ring held, sun in and carrier out, the output torque is ``(1 + eta ratio)``
    times the input (efficiency ``(1 + eta ratio) / (1 + ratio)``).
    ``ratio`` = ring teeth / sun teeth > 0. Signals: ``<name>.mode`` (the mesh
    train rolling forward/backward or stuck), ``<name>.sun.tau`` etc.
    """

    ratio = Param(check="positive", unit="1", doc="number of ring teeth / number of sun teeth")
    flanges = (("sun", ROTATIONAL), ("carrier", ROTATIONAL), ("ring", ROTATIONAL))

    def rows(self):
        r = self.ratio
        # LossyGear rows with flange_a = sun, flange_b = ring, support = carrier, gear ratio -r
        return [{"sun": 1.0, "ring": r, "carrier": -r - 1.0}, {"sun": 1.0, "carrier": -1.0}]


class LimitedSlipDifferential(Subsystem):
    """Open ``Differential`` with internal friction: a preloaded ``Clutch`` between the two
    side gears (plate-type limited slip). The side gears get small inertias of their own
    (``J_side``) so the clutch has a mass on each side.

    Ports ``carrier``, ``left``, ``right``. ``preload`` [N] is the clutch's normal force
    (``f_normalized`` = 1), ``mu`` and ``cgeo`` [m] its friction coefficient and effective
    radius: the sides turn together until the torque difference between them exceeds
    about ``2 * mu * cgeo * preload * peak``; a very large preload locks the differential.
    """

    ratio = Param(1.0, check="nonzero", unit="1", doc="carrier angle / mean angle of the sides")
    preload = Param(check="nonnegative", unit="N", doc="clutch normal force")
    mu = Param(0.1, check="nonnegative", unit="1", doc="clutch friction coefficient")
    cgeo = Param(0.05, check="nonnegative", unit="m", doc="clutch effective radius x surfaces")
    peak = Param(1.0, check="positive", unit="1", doc="static over kinetic friction")
    J_side = Param(0.01, check="positive", unit="kg m^2", doc="inertia of each side gear")
    ports = {"carrier": "diff.carrier", "left": "side_left.flange_b", "right": "side_right.flange_b"}

    def build(self):
        diff = self.part(Differential("diff", ratio=self.ratio))
        left = self.part(Inertia("side_left", J=self.J_side))
        right = self.part(Inertia("side_right", J=self.J_side))
        clutch = self.part(Clutch("lock", mu=self.mu, cgeo=self.cgeo, peak=self.peak, fn_max=self.preload))
        self.link(diff.left, left.flange_a)
        self.link(diff.right, right.flange_a)
        self.link(left.flange_a, clutch.flange_a)
        self.link(right.flange_a, clutch.flange_b)


class LossyDifferential(Subsystem):
    """Open differential with a mesh efficiency by power-flow direction (final drive): a ``LossyGear``
    (the pinion-ring mesh, ``ratio``), the ring gear's inertia ``J_ring``, and a bare ``Differential``
    (ratio 1) that splits the ring's torque equally to the sides.

    Ports ``carrier`` (the pinion shaft: input), ``left``, ``right``. With the pinion driving (traction)
    the sides receive ``eta_drive`` of the pinion's power; with the wheels driving (overrun, engine
    braking) the pinion receives ``eta_coast`` of theirs; the change of driving side is an event
    (``res.events``, kind "driving side") as on every ``LossyGear``; ``mesh.power`` is the loss [W].
    ``Differential`` alone stays ideal; ``LimitedSlipDifferential`` adds the locking friction instead.
    """

    ratio = Param(check="nonzero", unit="1", doc="pinion angle / ring angle (the final-drive ratio)")
    eta_drive = Param(1.0, check="positive", unit="1", doc="mesh efficiency with the pinion driving, <= 1")
    eta_coast = Param(1.0, check="positive", unit="1", doc="mesh efficiency with the wheels driving, <= 1")
    J_ring = Param(0.05, check="positive", unit="kg m^2", doc="inertia of the ring gear with the differential case")
    ports = {"carrier": "mesh.flange_a", "left": "diff.left", "right": "diff.right"}

    def validate(self):
        for pname in ("eta_drive", "eta_coast"):
            if getattr(self, pname) > 1.0:
                raise ParameterError(f"LossyDifferential '{self.name}': {pname} is an efficiency and must lie in "
                                     f"(0, 1], got {getattr(self, pname)}")

    def build(self):
        mesh = self.part(LossyGear("mesh", ratio=self.ratio, loss_table=[[0.0, self.eta_drive, self.eta_coast,
                                                                          0.0, 0.0]]))
        ring = self.part(Inertia("ring", J=self.J_ring))
        diff = self.part(Differential("diff", ratio=1.0))
        self.link(mesh.flange_b, ring.flange_a)
        self.link(ring.flange_b, diff.carrier)


__all__ = ["Differential", "Planetary", "LossyPlanetary", "LimitedSlipDifferential", "LossyDifferential"]
