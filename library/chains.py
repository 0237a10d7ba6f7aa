"""Chains of masses: a starting train and a chain-drive span (REFERENCES.md [002]).

Both are the examples of the matrix numerical-analytical method: a train of
n cars has a tridiagonal stiffness matrix; a chain-drive span with 6
coordinates per link has a block-tridiagonal stiffness matrix with 6 x 6
blocks that are not diagonal. Each builder takes the size as a parameter,
so the scenes scale for benchmarks.
"""

from __future__ import annotations

import math

import regmech as rm
from regmech.components import Fixed, Force, Inertia, Mass, RoadLoad, Spring, SpringDamper
from regmech.ports import ROTATIONAL, TRANSLATIONAL
from regmech.signals import Ramp, Sine

#: the 6 coordinates of a chain link: 3 translations [m], 3 rotations [rad]
LINK_COORDS = (("x", TRANSLATIONAL), ("y", TRANSLATIONAL), ("z", TRANSLATIONAL),
               ("rx", ROTATIONAL), ("ry", ROTATIONAL), ("rz", ROTATIONAL))


def train(n: int = 10, m_car: float = 60e3, c: float = 2e7, d: float = 5e4, force: float = 3e5,
          t_ramp: float = 10.0, c_r: float = 0.0015, v_eps: float = 0.05) -> rm.Model:
    """A freight train starting: n cars joined by elastic couplers, pulled at the front.

    Physics: cars ``car0 .. car{n-1}`` are masses ``m_car`` [kg] on a level
    track; neighbours are joined by couplers (draft gears), each a spring
    ``c`` [N/m] in parallel with a damper ``d`` [N s/m] (``coupler{i}``
    joins car i and car i+1). The locomotive is car 0: its tractive force
    ``traction`` rises linearly from 0 to ``force`` [N] over ``t_ramp`` [s].
    Each car has a rolling resistance ``c_r * m_car * g`` (``road{i}``, a
    ``RoadLoad`` with sign(v) smoothed over ``v_eps`` [m/s]). Everything
    starts at rest with the couplers unstretched.

    The stiffness matrix is tridiagonal (REFERENCES.md [002], the railway train);
    the free-free chain has the eigenfrequencies
    ``omega_k = 2 sqrt(c / m_car) sin(k pi / (2 n))``, k = 0..n-1 (k = 0 the
    rigid-body motion). Simulate some tens of seconds; the coupler forces
    ``coupler{i}.f`` show the wave running down the train.
    """
    if not isinstance(n, int) or n < 2:
        raise rm.ParameterError(f"train(): n must be an integer >= 2 (number of cars), got {n!r}")
    m = rm.Model(f"train_{n}")
    ground = m.add(Fixed("track", domain=TRANSLATIONAL))
    cars = [m.add(Mass(f"car{i}", m=m_car, s0=0.0, v0=0.0)) for i in range(n)]
    traction = m.add(Force("traction", f=Ramp(height=force, duration=t_ramp)))
    m.connect(traction.flange, cars[0].flange_a)
    m.connect(traction.support, ground.flange)
    for i, car in enumerate(cars):
        road = m.add(RoadLoad(f"road{i}", f_roll=c_r * m_car * 9.80665, v_eps=v_eps))
        m.connect(road.flange, car.flange_b)
        m.connect(road.support, ground.flange)
    for i in range(n - 1):
        coupler = m.add(SpringDamper(f"coupler{i}", c=c, d=d, domain=TRANSLATIONAL))
        m.connect(coupler.flange_a, cars[i].flange_b)
        m.connect(coupler.flange_b, cars[i + 1].flange_a)
    return m


