"""Structural-matrix form (``Model.linearize``) and modal analysis against closed forms."""

import numpy as np
import pytest

import regmech as rm
from regmech.analysis import modal
from regmech.components import (Clutch, Damper, Fixed, IdealGear, Inertia, Position, Shaft, Speed, Spring,
                                SpringDamper, Torque)
from regmech.components.elastic import TwoFlangeCompliant
from regmech.component import Param


def chain(n, J=1.0, c=1.0, ground_end=False):
    """Fixed -c- J0 -c- J1 ... -c- J(n-1) (free end unless ``ground_end``)."""
    m = rm.Model(f"chain{n}")
    fixed = m.add(Fixed("fixed"))
    prev = fixed.flange
    for i in range(n):
        s = m.add(Spring(f"c{i}", c=c))
        body = m.add(Inertia(f"J{i}", J=J))
        m.connect(prev, s.flange_a)
        m.connect(s.flange_b, body.flange_a)
        prev = body.flange_b
    if ground_end:
        s = m.add(Spring("c_end", c=c))
        m.connect(prev, s.flange_a)
        m.connect(s.flange_b, fixed.flange)
    return m


def fixed_free_closed_form(n, J, c):
    k = np.arange(1, n + 1)
    return 2 * np.sqrt(c / J) * np.sin((2 * k - 1) * np.pi / (2 * (2 * n + 1)))


@pytest.mark.parametrize("n", [5, 200])
def test_fixed_free_chain_all_modes(n):
    J, c = 0.3, 250.0
    res = modal(chain(n, J, c).linearize())
    assert not res.rigid.any()
    np.testing.assert_allclose(res.omega, fixed_free_closed_form(n, J, c), rtol=1e-9)
    # mass normalisation and M-orthogonality
    M = res.lin.M
    np.testing.assert_allclose(res.shapes.T @ M @ res.shapes, np.eye(n), atol=1e-9)


def test_fixed_free_chain_partial_sparse():
    n, J, c = 1200, 2.0, 1e4
    lin = chain(n, J, c).linearize()
    assert lin.sparse
    res = modal(lin, k=6)
    np.testing.assert_allclose(res.omega, fixed_free_closed_form(n, J, c)[:6], rtol=1e-9)
    # the k modes nearest a frequency in the middle of the spectrum
    w_all = fixed_free_closed_form(n, J, c)
    target = w_all[300] / (2 * np.pi)
    mid = modal(lin, k=3, sigma=target)
    expect = np.sort(w_all[np.argsort(np.abs(w_all ** 2 - w_all[300] ** 2))[:3]])
    np.testing.assert_allclose(mid.omega, expect, rtol=1e-9)


def test_free_free_chain_has_one_rigid_mode():
    m = rm.Model("free")
    a = m.add(Inertia("a", J=1.0))
    b = m.add(Inertia("b", J=3.0))
    s = m.add(Spring("s", c=12.0))
    m.connect(a.flange_b, s.flange_a)
    m.connect(s.flange_b, b.flange_a)
    res = modal(m.linearize())
    assert res.rigid.tolist() == [True, False]
    assert res.frequencies_hz[0] == 0.0
    np.testing.assert_allclose(res.omega[1], np.sqrt(12.0 * (1 / 1.0 + 1 / 3.0)), rtol=1e-12)
    table = res.table()
    assert table.columns == ["a", "b"]
    np.testing.assert_allclose(table.row(table.index[0]), [1.0, 1.0])         # rigid: both move alike
    np.testing.assert_allclose(table.row(table.index[1]), [1.0, -1.0 / 3.0])  # momentum balance


def test_free_free_long_chain_partial_finds_the_rigid_mode():
    n, c = 800, 1e4
    m = rm.Model("free_free")
    prev = None
    for i in range(n):
        body = m.add(Inertia(f"J{i}", J=1.0))
        if prev is not None:
            s = m.add(Spring(f"c{i}", c=c))
            m.connect(prev, s.flange_a)
            m.connect(s.flange_b, body.flange_a)
        prev = body.flange_b
    res = modal(m.linearize(), k=4)
    assert res.rigid.tolist() == [True, False, False, False]
    k = np.arange(1, 4)
    np.testing.assert_allclose(res.omega[1:], 2 * np.sqrt(c) * np.sin(k * np.pi / (2 * n)), rtol=1e-9)
    np.testing.assert_allclose(res.damped.eigenvalues, 1j * res.omega, rtol=1e-9)


