"""Engine drag (motoring) map at closed throttle: tau = throttle T_full(w) + (1 - throttle) T_drag(w)."""

import pickle

import numpy as np
import pytest

import regmech as rm
from regmech.bench.fuzz import energy_checks
from regmech.components import Engine, Inertia
from regmech.signals import Table

FULL = [(0.0, 100.0), (600.0, 100.0)]


def _coast(drag, J=0.5, w0=300.0):
    m = rm.Model("e")
    e = m.add(Engine("e", torque_map=FULL, drag_map=drag, throttle=Table([(0, 1.0), (0.5, 1.0), (0.5, 0.0)])))
    fly = m.add(Inertia("fly", J=J, phi0=0.0, w0=w0))
    m.connect(e.flange, fly.flange_a)
    return m, m.simulate(2.0, dt_out=0.01, solver="ida", rtol=1e-10, atol=1e-10)


def test_constant_drag_decelerates_linearly():
    m, res = _coast([(0.0, -20.0)])
    w_shift = 300.0 + 100.0 / 0.5 * 0.5          # full load until 0.5 s
    k = np.searchsorted(res.t, 1.5)
    assert res["fly.w"][k] == pytest.approx(w_shift - 20.0 / 0.5 * (res.t[k] - 0.5), rel=1e-9)
    assert res["e.tau"][k] == pytest.approx(-20.0, rel=1e-12)
    assert not energy_checks(res, m, rel=1e-8)


def test_speed_dependent_drag_follows_the_map():
    drag = [(0.0, -10.0), (500.0, -40.0)]
    m, res = _coast(drag)
    for k in range(60, len(res.t), 20):
        w = res["fly.w"][k]
        assert res["e.tau"][k] == pytest.approx(np.interp(w, *np.array(drag).T), rel=1e-9)


def test_drag_map_errors_classes_and_pickling():
    with pytest.raises(rm.ParameterError, match="Engine 'x'.*drag_map.*<= 0"):
        Engine("x", torque_map=FULL, drag_map=[(0.0, 5.0)])
    with pytest.raises(rm.ParameterError, match="drag_map"):
        Engine("x", torque_map=FULL, drag_map=[(1.0, -5.0), (0.0, -1.0)])
    a, b = Engine("a", torque_map=FULL), Engine("b", torque_map=FULL)
    c = Engine("c", torque_map=FULL, drag_map=[(0.0, -5.0)])
    assert type(a) is type(b) and type(c) is not type(a) and isinstance(c, Engine)
    d = pickle.loads(pickle.dumps(c))
    assert type(d) is type(c) and np.array_equal(d.drag_map, c.drag_map)
    a.drag_map = [(0.0, -5.0)]
    assert type(a) is type(c)
