"""Every error path of model assembly: type, message names the component, and the fix."""

import math
import warnings

import numpy as np
import pytest

import regmech as rm
from regmech.components import (Clutch, Damper, Fixed, IdealGear, Inertia, Mass, Position, Shaft, Spring,
                                 Torque)


@pytest.mark.parametrize("kwargs, param", [
    (dict(J=-1.0), "J"), (dict(J=0.0), "J"), (dict(J=math.nan), "J"), (dict(J="heavy"), "J"),
    (dict(J=1.0, w0=math.inf), "w0"), (dict(J=True), "J"),
])
def test_inertia_parameter_errors_name_component_and_parameter(kwargs, param):
    with pytest.raises(rm.ParameterError) as err:
        Inertia("flywheel", **kwargs)
    assert "flywheel" in str(err.value) and f"'{param}'" in str(err.value)


def test_zero_mass_missing_and_unknown_parameters():
    with pytest.raises(rm.ParameterError, match="'car'.*'m'"):
        Mass("car", m=0.0)
    with pytest.raises(rm.ParameterError, match="'k'.*'c' is required"):
        Spring("k")
    with pytest.raises(rm.ParameterError, match="unknown parameter.*stiffnes"):
        Spring("k", c=1.0, stiffnes=2.0)
    with pytest.raises(rm.ParameterError, match="'g'.*ratio"):
        IdealGear("g", ratio=0.0)
    with pytest.raises(rm.ParameterError, match="'c1'.*peak"):
        Clutch("c1", fn_max=1.0, peak=0.5)


def test_signal_parameter_accepts_number_signal_callable_and_rejects_junk():
    assert Torque("a", tau=2.0).tau.value(0.3) == 2.0
    assert Torque("b", tau=lambda t: 3 * t).tau.value(2.0) == 6.0
    with pytest.raises(rm.ParameterError, match="'c'.*'tau'"):
        Torque("c", tau="ten")


def _two_inertias():
    m = rm.Model("m")
    J1, J2 = m.add(Inertia("J1", J=1.0)), m.add(Inertia("J2", J=1.0))
    return m, J1, J2


def test_model_assembly_errors():
    m, J1, J2 = _two_inertias()
    with pytest.raises(rm.ModelError, match="already has a component named 'J1'"):
        m.add(Inertia("J1", J=2.0))
    with pytest.raises(rm.ModelError, match="'J2' was added.*twice"):
        m.add(J2)
    with pytest.raises(rm.UnknownFlangeError, match="'J1' has no flange 'flange_c'"):
        m.connect(J1.flange_c, J2.flange_a)
    with pytest.raises(rm.UnknownFlangeError, match="'J1' has no flange 'flange_x'"):
        m.connect("J1.flange_x", "J2.flange_a")
    car = m.add(Mass("car", m=1.0))
    with pytest.raises(rm.ModelError, match="cannot connect a rotational flange to a translational"):
        m.connect(J1.flange_b, car.flange_a)
    stranger = Inertia("stranger", J=1.0)
    with pytest.raises(rm.ModelError, match="add Inertia 'stranger' first"):
        m.connect(J1.flange_b, stranger.flange_a)


def test_dangling_flange_is_under_determined():
    m, J1, J2 = _two_inertias()
    k = m.add(Spring("k", c=10.0))
    m.connect(J1.flange_b, k.flange_a)
    with pytest.raises(rm.ModelError, match="flange k.flange_b .* not connected.*under-determined"):
        m.check()


def test_device_to_device_names_both_and_suggests_inertia():
    # two springs meeting without a mass: the point's force balance does not depend on its speed
    m, J1, J2 = _two_inertias()
    k, k2 = m.add(Spring("k", c=10.0)), m.add(Spring("k2", c=20.0))
    m.connect(J1.flange_b, k.flange_a)
    m.connect(k.flange_b, k2.flange_a)
    m.connect(k2.flange_b, J2.flange_a)
    with pytest.raises(rm.RegularityError) as err:
        m.check()
    msg = str(err.value)
    assert "'k'" in msg and "'k2'" in msg and "insert an Inertia" in msg


def test_spring_on_a_gear_without_inertia_is_reduced():
    # the massless point between them is the gear's dependent coordinate (Modelica runs this model)
    m, J1, J2 = _two_inertias()
    k, g = m.add(Spring("k", c=10.0)), m.add(IdealGear("gear", ratio=2.0))
    m.connect(J1.flange_b, k.flange_a)
    m.connect(k.flange_b, g.flange_a)
    m.connect(g.flange_b, J2.flange_a)
    report = m.check()
    assert any("follows from the constraint of IdealGear 'gear'" in n for n in report.regularity.notes)
    assert "reduced: massless point" in str(report)


