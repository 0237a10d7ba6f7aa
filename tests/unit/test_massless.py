"""Massless nodes accepted where determinate (``structure.regularity``, ``compile.massless``): each model runs in
its own structure and matches the same model with a tiny inertia inserted at the node."""

import numpy as np
import pytest

import regmech as rm
from regmech.components import Clutch, Damper, Fixed, IdealGear, Inertia, LossyGear, Mass, Spring, Torque
from regmech.components.wheel import Rolling
from regmech.errors import ModelError
from regmech.signals import Sine, Step

TINY = 1e-7


def _node(m, tiny, a, b, domain="rotational"):
    """Join flanges a and b directly, or through a tiny inertia (mass) when ``tiny``."""
    if tiny:
        body = m.add(Inertia("node", J=tiny) if domain == "rotational" else Mass("node", m=tiny))
        m.connect(a, body.flange_a)
        m.connect(body.flange_b, b)
    else:
        m.connect(a, b)


def maxwell(tiny=None):
    """A spring and a damper in series from an inertia to the ground (a Maxwell element)."""
    m = rm.Model("maxwell")
    J = m.add(Inertia("J", J=1.0, w0=10.0))
    k, d, g = m.add(Spring("k", c=100.0)), m.add(Damper("d", d=2.0)), m.add(Fixed("g"))
    m.connect(J.flange_b, k.flange_a)
    _node(m, tiny, k.flange_b, d.flange_a)
    m.connect(d.flange_b, g.flange)
    return m


def vehicle(tiny=None):
    """A torque on a wheel hub without inertia, rolling a car against a linear drag (as MSL's Vehicle)."""
    m = rm.Model("vehicle")
    car = m.add(Mass("car", m=1000.0))
    drag = m.add(Damper("drag", d=20.0, domain="translational"))
    road, ground = m.add(Fixed("road", domain="translational")), m.add(Fixed("ground", domain="translational"))
    wheel = m.add(Rolling("wheel", radius=0.3))
    tq = m.add(Torque("tq", tau=100.0))
    m.connect(wheel.axle, car.flange_a)
    m.connect(wheel.tread, road.flange)
    m.connect(drag.flange_a, car.flange_b)
    m.connect(drag.flange_b, ground.flange)
    _node(m, tiny, tq.flange, wheel.hub)
    return m


def spring_gear(tiny=None):
    m = rm.Model("spring_gear")
    J1, J2 = m.add(Inertia("J1", J=1.0, w0=1.0)), m.add(Inertia("J2", J=2.0))
    k, gear = m.add(Spring("k", c=10.0)), m.add(IdealGear("gear", ratio=2.0))
    m.connect(J1.flange_b, k.flange_a)
    _node(m, tiny, k.flange_b, gear.flange_a)
    m.connect(gear.flange_b, J2.flange_a)
    return m


def dampers(tiny=None):
    m = rm.Model("dampers")
    J1, J2 = m.add(Inertia("J1", J=1.0, w0=1.0)), m.add(Inertia("J2", J=2.0))
    d1, d2 = m.add(Damper("d1", d=1.0)), m.add(Damper("d2", d=3.0))
    m.connect(J1.flange_b, d1.flange_a)
    _node(m, tiny, d1.flange_b, d2.flange_a)
    m.connect(d2.flange_b, J2.flange_a)
    return m


def heat_losses(tiny=None):
    """A lossy gear joined to a clutch with no inertia between (as MSL's Rotational HeatLosses)."""
    m = rm.Model("heat_losses")
    J1, J2 = m.add(Inertia("J1", J=1.0)), m.add(Inertia("J2", J=2.0))
    src = m.add(Torque("src", tau=Sine(amplitude=10.0, freq_hz=1.0)))
    gear = m.add(LossyGear("gear", ratio=2.0, loss_table=[[0.0, 0.8, 0.8, 0.2, 0.2]]))
    cl = m.add(Clutch("cl", f_normalized=Step(1.0, 0.5), mu=0.3, fn_max=50.0, cgeo=1.0))
    d, g = m.add(Damper("d", d=1.0)), m.add(Fixed("g"))
    m.connect(src.flange, J1.flange_a)
    m.connect(J1.flange_b, gear.flange_a)
    _node(m, tiny, gear.flange_b, cl.flange_a)
    m.connect(cl.flange_b, J2.flange_a)
    m.connect(J2.flange_b, d.flange_a)
    m.connect(d.flange_b, g.flange)
    return m


@pytest.mark.parametrize("build, signal, note", [
    (heat_losses, "J2.w", "follows from the constraint of LossyGear 'gear'"),
    (maxwell, "J.w", "first-order node"),
    (vehicle, "car.v", "follows from the constraint of Rolling 'wheel'"),
    (spring_gear, "J2.w", "follows from the constraint of IdealGear 'gear'"),
    (dampers, "J2.w", "first-order node"),
])
def test_massless_node_matches_a_tiny_inertia(build, signal, note):
    m = build()
    report = m.check()
    assert any(note in n for n in report.regularity.notes)
    res = m.simulate(2.0, dt_out=0.01, accuracy=1e-6)
    ref = build(TINY).simulate(2.0, dt_out=0.01, accuracy=1e-6)
    assert np.max(np.abs(res[signal] - ref[signal])) <= 1e-4 * np.ptp(ref[signal])
    # the same events (stick/slip, driving side) at the same instants
    assert [(e.component, e.kind, e.new_mode) for e in res.events] == \
        [(e.component, e.kind, e.new_mode) for e in ref.events]
    assert np.allclose([e.t for e in res.events], [e.t for e in ref.events], atol=1e-5)


def test_maxwell_element_relaxes_with_its_time_constant():
    # the node: d v_p = -c (x_p - x_J) ... with J = 1 the motion is the third-order system of J, c, d; at the
    # end all the energy is in the damper's heat
    res = maxwell().simulate(5.0, dt_out=0.01, accuracy=1e-6)
    assert abs(res["J.w"][-1]) < 1e-3 * 10.0
    assert res["k.phi_rel"][-1] == pytest.approx(0.0, abs=1e-3)


def test_maxwell_linearises_to_the_analytic_poles():
    # states phi_J, w_J, x_p: J w' = c (x_p - phi), d x_p' = -c (x_p - phi)
    lin = maxwell().linearize(form="state_space")
    c, d = 100.0, 2.0
    A = np.array([[0, 1, 0], [-c, 0, c], [c / d, 0, -c / d]])
    got = np.sort_complex(lin.poles())
    expect = np.sort_complex(np.linalg.eigvals(A))
    assert np.allclose(got, expect, atol=1e-9)


def test_explicit_solver_refuses_a_massless_point_by_name():
    with pytest.raises(ModelError, match="massless points.*solver='ida'"):
        maxwell().simulate(0.1, solver="dop853")
