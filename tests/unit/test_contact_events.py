"""Kinks of piecewise laws (contacts of Backlash, ElastoBacklash, EndStop, ElastoGap) located as events
(``Device.switching_surfaces`` -> ``hybrid.surfaces``): contact times against closed forms, the contact
states in ``res.events``, the damped contact's release where its force vanishes, and the native IDA path
declining such models with the reason."""

import math

import numpy as np
import pytest

import regmech as rm
from regmech.components import ElastoGap, EndStop, Fixed, Inertia, Mass
from regmech.components.backlash import Backlash, ElastoBacklash

SOLVERS = [dict(solver="ida", rtol=1e-6), dict(solver="scipy:DOP853", rtol=1e-6), dict(solver="ida", rtol=1e-9)]


def _contacts(res):
    return [e for e in res.events if e.kind == "contact"]


def _two_inertias(cls=Backlash, **kw):
    m = rm.Model("play")
    J1 = m.add(Inertia("J1", J=1.0, phi0=0.0, w0=1.0))
    b = m.add(cls("b", c=1e4, b=0.2, **kw))
    J2 = m.add(Inertia("J2", J=1.0, phi0=0.0, w0=0.0))
    m.connect(J1.flange_b, b.flange_a)
    m.connect(b.flange_b, J2.flange_a)
    return m


@pytest.mark.parametrize("kw", SOLVERS, ids=lambda kw: f"{kw['solver']}-{kw['rtol']:g}")
@pytest.mark.parametrize("cls", [Backlash, ElastoBacklash])
def test_free_flight_across_the_play_then_contact_at_the_closed_form_times(cls, kw):
    """J1 (1 kg m^2, 1 rad/s) crosses the play b = 0.2 rad towards J2 (1 kg m^2, at rest): phi_rel = phi_2 -
    phi_1 = -t reaches -b/2 at t = 0.1 s (contact on the negative side, -1); the contact is a linear
    spring on the reduced inertia 0.5 kg m^2, omega = sqrt(c / 0.5), so it lets go after half a period
    pi / omega with the speeds exchanged (elastic), and J2 then crosses the play at 1 rad/s: contact on
    the positive side at 0.3 + pi/omega, release pi/omega later. Claimed: each contact time within
    10 rtol (relative to max(1 s, t)) of the closed form; measured 3e-7 s with ida at rtol 1e-6."""
    extra = {"d": 0.0} if cls is ElastoBacklash else {}
    res = _two_inertias(cls, **extra).simulate(0.5, dt_out=1e-2, **kw)
    half = math.pi / math.sqrt(1e4 / 0.5)
    exact = [(0.1, 0, -1), (0.1 + half, -1, 0), (0.3 + half, 0, 1), (0.3 + 2 * half, 1, 0)]
    got = _contacts(res)
    assert [(e.component, e.old_mode, e.new_mode) for e in got] == [("b", o, n) for _, o, n in exact]
    for e, (t, _, _) in zip(got, exact):
        assert abs(e.t - t) <= 10 * kw["rtol"] * max(1.0, t), (e, t)
    # after both contacts the speeds are exchanged twice: J1 back at 1 rad/s, J2 at rest
    assert abs(res["J1.w"][-1] - 1.0) < 100 * kw["rtol"]
    assert abs(res["J2.w"][-1]) < 100 * kw["rtol"]
    assert "contact" in str(got[0]) and "open" in str(got[0])


@pytest.mark.parametrize("domain", ["translational", "rotational"])
def test_end_stop_contact_and_release_at_the_closed_form_times(domain):
    """A 2 kg mass at 0.5 m/s from s = 0 hits the upper stop (0.1 m, c = 1e5 N/m, d = 0) at t = 0.2 s
    (code +1), leaves it half a contact period pi sqrt(m / c) later at -0.5 m/s, and hits the lower stop
    (-0.05 m) 0.3 s after that (code -1)."""
    m = rm.Model("stop")
    body = Mass("m", m=2.0, s0=0.0, v0=0.5) if domain == "translational" else \
        Inertia("m", J=2.0, phi0=0.0, w0=0.5)
    m.add(body)
    stop = m.add(EndStop("stop", lower=-0.05, upper=0.1, c=1e5, domain=domain))
    m.connect(body.flange_b, stop.flange)
    res = m.simulate(0.8, dt_out=1e-2, solver="ida", rtol=1e-8)
    half = math.pi * math.sqrt(2.0 / 1e5)
    exact = [(0.2, 0, 1), (0.2 + half, 1, 0), (0.5 + half, 0, -1), (0.5 + 2 * half, -1, 0)]
    got = _contacts(res)
    assert [(e.old_mode, e.new_mode) for e in got] == [(o, n) for _, o, n in exact]
    for e, (t, _, _) in zip(got, exact):
        assert abs(e.t - t) <= 1e-6, (e, t)
    v = res["m.v" if domain == "translational" else "m.w"]
    assert abs(v[-1] - 0.5) < 1e-5


