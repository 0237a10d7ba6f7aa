"""Scenes and model reduction."""

import numpy as np
import pytest

import regmech as rm
from regmech.components import (Clutch, Damper, Fixed, IdealGear, Inertia, Shaft, SpringDamper, Torque)
from regmech.scene import REDUCTION_SHARE
from regmech.signals import Sine


def drivetrain(pto_engaged=0.0, k_out=1e4):
    """Engine -> flywheel -> torsion damper -> gearbox -> gear -> output -> shaft -> load,
    plus a pump on a power take-off behind a clutch (engaged when pto_engaged > 0)."""
    m = rm.Model("pto")
    f = m.add(Fixed("ground"))
    eng = m.add(Torque("engine", tau=Sine(amplitude=20, freq_hz=2, offset=30)))
    J0 = m.add(Inertia("flywheel", J=0.3, phi0=0.0, w0=0.0))
    s1 = m.add(SpringDamper("torsion_damper", c=2000.0, d=2.0))
    J1 = m.add(Inertia("gearbox", J=0.05))
    g = m.add(IdealGear("gear", ratio=4.0))
    J2 = m.add(Inertia("out", J=0.5))
    s2 = m.add(Shaft("shaft", stiffness=k_out, damping=1.0))
    J3 = m.add(Inertia("load", J=20.0))
    d = m.add(Damper("drag", d=5.0))
    pc = m.add(Clutch("pto_clutch", fn_max=100.0, f_normalized=pto_engaged))
    Jp = m.add(Inertia("pump", J=0.1))
    pd = m.add(Damper("pump_load", d=0.5))
    for a, b in [(eng.flange, J0.flange_a), (J0.flange_b, s1.flange_a), (s1.flange_b, J1.flange_a),
                 (J1.flange_b, g.flange_a), (g.flange_b, J2.flange_a), (J2.flange_b, s2.flange_a),
                 (s2.flange_b, J3.flange_a), (J3.flange_b, d.flange_a), (d.flange_b, f.flange),
                 (J0.flange_a, pc.flange_a), (pc.flange_b, Jp.flange_a), (Jp.flange_b, pd.flange_a),
                 (pd.flange_b, f.flange)]:
        m.connect(a, b)
    return m


def test_open_clutch_branch_is_removed_and_outputs_unchanged():
    sc = rm.Scene(drivetrain(), t_end=1.0, outputs=["load.w", "shaft.tau"], solver="ida", rtol=1e-9)
    red = sc.reduction
    assert "pump" not in red.model and "pto_clutch" not in red.model and "pump_load" not in red.model
    rep = sc.report(repeats=1)
    assert rep.size_reduced["states"] < rep.size_full["states"]
    assert rep.max_error < 1e-6                      # both at rtol 1e-9: identical up to the solver error
    assert "pto_clutch" in str(rep) and "transmits nothing" in str(rep)


def test_engaged_branch_is_kept():
    sc = rm.Scene(drivetrain(pto_engaged=1.0), t_end=1.0, outputs=["load.w"])
    assert "pump" in sc.reduction.model and "pto_clutch" in sc.reduction.model


def test_near_rigid_shaft_becomes_rigid_within_target():
    sc = rm.Scene(drivetrain(k_out=1e8), t_end=1.0, outputs=["load.w", "flywheel.w"], band_hz=20.0,
                  accuracy=1e-3)           # simulations under the contract at 1e-4 (SOLVER_SHARE)
    acts = [a for a in sc.reduction.actions if a.kind == "rigidify" and a.applied]
    assert [a.components for a in acts] == [["shaft"]]
    rep = sc.report(repeats=1)
    assert rep.max_error <= REDUCTION_SHARE * 1e-3
    assert rep.size_reduced["states"] == rep.size_full["states"] - 2 - 2   # stiff mode gone, pump branch gone
    assert rep.speedup is not None                                        # measured, not asserted


def test_stiff_link_inside_the_band_is_refused_with_reason():
    # the shaft's local mode (~300 Hz) is far above the other links but inside 10 x 50 Hz
    sc = rm.Scene(drivetrain(k_out=1.5e6), t_end=0.5, outputs=["load.w"], band_hz=50.0)
    refused = [a for a in sc.reduction.actions if a.kind == "rigidify" and not a.applied]
    assert refused and refused[0].components == ["shaft"] and "inside" in refused[0].reason
    assert isinstance(sc.reduction.model["shaft"], Shaft) and sc.reduction.model["shaft"].stiffness == 1.5e6


def test_leaf_behind_gear_is_reflected_and_its_signals_reconstructed():
    m = rm.Model("leaf")
    drive = m.add(Torque("drive", tau=2.0))
    J1 = m.add(Inertia("J1", J=1.0, phi0=0.0, w0=0.0))
    g = m.add(IdealGear("gear", ratio=3.0))
    J2 = m.add(Inertia("J2", J=9.0))
    m.connect(drive.flange, J1.flange_a)
    m.connect(J1.flange_b, g.flange_a)
    m.connect(g.flange_b, J2.flange_a)
    sc = rm.Scene(m, t_end=1.0, outputs=["J1.w"], solver="ida", rtol=1e-10)
    assert "J2" not in sc.reduction.model and sc.reduction.model["J1"].J == pytest.approx(2.0)
    res = sc.simulate()
    assert np.allclose(res["J1.w"], 1.0 * res.t, atol=1e-9)           # 2 N m on J_eq = 1 + 9/9
    assert np.allclose(res["J2.w"], res["J1.w"] / 3.0)


def test_unknown_output_and_bad_options():
    with pytest.raises(rm.ModelError, match="output 'nothing.w'"):
        rm.Scene(drivetrain(), t_end=1.0, outputs=["nothing.w"])
    with pytest.raises(rm.ParameterError, match="band_hz"):
        rm.Scene(drivetrain(), t_end=1.0, outputs=["load.w"], passes=["rigidify"])


@pytest.mark.parametrize("name", ["first", "coupled_clutches", "one_way_clutch", "vehicle_launch", "train",
                                  "gear_shift", "excavator_swing", "chain_drive"])
def test_every_library_scene_reduces_and_runs(name):
    from regmech.library import SCENES
    if name not in SCENES:
        pytest.fail(f"scene {name} missing from the library")
    model = SCENES[name]()
    res0 = model.simulate(0.02, dt_out=0.005)
    out = [n for n in res0.names if n.endswith((".w", ".v"))][:2]
    sc = rm.Scene(model, t_end=0.02, outputs=out, band_hz=5.0, dt_out=0.005)
    res = sc.simulate()
    for n in out:
        assert np.all(np.isfinite(res[n]))
    assert str(sc.report(compare=False))
