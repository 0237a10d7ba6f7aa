"""Gearbox and DualClutchTransmission: ratios, power flow with mesh efficiency, energy books,
a shift against a hand-built box and against an independent scipy model of its phases
(gear 1 locked, break-away, interruption, slip of the new element, lock-up)."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import regmech as rm
from regmech.bench.fuzz import energy_checks
from regmech.components import Clutch, Damper, Fixed, IdealGear, Inertia, Speed, Torque
from regmech.components.gearbox import DualClutchTransmission, Gearbox
from regmech.errors import ParameterError
from regmech.signals import Pulse, Sine, Step

RATIOS = [3.5, 2.1, 1.4, 1.0, 0.8, -3.2]


def _driven(box, w_in=100.0, d=2.0, from_output=False, w_load0=None):
    """Speed source on one side of the box, a damper load on the other (starting at ``w_load0``)."""
    m = rm.Model("driven")
    src = m.add(Speed("src", w_ref=w_in))
    load = m.add(Damper("load", d=d))
    J_load = m.add(Inertia("J_load", J=0.5, w0=w_load0))
    g = m.add(Fixed("g"))
    m.add(box)
    drive, driven = (box.flange_b, box.flange_a) if from_output else (box.flange_a, box.flange_b)
    m.connect(src.flange, drive)
    m.connect(driven, J_load.flange_a)
    m.connect(J_load.flange_b, load.flange_a)
    m.connect(load.flange_b, g.flange)
    res = m.simulate(t_end=0.2, dt_out=0.1, solver="ida", rtol=1e-10, atol=1e-10)
    return m, res


@pytest.mark.parametrize("k", range(1, len(RATIOS) + 1))
def test_ratio_and_power_of_every_gear(k):
    r = RATIOS[k - 1]
    w_in, d = 100.0, 2.0
    box = Gearbox("gb", ratios=RATIOS, capacity=1e4, gear=k)
    m, res = _driven(box, w_in, d, w_load0=w_in / r)
    w_out = res["J_load.w"][-1]
    assert w_out == pytest.approx(w_in / r, rel=1e-10)
    # power in (speed source) = power into the load (damper), nothing lost in an ideal box at constant speed
    p_in = -res["src.power"][-1]
    assert p_in == pytest.approx(d * w_out ** 2, rel=1e-8)
    modes = {i: res[f"gb.shift{i}.mode"][-1] for i in range(1, len(RATIOS) + 1)}
    assert modes[k] == 0 and all(v == 2 for i, v in modes.items() if i != k)
    assert not energy_checks(res, m, rel=1e-8)


@pytest.mark.parametrize("from_output", [False, True])
def test_mesh_efficiency_by_direction_of_power_flow(from_output):
    """eta = 0.95 in gear 2: input driving, P_out = eta P_in; output driving (overrun), P_in = eta P_out."""
    eta, r = 0.95, 2.1
    box = Gearbox("gb", ratios=[3.5, r], capacity=1e4, gear=2, efficiency=[0.97, eta])
    m, res = _driven(box, 100.0, 2.0, from_output=from_output,
                     w_load0=100.0 * r if from_output else 100.0 / r)
    w_load = res["J_load.w"][-1]
    p_src = -res["src.power"][-1]
    p_load = 2.0 * w_load ** 2
    assert w_load == pytest.approx(100.0 * r if from_output else 100.0 / r, rel=1e-10)
    assert p_load == pytest.approx(eta * p_src, rel=1e-8)
    assert res["gb.gear2.power"][-1] == pytest.approx((1 - eta) * p_src, rel=1e-7)
    assert not energy_checks(res, m, rel=1e-8)


def _car(box_factory, T=120.0, J_e=0.2, J_v=12.0, d=1.5, w0=250.0, r1=3.5):
    m = rm.Model("car")
    eng = m.add(Torque("engine", tau=T))
    Je = m.add(Inertia("J_e", J=J_e, phi0=0.0, w0=w0))
    veh = m.add(Inertia("veh", J=J_v, phi0=0.0, w0=w0 / r1))
    load = m.add(Damper("drag", d=d))
    g = m.add(Fixed("g"))
    box_in, box_out = box_factory(m)
    m.connect(eng.flange, Je.flange_a)
    m.connect(Je.flange_b, box_in)
    m.connect(box_out, veh.flange_a)
    m.connect(veh.flange_b, load.flange_a)
    m.connect(load.flange_b, g.flange)
    return m


BOX = dict(ratios=[3.5, 2.0], capacity=[400.0, 600.0], J_in=0.01, J_out=0.02, J_gear=[0.003, 0.004], peak=1.2,
           release_time=0.1, engage_time=0.25, shift_delay=0.15)
SCHEDULE = [(0.0, 1), (0.3, 2)]


def _macro(m):
    gb = m.add(Gearbox("gb", gear=SCHEDULE, **BOX))
    return gb.flange_a, gb.flange_b


def _hand_built(m):
    """The same box by hand: IdealGear -> Inertia -> Clutch branches, Table engagement signals."""
    from regmech.signals import Table
    inp = m.add(Inertia("in", J=BOX["J_in"]))
    out = m.add(Inertia("out", J=BOX["J_out"]))
    f1 = Table([(0.0, 1.0), (0.3, 1.0), (0.4, 0.0)])
    f2 = Table([(0.0, 0.0), (0.45, 0.0), (0.7, 1.0)])
    for k, (r, cap, jg, f) in enumerate(zip(BOX["ratios"], BOX["capacity"], BOX["J_gear"], (f1, f2)), 1):
        gear = m.add(IdealGear(f"g{k}", ratio=r))
        idler = m.add(Inertia(f"idl{k}", J=jg))
        cl = m.add(Clutch(f"c{k}", mu=1.0, cgeo=1.0, fn_max=cap, peak=BOX["peak"], f_normalized=f))
        m.connect(inp.flange_b, gear.flange_a)
        m.connect(gear.flange_b, idler.flange_a)
        m.connect(idler.flange_b, cl.flange_a)
        m.connect(cl.flange_b, out.flange_a)
    return inp.flange_a, out.flange_b


def _independent(T=120.0, J_e=0.2, J_v=12.0, d=1.5, w0=250.0):
    """Two degrees of freedom (input side, output side) and the two elements, phase by phase with scipy."""
    r, cap, jg, peak = BOX["ratios"], BOX["capacity"], BOX["J_gear"], BOX["peak"]
    Mi = J_e + BOX["J_in"] + sum(j / rk ** 2 for j, rk in zip(jg, r))
    Mo = BOX["J_out"] + J_v
    f = [lambda t: float(np.interp(t, [0.3, 0.4], [1.0, 0.0])), lambda t: float(np.interp(t, [0.45, 0.7], [0.0, 1.0]))]

    def rhs(t, y, k, mode):
        wi, wo = y
        if mode == "stuck":
            c = held(t, y, k)
        elif mode == "slip":
            c = -np.sign(wo - wi / r[k]) * f[k](t) * cap[k]
        else:
            c = 0.0
        return [(T - c / r[k]) / Mi, (c - d * wo) / Mo]

    def held(t, y, k):
        return (T / (Mi * r[k]) + d * y[1] / Mo) / (1 / Mo + 1 / (Mi * r[k] ** 2))

    phases = []
    y, t = [w0, w0 / r[0]], 0.0
    plan = [(0, "stuck", 0.3), (0, "stuck", 0.4), (None, "free", 0.45), (1, "slip", 0.7), (1, "slip", 1.2)]
    events = {}
    k_mode = None
    for k, mode, t_end in plan:
        if k_mode is not None and k_mode[0] == k:
            mode = k_mode[1]          # the phase continues in the mode found by the previous segment
        while t < t_end - 1e-15:
            kk = 0 if k is None else k
            evs = []
            if mode == "stuck" and k is not None:
                ev = lambda tt, yy, *_: peak * cap[kk] * f[kk](tt) - abs(held(tt, yy, kk))
            elif mode == "slip":
                ev = lambda tt, yy, *_: yy[1] - yy[0] / r[kk]
            else:
                ev = None
            if ev is not None:
                ev.terminal = True
                evs = [ev]
            sol = solve_ivp(rhs, (t, t_end), y, args=(kk, mode), events=evs, rtol=1e-11, atol=1e-11,
                            dense_output=True, method="DOP853")
            phases.append((t, sol.t[-1], sol.sol))
            t, y = sol.t[-1], sol.y[:, -1]
            if sol.status == 1:
                events[(kk, mode)] = t
                mode = "slip" if mode == "stuck" else "stuck"
            k_mode = (k, mode)

    def at(tt):
        for a, b, s in phases:
            if a <= tt <= b:
                return s(tt)
        raise ValueError(tt)
    return at, events


def test_shift_against_hand_built_and_independent_model():
    ma = _car(_macro)
    mb = _car(_hand_built)
    ra = ma.simulate(t_end=1.2, dt_out=2e-3, solver="ida", rtol=1e-10, atol=1e-10)
    rb = mb.simulate(t_end=1.2, dt_out=2e-3, solver="ida", rtol=1e-10, atol=1e-10)
    for name in ("J_e.w", "veh.w"):
        assert np.max(np.abs(ra[name] - rb[name])) <= 1e-7 * np.max(np.abs(rb[name]))
    ev_a = [(e.t, e.component.split(".")[-1].replace("shift", "c"), e.old_mode, e.new_mode) for e in ra.events]
    ev_b = [(e.t, e.component, e.old_mode, e.new_mode) for e in rb.events]
    assert [x[1:] for x in ev_a] == [x[1:] for x in ev_b]
    assert np.allclose([x[0] for x in ev_a], [x[0] for x in ev_b], atol=1e-7)
    # the phases: locked in 1st, break-away while released, interruption, slip, lock-up in 2nd
    assert [(e.component, e.old_mode, e.new_mode) for e in ra.events] == [
        ("gb.shift1", 0, -1), ("gb.shift1", -1, 2), ("gb.shift2", 2, -1), ("gb.shift2", -1, 0)]
    at, events = _independent()
    w_scale = np.max(np.abs(ra["J_e.w"]))
    for k in range(0, len(ra.t), 25):
        wi, wo = at(ra.t[k])
        assert ra["J_e.w"][k] == pytest.approx(wi, abs=2e-7 * w_scale)
        assert ra["veh.w"][k] == pytest.approx(wo, abs=2e-7 * w_scale)
    assert ra.events[0].t == pytest.approx(events[(0, "stuck")], abs=1e-6)
    assert ra.events[3].t == pytest.approx(events[(1, "slip")], abs=1e-6)
    # torque interruption: between the release and the engagement nothing reaches the output
    gap = (ra.t > 0.401) & (ra.t < 0.449)
    assert np.all(ra["gb.shift1.tau"][gap] == 0) and np.all(ra["gb.shift2.tau"][gap] == 0)
    # after the lock-up: the new ratio
    k = np.searchsorted(ra.t, 1.15)
    assert ra["J_e.w"][k] / ra["veh.w"][k] == pytest.approx(2.0, rel=1e-9)
    assert not energy_checks(ra, ma, rel=1e-8)


def test_downshift_slips_forward_and_signal_selection():
    """2 -> 1 at 0.3 s, the gear given as a Step signal: the new element slips forward (input too slow)."""
    def box(m):
        gb = m.add(Gearbox("gb", ratios=[3.5, 2.0], capacity=400.0, gear=Step(height=-1, start_time=0.3, offset=2),
                           w_in0=None, w_out0=None))
        return gb.flange_a, gb.flange_b
    m = _car(box, T=60.0, w0=200.0, r1=2.0)
    res = m.simulate(t_end=1.5, dt_out=2e-3)
    seq = [(e.component, e.new_mode) for e in res.events]
    assert ("gb.shift1", 1) in seq and ("gb.shift1", 0) in seq
    k = np.searchsorted(res.t, 1.45)
    assert res["J_e.w"][k] / res["veh.w"][k] == pytest.approx(3.5, rel=1e-6)
    assert not energy_checks(res, m, rel=1e-4)


def test_neutral_transmits_nothing():
    box = Gearbox("gb", ratios=[3.0, 1.5], capacity=300.0, gear=0)
    m, res = _driven(box)
    assert np.all(res["gb.shift1.mode"] == 2) and np.all(res["gb.shift2.mode"] == 2)
    assert res["J_load.w"][-1] == 0.0


@pytest.mark.parametrize("kwargs, match", [
    (dict(ratios=[], capacity=1.0), "ratios"),
    (dict(ratios=[3.0, 0.0], capacity=1.0), "ratios.*gear 2"),
    (dict(ratios=[3.0, 2.0], capacity=[1.0]), "capacity.*1 entries for 2 gears"),
    (dict(ratios=[3.0, 2.0], capacity=-1.0), "capacity.*gear 1"),
    (dict(ratios=[3.0, 2.0], capacity=1.0, efficiency=1.2), "efficiency"),
    (dict(ratios=[3.0, 2.0], capacity=1.0, gear=3), "gear 3"),
    (dict(ratios=[3.0, 2.0], capacity=1.0, gear=1.5), "gear 1.5"),
    (dict(ratios=[3.0, 2.0], capacity=1.0, gear=[(0, 1), (0.1, 2)], engage_time=0.5, release_time=0.1), None),
    (dict(ratios=[3.0, 2.0], capacity=1.0, gear=[(0, 1), (0.5, 2), (0.6, 1)]), "before the previous one"),
    (dict(ratios=[3.0, 2.0], capacity=1.0, gear=[(0, 1), (0, 2)]), "strictly increasing"),
    (dict(ratios=[3.0, 2.0], capacity=1.0, gear=lambda t: 1), "callable"),
    (dict(ratios=[3.0, 2.0], capacity=1.0, gear=Step(height=0.5, start_time=1.0, offset=1)), "gear 1.5"),
    (dict(ratios=[3.0, 2.0], capacity=1.0, peak=0.9), "peak"),
    (dict(ratios=[3.0, 2.0], capacity=1.0, gear=Pulse(amplitude=1, period=1.0, offset=1)), "switches without end"),
    (dict(ratios=[3.0, 2.0], capacity=1.0, gear=Sine(amplitude=1, offset=1)), "varies"),
])
def test_parameter_errors_name_the_box(kwargs, match):
    if match is None:
        Gearbox("gb", **kwargs)            # a shift right after the start is fine
        return
    with pytest.raises(ParameterError, match=f"Gearbox 'gb'.*{match}"):
        Gearbox("gb", **kwargs)


def _dct_car(schedule, T=120.0, w0=250.0):
    def box(m):
        dct = m.add(DualClutchTransmission("dct", ratios=[3.5, 2.1, 1.4], gear=schedule, capacity=400.0, w_in0=w0,
                                           sync_capacity=60.0, sync_time=0.1, handover_time=0.25))
        return dct.flange_a, dct.flange_b
    return _car(box, T=T, w0=w0)


def test_dct_shifts_without_torque_interruption():
    m = _dct_car([(0.0, 1), (0.3, 2), (1.2, 3)])
    res = m.simulate(t_end=2.2, dt_out=2e-3, solver="ida", rtol=1e-8, atol=1e-8)
    # the vehicle is pulled all the time: its acceleration never drops to the coasting value -d w / J
    coast = -1.5 * res["veh.w"] / 12.0
    assert np.all(res["veh.a"] > coast + 0.2)
    for t_check, r in ((0.25, 3.5), (1.15, 2.1), (2.15, 1.4)):
        k = np.searchsorted(res.t, t_check)
        assert res["J_e.w"][k] / res["veh.w"][k] == pytest.approx(r, rel=1e-7)
    comps = {e.component for e in res.events}
    assert {"dct.K1", "dct.K2", "dct.sync2", "dct.sync3"} <= comps
    assert not energy_checks(res, m, rel=1e-6)


def test_dct_refuses_a_shift_on_one_shaft():
    with pytest.raises(ParameterError, match="DualClutchTransmission 'dct'.*stays on shaft 1"):
        DualClutchTransmission("dct", ratios=[3.5, 2.1, 1.4], gear=[(0, 1), (1, 3)], capacity=300.0)
    with pytest.raises(ParameterError, match="at least two"):
        DualClutchTransmission("dct", ratios=[3.5], capacity=300.0)