class ChainJoint(rm.Device):
    """Linearised joint between two chain links (rigid-body-spring model).

    Two rigid links of pitch ``L`` [m] (centres of mass L apart along x) meet
    at a joint point at ``(L/2, offset_y, offset_z)`` from the centre of link
    a and ``(-L/2, offset_y, offset_z)`` from that of link b; the joint is a
    set of six springs, with dampers in parallel, on the relative motion of
    the two links at that point (small rotations: ``u + theta x r``). Flanges
    ``a_<q>`` and ``b_<q>`` for q in x, y, z [m] and rx, ry, rz [rad] are the
    coordinates of link a and link b. With ``h = L/2``, ``ey = offset_y``,
    ``ez = offset_z``, the device coordinates (rows) are::

        e0 = x_b - x_a + ez (ry_b - ry_a) - ey (rz_b - rz_a)    axial stretch    [m]
        e1 = y_b - y_a - h (rz_a + rz_b) - ez (rx_b - rx_a)     shear in y       [m]
        e2 = z_b - z_a + h (ry_a + ry_b) + ey (rx_b - rx_a)     shear in z       [m]
        e3 = rx_b - rx_a                                        torsion          [rad]
        e4 = ry_b - ry_a                                        bending about y  [rad]
        e5 = rz_b - rz_a                                        bending about z  [rad]

    Forces ``tau_r = k_r (e_r + beta * e_r')`` with ``k = (c_axial, c_shear,
    c_shear, c_torsion, c_bend_y, c_bend_z)`` (stiffness-proportional
    damping, ``beta`` [s]). The shear rows couple the translations of one
    link with the rotations of the next, so the off-diagonal 6 x 6 blocks of
    a chain's stiffness matrix are full; in a uniform chain with the joints
    on the links' axis (offsets 0) these couplings cancel in the diagonal
    blocks, and an eccentric joint (a cranked or offset-link chain, centre
    of mass off the pin line) fills the diagonal blocks as well.
    """

    kind = "compliant"
    default_domain = TRANSLATIONAL
    flanges = tuple((f"{side}_{q}", dom) for side in "ab" for q, dom in LINK_COORDS)
    rel_names = {TRANSLATIONAL: ("s_rel", "v_rel", "a_rel", "f")}    # row 0: the axial stretch and force
    pitch = rm.Param(check="positive", unit="m", doc="link pitch L")
    c_axial = rm.Param(check="positive", unit="N/m", doc="axial stiffness")
    c_shear = rm.Param(check="positive", unit="N/m", doc="shear stiffness (y and z)")
    c_torsion = rm.Param(check="positive", unit="N m/rad", doc="torsional stiffness")
    c_bend_y = rm.Param(check="positive", unit="N m/rad", doc="bending stiffness about y")
    c_bend_z = rm.Param(check="positive", unit="N m/rad", doc="bending stiffness about z (in the sprocket plane)")
    beta = rm.Param(0.0, check="nonnegative", unit="s", doc="stiffness-proportional damping time")
    offset_y = rm.Param(0.0, unit="m", doc="joint point's offset from the link axis in y")
    offset_z = rm.Param(0.0, unit="m", doc="joint point's offset from the link axis in z")

    def rows(self):
        h, ey, ez = self.pitch / 2, self.offset_y, self.offset_z
        return [{"a_x": -1.0, "b_x": 1.0, "a_ry": -ez, "b_ry": ez, "a_rz": ey, "b_rz": -ey},
                {"a_y": -1.0, "b_y": 1.0, "a_rz": -h, "b_rz": -h, "a_rx": ez, "b_rx": -ez},
                {"a_z": -1.0, "b_z": 1.0, "a_ry": h, "b_ry": h, "a_rx": -ey, "b_rx": ey},
                {"a_rx": -1.0, "b_rx": 1.0},
                {"a_ry": -1.0, "b_ry": 1.0},
                {"a_rz": -1.0, "b_rz": 1.0}]

    def _stiffness(self):
        return (self.c_axial, self.c_shear, self.c_shear, self.c_torsion, self.c_bend_y, self.c_bend_z)

    def laws(self, e, de):
        return [k * (er + self.beta * der) for k, er, der in zip(self._stiffness(), e, de)]

    def potential(self, e):
        return sum(k * er ** 2 / 2 for k, er in zip(self._stiffness(), e))


