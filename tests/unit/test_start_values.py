"""Fixed start values that cannot be met are errors naming the masses, the devices and the fix.

One mechanism covers every way a start value can be contradicted: the ground a
mass is connected to (it was once silently dropped), several
masses on one point, rigid shafts and gears, and motion sources whose reference
at ``t_start`` disagrees. Values equal up to round-off pass.
"""

import numpy as np
import pytest

import regmech as rm
from regmech.components import (Fixed, IdealGear, Inertia, LinearSpeed, Mass, Position, Shaft, Speed, Spring,
                                Torque)
from regmech.signals import Ramp, Sine


def _free_mass(m):
    """A second, free mass so the model has something to integrate."""
    J = m.add(Inertia("Jfree", J=1.0, w0=1.0))
    drive = m.add(Torque("drive", tau=1.0))
    m.connect(drive.flange, J.flange_a)


def _on_ground(body_kwargs, ground_kwargs=None, domain="rotational"):
    m = rm.Model("on_ground")
    f = m.add(Fixed("f", **(ground_kwargs or {})))
    body = m.add(Inertia("J1", J=1.0, **body_kwargs) if domain == "rotational" else Mass("J1", m=1.0, **body_kwargs))
    m.connect(f.flange, body.flange_a)
    _free_mass(m)
    return m


@pytest.mark.parametrize("body, ground, what, shown", [
    (dict(w0=5.0), {}, "velocities", "w0=5"),
    (dict(phi0=3.0), dict(phi0=2.0), "positions", "phi0=3"),
    (dict(phi0=1e-6), {}, "positions", "phi0=1e-06"),
    (dict(phi0=2.0, w0=-0.5), dict(phi0=2.0), "velocities", "w0=-0.5"),
])
def test_a_start_value_that_contradicts_the_ground_is_an_error(body, ground, what, shown):
    m = _on_ground(body, ground)
    with pytest.raises(rm.StructureError) as err:
        m.simulate(t_end=0.1)
    msg = str(err.value)
    assert f"inconsistent start {what}" in msg
    assert "Inertia 'J1'" in msg and shown in msg and "Fixed 'f'" in msg
    assert "Fix:" in msg and "drop its start value" in msg


def test_translational_mass_on_the_ground():
    m = rm.Model("slider")
    f = m.add(Fixed("f", s0=0.25))
    body = m.add(Mass("M", m=2.0, s0=0.5, v0=0.0))
    m.connect(f.flange, body.flange_a)
    spring, M2 = m.add(Spring("k", c=10.0, domain="translational")), m.add(Mass("M2", m=1.0, v0=1.0))
    m.connect(body.flange_b, spring.flange_a)
    m.connect(spring.flange_b, M2.flange_a)
    with pytest.raises(rm.StructureError, match=r"Fixed 'f' \(phi0=0.25\), Mass 'M' \(s0=0.5\)"):
        m.compile().initial_y(0.0)


@pytest.mark.parametrize("body, ground", [
    (dict(w0=0.0), {}),
    (dict(phi0=2.0, w0=0.0), dict(phi0=2.0)),
    (dict(phi0=0.1 * 3), dict(phi0=0.3)),                  # 0.30000000000000004 against 0.3: round-off
    (dict(phi0=2.0 * (1 + 4e-16)), dict(phi0=2.0)),
])
def test_start_values_that_agree_with_the_ground_pass(body, ground):
    m = _on_ground(body, ground)
    res = m.simulate(t_end=0.1)
    assert np.all(res["J1.w"] == 0.0)
    assert np.allclose(res["J1.phi"], ground.get("phi0", 0.0), rtol=0, atol=1e-15)


def test_two_grounds_at_different_positions_on_one_point():
    m = rm.Model("grounds")
    f1, f2 = m.add(Fixed("f1", phi0=0.0)), m.add(Fixed("f2", phi0=1.0))
    m.connect(f1.flange, f2.flange)
    spring = m.add(Spring("k", c=1.0))
    m.connect(f1.flange, spring.flange_a)
    J = m.add(Inertia("J", J=1.0))
    m.connect(spring.flange_b, J.flange_a)
    with pytest.raises(rm.StructureError, match=r"Fixed 'f1' \(phi0=0\), Fixed 'f2' \(phi0=1\)"):
        m.compile()


def test_masses_joined_at_one_point_with_different_starts():
    m = rm.Model("point")
    J1, J2 = m.add(Inertia("J1", J=1.0, w0=1.0)), m.add(Inertia("J2", J=1.0, w0=2.0))
    m.connect(J1.flange_b, J2.flange_a)
    with pytest.raises(rm.StructureError, match=r"J1' \(w0=1\), Inertia 'J2' \(w0=2\).*give it on one of them only"):
        m.compile()
    J2.w0 = 1.0 + 1e-15                                      # equal up to round-off
    assert m.simulate(t_end=0.1)["J2.w"][0] == 1.0


