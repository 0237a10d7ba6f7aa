"""Start values on devices: ``phi_rel_start`` / ``w_rel_start`` fix a device's own
coordinate at the start, as MSL's ``phi_rel(start=..., fixed=true)``; contradictions name the device."""

import inspect
import math

import numpy as np
import pytest

import regmech as rm
from regmech.components import Clutch, Fixed, Inertia, Mass, Shaft, Spring, SpringDamper
from regmech.errors import StructureError


def two_masses(J2_start=None, **spring):
    m = rm.Model("pretwisted")
    J1 = m.add(Inertia("J1", J=1.0, phi0=0.0, w0=0.0))
    J2 = m.add(Inertia("J2", J=2.0, **(J2_start or {})))
    s = m.add(Spring("s", c=100.0, **spring))
    m.connect(J1.flange_b, s.flange_a)
    m.connect(s.flange_b, J2.flange_a)
    return m


@pytest.mark.parametrize("solver", ["ida", "scipy:DOP853", "expm"])
def test_pretwisted_free_pair_follows_the_closed_form(solver):
    """Two free inertias (1 and 2 kg m^2) on a spring c = 100 N m/rad started twisted by 0.1 rad and
    separating at 1 rad/s: phi_rel(t) = 0.1 cos(w t) + (1/w) sin(w t), w = sqrt(c / mu), mu = 2/3; the
    masses' own start values (J1 at rest at 0) are kept, J2 takes the rest."""
    m = two_masses(phi_rel_start=0.1, w_rel_start=1.0)
    opts = {"h": 1e-3} if solver == "expm" else {"rtol": 1e-9}
    r = m.simulate(0.5, 0.01, solver=solver, **opts)
    w = math.sqrt(100.0 / (2.0 / 3.0))
    exact = 0.1 * np.cos(w * r.t) + np.sin(w * r.t) / w
    assert np.max(np.abs(r["s.phi_rel"] - exact)) < 1e-6
    assert r["J1.phi"][0] == pytest.approx(0.0, abs=1e-12)
    assert r["J2.phi"][0] == pytest.approx(0.1, abs=1e-12)
    assert r["J2.w"][0] == pytest.approx(1.0, abs=1e-12)
    # momentum: J1 at rest, J2 at 1 rad/s -> 2 kg m^2 rad/s, kept
    assert np.allclose(1.0 * r["J1.w"] + 2.0 * r["J2.w"], 2.0, atol=1e-6)


def test_spring_to_the_ground_sets_the_mass_position():
    m = rm.Model("preloaded")
    f = m.add(Fixed("f", phi0=0.3))
    J = m.add(Inertia("J", J=1.0))
    s = m.add(SpringDamper("s", c=10.0, d=1.0, phi_rel_start=0.2))
    m.connect(f.flange, s.flange_a)
    m.connect(s.flange_b, J.flange_a)
    r = m.simulate(0.1, 0.05, solver="ida")
    assert r["J.phi"][0] == pytest.approx(0.5, abs=1e-12)       # ground 0.3 + twist 0.2
    assert r["s.tau"][0] == pytest.approx(10.0 * 0.2, rel=1e-9)   # the preload


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


def test_translational_spring_start_length():
    m = rm.Model("slide")
    a = m.add(Mass("a", m=1.0, s0=1.0, v0=0.0))
    b = m.add(Mass("b", m=1.0))
    s = m.add(Spring("s", c=50.0, phi_rel_start=-0.05, domain="translational"))
    m.connect(a.flange_b, s.flange_a)
    m.connect(s.flange_b, b.flange_a)
    r = m.simulate(0.1, 0.05, solver="ida")
    assert r["b.s"][0] == pytest.approx(0.95, abs=1e-12)
    assert r["s.f"][0] == pytest.approx(50.0 * -0.05, rel=1e-9)       # the preload
    assert s.param_unit("phi_rel_start") == "m"
    assert Spring.phi_rel_start.unit_in("translational") == "m"
    assert Spring.w_rel_start.unit_in("translational") == "m/s"


def test_start_relation_that_contradicts_mass_starts_names_the_device():
    m = two_masses(J2_start={"phi0": 0.5}, phi_rel_start=0.1)
    with pytest.raises(StructureError) as e:
        m.simulate(0.1)
    text = str(e.value)
    assert "inconsistent start positions" in text
    assert "Spring 's' (phi_rel_start=0.1)" in text and "J2" in text and "phi_rel_start of Spring 's'" in text


def test_speed_relation_that_contradicts_mass_speeds_names_the_device():
    m = two_masses(J2_start={"w0": 3.0}, w_rel_start=1.0)
    with pytest.raises(StructureError, match=r"inconsistent start velocities.*w_rel_start=1"):
        m.simulate(0.1)


def test_rigid_shaft_cannot_start_twisted():
    m = rm.Model("rigid")
    J1 = m.add(Inertia("J1", J=1.0))
    J2 = m.add(Inertia("J2", J=1.0))
    sh = m.add(Shaft("sh", stiffness=None, phi_rel_start=0.1))
    m.connect(J1.flange_b, sh.flange_a)
    m.connect(sh.flange_b, J2.flange_a)
    with pytest.raises(StructureError, match=r"Shaft 'sh' \(phi_rel_start=0.1\)"):
        m.simulate(0.1)


def test_clutch_start_slip_speed():
    """A disengaged clutch started slipping at -10 rad/s against J1 at 10 rad/s: J2 starts at rest."""
    m = rm.Model("slip")
    J1 = m.add(Inertia("J1", J=1.0, w0=10.0))
    J2 = m.add(Inertia("J2", J=1.0))
    c = m.add(Clutch("c", fn_max=100.0, f_normalized=0.0, w_rel_start=-10.0))
    m.connect(J1.flange_b, c.flange_a)
    m.connect(c.flange_b, J2.flange_a)
    r = m.simulate(0.1, 0.05, solver="ida")
    assert r["J2.w"][0] == pytest.approx(0.0, abs=1e-12)
    assert r["J1.w"][0] == pytest.approx(10.0, abs=1e-12)


def test_signatures_show_the_start_parameters():
    sig = inspect.signature(Spring)
    assert sig.parameters["phi_rel_start"].default is None
    assert sig.parameters["w_rel_start"].default is None
    assert "w_rel_start" in inspect.signature(Clutch).parameters
    assert "phi_rel_start" not in inspect.signature(Clutch).parameters


def test_a_non_finite_start_value_on_a_device_is_refused():
    with pytest.raises(rm.ParameterError, match="phi_rel_start"):
        Spring("s", c=1.0, phi_rel_start=float("nan"))
