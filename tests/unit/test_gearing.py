"""Differential and Planetary: kinematics, torque relations, closed forms."""

import numpy as np
import pytest

import regmech as rm
from regmech.components import Damper, Fixed, Inertia, Torque
from regmech.components.gearing import Differential, Planetary

TIGHT = dict(rtol=1e-10, atol=1e-12)


def _differential_model(ratio=3.0, T=10.0, Jc=0.5, Jl=2.0, Jr=1.0, d_left=0.0, carrier_fixed=False,
                        left_torque=0.0):
    """drive torque T -> carrier inertia Jc -> differential -> side inertias Jl, Jr;
    optional damper d_left from the left side to the ground."""
    m = rm.Model("diff")
    fixed = m.add(Fixed("fixed"))
    diff = m.add(Differential("diff", ratio=ratio))
    left = m.add(Inertia("left", J=Jl, phi0=0.0, w0=0.0))
    right = m.add(Inertia("right", J=Jr, phi0=0.0))
    m.connect(diff.left, left.flange_a)
    m.connect(diff.right, right.flange_a)
    if carrier_fixed:
        m.connect(diff.carrier, fixed.flange)
    else:
        drive = m.add(Torque("drive", tau=T))
        carrier = m.add(Inertia("carrier", J=Jc, phi0=0.0, w0=0.0))
        m.connect(drive.flange, carrier.flange_a)
        m.connect(carrier.flange_b, diff.carrier)
    if d_left:
        damper = m.add(Damper("brake_load", d=d_left))
        m.connect(damper.flange_a, left.flange_b)
        m.connect(damper.flange_b, fixed.flange)
    if left_torque:
        tl = m.add(Torque("left_drive", tau=left_torque))
        m.connect(tl.flange, left.flange_b)
    return m