def geared(coupling_stiffness, J=(0.4, 0.2, 1.5), c1=300.0, c3=80.0, ratio=3.0):
    """ground -c1- J1 -gear(ratio)- J2 -coupling- J3 -c3- ground."""
    m = rm.Model("geared")
    fixed = m.add(Fixed("fixed"))
    j1, j2, j3 = (m.add(Inertia(f"J{i + 1}", J=v)) for i, v in enumerate(J))
    s1 = m.add(Spring("c1", c=c1))
    gear = m.add(IdealGear("gear", ratio=ratio))
    coupling = m.add(Shaft("coupling", stiffness=coupling_stiffness))
    s3 = m.add(Spring("c3", c=c3))
    m.connect(fixed.flange, s1.flange_a)
    m.connect(s1.flange_b, j1.flange_a)
    m.connect(j1.flange_b, gear.flange_a)
    m.connect(gear.flange_b, j2.flange_a)
    m.connect(j2.flange_b, coupling.flange_a)
    m.connect(coupling.flange_b, j3.flange_a)
    m.connect(j3.flange_b, s3.flange_a)
    m.connect(s3.flange_b, fixed.flange)
    return m


def test_gear_reduced_closed_form_and_locked_coupling():
    J1, J2, J3 = 0.4, 0.2, 1.5
    c1, c2, c3, r = 300.0, 500.0, 80.0, 3.0
    # compliant coupling: coordinates (phi1, phi3), phi2 = phi1 / r
    M1, M2 = J1 + J2 / r ** 2, J3
    K11, K12, K22 = c1 + c2 / r ** 2, -c2 / r, c2 + c3
    a, b, cc = M1 * M2, -(K11 * M2 + K22 * M1), K11 * K22 - K12 ** 2
    disc = np.sqrt(b * b - 4 * a * cc)
    expect = np.sqrt(np.array([(-b - disc) / (2 * a), (-b + disc) / (2 * a)]))
    res = modal(geared(c2).linearize())
    np.testing.assert_allclose(res.omega, expect, rtol=1e-12)
    # locked (rigid) coupling: J2 and J3 merge, one degree of freedom
    locked = modal(geared(None).linearize())
    assert locked.lin.n == 1
    w_locked = np.sqrt((c1 + c3 / r ** 2) / (J1 + (J2 + J3) / r ** 2))
    np.testing.assert_allclose(locked.omega, [w_locked], rtol=1e-12)
    # the mode table maps the merged coordinate back through the gear
    row = locked.table(normalize=False).row(locked.table(normalize=False).index[0])
    np.testing.assert_allclose(row[1:] / row[0], [1 / r, 1 / r], rtol=1e-12)


def test_msl_first_two_inertias_through_gear():
    from regmech.library import first
    lin = first().linearize()
    res = modal(lin)
    J_reduced = 0.1 * 10.0 ** 2 + 2.0
    f = np.sqrt(1e4 * (1 / J_reduced + 1 / 2.0)) / (2 * np.pi)
    np.testing.assert_allclose(res.frequencies_hz, [0.0, f], rtol=1e-12)
    assert lin.input_names == ["torque.tau"]
    np.testing.assert_allclose(np.ravel(lin.W), [10.0, 0.0])   # the torque reaches inertia2 through the gear


def test_damped_single_degree_of_freedom():
    J, c, d = 2.0, 800.0, 12.0
    m = rm.Model("sdof")
    fixed = m.add(Fixed("fixed"))
    body = m.add(Inertia("J", J=J))
    sd = m.add(SpringDamper("sd", c=c, d=d))
    m.connect(fixed.flange, sd.flange_a)
    m.connect(sd.flange_b, body.flange_a)
    res = modal(m.linearize())
    damped = res.damped
    wn = np.sqrt(c / J)
    zeta = d / (2 * np.sqrt(c * J))
    np.testing.assert_allclose(damped.eigenvalues, [complex(-zeta * wn, wn * np.sqrt(1 - zeta ** 2))], rtol=1e-12)
    np.testing.assert_allclose(damped.damping_ratio, [zeta], rtol=1e-12)
    np.testing.assert_allclose(damped.natural_hz, [wn / (2 * np.pi)], rtol=1e-12)
    assert damped.oscillatory.tolist() == [True]