def chain_drive(n_links: int = 20, pitch: float = 0.0127, m_link: float = 8.9e-3, width: float = 0.012,
                c_axial: float = 5e7, c_shear: float = 5e7, c_torsion: float = 20.0, c_bend_y: float = 20.0,
                c_bend_z: float = 2.0, beta: float = 1e-5, tension: float = 500.0, teeth: int = 17,
                sprocket_rev_s: float = 25.0, f_axial: float = 50.0, f_lateral: float = 20.0,
                offset_y: float = 0.0, offset_z: float = 0.0) -> rm.Model:
    """A roller-chain span between two sprockets, excited by the polygonal action.

    Physics: ``n_links`` links, each a rigid body with 6 coordinates, all
    separate masses: translations ``link{i}_x`` (along the span), ``_y`` (in
    the sprocket plane, across), ``_z`` (out of plane), each of mass
    ``m_link`` [kg], and rotations ``link{i}_rx`` (about the span axis),
    ``_ry``, ``_rz`` with the inertias of a bar of length ``pitch`` [m] and
    square section ``width`` [m]: ``J_x = m w^2/6``, ``J_y = J_z = m (L^2 + w^2)/12``.
    Neighbouring links (and the end links with the sprockets, held fixed)
    are joined by ``ChainJoint`` devices ``joint0 .. joint{n_links}`` with
    axial, shear, torsional and bending stiffnesses [N/m, N m/rad] and
    stiffness-proportional damping ``beta`` [s]. The static ``tension`` [N]
    gives each link the geometric (string) stiffness ``tension * pitch``
    [N m/rad] against rotation about y and z (``geo{i}_ry``, ``geo{i}_rz``,
    springs to the ground): a bar pulled at both ends by T turns back with
    the torque ``T L theta``. The stiffness matrix is block-tridiagonal with
    6 x 6 blocks; the blocks between neighbours are not diagonal (shear
    couples y with rz and z with ry), and with eccentric joints
    (``offset_y``, ``offset_z`` [m], cranked links) neither are the diagonal
    blocks (see ``ChainJoint``).

    Excitation (polygonal action of the driving sprocket with ``teeth``
    teeth at ``sprocket_rev_s`` [rev/s]): at the tooth frequency
    ``teeth * sprocket_rev_s`` [Hz] the first link gets an axial force of
    amplitude ``f_axial`` [N] (tension fluctuation, ``axial_drive``) and a
    lateral force of amplitude ``f_lateral`` [N] (``lateral_drive``). The
    span starts at rest in its straight position. Lowest lateral mode:
    about ``sqrt(tension / (m_link / pitch)) / (2 * span)`` Hz for a span
    of ``(n_links + 1) * pitch`` between the sprocket contacts.
    """
    if not isinstance(n_links, int) or n_links < 1:
        raise rm.ParameterError(f"chain_drive(): n_links must be an integer >= 1, got {n_links!r}")
    m = rm.Model(f"chain_drive_{n_links}")
    ground = {TRANSLATIONAL: m.add(Fixed("frame_s", domain=TRANSLATIONAL)),
              ROTATIONAL: m.add(Fixed("frame_phi", domain=ROTATIONAL))}
    j_axis = m_link * width ** 2 / 6.0
    j_cross = m_link * (pitch ** 2 + width ** 2) / 12.0
    links = []
    for i in range(n_links):
        link = {}
        for q, dom in LINK_COORDS:
            name = f"link{i}_{q}"
            if dom == TRANSLATIONAL:
                link[q] = m.add(Mass(name, m=m_link, s0=0.0, v0=0.0))
            else:
                link[q] = m.add(Inertia(name, J=j_axis if q == "rx" else j_cross, phi0=0.0, w0=0.0))
        for q in ("ry", "rz"):
            geo = m.add(Spring(f"geo{i}_{q}", c=tension * pitch))
            m.connect(geo.flange_a, ground[ROTATIONAL].flange)
            m.connect(geo.flange_b, link[q].flange_b)
        links.append(link)
    joint_params = dict(pitch=pitch, c_axial=c_axial, c_shear=c_shear, c_torsion=c_torsion,
                        c_bend_y=c_bend_y, c_bend_z=c_bend_z, beta=beta, offset_y=offset_y, offset_z=offset_z)
    for j in range(n_links + 1):
        joint = m.add(ChainJoint(f"joint{j}", **joint_params))
        for side, k in (("a", j - 1), ("b", j)):
            for q, dom in LINK_COORDS:
                target = links[k][q].flange_a if 0 <= k < n_links else ground[dom].flange
                m.connect(joint.get_flange(f"{side}_{q}"), target)
    f_tooth = teeth * sprocket_rev_s
    for name, q, amp in (("axial_drive", "x", f_axial), ("lateral_drive", "y", f_lateral)):
        src = m.add(Force(name, f=Sine(amplitude=amp, freq_hz=f_tooth)))
        m.connect(src.flange, links[0][q].flange_b)
        m.connect(src.support, ground[TRANSLATIONAL].flange)
    return m


def free_chain_frequencies(n: int, c: float, m: float):
    """Eigenfrequencies [rad/s] of a free-free chain of n equal masses m joined by springs c."""
    return [2.0 * math.sqrt(c / m) * math.sin(k * math.pi / (2 * n)) for k in range(n)]


__all__ = ["train", "chain_drive", "ChainJoint", "free_chain_frequencies", "LINK_COORDS"]