def test_differential_rigid_accelerations_match_hand_solution():
    # Jc ac = T - lam; J_side a_side = (ratio/2) lam; ac = ratio (al + ar)/2
    ratio, T, Jc, Jl, Jr = 3.0, 10.0, 0.5, 2.0, 1.0
    lam = T / (1.0 + Jc * ratio ** 2 / 4 * (1 / Jl + 1 / Jr))
    res = _differential_model(ratio, T, Jc, Jl, Jr).simulate(1.0, dt_out=0.1, **TIGHT, solver="ida")
    t = res.t
    np.testing.assert_allclose(res["right.w"], ratio * lam / (2 * Jr) * t, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(res["left.w"], ratio * lam / (2 * Jl) * t, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(res["diff.tau"], lam, rtol=1e-8)


def test_differential_kinematics_and_equal_side_torques():
    res = _differential_model(d_left=3.0).simulate(2.0, dt_out=0.01, **TIGHT, solver="ida")
    ratio = 3.0
    # carrier = ratio * mean of the sides, at every output instant
    np.testing.assert_allclose(res["carrier.phi"], ratio * (res["left.phi"] + res["right.phi"]) / 2,
                               rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(res["carrier.w"], ratio * (res["left.w"] + res["right.w"]) / 2,
                               rtol=1e-8, atol=1e-10)
    # equal torques on both sides, and -ratio/2 times the carrier torque
    np.testing.assert_allclose(res["diff.left.tau"], res["diff.right.tau"], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(res["diff.left.tau"], -ratio / 2 * res["diff.carrier.tau"], rtol=1e-12)
    assert np.abs(res["diff.left.tau"]).max() > 1.0      # a torque was actually transmitted
    # ideal gearing absorbs no power
    np.testing.assert_allclose(res["diff.power"], 0.0, atol=1e-8 * np.abs(res["drive.power"]).max())


def test_one_wheel_on_ice_spins_at_twice_the_mean():
    # the left wheel pulls a heavy load (large damping), the right one is on ice (tiny inertia, no load):
    # the side torques are equal, so the small right torque leaves the left wheel nearly at rest
    ratio = 2.0
    res = _differential_model(ratio=ratio, T=5.0, Jc=0.5, Jl=2.0, Jr=1e-4, d_left=50.0).simulate(
        1.0, dt_out=0.01, **TIGHT, solver="ida")
    mean = res["carrier.w"][-1] / ratio
    assert mean > 1.0
    assert res["right.w"][-1] == pytest.approx(2 * mean, rel=1e-3)
    assert abs(res["left.w"][-1]) < 1e-3 * mean
    # and the torque through the differential is tiny compared to the drive torque
    assert np.abs(res["diff.left.tau"][-1]) < 1e-3 * 5.0


def test_locked_carrier_sides_turn_opposite():
    res = _differential_model(carrier_fixed=True, Jl=2.0, Jr=2.0, left_torque=4.0).simulate(
        1.0, dt_out=0.05, **TIGHT, solver="ida")
    np.testing.assert_allclose(res["left.w"], -res["right.w"], rtol=1e-9, atol=1e-12)
    # two equal inertias driven together by 4 N m: a = 4 / (2 + 2)
    np.testing.assert_allclose(res["left.w"], 1.0 * res.t, rtol=1e-8, atol=1e-12)


def test_differential_with_rotating_support_uses_relative_angles():
    # support (housing) on an inertia spun up by its own torque: the relation holds relative to it
    m = rm.Model("diff_support")
    diff = m.add(Differential("diff", ratio=2.5))
    housing = m.add(Inertia("housing", J=3.0, phi0=0.0, w0=1.0))
    parts = {n: m.add(Inertia(n, J=1.0, phi0=0.0, w0=None if n == "right" else 0.0))
             for n in ("carrier", "left", "right")}
    for name, inertia in parts.items():
        m.connect(diff.get_flange(name), inertia.flange_a)
    m.connect(diff.support, housing.flange_a)
    drive = m.add(Torque("drive", tau=2.0))
    m.connect(drive.flange, parts["carrier"].flange_b)
    res = m.simulate(1.0, dt_out=0.05, **TIGHT, solver="ida")
    s = res["housing.phi"]
    np.testing.assert_allclose(res["carrier.phi"] - s, 2.5 * ((res["left.phi"] + res["right.phi"]) / 2 - s),
                               rtol=1e-9, atol=1e-10)
    # the reaction on the housing closes the torque balance of the device
    total = res["diff.carrier.tau"] + res["diff.left.tau"] + res["diff.right.tau"] + res["diff.support.tau"]
    np.testing.assert_allclose(total, 0.0, atol=1e-10)


def test_differential_zero_ratio_refused():
    with pytest.raises(rm.ParameterError, match="ratio"):
        Differential("d", ratio=0.0)


def _planetary_model(ratio, ring_fixed=False):
    m = rm.Model("planetary")
    fixed = m.add(Fixed("fixed"))
    pg = m.add(Planetary("planetary", ratio=ratio))
    sun = m.add(Inertia("sun", J=0.1, phi0=0.0, w0=0.0))
    carrier = m.add(Inertia("carrier", J=2.0, phi0=0.0, w0=0.0))
    m.connect(pg.sun, sun.flange_a)
    m.connect(pg.carrier, carrier.flange_a)
    if ring_fixed:
        m.connect(pg.ring, fixed.flange)
    else:
        ring = m.add(Inertia("ring", J=1.0, phi0=0.0))
        m.connect(pg.ring, ring.flange_a)
    drive = m.add(Torque("drive", tau=1.5))
    m.connect(drive.flange, sun.flange_b)
    return m


def test_planetary_willis_relation_and_torque_ratios():
    ratio = 100 / 50
    res = _planetary_model(ratio).simulate(1.0, dt_out=0.05, **TIGHT, solver="ida")
    np.testing.assert_allclose((1 + ratio) * res["carrier.phi"], res["sun.phi"] + ratio * res["ring.phi"],
                               rtol=1e-9, atol=1e-11)
    sun_tau = res["planetary.sun.tau"]
    assert np.abs(sun_tau).min() > 0.1
    np.testing.assert_allclose(res["planetary.ring.tau"], ratio * sun_tau, rtol=1e-12)
    np.testing.assert_allclose(res["planetary.carrier.tau"], -(1 + ratio) * sun_tau, rtol=1e-12)
    np.testing.assert_allclose(res["planetary.tau"], sun_tau, rtol=1e-12)


def test_planetary_locked_ring_reduction():
    # ring held: sun in, carrier out, reduction 1 + ratio; rigid system with J_eff at the sun
    ratio = 3.0
    res = _planetary_model(ratio, ring_fixed=True).simulate(1.0, dt_out=0.05, **TIGHT, solver="ida")
    np.testing.assert_allclose(res["sun.w"], (1 + ratio) * res["carrier.w"], rtol=1e-9, atol=1e-12)
    J_eff = 0.1 + 2.0 / (1 + ratio) ** 2
    np.testing.assert_allclose(res["sun.w"], 1.5 / J_eff * res.t, rtol=1e-8, atol=1e-12)
    # the carrier gets (1 + ratio) times the torque through the sun (minus the sun's own inertia share)
    sun_tau = res["planetary.sun.tau"]
    np.testing.assert_allclose(sun_tau, 1.5 - 0.1 * 1.5 / J_eff, rtol=1e-8)


def test_planetary_ratio_must_be_positive():
    with pytest.raises(rm.ParameterError, match="ratio"):
        Planetary("p", ratio=-2.0)
