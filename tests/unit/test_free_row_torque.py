"""A friction row in mode Free (or Held) reads a torque of exactly zero: its law is ``lam = 0``, whatever
round-off the solve that carried the multiplier left in it (a released shift clutch of ``six_speed_car`` read
1.8e-18 N m on a fresh machine whose LU pivoted otherwise, and its test of the torque interruption failed)."""

import numpy as np

import regmech as rm
from regmech.components import Clutch, Inertia, Torque
from regmech.modes import FREE
from regmech.signals import Constant, Ramp


def released_clutch():
    m = rm.Model("released")
    drive = m.add(Torque("drive", tau=Constant(1.0)))
    a = m.add(Inertia("a", J=1.0, w0=0.0))
    cl = m.add(Clutch("cl", mu=0.3, peak=1.1, fn_max=100.0,
                      f_normalized=Ramp(height=-1.0, duration=0.2, offset=1.0, start_time=0.3)))
    b = m.add(Inertia("b", J=2.0))
    m.connect(drive.flange, a.flange_a)
    m.connect(a.flange_b, cl.flange_a)
    m.connect(cl.flange_b, b.flange_a)
    return m


def test_a_free_rows_torque_is_exactly_zero_whatever_its_multiplier_holds():
    res = released_clutch().simulate(1.0, 1e-2, solver="ida", rtol=1e-8)
    mode = res["cl.mode"]
    free = mode == FREE
    assert free.any() and (~free).any()
    assert np.any(res["cl.tau"][~free] != 0.0)
    traj = res._traj
    c = traj.c
    j = 0                                  # the model's one friction row
    col = c.ilam[c.mp + c.mv + j]
    traj.Y[free, col] = 1e-18              # the round-off another machine's solve may leave there
    res._cache.clear()
    assert np.all(res["cl.tau"][free] == 0.0) and np.all(res["cl.power"][free] == 0.0)


def test_a_stuck_rows_slip_power_and_heat_are_exactly_zero_whatever_the_speeds_hold():
    """The mirror rule: a Stuck row's law is ``w_rel = 0``; its relative speed, power and heat flow read exactly
    zero, whatever residue of that constraint the solvers left in the speeds (else ``heat_flow = lam w_rel`` is
    noise of either sign there: a loss element supplying power)."""
    from regmech.modes import STUCK
    res = rm.library.coupled_clutches().simulate(1.5, 1e-2, solver="ida")
    stuck = res["clutch1.mode"] == STUCK
    assert stuck.any() and (~stuck).any()
    assert np.any(res["clutch1.heat_flow"][~stuck] > 0.0)
    traj = res._traj
    c = traj.c
    k = c.structure.coord_names.index("J2")
    traj.Y[stuck, c.iv[k]] += 1e-9           # a residue of the stuck constraint in the second inertia's speed
    res._cache.clear()
    traj._recipes.clear()
    traj.YPv[stuck, k] += 1e-3                # and of its derivative in the acceleration
    assert np.all(res["J2.w"][stuck] != res["J1.w"][stuck])         # the speeds do carry it
    assert np.all(res["J2.a"][stuck] != res["J1.a"][stuck])
    for name in ("w_rel", "a_rel", "power", "heat_flow"):
        assert np.all(res[f"clutch1.{name}"][stuck] == 0.0), name
    assert np.any(res["clutch1.a_rel"][~stuck] != 0.0)
