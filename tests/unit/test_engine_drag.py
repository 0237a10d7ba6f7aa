"""Engine drag (motoring) map at closed throttle: tau = throttle T_full(w) + (1 - throttle) T_drag(w)."""

import pickle

import numpy as np
import pytest

import regmech as rm
from regmech.bench.fuzz import energy_checks
from regmech.components import Engine, Inertia, Speed
from regmech.signals import Ramp, Table

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
    with pytest.raises(rm.ParameterError, match=r"drag_map must oppose the rotation.*row 1"):
        Engine("x", torque_map=FULL, drag_map=[[0.0, 0.0], [600.0, 60.0]])
    a.drag_map = [[0.0, 0.0], [600.0, -30.0]]
    assert type(a)._drag[1, 1] == -30.0 and type(a) is not type(c)


#: the full-load map of the blend test: (rad/s, N m)
FULL_MAP = [[0.0, 50.0], [100.0, 150.0], [400.0, 200.0], [600.0, 120.0]]
TIGHT = dict(rtol=1e-10, atol=1e-10)

DRAG_MAP = [[0.0, 0.0], [600.0, -60.0]]      # rad/s, N m: T_drag = -0.1 w


def test_engine_drag_at_closed_throttle_brakes_as_the_closed_form():
    """Closed throttle, no load: J dw/dt = T_drag(w) = -0.1 w, so w = w0 exp(-0.1 t / J) (engine braking)."""
    m = rm.Model("overrun")
    engine = m.add(Engine("engine", torque_map=FULL_MAP, drag_map=DRAG_MAP, throttle=0.0))
    crank = m.add(Inertia("crank", J=0.2, w0=300.0))
    m.connect(engine.flange, crank.flange_a)
    res = m.simulate(2.0, dt_out=0.01, solver="ida", **TIGHT)
    exact = 300.0 * np.exp(-0.1 * res.t / 0.2)
    assert np.max(np.abs(res["crank.w"] - exact)) < 1e-6 * 300.0
    assert np.all(res["engine.tau"] <= 0.0)
    # the engine absorbs what the crank loses: the source's work is negative
    assert np.all(res["engine.power"] >= 0.0)


def test_engine_blends_full_load_and_drag_by_the_throttle():
    m = rm.Model("engine_sweep_drag")
    engine = m.add(Engine("engine", torque_map=FULL_MAP, drag_map=DRAG_MAP, throttle=Ramp(height=1.0, duration=1.0)))
    crank = m.add(Inertia("crank", J=0.2))
    drive = m.add(Speed("speed", w_ref=Ramp(height=500.0, duration=1.0, offset=50.0)))
    m.connect(engine.flange, crank.flange_a)
    m.connect(drive.flange, crank.flange_b)
    res = m.simulate(1.0, dt_out=1e-2, rtol=1e-8, solver="ida")
    w, thr = res["crank.w"], np.clip(res.t, 0.0, 1.0)
    full = np.interp(w, *np.array(FULL_MAP).T)
    drag = np.interp(w, *np.array(DRAG_MAP).T)
    assert np.allclose(res["engine.tau"], thr * full + (1 - thr) * drag, rtol=1e-6, atol=1e-6)

