"""Analytic frequency sensitivities against central finite differences of rebuilt models."""

import numpy as np
import pytest

import regmech as rm
from regmech.analysis import modal, sensitivities
from regmech.components import Fixed, IdealGear, Inertia, Shaft, Spring, SpringDamper

BASE = {"J1": 0.4, "J2": 0.25, "J3": 1.3, "J4": 0.7, "c0": 900.0, "c1": 2500.0, "c2": 600.0, "d2": 3.0}


def drivetrain(p):
    """ground -c0- J1 -gear(2.5)- J2 -shaft c1- J3 -spring-damper c2, d2- J4 (free end)."""
    m = rm.Model("drivetrain")
    fixed = m.add(Fixed("fixed"))
    J = {k: m.add(Inertia(k, J=p[k])) for k in ("J1", "J2", "J3", "J4")}
    c0 = m.add(Spring("c0", c=p["c0"]))
    gear = m.add(IdealGear("gear", ratio=2.5))
    c1 = m.add(Shaft("c1", stiffness=p["c1"]))
    c2 = m.add(SpringDamper("c2", c=p["c2"], d=p["d2"]))
    m.connect(fixed.flange, c0.flange_a)
    m.connect(c0.flange_b, J["J1"].flange_a)
    m.connect(J["J1"].flange_b, gear.flange_a)
    m.connect(gear.flange_b, J["J2"].flange_a)
    m.connect(J["J2"].flange_b, c1.flange_a)
    m.connect(c1.flange_b, J["J3"].flange_a)
    m.connect(J["J3"].flange_b, c2.flange_a)
    m.connect(c2.flange_b, J["J4"].flange_a)
    return m


def frequencies(p):
    return modal(drivetrain(p).linearize()).frequencies_hz


LABEL = {"J1": "J1.J", "J2": "J2.J", "J3": "J3.J", "J4": "J4.J", "c0": "c0.c", "c1": "c1.stiffness", "c2": "c2.c"}


def test_sensitivities_match_central_differences():
    sens = sensitivities(modal(drivetrain(BASE).linearize()))
    assert set(sens.parameters) == set(LABEL.values())       # dampings do not change undamped frequencies
    assert sens.modes == [1, 2, 3]
    h = 1e-4
    for key, label in LABEL.items():
        up, down = dict(BASE), dict(BASE)
        up[key] *= 1 + h
        down[key] *= 1 - h
        fd = (frequencies(up) - frequencies(down)) / (2 * h * BASE[key])
        an = sens.d_freq_hz[:, sens.parameters.index(label)]
        np.testing.assert_allclose(an, fd, rtol=1e-6, atol=1e-9 * np.abs(fd).max(), err_msg=label)


def test_relative_sensitivities_sum_rule():
    # w^2 is homogeneous of degree 1 in the stiffnesses and -1 in the inertias:
    # sum of (p/f) df/dp over all stiffnesses = 1/2, over all inertias = -1/2
    sens = sensitivities(modal(drivetrain(BASE).linearize()))
    rel = sens.relative
    stiff = [sens.parameters.index(LABEL[k]) for k in ("c0", "c1", "c2")]
    inert = [sens.parameters.index(LABEL[k]) for k in ("J1", "J2", "J3", "J4")]
    np.testing.assert_allclose(rel[:, stiff].sum(axis=1), 0.5, rtol=1e-10)
    np.testing.assert_allclose(rel[:, inert].sum(axis=1), -0.5, rtol=1e-10)


def test_rigid_modes_are_left_out_and_tables_build():
    m = rm.Model("free")
    a, b = m.add(Inertia("a", J=1.0)), m.add(Inertia("b", J=2.0))
    s = m.add(Spring("s", c=8.0))
    m.connect(a.flange_b, s.flange_a)
    m.connect(s.flange_b, b.flange_a)
    sens = modal(m.linearize()).sensitivities()
    assert sens.modes == [2]
    # w^2 = c (1/Ja + 1/Jb): d(w^2)/dc = 1/Ja + 1/Jb
    np.testing.assert_allclose(sens.d_omega2[0, sens.parameters.index("s.c")], 1.5, rtol=1e-12)
    np.testing.assert_allclose(sens.d_omega2[0, sens.parameters.index("a.J")], -8.0 / 1.0 ** 2, rtol=1e-12)
    text = str(sens.table("hz"))
    assert "s.c" in text and "mode 2" in text
    with pytest.raises(KeyError):
        sens.table("bogus")
    pd = pytest.importorskip("pandas")
    df = sens.to_dataframe()
    assert isinstance(df, pd.DataFrame) and list(df.columns) == sens.parameters
