"""Start values on devices (issue 17 item 8): phi_rel_start / w_rel_start of springs, shafts and other
two-flange compliant devices, met exactly by the initialisation (least mass-weighted change of the free
start values), with contradictions refused naming the device."""

import math

import numpy as np
import pytest

import regmech as rm
from regmech.components import Fixed, Inertia, Mass, Shaft, Spring, SpringDamper


def test_pretwisted_spring_oscillates_from_its_start_twist():
    """Ground -- spring -- J: phi(t) = phi_rel_start cos(w t) + w_rel_start / w sin(w t)."""
    c, J = 400.0, 0.25
    m = rm.Model("pre")
    g = m.add(Fixed("g"))
    s = m.add(Spring("s", c=c, phi_rel_start=0.2, w_rel_start=3.0))
    body = m.add(Inertia("body", J=J))
    m.connect(g.flange, s.flange_a)
    m.connect(s.flange_b, body.flange_a)
    res = m.simulate(0.5, dt_out=1e-3, solver="ida", rtol=1e-10, atol=1e-12)
    om = math.sqrt(c / J)
    expect = 0.2 * np.cos(om * res.t) + 3.0 / om * np.sin(om * res.t)
    assert np.max(np.abs(res["body.phi"] - expect)) < 1e-7


def test_two_free_masses_share_the_start_twist_by_their_inertia():
    m = rm.Model("pair")
    J1 = m.add(Inertia("J1", J=1.0))
    J2 = m.add(Inertia("J2", J=3.0))
    s = m.add(Spring("s", c=100.0, phi_rel_start=0.2, w_rel_start=1.0))
    m.connect(J1.flange_b, s.flange_a)
    m.connect(s.flange_b, J2.flange_a)
    res = m.simulate(0.01, dt_out=0.005, solver="ida", rtol=1e-10)
    assert res["s.phi_rel"][0] == pytest.approx(0.2) and res["s.w_rel"][0] == pytest.approx(1.0)
    # the least mass-weighted change from rest: no net angle or momentum
    assert res["J1.phi"][0] + 3.0 * res["J2.phi"][0] == pytest.approx(0.0, abs=1e-12)
    assert res["J1.w"][0] == pytest.approx(-0.75) and res["J2.w"][0] == pytest.approx(0.25)


def test_translational_preload_with_a_fixed_mass():
    m = rm.Model("lin")
    M1 = m.add(Mass("M1", m=2.0, s0=1.0, v0=0.0))
    M2 = m.add(Mass("M2", m=1.0))
    sd = m.add(SpringDamper("sd", c=1e3, d=5.0, phi_rel_start=-0.01, domain="translational"))
    m.connect(M1.flange_b, sd.flange_a)
    m.connect(sd.flange_b, M2.flange_a)
    res = m.simulate(0.01, dt_out=0.005, solver="ida", rtol=1e-10)
    assert res["M1.s"][0] == 1.0 and res["M2.s"][0] == pytest.approx(0.99)
    assert res["sd.f"][0] == pytest.approx(-10.0)
    assert sd.param_unit("phi_rel_start") == "m"


def test_contradicting_start_values_name_the_device():
    m = rm.Model("bad")
    g = m.add(Fixed("g"))
    J = m.add(Inertia("J", J=1.0, phi0=0.5))
    sh = m.add(Shaft("sh", phi_rel_start=0.1))           # rigid: phi_rel is 0
    m.connect(g.flange, sh.flange_a)
    m.connect(sh.flange_b, J.flange_a)
    with pytest.raises(rm.StructureError, match=r"Shaft 'sh' \(phi_rel_start=0.1\)"):
        m.simulate(0.1)
    m2 = rm.Model("bad2")
    g2 = m2.add(Fixed("g"))
    J2 = m2.add(Inertia("J", J=1.0, w0=2.0))
    sp = m2.add(Spring("sp", c=1.0, w_rel_start=1.0))
    m2.connect(g2.flange, sp.flange_a)
    m2.connect(sp.flange_b, J2.flange_a)
    with pytest.raises(rm.StructureError, match=r"w_rel_start=1"):
        m2.simulate(0.1)
    with pytest.raises(rm.ParameterError, match="phi_rel_start"):
        Spring("s", c=1.0, phi_rel_start=float("nan"))