def test_massless_spring_under_load():
    m = rm.Model("m")
    f, J1 = m.add(Fixed("f")), m.add(Inertia("J1", J=1.0))
    k, load = m.add(Spring("k", c=10.0)), m.add(Torque("load", tau=1.0))
    m.connect(J1.flange_b, k.flange_a)
    m.connect(k.flange_b, load.flange)
    with pytest.raises(rm.RegularityError, match="'k' carries the load of Torque 'load' at a massless point"):
        m.check()


def test_dampers_meeting_at_massless_point_make_a_first_order_node():
    m, J1, J2 = _two_inertias()
    d1, d2 = m.add(Damper("d1", d=1.0)), m.add(Damper("d2", d=1.0))
    m.connect(J1.flange_b, d1.flange_a)
    m.connect(d1.flange_b, d2.flange_a)
    m.connect(d2.flange_b, J2.flange_a)
    report = m.check()
    assert any("first-order node between Damper 'd1', Damper 'd2'" in n for n in report.regularity.notes)


def test_clutch_on_massless_end_of_elastic_shaft():
    m, J1, J2 = _two_inertias()
    s = m.add(Shaft("shaft", stiffness=1e3))
    c = m.add(Clutch("clutch", fn_max=10.0))
    m.connect(J1.flange_b, s.flange_a)
    m.connect(s.flange_b, c.flange_a)
    m.connect(c.flange_b, J2.flange_a)
    with pytest.raises(rm.RegularityError, match="'clutch' has no mass on one side.*Position 3.*'shaft'"):
        m.check()


def test_redundant_rigid_constraints_name_devices():
    m, J1, J2 = _two_inertias()
    s1, s2 = m.add(Shaft("s1")), m.add(Shaft("s2"))
    for s in (s1, s2):
        m.connect(J1.flange_b, s.flange_a)
        m.connect(s.flange_b, J2.flange_a)
    with pytest.raises(rm.StructureError) as err:
        m.compile()
    assert "'s1'" in str(err.value) and "'s2'" in str(err.value) and "remove one" in str(err.value)


def test_motion_source_on_ground_is_refused():
    m = rm.Model("m")
    f, p = m.add(Fixed("f")), m.add(Position("p", phi_ref=1.0))
    J = m.add(Inertia("J", J=1.0))
    m.connect(p.flange, f.flange)
    m.connect(J.flange_a, f.flange)
    with pytest.raises(rm.ModelError, match="'p' drives a point that is fixed to the ground"):
        m.check()


def test_inconsistent_fixed_start_values():
    m = rm.Model("m")
    J1, J2 = m.add(Inertia("J1", J=1.0, w0=1.0)), m.add(Inertia("J2", J=1.0, w0=2.0))
    s = m.add(Shaft("s"))
    m.connect(J1.flange_b, s.flange_a)
    m.connect(s.flange_b, J2.flange_a)
    with pytest.raises(rm.StructureError, match="inconsistent start velocities.*J1.*J2"):
        m.simulate(0.1)


def test_stretched_spectrum_warns():
    m = rm.Model("stiff")
    f = m.add(Fixed("f"))
    J = [m.add(Inertia(f"J{i}", J=1.0)) for i in range(3)]
    k1, k2, k3 = m.add(Spring("k1", c=1.0)), m.add(Spring("k2", c=1e9)), m.add(Spring("k3", c=1.0))
    m.connect(f.flange, k1.flange_a)
    m.connect(k1.flange_b, J[0].flange_a)
    m.connect(J[0].flange_b, k2.flange_a)
    m.connect(k2.flange_b, J[1].flange_a)
    m.connect(J[1].flange_b, k3.flange_a)
    m.connect(k3.flange_b, J[2].flange_a)
    with pytest.warns(rm.RegularityWarning, match="stretched spectrum"):
        m.check()


def test_regular_model_check_report_and_no_warning():
    from regmech.library import first
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        report = first().check()
    assert report.masses == 3 and "3 mass node(s)" in str(report)


def test_empty_model_and_bad_times():
    with pytest.raises(rm.ModelError, match="empty"):
        rm.Model("nothing").check()
    from regmech.library import first
    with pytest.raises(rm.ParameterError, match="t_end"):
        first().simulate(t_end=-1.0)
    with pytest.raises(rm.ParameterError, match="unknown solver"):
        first().simulate(t_end=0.1, solver="magic")