def _rigid_to_ground(device):
    m = rm.Model("rigid_ground")
    f, J = m.add(Fixed("f")), m.add(Inertia("J1", J=1.0, w0=5.0))
    d = m.add(device)
    m.connect(J.flange_b, d.flange_a)
    m.connect(d.flange_b, f.flange)
    _free_mass(m)
    return m


@pytest.mark.parametrize("device", [Shaft("s", stiffness=None), IdealGear("s", ratio=3.0)])
def test_rigid_path_to_the_ground(device):
    with pytest.raises(rm.StructureError) as err:
        _rigid_to_ground(device).simulate(t_end=0.1)
    msg = str(err.value)
    assert "Inertia 'J1' (w0=5) contradicts" in msg and "'s' (to the ground)" in msg
    assert "drop its start velocity" in msg


def _gear_pair(w1, w2, ratio):
    m = rm.Model("gears")
    J1, J2 = m.add(Inertia("J1", J=1.0, w0=w1)), m.add(Inertia("J2", J=2.0, w0=w2))
    g = m.add(IdealGear("g", ratio=ratio))
    m.connect(J1.flange_b, g.flange_a)
    m.connect(g.flange_b, J2.flange_a)
    return m


def test_start_values_through_an_ideal_gear():
    with pytest.raises(rm.StructureError) as err:
        _gear_pair(5.0, 5.0, 2.0).simulate(t_end=0.1)
    msg = str(err.value)
    assert "Inertia 'J1' (w0=5), Inertia 'J2' (w0=5) cannot all hold with IdealGear 'g'" in msg
    assert "one mass of each rigidly joined group only" in msg
    # w_b = w_a / ratio, given with round-off (1/3 is not exact in binary)
    res = _gear_pair(1.0, 1.0 / 3.0, 3.0).simulate(t_end=0.1)
    assert res["J1.w"][0] == 1.0 and res["J2.w"][0] == 1.0 / 3.0


def test_only_the_conflicting_group_is_named():
    m = _gear_pair(5.0, 5.0, 2.0)
    J3, J4 = m.add(Inertia("J3", J=1.0, w0=7.0)), m.add(Inertia("J4", J=1.0))
    s = m.add(Shaft("s34", stiffness=None))
    m.connect(J3.flange_b, s.flange_a)
    m.connect(s.flange_b, J4.flange_a)
    with pytest.raises(rm.StructureError) as err:
        m.compile().initial_y(0.0)
    assert "'J1'" in str(err.value) and "'J3'" not in str(err.value) and "s34" not in str(err.value)


def _driven(source, **start):
    m = rm.Model("driven")
    J = m.add(Inertia("J1", J=1.0, **start))
    src = m.add(source)
    m.connect(src.flange, J.flange_a)
    return m


@pytest.mark.parametrize("source, start, t_start, shown", [
    (Speed("p", w_ref=3.0), dict(w0=5.0), 0.0, "w_ref=3"),
    (Speed("p", w_ref=Sine(amplitude=2.0, freq_hz=1.0, offset=1.0)), dict(w0=1.0), 0.25, "w_ref=3"),
    (Position("p", phi_ref=Ramp(height=1.0, duration=1.0)), dict(phi0=0.0), 0.5, "phi_ref=0.5"),
    (Position("p", phi_ref=Ramp(height=1.0, duration=1.0)), dict(w0=5.0), 0.0, "d/dt phi_ref=1"),
    (LinearSpeed("p", v_ref=-1.0), dict(), 0.0, "v_ref=-1"),
])
def test_a_motion_source_whose_reference_at_t_start_contradicts_a_start_value(source, start, t_start, shown):
    if isinstance(source, LinearSpeed):
        m = rm.Model("driven")
        M = m.add(Mass("M1", m=1.0, v0=2.0))
        m.connect(m.add(source).flange, M.flange_a)
    else:
        m = _driven(source, **start)
    with pytest.raises(rm.StructureError) as err:
        m.simulate(t_end=t_start + 0.1, t_start=t_start)
    msg = str(err.value)
    assert f"at t={t_start:g}" in msg and "'p' (" + shown + ")" in msg
    assert "the source sets it" in msg


