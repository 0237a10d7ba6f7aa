"""The ODE-form driver's vectorised per-step work gives what the per-item work gave (speed)."""

import numpy as np
import pytest

import regmech as rm
from regmech.library import coupled_clutches, first
from regmech.solvers.ode_driver import EventWatch


def _grid(ts, g):
    return [(float(t), np.asarray(v, float)) for t, v in zip(ts, g)]


def test_suspect_reads_the_vertex_of_a_dip_between_samples():
    # one guard, a parabola with its minimum -0.01 at 0.45 between samples that are all positive (min_gap 1:
    # no interval counts as an aliased swing)
    ts = np.array([0.0, 0.3, 0.6, 1.0])
    g = (4.0 * (ts - 0.45) ** 2 - 0.01)[:, None]
    s = EventWatch._suspect(_grid(ts, g), np.array([True]), 1.0, 1.0)
    assert s == pytest.approx(0.45)
    # a disarmed guard suggests nothing; neither does a guard clearly away from zero
    assert EventWatch._suspect(_grid(ts, g), np.array([False]), 1.0, 1.0) is None
    assert EventWatch._suspect(_grid(ts, g + 1.0), np.array([True]), 1.0, 1.0) is None
    # nothing past ``upto``
    assert EventWatch._suspect(_grid(ts, g), np.array([True]), 0.3, 1.0) is None


def test_suspect_reads_the_middle_of_an_aliased_swing():
    ts = np.array([0.0, 0.5, 1.0])
    g = np.array([[1.0, 5.0], [0.2, 5.0], [1.0, 5.0]])      # guard 0 moves by more than its distance from zero
    g2 = g.copy()
    g2[1, 0] = 0.9                       # a small move: the parabola's vertex stays positive, no swing
    assert EventWatch._suspect(_grid(ts, g2), np.array([True, True]), 1.0, 0.1) is None
    s = EventWatch._suspect(_grid(ts, g), np.array([True, True]), 1.0, 0.1)
    assert s == pytest.approx(0.25)


@pytest.mark.parametrize("method", ["DOP853", "RK45"])
def test_interpolate_many_is_interpolate(method):
    from regmech.solvers.ode_driver import OdeProblem
    from regmech.solvers.scipy_ivp import ScipyStepper
    m = first()
    c = m.compile()
    y, _ = c.initial_y(0.0, c.modes0)
    problem = OdeProblem(c, c.modes0)
    st = ScipyStepper(method, problem, 0.0, c.ode_state(y), 1.0, rtol=1e-6, atol=1e-8)
    st.step()
    st.step()
    tq = list(np.linspace(st.t_old, st.t, 7)[1:-1])
    many = st.interpolate_many(tq)
    for q, u in zip(tq, many):
        np.testing.assert_allclose(u, st.interpolate(q), rtol=1e-14, atol=1e-14 * np.abs(st.u).max())


@pytest.mark.parametrize("model", [first, coupled_clutches])
def test_ode_form_matches_ida(model):
    # the lift's dense blocks (First: a gear; CoupledClutches: clutches) leave the answer as it was
    m = model()
    a = m.simulate(1.0, 1e-2, solver="scipy:DOP853", rtol=1e-9)
    b = m.simulate(1.0, 1e-2, solver="ida", rtol=1e-10)
    for name in [k for k in ("J1.w", "J2.w", "J3.w", "J4.w", "inertia1.w", "inertia2.w") if k in a.names]:
        ya, yb = np.asarray(a[name]), np.interp(a.t, b.t, b[name])
        assert np.max(np.abs(ya - yb)) <= 1e-5 * max(np.ptp(yb), 1.0), name


@pytest.mark.parametrize("solver", ["dop853", "dopri5", "scipy:RK45", "scipy:DOP853", "scipy:Radau"])
def test_a_steps_output_rows_written_as_a_block_are_the_rows_written_one_by_one(solver, monkeypatch):
    """``_Sink.states`` (a step's interpolated rows at once) against ``state`` row by row: the same instants, states,
    rates, flags and modes, on a chain with a device state (a DC motor's current) and step inputs whose
    breakpoints fall on output instants, with a start off the grid and dense output (several rows a step)."""
    from regmech.bench.hard_models import benchmark_chain
    from regmech.components import DCMotor, Inertia, SpringDamper
    from regmech.signals import Step
    from regmech.solvers import ode_driver

    m = benchmark_chain(20, tau=Step(height=5.0, start_time=0.2))
    motor = m.add(DCMotor("motor", u=Step(height=12.0, start_time=0.05), R=0.5, L=0.01, k=0.8))
    rotor = m.add(Inertia("rotor", J=0.1))
    coupling = m.add(SpringDamper("coupling", c=1e3, d=1.0))
    m.connect(motor.flange, rotor.flange_a)
    m.connect(rotor.flange_b, coupling.flange_a)
    m.connect(coupling.flange_b, m.components["J0"].flange_b)
    assert m.compile().nz > 0
    calls = []
    block = ode_driver._Sink.states

    def counted(self, ts, U, modes):
        calls.append(len(ts))
        return block(self, ts, U, modes)
    monkeypatch.setattr(ode_driver._Sink, "states", counted)
    kw = dict(t_start=0.0123, dt_out=1e-4, solver=solver, rtol=1e-6)
    a = m.simulate(0.3, **kw)
    assert calls and max(calls) >= 3                            # the block path ran
    monkeypatch.setattr(ode_driver._Sink, "takes_blocks", property(lambda self: False))
    b = m.simulate(0.3, **kw)
    ta, tb = a._traj, b._traj
    assert np.array_equal(ta.t, tb.t) and np.array_equal(ta.left, tb.left) and np.array_equal(ta.modes, tb.modes)
    np.testing.assert_array_equal(ta.Y, tb.Y)
    for name in ("J0.a", "J19.a", "motor.i", "rotor.a"):
        np.testing.assert_array_equal(a[name], b[name])
