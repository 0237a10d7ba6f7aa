"""The fast paths of the mode logic agree with the general ones they stand for.

* the dense KKT factorisation of small systems (``compile.kkt``) with the sparse one, and both
  refuse the same singular systems;
* the dense locking of stuck devices (``Holding._lock_dense``) with ``CompiledSystem.project``,
  and it leaves conflicting constraints to ``project`` (which names them);
* the event functions of a few devices in plain Python, planned once per segment
  (``EventFunctions._event_values_small``), with the vectorised ones, in every mode.
"""

from __future__ import annotations

import copy
import itertools

import numpy as np
import pytest

import regmech as rm
from regmech.compile import kkt
from regmech.compile.system import PIVOT_TOL
from regmech.components import Brake, Clutch, Fixed, Inertia, OneWayClutch, Speed, Spring, Torque
from regmech.hybrid import attach
from regmech.modes import BACKWARD, FORWARD, FREE, HELD, STUCK
from regmech.signals import Sine, Step


def clutches(one_way=False):
    """Four inertias and three clutches (the third a freewheel when ``one_way``); normal forces a sine
    (evaluated at every call) and steps (evaluated once per segment)."""
    m = rm.Model("fast_paths")
    f = m.add(Fixed("f"))
    tq = m.add(Torque("tq", tau=Sine(amplitude=3.0, freq_hz=2.0)))
    J = [m.add(Inertia(f"J{k}", J=1.0 + 0.5 * k, w0=2.0 - k)) for k in range(4)]
    m.connect(tq.support, f.flange)
    m.connect(tq.flange, J[0].flange_a)
    sig = [Sine(amplitude=1.0, freq_hz=0.3, phase=1.0), Step(start_time=0.2), Step(start_time=0.4)]
    for k in range(3):
        cls = OneWayClutch if (one_way and k == 2) else Clutch
        cl = m.add(cls(f"c{k}", mu=0.4, peak=1.2, fn_max=5.0 + k, f_normalized=sig[k]))
        m.connect(J[k].flange_b, cl.flange_a)
        m.connect(cl.flange_b, J[k + 1].flange_a)
    sp = m.add(Spring("s", c=50.0))
    m.connect(J[3].flange_b, sp.flange_a)
    m.connect(sp.flange_b, f.flange)
    return m


def test_dense_and_sparse_kkt_agree():
    c = attach(clutches().compile())
    rng = np.random.default_rng(3)
    assert c.n + c.m <= kkt.DENSE_MAX
    for modes in itertools.product((BACKWARD, STUCK, FORWARD, FREE), repeat=3):
        modes = np.array(modes)
        rel, _ = c.friction.relations(0.1, rng.standard_normal(c.n), modes)
        dense = kkt._dense(c, modes, rel, PIVOT_TOL)
        sparse = kkt._sparse(c, modes, rel, PIVOT_TOL)
        assert isinstance(dense, kkt.DenseLU)
        rhs = rng.standard_normal(c.n + c.m)
        a, b = dense.solve(rhs), sparse.solve(rhs)
        assert np.abs(a - b).max() <= 1e-12 * max(1.0, np.abs(b).max())


def test_dense_and_sparse_kkt_refuse_the_same_singular_system():
    """Two brakes stuck on one inertia: their holding torques are not unique."""
    m = rm.Model("two_brakes")
    J = m.add(Inertia("J", J=1.0, w0=0.0))
    b1 = m.add(Brake("b1", fn_max=10.0))
    b2 = m.add(Brake("b2", fn_max=10.0))
    m.connect(J.flange_a, b1.flange)
    m.connect(J.flange_b, b2.flange)
    c = attach(m.compile())
    modes = np.array([STUCK, STUCK])
    rel, _ = c.friction.relations(0.0, np.zeros(c.n), modes)
    assert kkt._dense(c, modes, rel, PIVOT_TOL) is None
    assert kkt._sparse(c, modes, rel, PIVOT_TOL) is None
    c._kkt_cache.clear()
    with pytest.raises(rm.StructureError, match="b1.*b2|not unique"):
        c.accelerations(0.0, np.zeros(c.n), np.zeros(c.n), np.zeros(c.nz), modes)


def test_dense_lock_matches_project():
    c = attach(clutches().compile())
    fr = c.friction
    rng = np.random.default_rng(5)
    for lock in itertools.product((False, True), repeat=3):
        lock = np.array(lock)
        if not lock.any():
            continue
        v = rng.standard_normal(c.n)
        dense = fr._lock_dense(0.3, v, lock)
        _, ref = c.project(0.3, np.zeros(c.n), v, None, None, np.where(lock, STUCK, FREE))
        assert dense is not None
        assert np.abs(dense - ref).max() <= 1e-12 * max(1.0, np.abs(v).max())
        assert np.abs(fr.w_rel(dense)[lock]).max() <= 1e-14 * max(1.0, np.abs(v).max())


