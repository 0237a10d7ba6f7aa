"""Stick/slip logic at the edges of round-off, on MSL examples and their branches.

* MSL ``Rotational.Examples.Friction`` (``regmech.library.friction``): the clutch (peak 1) breaks away at
  t = 0.0593 s with its load a few 1e-8 N m short of its capacity where the root finder stops; sliding then
  starts with a relative acceleration against its direction, of the size of that shortfall. Judged by the
  motion a moment later, the break-away stands (it refused the run at rtol 1e-8 and 3e-8).
* The brake branch of MSL ``Translational.Examples.HeatLosses``: a brake engaging under a Sine normal force
  (capacity 1e-17 N at t = 2e-20 s) on a mass whose spring force is round-off of its positions holds it.
* MSL ``Rotational.Examples.HeatLosses``'s lossy gear, a node inertia after it, a clutch, a one-way clutch and
  a brake: the gear breaks away at rest while the chain of three stuck devices behind it holds the motion;
  the chain's load ends the sharing (it chattered on the gear's round-off slip).

The reference for each is an independent run at a tighter tolerance (the same equations under another
method or tolerance), and the rest that the physics demands where nothing drives.
"""

import numpy as np
import pytest

import regmech as rm
from regmech.components import (Brake, Clutch, Fixed, Inertia, LinearBrake, LossyGear, Mass, OneWayClutch, Spring,
                                 Torque)
from regmech.library import friction
from regmech.signals import Sine


def largest_difference(res, ref, names):
    """Largest difference of ``res`` from ``ref`` on ``ref``'s rows, relative to each signal's range."""
    return max(np.max(np.abs(np.interp(ref.t, res.t, res[s]) - ref[s])) / np.ptp(ref[s]) for s in names)


@pytest.fixture(scope="module")
def friction_reference():
    return friction().simulate(3.0, 1e-3, solver="ida", rtol=1e-10)


@pytest.mark.parametrize("opts", [{"solver": "ida", "rtol": 1e-8}, {"solver": "ida", "rtol": 3e-8},
                                  {"solver": "ida", "rtol": 1e-6}, {}], ids=["ida-1e-8", "ida-3e-8", "ida-1e-6", "default"])
def test_msl_friction_breaks_away_at_a_tie_and_agrees_with_a_tight_run(opts, friction_reference):
    res = friction().simulate(3.0, 1e-3, **opts)
    names = ["inertia1.w", "inertia2.w", "inertia3.w"]
    assert largest_difference(res, friction_reference, names) < 2e-4
    clutch = [e.t for e in res.events if e.component == "clutch"]
    ref_clutch = [e.t for e in friction_reference.events if e.component == "clutch"]
    assert len(clutch) == len(ref_clutch)
    assert np.allclose(clutch, ref_clutch, atol=5e-5)
    # the brake holds inertia1 from its stop on
    stop = ref_clutch[-1]
    assert np.max(np.abs(res["inertia1.w"][res.t > stop])) < 1e-9


def brake_branch():
    """Two masses on a 100 N/m spring of length 0.1 m started at it (0.7 and 0.8 m: a spring force of round-off),
    the second braked to the ground under ``fn = 100 sin(4 pi t)`` N."""
    m = rm.Model("brake_branch")
    fixed = m.add(Fixed("fixed", domain="translational"))
    a = m.add(Mass("mass2", m=1.0, s0=0.7, v0=0.0))
    spring = m.add(Spring("spring", c=100.0, phi_rel0=0.1, phi_rel_start=0.1, domain="translational"))
    b = m.add(Mass("mass3", m=1.0, v0=0.0))
    brake = m.add(LinearBrake("brake", fn_max=100.0, f_normalized=Sine(amplitude=1.0, freq_hz=2.0)))
    m.connect(a.flange_b, spring.flange_a)
    m.connect(spring.flange_b, b.flange_a)
    m.connect(b.flange_b, brake.flange)
    m.connect(brake.support, fixed.flange)
    return m


@pytest.mark.parametrize("opts", [{"solver": "ida", "rtol": 1e-8}, {"solver": "ida", "rtol": 1e-6}, {}],
                         ids=["ida-1e-8", "ida-1e-6", "default"])
def test_a_brake_engaging_from_zero_force_holds_a_load_of_round_off(opts):
    res = brake_branch().simulate(2.0, 1e-3, **opts)
    assert np.max(np.abs(res["mass3.v"])) < 1e-12 and np.max(np.abs(res["mass2.v"])) < 1e-12
    assert np.allclose(res["mass3.s"], 0.8, atol=1e-12)


def gear_chain():
    """MSL Rotational.Examples.HeatLosses's second branch driven directly: ``20 sin(10 pi t)`` N m -> inertia4
    (J 2, at rest) -> lossy gear (ratio 2, table [0 .8 .8 1 1; 1 .7 .7 2 2]) -> node (J 0.01) -> clutch
    (fn_max 10) -> inertia5 (J 2) -> one-way clutch (fn_max 1) -> inertia6 (J 2) -> brake (fn_max 2); the
    three normal forces ``sin(0.4 pi t)``."""
    m = rm.Model("gear_chain")
    fixed = m.add(Fixed("fixed"))
    force = Sine(amplitude=1.0, freq_hz=0.2)
    torque = m.add(Torque("torque", tau=Sine(amplitude=20.0, freq_hz=5.0)))
    i4 = m.add(Inertia("inertia4", J=2.0, phi0=0.0, w0=0.0))
    gear = m.add(LossyGear("lossyGear", ratio=2.0, loss_table=[[0, 0.8, 0.8, 1, 1], [1, 0.7, 0.7, 2, 2]]))
    node = m.add(Inertia("node", J=0.01))
    clutch = m.add(Clutch("clutch", fn_max=10.0, f_normalized=force, w_rel_start=0.0))
    i5 = m.add(Inertia("inertia5", J=2.0))
    owc = m.add(OneWayClutch("oneWayClutch", fn_max=1.0, f_normalized=force))
    i6 = m.add(Inertia("inertia6", J=2.0))
    brake = m.add(Brake("brake", fn_max=2.0, f_normalized=force))
    m.connect(torque.flange, i4.flange_a)
    m.connect(i4.flange_b, gear.flange_a)
    m.connect(gear.flange_b, node.flange_a)
    m.connect(node.flange_b, clutch.flange_a)
    m.connect(clutch.flange_b, i5.flange_a)
    m.connect(i5.flange_b, owc.flange_a)
    m.connect(owc.flange_b, i6.flange_a)
    m.connect(i6.flange_b, brake.flange)
    m.connect(brake.support, fixed.flange)
    return m


@pytest.mark.parametrize("opts", [{"solver": "ida", "rtol": 1e-6}, {"solver": "ida", "rtol": 1e-8}],
                         ids=["ida-1e-6", "ida-1e-8"])
def test_a_lossy_gear_rolling_at_rest_behind_a_stuck_chain_does_not_chatter(opts):
    t_end = 0.3
    res = gear_chain().simulate(t_end, 1e-3, **opts)
    ref = gear_chain().simulate(t_end, 1e-3, solver="dop853", rtol=1e-10)
    assert largest_difference(res, ref, ["inertia4.w", "node.w", "inertia5.w", "inertia6.w"]) < 2e-3