def test_damped_partial_on_large_chain_with_proportional_damping():
    # a damper d from every mass to the ground: B = d I, so lambda = -d/2J +- i sqrt(w_k^2 - (d/2J)^2)
    n, J, c, d = 500, 1.0, 1e4, 0.02
    m = chain(n, J, c)
    for i in range(n):
        dmp = m.add(Damper(f"d{i}", d=d))
        m.connect(m[f"J{i}"].flange_a, dmp.flange_a)
        m.connect(dmp.flange_b, m["fixed"].flange)
    lin = m.linearize()
    part = rm.analysis.damped_modes(lin, k=4)
    w = fixed_free_closed_form(n, J, c)[:4]
    sigma = d / (2 * J)
    np.testing.assert_allclose(part.eigenvalues, -sigma + 1j * np.sqrt(w ** 2 - sigma ** 2), rtol=1e-9)


def test_position_source_holds_its_point_and_is_a_kinematic_input():
    m = rm.Model("base")
    pos = m.add(Position("pos", phi_ref=0.0))
    s = m.add(Spring("s", c=100.0))
    body = m.add(Inertia("J", J=4.0))
    m.connect(pos.flange, s.flange_a)
    m.connect(s.flange_b, body.flange_a)
    lin = m.linearize()
    assert lin.coords == ["J"]
    assert lin.kinematic_names == ["pos.phi_ref"] and lin.kinematic_levels == ["position"]
    np.testing.assert_allclose(modal(lin).omega, [5.0])
    np.testing.assert_allclose(np.ravel(lin.K_g), [-100.0])   # force on J = -K_g g = c g


def test_cubic_spring_linearised_at_the_operating_point():
    class CubicSpring(TwoFlangeCompliant):
        c = Param(check="positive")
        c3 = Param(check="nonnegative")

        def law(self, rel, rel_dot):
            return self.c * rel + self.c3 * rel ** 3

    m = rm.Model("cubic")
    fixed = m.add(Fixed("fixed"))
    spring = m.add(CubicSpring("spring", c=50.0, c3=400.0))
    body = m.add(Inertia("J", J=0.5))
    m.connect(fixed.flange, spring.flange_a)
    m.connect(spring.flange_b, body.flange_a)
    phi = 0.2
    lin = m.linearize(at={"J.phi": phi})
    np.testing.assert_allclose(lin.x0, [phi])
    np.testing.assert_allclose(np.ravel(lin.C), [50.0 + 3 * 400.0 * phi ** 2], rtol=1e-12)
    lin0 = m.linearize(at=(np.array([0.0]), np.array([0.0])))
    np.testing.assert_allclose(np.ravel(lin0.C), [50.0])


def clutch_model(mu_table=None):
    m = rm.Model("clutched")
    fixed = m.add(Fixed("fixed"))
    j1, j2 = m.add(Inertia("J1", J=1.0)), m.add(Inertia("J2", J=3.0))
    s1, s2 = m.add(Spring("s1", c=40.0)), m.add(Spring("s2", c=90.0))
    kw = dict(mu_table=mu_table) if mu_table is not None else {}
    cl = m.add(Clutch("clutch", fn_max=100.0, **kw))
    m.connect(fixed.flange, s1.flange_a)
    m.connect(s1.flange_b, j1.flange_a)
    m.connect(j1.flange_b, cl.flange_a)
    m.connect(cl.flange_b, j2.flange_a)
    m.connect(j2.flange_b, s2.flange_a)
    m.connect(s2.flange_b, fixed.flange)
    return m


