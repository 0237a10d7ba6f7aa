"""Backlash and ElastoBacklash: the law along prescribed motion, continuity,
no pulling, free flight in the play, energy."""

import numpy as np
import pytest

import regmech as rm
from regmech.components import Fixed, Inertia, Mass, Position, SpringDamper
from regmech.components.backlash import Backlash, ElastoBacklash
from regmech.signals import Sine


def msl_elasto_backlash(phi_diff, w_rel, c, d, b):
    """MSL ElastoBacklash torque, written independently with numpy (min/max as in the MSL source)."""
    phi_diff, w_rel = np.broadcast_arrays(np.asarray(phi_diff, float), np.asarray(w_rel, float))
    tau = np.zeros_like(phi_diff)
    bmax = b / 2
    tau_d = d * w_rel
    up = phi_diff > bmax
    tc = c * (phi_diff - bmax)
    tau[up] = np.where(tc[up] + tau_d[up] <= 0, 0.0, tc[up] + np.minimum(tc[up], tau_d[up]))
    lo = phi_diff < -bmax
    tc = c * (phi_diff + bmax)
    tau[lo] = np.where(tc[lo] + tau_d[lo] >= 0, 0.0, tc[lo] + np.maximum(tc[lo], tau_d[lo]))
    return tau


def _prescribed(device, amplitude=1.0, freq_hz=1.0, offset=0.2):
    """flange_a fixed, flange_b moved along offset + amplitude*sin(2 pi f t)."""
    m = rm.Model("prescribed")
    fixed = m.add(Fixed("fixed", domain=device.domain))
    m.add(device)
    drive = m.add(Position("drive", phi_ref=Sine(amplitude=amplitude, freq_hz=freq_hz, offset=offset),
                           domain=device.domain))
    m.connect(device.flange_a, fixed.flange)
    m.connect(device.flange_b, drive.flange)
    m.connect(drive.support, fixed.flange)
    return m


@pytest.mark.parametrize("c,d,b", [(100.0, 30.0, 0.6), (50.0, 0.0, 0.4), (80.0, 500.0, 1.0)])
def test_elasto_backlash_law_matches_msl_formula(c, d, b):
    dev = ElastoBacklash("eb", c=c, d=d, b=b, phi_rel0=0.1)
    res = _prescribed(dev).simulate(2.0, dt_out=1e-3, rtol=1e-8, solver="ida")
    phi, w = res["eb.phi_rel"], res["eb.w_rel"]
    t = res.t
    np.testing.assert_allclose(phi, 0.2 + np.sin(2 * np.pi * t), atol=1e-9)
    expected = msl_elasto_backlash(phi - 0.1, w, c, d, b)
    np.testing.assert_allclose(res["eb.tau"], expected, rtol=1e-10, atol=1e-10)
    # all branches visited: play, pushing, pulling side, and (with damping) the clipped branches
    assert np.any(expected == 0) and np.any(expected > 0) and np.any(expected < 0)
    # flange torques: tau = flange_b.tau = -flange_a.tau
    np.testing.assert_allclose(res["eb.flange_b.tau"], res["eb.tau"])
    np.testing.assert_allclose(res["eb.flange_a.tau"], -res["eb.tau"])


def test_elasto_backlash_torque_continuous_at_contact_and_never_pulling():
    c, d, b = 100.0, 400.0, 0.6
    dev = ElastoBacklash("eb", c=c, d=d, b=b)
    res = _prescribed(dev, offset=0.0).simulate(2.0, dt_out=2e-4, rtol=1e-8, solver="ida")
    phi, tau = res["eb.phi_rel"], res["eb.tau"]
    # contact pushes only: tau has the sign of the penetration
    assert np.all(tau * np.sign(phi) >= -1e-12)
    # continuity: between output points the torque changes by no more than its smooth parts allow,
    # |d tau| <= 2 c |d phi| + d |d w|; a jump of d*w_rel (400 * 6 N m at contact) would break this
    steps = np.abs(np.diff(tau))
    bound = 2 * c * np.abs(np.diff(phi)) + d * np.abs(np.diff(res["eb.w_rel"]))
    assert np.all(steps <= bound * (1 + 1e-6) + 1e-9)
    # where the speed is large at contact, the plain spring-damper would jump by d*w: ours stays near zero
    near_contact = np.abs(np.abs(phi) - b / 2) < 1e-3
    assert near_contact.any()
    assert np.abs(tau[near_contact]).max() < 2 * c * 1e-3 + 1e-9


