"""Planetary efficiency with the carrier-stopped train, limited-slip differential."""

import numpy as np
import pytest

import regmech as rm
from regmech.components import (Fixed, Inertia, LimitedSlipDifferential, LossyPlanetary, Planetary, Torque)


def planetary_ring_held(cls, eta=0.9, T=10.0, r=2.0, **kw):
    m = rm.Model("ring_held")
    f = m.add(Fixed("housing"))
    drive = m.add(Torque("drive", tau=T))
    sun = m.add(Inertia("sun", J=1e-3, phi0=0.0, w0=0.0))
    ring = m.add(Inertia("ring", J=1e-3))
    carrier = m.add(Inertia("carrier", J=2.0))
    ps = m.add(cls("ps", ratio=r, **kw))
    m.connect(drive.flange, sun.flange_a)
    m.connect(sun.flange_b, ps.sun)
    m.connect(ps.ring, ring.flange_a)
    m.connect(ring.flange_b, f.flange)
    m.connect(ps.carrier, carrier.flange_a)
    return m


def test_lossy_planetary_output_torque_is_one_plus_eta_ratio_times_input():
    eta, T, r = 0.9, 10.0, 2.0
    res = planetary_ring_held(LossyPlanetary, eta, T, r, loss_table=[[0.0, eta, eta, 0.0, 0.0]]).simulate(
        1.0, dt_out=1e-2, rtol=1e-9, solver="ida")
    a_c = np.gradient(res["carrier.w"], res.t)[5:-5]
    J_eff = 2.0 + 1e-3 * (1 + r) ** 2 * (1 + eta * r) / (1 + r)   # sun inertia reflected (driving side)
    assert np.allclose(a_c, (1 + eta * r) * T / J_eff, rtol=2e-4)
    assert np.allclose(res["sun.w"], (1 + r) * res["carrier.w"], atol=1e-9)      # Willis, ring held
    assert np.all(res["ps.mode"][1:] == 1)                                        # the sun drives the train
    assert res["ps.power"].min() > -1e-9 and res["ps.power"][-1] > 0              # it only dissipates


def test_ideal_table_equals_ideal_planetary():
    a = planetary_ring_held(LossyPlanetary, loss_table=[[0.0, 1.0, 1.0, 0.0, 0.0]]).simulate(0.5, dt_out=0.05, rtol=1e-10,
                                                                                          solver="ida")
    b = planetary_ring_held(Planetary).simulate(0.5, dt_out=0.05, rtol=1e-10, solver="ida")
    assert np.allclose(a["carrier.w"], b["carrier.w"], rtol=1e-9, atol=1e-12)


def lsd_on_ice(preload):
    m = rm.Model("lsd")
    f = m.add(Fixed("ground"))
    drive = m.add(Torque("drive", tau=200.0))
    crown = m.add(Inertia("crown", J=0.05, phi0=0.0, w0=0.0))
    lsd = m.add(LimitedSlipDifferential("lsd", ratio=1.0, preload=preload, mu=0.1, cgeo=0.05))
    wl = m.add(Inertia("wheel_ice", J=1.0))
    wr = m.add(Inertia("wheel_grip", J=1.0))
    load = m.add(rm.components.Damper("road_grip", d=50.0))
    m.connect(drive.flange, crown.flange_a)
    m.connect(crown.flange_b, lsd.carrier)
    m.connect(lsd.left, wl.flange_a)
    m.connect(lsd.right, wr.flange_a)
    m.connect(wr.flange_b, load.flange_a)
    m.connect(load.flange_b, f.flange)
    return m


@pytest.mark.parametrize("preload", [0.0, 2e3, 1e6])
def test_limited_slip_differential_transfers_torque_to_the_gripping_wheel(preload):
    res = lsd_on_ice(preload).simulate(1.0, dt_out=1e-2, rtol=1e-8, solver="ida")
    slip = res["wheel_ice.w"][-1] - res["wheel_grip.w"][-1]
    if preload == 0.0:
        assert slip > 10.0                           # open: the wheel on ice spins away
    elif preload == 1e6:
        assert abs(slip) < 1e-8                      # locked by the preload
        assert np.all(res["lsd.lock.mode"][1:] == 0)
    else:
        # sliding plates carry mu cgeo fn = 10 N m from the fast side to the slow side
        sliding = res["lsd.lock.mode"] != 0
        assert sliding[-1] and np.allclose(np.abs(res["lsd.lock.tau"][sliding]), 10.0)
        open_slip = lsd_on_ice(0.0).simulate(1.0, dt_out=1e-2, rtol=1e-8, solver="ida")
        assert 0 < slip < open_slip["wheel_ice.w"][-1] - open_slip["wheel_grip.w"][-1]
