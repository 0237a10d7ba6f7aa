"""Which coordinate a rigid constraint computes (the dummy) must not decide the accuracy of a run.

Fuzz seed 60000: a Position servo drives the carrier of an ideal differential between a heavy wheel
(J2 = 2.014 kg m^2) and a light one (J3 = 0.01519 kg m^2). The difference mode is free, so the constraint
force moves the light wheel most: ``a2 = 2 J3 / (J2 + J3) a1``, ``a3 = 2 J2 / (J2 + J3) a1``. With the heavy
wheel taken as the dummy (its speed the difference ``2 w1 - w3`` of two large speeds), IDA's error test on its
acceleration failed step after step: 42,814 steps to 0.47 s and 4e-2 of J2's speed range off at rtol 1e-4,
2.65e-4 at rtol 1e-8 on the fuzz model, where DOP853 and Radau agreed with each other.
"""

import math

import numpy as np
import pytest

import regmech as rm
from regmech.components import Differential, Inertia, Position, Torque
from regmech.signals import Sine, Step

J1, J2, J3 = 1.19, 2.014, 0.01519


def _model(j3=J3):
    m = rm.Model("servo_differential")
    m.add(Inertia("J1", J=J1))
    m.add(Position("servo", phi_ref=Sine(0.165, 39.19 / (2 * math.pi), 3.163, 0.08989)))
    m.add(Differential("diff", ratio=1.0))
    m.add(Inertia("J2", J=J2))
    m.add(Inertia("J3", J=j3))
    m.add(Torque("tq", tau=Step(height=0.0, start_time=0.3)))     # a time event: a restart mid-run
    m.connect("servo.flange", "J1.flange_b")
    m.connect("diff.carrier", "J1.flange_a")
    m.connect("diff.left", "J2.flange_b")
    m.connect("diff.right", "J3.flange_b")
    m.connect("tq.flange", "J2.flange_a")
    return m


def _speed_error(res, j3=J3):
    """Largest error of J2's speed over its range: w2 - w2(0) = 2 J3 / (J2 + J3) (w1 - w1(0)) exactly."""
    k = 2.0 * j3 / (J2 + j3)
    exact = res["J2.w"][0] + k * (res["J1.w"] - res["J1.w"][0])
    return float(np.max(np.abs(res["J2.w"] - exact)) / np.ptp(exact))


@pytest.mark.parametrize("solver", ["ida", "scipy:DOP853", "scipy:Radau"])
def test_heavy_wheel_of_a_driven_differential_follows_the_closed_form(solver):
    res = _model().simulate(0.47, dt_out=0.0022, solver=solver, rtol=1e-6)
    assert _speed_error(res) < 1e-4
    # the free difference mode keeps its momentum: J2 w2 - J3 w3 is constant
    q = J2 * res["J2.w"] - J3 * res["J3.w"]
    assert np.ptp(q) < 1e-4 * J2 * np.ptp(res["J2.w"])


def test_ida_needs_no_more_steps_for_a_light_wheel_than_for_a_heavy_one():
    """The work is a count, not a time: with the light wheel as the dummy IDA took 32,089 steps at rtol 1e-6
    (one Jacobian each), against ~350 with J3 = 1 kg m^2."""
    light = _model().simulate(0.47, dt_out=0.0022, solver="ida", rtol=1e-6)
    heavy = _model(j3=1.0).simulate(0.47, dt_out=0.0022, solver="ida", rtol=1e-6)
    assert light.stats.steps < 3 * heavy.stats.steps
    assert _speed_error(heavy, j3=1.0) < 1e-4


def test_reflected_mass_of_rigid_groups():
    """``_reflected_mass``: a coordinate's inertia is its rigid group's, reflected through the rows' ratios; rows
    of three coordinates join nothing."""
    import scipy.sparse as sp
    from regmech.structure.system import _reflected_mass
    # x0 - x1 = 0 (a shaft), x1 - 3 x2 = 0 (a gear: x2 turns a third of x1), x3 + x4 - 2 x5 = 0 (a differential)
    G = sp.csr_matrix(np.array([[1.0, -1.0, 0, 0, 0, 0], [0, 1.0, -3.0, 0, 0, 0], [0, 0, 0, 1.0, 1.0, -2.0]]))
    mass = np.array([1.0, 0.5, 9.0, 2.0, 3.0, 4.0])
    got = _reflected_mass(G, mass)
    # per unit of x0: x1 moves 1, x2 moves 1/3 -> M0 = 1 + 0.5 + 9/9 = 2.5; M2 = 2.5 * 9
    assert got[:3] == pytest.approx([2.5, 2.5, 22.5])
    assert got[3:] == pytest.approx(mass[3:])


def test_light_wheel_on_a_heavy_hub_is_not_the_rolling_dummy():
    """Fuzz CI seed 4004: two wheels on one hub (J1 between them on rigid shafts), their axles moved by a
    LinearPosition. Each rolling constraint needs a dummy, the tread or the hub. By its own inertia the light
    wheel (0.040 kg m^2) was the best dummy and a tread stayed a state, so the whole hub followed that tread's
    state over the radius 0.134 m; the hub's inertia is 2.22 kg m^2, and both treads are now the dummies."""
    from regmech.components import Shaft, Wheel
    from regmech.components.sources import LinearPosition
    m = rm.Model("hub")
    m.add(Inertia("J1", J=0.6361))
    m.add(Wheel("wheel1", radius=0.4102, J=1.547, m_axle=20.08, fn=1387.0))
    m.add(Wheel("wheel2", radius=0.1344, J=0.04014, m_axle=1.002, fn=1135.0))
    m.add(Shaft("shaft1", stiffness=None))
    m.add(Shaft("shaft2", stiffness=None))
    m.add(LinearPosition("servo", s_ref=Sine(1.0, 1.0), domain="translational"))
    m.connect("shaft1.flange_a", "J1.flange_b")
    m.connect("shaft1.flange_b", "wheel1.hub")
    m.connect("shaft2.flange_a", "J1.flange_a")
    m.connect("shaft2.flange_b", "wheel2.hub")
    m.connect("wheel1.axle", "wheel2.axle")
    m.connect("servo.flange", "wheel1.axle")
    st = m.compile().structure
    dummies = {st.coord_names[k] for k in st.dummy_v}
    assert {"wheel1.tread", "wheel2.tread"} <= dummies
