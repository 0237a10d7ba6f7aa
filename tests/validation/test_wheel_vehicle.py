"""Wheel (tyre compliance + stick/slip road contact), Magic-Formula tyre, the launch scene."""

import numpy as np
import pytest
from scipy.integrate import simpson

import regmech as rm
from regmech.components import MagicFormulaWheel, Mass, Torque, Wheel


def single_wheel(T, mu, fn=4000.0, m_body=400.0):
    m = rm.Model("single_wheel")
    drive = m.add(Torque("drive", tau=T))
    w = m.add(Wheel("wheel", radius=0.3, J=1.0, fn=fn, mu=mu, peak=1.1, w0=0.0, v0=0.0))
    body = m.add(Mass("body", m=m_body))
    m.connect(drive.flange, "wheel.hub")
    m.connect(w.axle, body.flange_a)
    return m


def test_wheel_grips_with_elastic_slip_only_and_balances_energy():
    res = single_wheel(T=500.0, mu=0.9).simulate(2.0, dt_out=1e-3, rtol=1e-9, solver="ida")
    assert np.all(res["wheel.road_contact.mode"] == 0)          # never slides
    # steady traction drives body + axle + the wheel's inertia; tread and contact patch sit at the
    # contact point, which stands still while the wheel rolls
    a_expected = 500.0 / 0.3 / (400.0 + 20.0 + 1.0 / 0.3**2)
    late = res.t > 1.0
    acc = np.gradient(res["body.v"], res.t)[late]
    assert np.mean(acc) == pytest.approx(a_expected, rel=2e-3)
    slip = 0.3 * res["wheel.J.w"] - res["body.v"]
    assert np.max(np.abs(slip[late])) < 0.05                     # elastic slip: small, bounded
    t = res.t
    work = simpson(-res["drive.power"], x=t)
    kinetic = sum(res[n] for n in res.names if n.endswith(".kinetic"))
    potential = res["wheel.tyre.potential"]
    dissipated = simpson(500.0 * res["wheel.tyre.v_rel"] ** 2 + res["wheel.road_contact.power"], x=t)
    assert work == pytest.approx(kinetic[-1] - kinetic[0] + potential[-1] - potential[0] + dissipated, rel=1e-6)


def test_wheel_spins_when_torque_exceeds_grip():
    res = single_wheel(T=3000.0, mu=0.3).simulate(1.0, dt_out=1e-3, rtol=1e-8, solver="ida")
    ev = [e for e in res.events if e.component == "wheel.road_contact"]
    assert ev and ev[0].new_mode == 1
    sliding = res["wheel.road_contact.mode"] == 1
    assert np.allclose(res["wheel.road_contact.f"][sliding], 0.3 * 4000.0)
    assert 0.3 * res["wheel.J.w"][-1] > 5 * res["body.v"][-1]   # wheel spin


def test_magic_formula_wheel_force_follows_the_formula():
    m = rm.Model("mf")
    drive = m.add(Torque("drive", tau=300.0))
    w = m.add(MagicFormulaWheel("wheel", radius=0.3, J=1.0, fn=4000.0, w0=10.0 / 0.3))
    body = m.add(Mass("body", m=500.0, v0=10.0))
    m.connect(drive.flange, w.hub)
    m.connect(w.axle, body.flange_a)
    res = m.simulate(1.0, dt_out=1e-2, rtol=1e-9, solver="ida")
    v, wr = res["body.v"], 0.3 * res["wheel.J.w"]
    kappa = (wr - v) / np.sqrt(v**2 + 0.5**2)
    bk = 10.0 * kappa
    F = 4000.0 * np.sin(1.9 * np.arctan(bk - 0.97 * (bk - np.arctan(bk))))
    assert np.allclose(np.gradient(v, res.t)[5:-5] * 500.0, F[5:-5], rtol=1e-2)
    assert 0 < kappa[-1] < 0.05                                   # small traction slip


def test_subsystem_names_ports_and_errors():
    m = single_wheel(T=1.0, mu=0.9)
    assert isinstance(m["wheel"], Wheel) and "wheel.J" in m and "wheel.road_contact" in m
    with pytest.raises(rm.UnknownFlangeError, match="has no flange 'rim'"):
        m["wheel"].rim


@pytest.mark.parametrize("mu, spins", [(0.9, False), (0.15, True)])
def test_vehicle_launch_clutch_locks_and_wheels_slip_only_on_low_grip(mu, spins):
    from regmech.library import SCENES
    res = SCENES["vehicle_launch"](mu_road=mu, clutch_fn_max=3000.0).simulate(3.0, dt_out=1e-2, rtol=1e-6, solver="ida")
    clutch = [(e.old_mode, e.new_mode) for e in res.events if e.component == "clutch"]
    assert clutch[0] == (2, -1) and (-1, 0) in clutch            # engages slipping, then locks
    slid = any(e.new_mode in (-1, 1) for e in res.events if "road_contact" in e.component)
    assert slid == spins
    assert res["body.v"][-1] > 1.0