def test_damped_gap_lets_go_where_its_force_vanishes():
    """ElastoGap with damping: the limited damper lets go while the flanges still overlap (tau_c + tau_d
    reaches 0 before the penetration does); the release event is there: force 0, gap still closed."""
    m = rm.Model("gap")
    a = m.add(Mass("a", m=1.0, s0=0.0, v0=0.0))
    b = m.add(Mass("b", m=1.0, s0=0.0, v0=-1.0))
    gap = m.add(ElastoGap("gap", c=1e4, d=60.0, phi_rel0=-0.05))
    m.connect(a.flange_b, gap.flange_a)
    m.connect(gap.flange_b, b.flange_a)
    res = m.simulate(0.2, dt_out=1e-3, solver="ida", rtol=1e-9)
    got = _contacts(res)
    assert [(e.old_mode, e.new_mode) for e in got] == [(0, 1), (1, 0)]
    assert abs(got[0].t - 0.05) < 1e-7
    t_off = got[1].t
    k = np.searchsorted(res.t, t_off)
    rows = np.nonzero(np.abs(res.t - t_off) < 1e-12)[0]
    assert len(rows) and k < len(res.t)
    i = rows[-1]
    assert res["gap.s_rel"][i] < -0.05                  # still overlapping: the damper let go first
    assert abs(res["gap.f"][i]) < 1e-6 * np.max(np.abs(res["gap.f"]))
    # never pulling, never supplying energy
    assert np.all(res["gap.f"] <= 1e-9 * np.max(np.abs(res["gap.f"])))


def test_ode_solvers_and_ida_see_the_same_contacts():
    res_ida = _two_inertias().simulate(0.5, dt_out=1e-2, solver="ida", rtol=1e-8)
    res_ode = _two_inertias().simulate(0.5, dt_out=1e-2, solver="scipy:Radau", rtol=1e-8)
    a, b = _contacts(res_ida), _contacts(res_ode)
    assert [(e.component, e.old_mode, e.new_mode) for e in a] == [(e.component, e.old_mode, e.new_mode) for e in b]
    assert max(abs(x.t - y.t) for x, y in zip(a, b)) < 1e-6


@pytest.mark.parametrize("cls, kw", [(Backlash, {}), (ElastoBacklash, {"d": 5.0})], ids=["Backlash", "ElastoBacklash"])
def test_native_ida_locates_the_contacts_in_compiled_code_where_python_does(cls, kw):
    """The switching surfaces of a nonlinear device class are evaluated by the compiled event function: the
    same contacts, at the same times within the tolerance, as on the Python path."""
    m = _two_inertias(cls, **kw)
    native = m.simulate(0.5, dt_out=1e-2, solver="ida", rtol=1e-9, native=True)
    usual = m.simulate(0.5, dt_out=1e-2, solver="ida", rtol=1e-9, native=False)
    assert native.stats.extra["native"] is True and "native" not in usual.stats.extra
    a, b = _contacts(native), _contacts(usual)
    assert len(a) == len(b) == 4
    assert [(x.component, x.new_mode) for x in a] == [(x.component, x.new_mode) for x in b]
    assert max(abs(x.t - y.t) for x, y in zip(a, b)) < 1e-7
    # the output grid's rows (an event a round-off past a grid point adds its rows beside it on one path only)
    grid = np.round(np.arange(0.0, 0.5 + 1e-9, 1e-2), 12)
    on_grid = [np.searchsorted(np.round(r.t, 12), grid) for r in (native, usual)]
    np.testing.assert_allclose(native["J2.w"][on_grid[0]], usual["J2.w"][on_grid[1]], rtol=0, atol=1e-6)