def test_backlash_is_a_dead_zone_spring():
    c, b = 40.0, 0.5
    dev = Backlash("bl", c=c, b=b)
    res = _prescribed(dev, offset=0.0).simulate(1.0, dt_out=1e-3, rtol=1e-8, solver="ida")
    phi = res["bl.phi_rel"]
    dz = np.where(phi > b / 2, phi - b / 2, np.where(phi < -b / 2, phi + b / 2, 0.0))
    np.testing.assert_allclose(res["bl.tau"], c * dz, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(res["bl.potential"], c * dz ** 2 / 2, rtol=1e-12, atol=1e-14)


def test_zero_backlash_is_a_spring_damper():
    def build(device):
        m = rm.Model("sd")
        fixed = m.add(Fixed("fixed"))
        J = m.add(Inertia("J", J=2.0, phi0=0.3, w0=-1.0))
        m.add(device)
        m.connect(device.flange_a, fixed.flange)
        m.connect(device.flange_b, J.flange_a)
        return m
    r1 = build(ElastoBacklash("link", c=500.0, d=3.0, b=0.0)).simulate(1.0, dt_out=0.01, rtol=1e-10, atol=1e-12,
                                                                        solver="ida")
    r2 = build(SpringDamper("link", c=500.0, d=3.0)).simulate(1.0, dt_out=0.01, rtol=1e-10, atol=1e-12, solver="ida")
    np.testing.assert_allclose(r1["J.phi"], r2["J.phi"], atol=1e-8)


def test_free_flight_inside_the_play_then_contact():
    # an inertia starting in the middle of the play at speed w0 coasts untouched until |phi| = b/2
    b, w0 = 0.4, 2.0
    m = rm.Model("flight")
    fixed = m.add(Fixed("fixed"))
    eb = m.add(ElastoBacklash("eb", c=1e4, d=20.0, b=b))
    J = m.add(Inertia("J", J=0.5, phi0=0.0, w0=w0))
    m.connect(eb.flange_a, fixed.flange)
    m.connect(eb.flange_b, J.flange_a)
    res = m.simulate(0.3, dt_out=1e-3, rtol=1e-9, atol=1e-11, solver="ida")
    t_contact = (b / 2) / w0
    free = res.t < t_contact - 1e-9
    np.testing.assert_allclose(res["J.phi"][free], w0 * res.t[free], rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(res["eb.tau"][free], 0.0, atol=1e-12)
    # after the contact the inertia bounces back: lost energy, never gained
    ke = res["J.kinetic"]
    assert res["J.w"][-1] < 0
    total = ke + res["eb.potential"]
    assert np.all(np.diff(total) <= 1e-9 * total[0])
    assert total[-1] < total[0]


def test_translational_elasto_backlash_dissipates_only():
    # translational version (coupler slack): energy audit power = d(potential)/dt + dissipation >= 0
    m = rm.Model("slack")
    fixed = m.add(Fixed("fixed", domain="translational"))
    eb = m.add(ElastoBacklash("slack", c=2e5, d=800.0, b=0.02, domain="translational"))
    car = m.add(Mass("car", m=100.0, s0=0.0, v0=1.5))
    m.connect(eb.flange_a, fixed.flange)
    m.connect(eb.flange_b, car.flange_a)
    res = m.simulate(1.0, dt_out=2e-4, rtol=1e-9, atol=1e-11, solver="ida")
    assert "slack.s_rel" in res and "slack.f" in res
    t = res.t
    dissipated = np.cumsum(np.concatenate([[0.0], np.diff(t) * (res["slack.power"][1:] + res["slack.power"][:-1]) / 2]))
    dissipated -= res["slack.potential"] - res["slack.potential"][0]
    assert np.all(np.diff(dissipated) >= -1e-6)
    assert dissipated[-1] > 0.1
    # energy balance of the whole (no sources): kinetic + potential + dissipated is constant
    total = res["car.kinetic"] + res["slack.potential"] + dissipated
    np.testing.assert_allclose(total, total[0], rtol=2e-4)


def test_parameter_errors_name_the_component():
    with pytest.raises(rm.ParameterError, match="eb.*'b'"):
        ElastoBacklash("eb", c=1.0, d=0.0, b=-0.1)
    with pytest.raises(rm.ParameterError, match="'c' is required"):
        Backlash("bl", b=0.1)