@pytest.mark.parametrize("source, start, t_start", [
    (Speed("p", w_ref=Sine(amplitude=2.0, freq_hz=1.0, offset=1.0)), dict(w0=3.0), 0.25),
    (Position("p", phi_ref=Ramp(height=1.0, duration=1.0)), dict(phi0=0.5, w0=1.0), 0.5),
    (Position("p", phi_ref=Ramp(height=0.3, duration=1.0)), dict(phi0=0.1 * 3 * 0.5), 0.5),
])
def test_start_values_that_agree_with_the_source_pass(source, start, t_start):
    res = _driven(source, **start).simulate(t_end=t_start + 0.1, t_start=t_start)
    for key, name in (("phi0", "J1.phi"), ("w0", "J1.w")):
        if key in start:
            assert res[name][0] == pytest.approx(start[key], rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("solver", ["ida", "scipy:DOP853", "expm"])
def test_every_solver_refuses_a_start_value_on_the_ground(solver):
    with pytest.raises(rm.StructureError, match="Inertia 'J1' \\(w0=5\\)"):
        _on_ground(dict(w0=5.0)).simulate(t_end=0.1, solver=solver)


def test_random_gear_trees_with_consistent_and_perturbed_start_speeds():
    """Gear trees with every start speed fixed: exactly consistent values (up to the round-off of
    computing them) pass, a relative perturbation of 1e-6 on any one of them is refused."""
    rng = np.random.default_rng(13)
    for trial in range(12):
        n = int(rng.integers(3, 9))
        ratios = rng.choice([-3.0, -0.7, 0.5, 1.7, 2.0, 7.0], size=n - 1)
        parents = [int(rng.integers(0, k)) for k in range(1, n)]
        w = [float(rng.uniform(-10, 10))]
        for k in range(1, n):
            w.append(w[parents[k - 1]] / ratios[k - 1])      # w_b = w_a / ratio
        bad = int(rng.integers(0, n)) if trial % 2 else None

        def build():
            m = rm.Model(f"tree{trial}")
            Js = [m.add(Inertia(f"J{k}", J=float(rng.uniform(0.1, 2.0)),
                                w0=w[k] * (1 + 1e-6 if k == bad else 1.0))) for k in range(n)]
            for k in range(1, n):
                g = m.add(IdealGear(f"g{k}", ratio=float(ratios[k - 1])))
                m.connect(Js[parents[k - 1]].flange_b, g.flange_a)
                m.connect(g.flange_b, Js[k].flange_a)
            return m

        m = build()
        if bad is None:
            y, _ = m.compile().initial_y(0.0)
            c = m.compile()
            assert np.allclose(y[c.iv], w, rtol=1e-12, atol=0)
        else:
            with pytest.raises(rm.StructureError, match=f"Inertia 'J{bad}'"):
                m.compile().initial_y(0.0)


def test_scene_grounding_a_heavy_mass_keeps_its_start_position():
    """``ground_heavy`` fixes a heavy mass at rest where it starts (a Fixed at 0 would contradict
    its start angle, and change the deflection of the spring to it)."""
    m = rm.Model("heavy")
    heavy = m.add(Inertia("heavy", J=1e6, phi0=0.7, w0=0.0))
    k = m.add(Spring("k", c=100.0))
    J = m.add(Inertia("J", J=1.0, phi0=0.7))
    m.connect(heavy.flange_b, k.flange_a)
    m.connect(k.flange_b, J.flange_a)
    drive = m.add(Torque("drive", tau=1.0))
    m.connect(drive.flange, J.flange_b)
    sc = rm.Scene(m, t_end=0.5, outputs=["J.phi"], heavy_ratio=1e4, passes=["ground_heavy"])
    assert any(a.kind == "ground_heavy" and a.applied for a in sc.reduction.actions)
    red = sc.simulate(dt_out=0.05)["J.phi"]
    full = m.simulate(t_end=0.5, dt_out=0.05)["J.phi"]
    assert red[0] == 0.7
    assert np.max(np.abs(red - full)) < 1e-4 * np.ptp(full) + 1e-9


def test_linearize_at_speeds_that_a_stuck_clutch_cannot_hold():
    from regmech.components import Clutch
    m = rm.Model("clutch")
    J1, J2 = m.add(Inertia("J1", J=1.0)), m.add(Inertia("J2", J=1.0))
    c = m.add(Clutch("c", mu=0.5, peak=1.1, fn_max=20, f_normalized=1.0))
    m.connect(J1.flange_b, c.flange_a)
    m.connect(c.flange_b, J2.flange_a)
    with pytest.raises(rm.StructureError) as err:
        m.linearize(modes={"c": "Stuck"}, at={"J1.w": 1.0, "J2.w": 2.0})
    msg = str(err.value)
    assert "Inertia 'J1' (w=1), Inertia 'J2' (w=2)" in msg and "Clutch 'c' (stuck)" in msg
    assert "give the speed on one side only" in msg
    assert m.linearize(modes={"c": "Stuck"}, at={"J1.w": 1.0}).M.shape == (1, 1)