def test_a_play_below_b_eps_is_a_plain_spring_without_contact_events():
    m = rm.Model("noplay")
    J1 = m.add(Inertia("J1", J=1.0, w0=1.0))
    e = m.add(ElastoBacklash("e", c=100.0, d=1.0, b=0.0))
    J2 = m.add(Inertia("J2", J=1.0))
    f = m.add(Fixed("f"))
    m.connect(J1.flange_b, e.flange_a)
    m.connect(e.flange_b, J2.flange_a)
    m.connect(J2.flange_b, f.flange)
    res = m.simulate(1.0, dt_out=1e-2, solver="ida")
    assert not _contacts(res)


def _rattle():
    """A sine torque rattling J1 (0.05 kg m^2) in a 0.02 rad play (2e4 N m/rad) against J2 (0.2 kg m^2) held by
    a spring (50 N m/rad) and a damper (5 N m s/rad) to the ground: 46 contacts in 0.4 s."""
    from regmech.components import Damper, Spring, Torque
    from regmech.signals import Sine
    m = rm.Model("rattle")
    f = m.add(Fixed("f"))
    drv = m.add(Torque("drive", tau=Sine(amplitude=20.0, freq_hz=3.0)))
    J1 = m.add(Inertia("J1", J=0.05))
    bl = m.add(Backlash("bl", c=2e4, b=0.02))
    J2 = m.add(Inertia("J2", J=0.2))
    k = m.add(Spring("k", c=50.0))
    d = m.add(Damper("d", d=5.0))
    m.connect(drv.flange, J1.flange_a)
    m.connect(drv.support, f.flange)
    m.connect(J1.flange_b, bl.flange_a)
    m.connect(bl.flange_b, J2.flange_a)
    for dev in (k, d):
        m.connect(J2.flange_b, dev.flange_a)
        m.connect(dev.flange_b, f.flange)
    return m


@pytest.mark.slow
@pytest.mark.parametrize("dt_out", [1e-3, 1e-2])
@pytest.mark.parametrize("solver", ["ida", "scipy:DOP853"])
def test_energy_books_of_a_rattling_backlash_close(solver, dt_out):
    """The books of the fuzz suite (``bench.fuzz.energy_checks``) at rtol 1e-6 over a rattle: with the contacts
    located, output rows lie on the kinks and the quadrature no longer straddles them (before: books 3.1e-2
    of the energy scale at dt_out 1e-2, a finding on both solvers; now 1.0e-2 within the quadrature
    estimate); IDA's row at a contact is the consistent one (its interpolated accelerations put the power
    balance 4.5e-4 off at that row)."""
    from regmech.bench.fuzz import energy_checks
    m = _rattle()
    res = m.simulate(0.4, dt_out=dt_out, solver=solver, rtol=1e-6)
    assert len(_contacts(res)) > 20
    findings = energy_checks(res, m, rel=1e-6)
    assert not findings, [str(f) for f in findings]


def test_a_surface_reached_at_another_events_instant_is_an_event_not_a_silent_flip():
    """``SurfaceSet.begin`` takes the sides of a new segment from the surfaces' signs. A surface that reached zero
    at the instant of another event (a friction event, a breakpoint, a twin surface's crossing) starts the next
    segment a round-off past it: its device's contact state changed there, and ``begin`` now returns the change
    for the drivers to record (two symmetric backlashes touching at once under a fixed-step method lost one of
    the two contact events that way, and later left a contact they had never entered). None at a run's start."""
    from types import SimpleNamespace
    from regmech.hybrid.surfaces import SurfaceSet
    g = np.array([0.3, -0.2, 0.5])
    c = SimpleNamespace(n_surf=3, surface_owner=[("bl1", 1), ("bl1", -1), ("bl2", 1)],
                        surface_values=lambda t, y: g.copy(), surface_kinds={})
    s = SurfaceSet(c)
    s.reset()
    assert s.begin(0.0, None) == []                         # the run's start: the states as they are
    assert s.states() == {"bl1": 1, "bl2": 1}
    g[:] = [0.3, -0.2, -1e-17]                              # bl2's surface a round-off past zero at a restart
    assert s.begin(0.1, None) == [("bl2", 1, 0, "contact")]
    assert s.begin(0.2, None) == []                         # reported once
    s.cross([0])                                            # a crossing keeps the side it gave (no second report)
    g[:] = [1e-17, -0.2, -1e-17]
    assert s.begin(0.3, None) == []
    s.reset()
    assert s.begin(0.0, None) == []
