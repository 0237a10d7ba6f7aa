"""LossyDifferential: the final drive's mesh efficiency by power-flow direction."""

import numpy as np
import pytest

import regmech as rm
from regmech.components import Damper, Fixed, Inertia, LossyDifferential, Torque
from regmech.signals import Step


def _axle(traction=True, motor=50.0):
    m = rm.Model("final_drive")
    f = m.add(Fixed("f"))
    pin = m.add(Inertia("pinion", J=0.01))
    d = m.add(LossyDifferential("fd", ratio=4.0, eta_drive=0.95, eta_coast=0.9))
    L = m.add(Inertia("wl", J=1.0))
    R = m.add(Inertia("wr", J=1.0))
    m.connect(pin.flange_b, d.carrier)
    m.connect(d.left, L.flange_a)
    m.connect(d.right, R.flange_a)
    if traction:
        mot = m.add(Torque("motor", tau=motor))
        m.connect(mot.flange, pin.flange_a)
        for w, nm in ((L, "dl"), (R, "dr")):
            dd = m.add(Damper(nm, d=2.0))
            m.connect(w.flange_b, dd.flange_a)
            m.connect(dd.flange_b, f.flange)
    else:
        for w, nm in ((L, "tl"), (R, "tr")):
            t = m.add(Torque(nm, tau=20.0))
            m.connect(t.flange, w.flange_b)
        dd = m.add(Damper("brake", d=0.5))
        m.connect(pin.flange_a, dd.flange_a)
        m.connect(dd.flange_b, f.flange)
    return m


@pytest.mark.parametrize("traction", [True, False])
def test_steady_power_ratio_is_the_efficiency_of_the_driving_side(traction):
    """Steady state (10 s, time constants below 1 s): traction, the wheels' dampers take eta_drive of the
    motor's power; overrun, the pinion's damper takes eta_coast of the wheel torques' power."""
    r = _axle(traction).simulate(10.0, 0.1, solver="ida", rtol=1e-9)
    wp, ww = r["pinion.w"][-1], r["wl.w"][-1]
    assert wp == pytest.approx(4.0 * ww, rel=1e-9)                 # the kinematics stay ideal
    if traction:
        p_in, p_out, eta = 50.0 * wp, 2 * 2.0 * ww ** 2, 0.95
    else:
        p_in, p_out, eta = 2 * 20.0 * ww, 0.5 * wp ** 2, 0.9
    assert p_out / p_in == pytest.approx(eta, rel=1e-6)
    assert r["fd.mesh.power"][-1] == pytest.approx((1 - eta) * p_in, rel=1e-6)
    assert np.all(r["fd.mesh.power"] >= -1e-9 * p_in)            # a loss never supplies power
    assert r["wl.w"][-1] == pytest.approx(r["wr.w"][-1], rel=1e-12)     # equal split


def test_a_torque_reversal_changes_the_driving_side_at_an_event():
    """The motor's torque steps from +50 to -20 N m at 1 s while the axle turns forward: the wheels drive
    the pinion from then on (engine braking); the change is an event of kind "driving side"."""
    r = _axle(True, motor=Step(height=-70.0, start_time=1.0, offset=50.0)).simulate(2.0, 0.01, solver="ida",
                                                                                     rtol=1e-9)
    sides = [e for e in r.events if e.component.startswith("fd.mesh") and e.kind == "driving side"]
    assert sides and sides[0].t == pytest.approx(1.0, abs=1e-6)
    assert np.all(r["fd.mesh.power"] >= -1e-6)


def test_efficiencies_above_one_are_refused():
    with pytest.raises(rm.ParameterError, match=r"eta_coast is an efficiency"):
        LossyDifferential("fd", ratio=3.5, eta_coast=1.2)