def test_stuck_clutch_merges_and_free_clutch_separates():
    m = clutch_model()
    stuck = modal(m.linearize(modes={"clutch": "Stuck"}))
    assert stuck.lin.n == 1
    np.testing.assert_allclose(stuck.omega, [np.sqrt(130.0 / 4.0)], rtol=1e-12)
    free = modal(m.linearize(modes=[2]))
    np.testing.assert_allclose(free.omega, np.sort([np.sqrt(40.0), np.sqrt(30.0)]), rtol=1e-12)


def test_sliding_clutch_with_falling_friction_gives_negative_damping():
    m = clutch_model(mu_table=[(0.0, 0.5), (2.0, 0.3)])
    lin = m.linearize(modes={"clutch": "Forward"}, at={"J1.w": 0.0, "J2.w": 1.0})
    d = -0.1 * 100.0    # dmu/dw * cgeo * fn_max
    np.testing.assert_allclose(lin.B, d * np.array([[1.0, -1.0], [-1.0, 1.0]]), rtol=1e-12)
    np.testing.assert_allclose(lin.output("clutch.tau").a1, d * np.array([-1.0, 1.0]))


def test_speed_source_is_held_fixed_for_modes():
    m = rm.Model("driven")
    motor = m.add(Speed("motor", w_ref=100.0))
    hub = m.add(Inertia("hub", J=1.0))
    shaft = m.add(Shaft("shaft", stiffness=1e3))
    load = m.add(Inertia("load", J=10.0))
    m.connect(motor.flange, hub.flange_a)
    m.connect(hub.flange_b, shaft.flange_a)
    m.connect(shaft.flange_b, load.flange_a)
    lin = m.linearize()
    assert lin.coords == ["load"]
    assert lin.kinematic_names == ["motor.w_ref"] and lin.kinematic_levels == ["speed"]
    np.testing.assert_allclose(modal(lin).omega, [10.0], rtol=1e-12)


def test_errors_name_the_problem():
    lin = chain(3).linearize()
    with pytest.raises(rm.ParameterError, match="no linear output"):
        lin.output("J0.nope")
    with pytest.raises(rm.ParameterError, match="no friction devices"):
        chain(3).linearize(modes=[0])
    with pytest.raises(rm.ParameterError, match="not a position or speed"):
        chain(3).linearize(at={"c0.phi": 1.0})
    with pytest.raises(rm.ParameterError, match="between 1 and"):
        modal(lin, k=0)
    m = clutch_model()
    with pytest.raises(rm.ParameterError, match="Backward"):
        m.linearize(modes={"clutch": "sideways"})


def test_torque_source_and_outputs():
    m = chain(2)
    drive = m.add(Torque("drive", tau=1.0))
    m.connect(drive.flange, m["J1"].flange_b)
    lin = m.linearize()
    assert lin.input_names == ["drive.tau"]
    np.testing.assert_allclose(np.ravel(lin.W), [0.0, 1.0])
    assert {"J0.phi", "J1.w", "c1.tau", "c1.phi_rel"} <= set(lin.outputs())
    assert "drive.tau" not in lin.outputs()


def test_linearize_accepts_held_for_devices_locking_an_already_locked_motion():
    # two brakes on one inertia: 'stuck' for both is singular (named, with the remedy);
    # 'held' (what a simulation records for the second) gives the locked motion
    from regmech.components import Brake
    m = rm.Model("two_brakes")
    J = m.add(Inertia("J", J=1.0))
    J2 = m.add(Inertia("J2", J=2.0))
    s = m.add(Spring("s", c=100.0))
    m.connect(J.flange_b, s.flange_a)
    m.connect(s.flange_b, J2.flange_a)
    m.add(Brake("b1", fn_max=10.0))
    m.add(Brake("b2", fn_max=10.0))
    m.connect(J2.flange_b, m["b1"].flange)
    m.connect(J2.flange_b, m["b2"].flange)
    lm = m.linearize(modes={"b1": "stuck", "b2": "held"})
    np.testing.assert_allclose(np.ravel(lm.M), [1.0])
    np.testing.assert_allclose(np.ravel(lm.C), [100.0])
    np.testing.assert_allclose(np.ravel(m.linearize(modes=[0, 3]).C), [100.0])      # codes as recorded
    with pytest.raises(rm.StructureError, match="'held'"):
        m.linearize(modes={"b1": "stuck", "b2": "stuck"})