def test_conflicting_lock_is_left_to_project():
    """A speed source drives J against a stuck brake: the dense lock gives up, and ``project``
    names the conflict."""
    m = rm.Model("driven_brake")
    J = m.add(Inertia("J", J=1.0))
    src = m.add(Speed("drive", w_ref=1.0))
    br = m.add(Brake("brake", fn_max=10.0))
    m.connect(src.flange, J.flange_a)
    m.connect(J.flange_b, br.flange)
    c = attach(m.compile())
    v = np.array([1.0])
    assert c.friction._lock_dense(0.0, v, np.array([True])) is None
    with pytest.raises(rm.StructureError):
        c.friction._lock_velocities(0.0, np.zeros(c.n), v, np.array([STUCK]), np.array([FORWARD]))


@pytest.mark.parametrize("one_way", [False, True])
def test_small_event_functions_equal_the_vectorised_ones(one_way):
    c = attach(clutches(one_way).compile())
    fr = c.friction
    assert fr._small is not None
    ref = copy.copy(fr)
    ref._small = None                 # the vectorised path, with the same devices and state,
    ref._varying = list(range(ref.mf))     # every capacity evaluated at every call
    rng = np.random.default_rng(11)
    codes = (BACKWARD, STUCK, FORWARD, FREE, HELD)
    for modes in itertools.product(codes, codes, (STUCK, FORWARD, FREE) if one_way else codes):
        modes = np.array(modes)
        for engaged in ([True, True, True], [False, True, False]):
            fr.engaged = ref.engaged = np.array(engaged)
            fr._small_for = ref._at_segment = None       # a new segment, as after settle
            c._t_right = 0.2
            for t in (0.05, 0.1, 0.2):             # the last one the segment's end (left limits)
                y = rng.standard_normal(c.N)
                np.testing.assert_array_equal(fr.event_values(t, y, y, modes), ref.event_values(t, y, y, modes))


@pytest.mark.parametrize("small", [True, False])
def test_a_device_sliding_or_freewheeling_at_exactly_zero_slip_has_its_function_armed(small):
    """A first function that starts a segment at 0.0 is disarmed by the ODE driver until it is positive and left
    inactive by IDA's root finding, so the slip could pass zero unseen: a device sliding, or a freewheel running free,
    at exactly zero slip gets 1e-300 (the freewheel's was 0.0)."""
    c = attach(clutches(one_way=True).compile())
    fr = c.friction
    if not small:
        fr._small = None
    y = np.zeros(c.N)            # every speed equal: every slip exactly zero
    for modes in ([FORWARD, BACKWARD, FREE], [BACKWARD, FORWARD, FORWARD]):
        modes = np.array(modes)
        fr._small_for = fr._at_segment = None
        fr.engaged = np.array([True, True, modes[2] == FORWARD])
        c._t_right = 1.0
        first = fr.event_values(0.1, y, y, modes)[0::2]
        assert np.all(first > 0.0), first


def test_a_run_ending_with_a_freewheel_turning_backward_is_refused():
    """``check_final`` (and the check at every event) refuses a one-way clutch left free with a negative slip, which
    a freewheel cannot have: its message names the clutch."""
    c = attach(clutches(one_way=True).compile())
    fr = c.friction
    y = np.zeros(c.N)
    v = np.zeros(c.n)
    v[0] = 1.0
    y[c.iv] = v
    fr.check_final(0.5, y, y, np.array([STUCK, STUCK, FREE]))        # the sliding ones are fine at zero slip
    for k in range(c.n):
        v = np.zeros(c.n)
        v[k] = 1.0
        if fr.w_rel(v)[2] < 0:
            break
    y[c.iv] = v
    with pytest.raises(rm.SimulationError, match="one-way clutch 'c2' would freewheel backward"):
        fr.check_final(0.5, y, y, np.array([STUCK, STUCK, FREE]))


def test_a_run_ending_with_a_non_finite_speed_is_refused_by_name():
    """``check_final``: a NaN speed passes every sign comparison, so it is refused before them, naming the mass."""
    c = attach(clutches(one_way=True).compile())
    y = np.zeros(c.N)
    v = np.zeros(c.n)
    v[1] = np.nan
    y[c.iv] = v
    with pytest.raises(rm.SimulationError, match=f"non-finite speeds of \\['{c.structure.coord_names[1]}'\\]"):
        c.friction.check_final(0.5, y, y, np.array([STUCK, STUCK, FREE]))
