"""A passive linear model's energy may not grow (``regmech.solvers.passive``): a run whose energy grew more than
twofold is refused, naming the model, the growth and what to do; models the book cannot judge are not checked."""

import numpy as np
import pytest

import regmech as rm
from regmech.bench.hard_models import energy, undamped_chain
from regmech.components import Fixed, Inertia, Spring, SpringDamper, Torque
from regmech.signals import Constant, Sine
from regmech.solvers.passive import ENERGY_GROWTH, passive_energy


@pytest.mark.parametrize("solver, rtol", [("scipy:RK45", 1e-2), ("dopri5", 1e-2), ("scipy:LSODA", 1e-2),
                                          ("ida", 1e-1)])
def test_a_run_whose_energy_grew_on_a_passive_model_is_refused(solver, rtol):
    # the hard case long_horizon (undamped 4-inertia chain, 100 s): RK45 at rtol 1e-2 returned an answer whose
    # energy had grown 12,169-fold (38 times the range off) with no error; ida at 0.1 691-fold, LSODA 32-fold
    m, _ = undamped_chain()
    with pytest.raises(rm.SimulationError) as err:
        m.simulate(100.0, 0.1, solver=solver, rtol=rtol)
    msg = str(err.value)
    assert "passive" in msg and "energy grew" in msg and "'undamped_chain'" in msg and solver in msg
    assert "tighter rtol" in msg and "accuracy=" in msg
    assert "spring" in msg              # the fastest link, where the instability grows


@pytest.mark.parametrize("solver, rtol", [("scipy:RK45", 1e-3), ("scipy:DOP853", 1e-2), ("ida", 1e-2),
                                          ("dop853", 1e-6)])
def test_runs_whose_energy_stays_are_returned(solver, rtol):
    m, e0 = undamped_chain()
    res = m.simulate(100.0, 0.1, solver=solver, rtol=rtol)
    assert energy(res, 4).max() <= ENERGY_GROWTH * e0


def test_the_book_is_the_energy_of_masses_and_springs():
    m, e0 = undamped_chain()
    res = m.simulate(1.0, 0.1, solver="expm")
    book = passive_energy(m.compile())
    assert book is not None
    np.testing.assert_allclose(book.of_rows(res._traj.Y), energy(res, 4), rtol=1e-12, atol=1e-12 * e0)


def two_masses(**spring):
    m = rm.Model("pair")
    ground = m.add(Fixed("ground"))
    a = m.add(Inertia("a", J=1.0, w0=3.0))
    b = m.add(Inertia("b", J=2.0))
    s = m.add(SpringDamper("s", c=100.0, d=0.5, **spring))
    g = m.add(Spring("g", c=10.0))
    m.connect(a.flange_b, s.flange_a)
    m.connect(s.flange_b, b.flange_a)
    m.connect(b.flange_b, g.flange_a)
    m.connect(g.flange_b, ground.flange)
    return m


def test_models_the_book_cannot_judge_are_not_checked():
    assert passive_energy(two_masses().compile()) is not None
    assert passive_energy(two_masses(phi_rel0=0.1).compile()) is None          # a preload: its work is not booked
    for tau in (Constant(1.0), Sine(amplitude=1.0, freq_hz=2.0)):              # a source
        m = two_masses()
        drive = m.add(Torque("drive", tau=tau))
        m.connect(drive.flange, m.components["a"].flange_a)
        assert passive_energy(m.compile()) is None
    m = two_masses()
    drive = m.add(Torque("drive", tau=Constant(0.0)))                          # a source that does nothing
    m.connect(drive.flange, m.components["a"].flange_a)
    assert passive_energy(m.compile()) is not None
    from regmech.library import coupled_clutches
    assert passive_energy(coupled_clutches().compile()) is None                # friction, sources


def test_a_damped_passive_model_loses_energy_and_runs():
    res = two_masses().simulate(5.0, 0.01, solver="scipy:RK45", rtol=1e-2)
    book = passive_energy(res._traj.c)
    E = book.of_rows(res._traj.Y)
    assert E[-1] < E[0] and E.max() <= ENERGY_GROWTH * E[0]


def test_a_damping_matrix_that_is_not_semidefinite_is_no_passive_model():
    """A speed-dependent load of negative nominal torque between two damped masses (it drives: the review's
    model) has a symmetric damping matrix with a positive diagonal, [[0.5, 1], [1, 0.5]], and an eigenvalue -0.5:
    its energy grows 74-fold in 5 s, so the book may not judge it (it refused the exact flow of expm)."""
    from regmech.components import Damper, LinearSpeedDependentTorque
    m = rm.Model("self_excited")
    g = m.add(Fixed("g"))
    a = m.add(Inertia("a", J=1.0, w0=1.0))
    b = m.add(Inertia("b", J=1.0, w0=0.0))
    load = m.add(LinearSpeedDependentTorque("load", tau_nominal=-1.0, w_nominal=1.0))
    da, db = m.add(Damper("da", d=1.5)), m.add(Damper("db", d=1.5))
    m.connect(a.flange_b, load.flange)
    m.connect(load.support, b.flange_a)
    m.connect(a.flange_a, da.flange_a)
    m.connect(da.flange_b, g.flange)
    m.connect(b.flange_b, db.flange_a)
    m.connect(db.flange_b, g.flange)
    assert passive_energy(m.compile()) is None
    for solver in ("expm", "ida"):
        res = m.simulate(5.0, 0.1, solver=solver, **({"rtol": 1e-10} if solver == "ida" else {}))
        E = 0.5 * (res["a.w"] ** 2 + res["b.w"] ** 2)
        assert E.max() > 50 * E[0]                   # the growth is the model's own


def spun_chain(spin):
    """A free 4-inertia chain of springs (a random fuzz model), every inertia spun by ``spin`` rad/s more."""
    m = rm.Model("spun")
    values = [(0.0486, 0.0, 0.0), (9.58, -0.00878, 10.22), (1.328, 0.0, -2.463), (18.40, -0.01294, -2.115)]
    J = [m.add(Inertia(f"J{i}", J=j, phi0=p, w0=w + spin)) for i, (j, p, w) in enumerate(values)]
    for i, c in enumerate((191.26, 300.79, 7328.6)):
        k = m.add(Spring(f"k{i + 1}", c=c))
        m.connect(J[i].flange_b, k.flange_a)
        m.connect(k.flange_b, J[i + 1].flange_a)
    return m


def test_a_common_spin_does_not_hide_a_vibration_that_grew():
    """At 190 rad/s the chain's spin holds so much kinetic energy that dopri5 at rtol 0.0136 (an answer 5 times the
    range off) moved the total by 5 %: the book leaves the free group's common motion out (its momentum is
    conserved), and the run is refused."""
    m = spun_chain(190.1)
    book = passive_energy(m.compile())
    assert [list(g) for g in book.free] == [[0, 1, 2, 3]]
    with pytest.raises(rm.SimulationError) as err:
        m.simulate(0.5, 1e-3, solver="dopri5", rtol=0.0136)
    assert "common spin" in str(err.value)
    res = m.simulate(0.5, 1e-3, solver="dop853", rtol=1e-8)          # a right answer keeps its vibration's energy
    E = book.of_rows(res._traj.Y)
    assert np.max(np.abs(E / E[0] - 1.0)) < 1e-5
    # a grounded group has no free common motion
    assert passive_energy(two_masses().compile()).free == ()


def test_the_book_keeps_its_precision_on_a_long_spin():
    """500 s at 190 rad/s: the angles reach 1e5 rad; the book measures the twist (the group's common angle taken
    out), so a right answer's vibration energy stays put, and the result's own positions are not touched."""
    m = spun_chain(190.1)
    res = m.simulate(500.0, 0.5, solver="expm")
    Y = res._traj.Y.copy()
    E = passive_energy(m.compile()).of_rows(res._traj.Y)
    assert np.abs(res["J0.phi"]).max() > 9e4
    assert np.max(np.abs(E / E[0] - 1.0)) < 1e-6
    np.testing.assert_array_equal(res._traj.Y, Y)
