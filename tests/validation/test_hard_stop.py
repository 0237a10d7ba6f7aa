"""HardStop / LinearHardStop (rigid impacts with a coefficient of restitution, holding contact, the Zeno rule)
against closed forms, on IDA, scipy:DOP853 and the default call, with their energy books."""

import math

import numpy as np
import pytest

import regmech as rm
from regmech.bench.fuzz import energy_checks
from regmech.components import (Fixed, Force, HardStop, IdealGear, Inertia, LinearHardStop, Mass, Spring,
                                Torque)
from regmech.errors import ModelError, ParameterError, RegmechError, SimulationError
from regmech.signals import Ramp

IDA = dict(solver="ida", rtol=1e-10, atol=1e-12)
DOP = dict(solver="scipy:DOP853", rtol=1e-10, atol=1e-12)
RUNS = {"ida": IDA, "dop853": DOP, "auto": {}}
#: impact times: tight runs to 1e-8 s; the default call (accuracy contract at its default) to 1e-5 s
T_TOL = {"ida": 1e-8, "dop853": 1e-8, "auto": 1e-5}

J, TAU, UPPER = 2.0, 4.0, 0.5          # a = 2 rad/s^2 from rest at phi = 0 towards the upper limit
A = TAU / J


def _inertia_model(e, tau=TAU, lower=-1.0, upper=UPPER):
    m = rm.Model("hard_stop")
    body = m.add(Inertia("J", J=J, phi0=0.0, w0=0.0))
    drive = m.add(Torque("drive", tau=tau))
    stop = m.add(HardStop("stop", lower=lower, upper=upper, e=e))
    m.connect(drive.flange, body.flange_a)
    m.connect(body.flange_b, stop.flange)
    return m


def _closed_form_bounces(e, n):
    """Impact times and speeds into the stop of a body from rest under constant acceleration A."""
    t1 = math.sqrt(2 * UPPER / A)
    w = A * t1
    times, speeds = [t1], [w]
    for _ in range(n - 1):
        times.append(times[-1] + 2 * e * speeds[-1] / A)       # up and down again at -e w
        speeds.append(e * speeds[-1])
    return np.array(times), np.array(speeds)


def _rows_at(res, name, t):
    """The values of ``name`` on the rows at instant ``t`` (before and after an event)."""
    k = np.nonzero(np.abs(res.t - t) <= 1e-12 * max(1.0, t))[0]
    return res[name][k]


def _books(res, sources=("drive",), bodies=("J",), stored=()):
    """kinetic + stored + dissipated - work in, at every row [J], and the energy scale."""
    kin = sum(res[f"{b}.kinetic"] for b in bodies)
    pot = sum((res[f"{s}.potential"] for s in stored), np.zeros_like(res.t))
    work = sum((-res.integral(f"{s}.power") for s in sources), np.zeros_like(res.t))
    books = (kin - kin[0]) + (pot - pot[0]) + res["stop.heat"] - work
    return books, max(float(kin.max()), float(np.abs(work).max()), 1e-300)


@pytest.mark.parametrize("run", list(RUNS))
def test_bouncing_inertia_closed_form(run):
    """e = 0.8: impact times from constant acceleration between impacts, rebound speed -e times the speed in,
    each impact's loss (1 - e^2) J w^2 / 2 booked in stop.heat, books closed."""
    e, n = 0.8, 6
    res = _inertia_model(e).simulate(t_end=4.6, dt_out=1e-2, **RUNS[run])
    impacts = [ev for ev in res.events if ev.kind == "impact"]
    times, speeds = _closed_form_bounces(e, n)
    assert len(impacts) == n                       # 4.6 s holds six impacts (the seventh at 4.88 s)
    assert all(ev.component == "stop" and ev.old_mode == 0 and ev.new_mode == 1 for ev in impacts)
    np.testing.assert_allclose([ev.t for ev in impacts], times, rtol=0, atol=T_TOL[run])
    for ev, w in zip(impacts, speeds):
        before, after = _rows_at(res, "J.w", ev.t)[[0, -1]]
        assert before == pytest.approx(w, rel=1e-6 if run == "auto" else 1e-9)
        # -e w to the restart's nudge (``hybrid.impacts``: 1e-12 rad inside the limit, its load's work taken from
        # the rebound: here 2 a delta / (e w)^2 < 1e-11)
        assert after == pytest.approx(-e * before, rel=1e-10)
        assert ev.value == pytest.approx((1 - e ** 2) * J * before ** 2 / 2, rel=1e-10)
    assert not [ev for ev in res.events if ev.kind == "contact"]      # never comes to rest here
    assert np.all(res["J.phi"] <= UPPER + 1e-9)
    books, scale = _books(res)
    assert np.abs(books).max() <= (1e-9 if run != "auto" else 1e-5) * scale
    heat = res["stop.heat"]
    assert heat[-1] == pytest.approx(sum(ev.value for ev in impacts), rel=1e-12)
    assert np.all(np.diff(heat) >= 0)


@pytest.mark.parametrize("run", list(RUNS))
def test_plastic_impact_holds_and_releases(run):
    """e = 0: at the upper limit the body stops and the contact holds with the applied torque (a ramp
    4 - 2 (t - 1) N m from t = 1 s), releases where it passes zero (t = 3 s), the body swings to the lower limit
    (phi = 0.5 - (t - 3)^3 / 6 up to t = 5 s, then -2 rad/s^2) and holds there with -4 N m."""
    tau = Ramp(height=-8.0, duration=4.0, start_time=1.0, offset=4.0)
    res = _inertia_model(0.0, tau=tau).simulate(t_end=5.5, dt_out=1e-2, **RUNS[run])
    t1 = math.sqrt(2 * UPPER / A)
    phi5, w5 = UPPER - 8.0 / 6, -2.0
    s = -1.0 + math.sqrt(1.0 + (phi5 + 1.0))                  # phi5 + w5 s - s^2 = -1 with w5 = -2
    t_low = 5.0 + s
    got = [(ev.kind, ev.old_mode, ev.new_mode) for ev in res.events if ev.kind != "mode"]
    assert got == [("impact", 0, 1), ("contact", 0, 1), ("contact", 1, 0), ("impact", 0, -1), ("contact", 0, -1)]
    ev = [e for e in res.events if e.kind != "mode"]
    tol = T_TOL[run]
    assert ev[0].t == pytest.approx(t1, abs=tol) and ev[1].t == ev[0].t
    assert ev[0].value == pytest.approx(J * (A * t1) ** 2 / 2, rel=1e-9)          # all of it
    assert ev[2].t == pytest.approx(3.0, abs=max(tol, 1e-9))                         # the contact force's zero
    assert ev[3].t == pytest.approx(t_low, abs=tol * 10)
    hold = (res.t > t1 + 1e-6) & (res.t < 3.0 - 1e-6)
    assert hold.sum() > 100
    assert np.all(res["J.w"][hold] == pytest.approx(0.0, abs=1e-9))
    assert np.all(res["J.phi"][hold] == pytest.approx(UPPER, abs=1e-9))
    applied = np.where(res.t[hold] < 1.0, 4.0, 4.0 - 2.0 * (res.t[hold] - 1.0))
    np.testing.assert_allclose(res["stop.tau"][hold], applied, rtol=1e-7, atol=1e-7)
    free = (res.t > 3.0 + 1e-6) & (res.t < 5.0)
    np.testing.assert_allclose(res["J.phi"][free], UPPER - (res.t[free] - 3.0) ** 3 / 6, rtol=0,
                               atol=1e-5 if run == "auto" else 1e-8)
    assert np.all(res["stop.tau"][free] == 0.0)
    end = res.t > t_low + 1e-6
    np.testing.assert_allclose(res["stop.tau"][end], -4.0, rtol=1e-7)
    assert np.all(res["J.phi"][end] == pytest.approx(-1.0, abs=1e-9))
    books, scale = _books(res)
    assert np.abs(books).max() <= (1e-9 if run != "auto" else 1e-5) * scale


def _spring_pair(e):
    """J1 (hits the stop) joined to J2 by a spring; both start at 2 rad/s towards the upper limit at 0.3 rad."""
    m = rm.Model("pair")
    j1 = m.add(Inertia("J1", J=1.0, phi0=0.0, w0=2.0))
    j2 = m.add(Inertia("J2", J=2.0, phi0=0.0, w0=2.0))
    k = m.add(Spring("k", c=100.0))
    stop = m.add(HardStop("stop", lower=-0.3, upper=0.3, e=e))
    m.connect(j1.flange_b, k.flange_a)
    m.connect(k.flange_b, j2.flange_a)
    m.connect(j1.flange_a, stop.flange)
    return m


def test_two_inertias_spring_books_and_solvers_agree():
    """The impulse acts on J1 alone (the spring transmits no impulse): J2's speed and momentum are continuous at
    every impact, J1's speed jumps to -e times its value, the loss is (1 - e^2) J1 w1^2 / 2; kinetic + spring
    energy + stop.heat stays at its start value; IDA and DOP853 agree."""
    e = 0.7
    runs = {name: _spring_pair(e).simulate(t_end=3.0, dt_out=1e-3, **kw) for name, kw in (("ida", IDA), ("dop", DOP))}
    for name, res in runs.items():
        impacts = [ev for ev in res.events if ev.kind == "impact"]
        assert len(impacts) >= 5, name
        for ev in impacts:
            w1 = _rows_at(res, "J1.w", ev.t)
            w2 = _rows_at(res, "J2.w", ev.t)
            assert w2[-1] == pytest.approx(w2[0], rel=1e-12, abs=1e-12)
            # -e w1 to the spring's work over the restart's nudge: w+^2 = (e w1)^2 - 2 a delta, a < 100 rad/s^2
            if any(c.kind == "contact" and c.t == ev.t for c in res.events):
                # the Zeno rule: a rebound too small to rise above the restart's nudge becomes a contact
                assert w1[-1] == 0.0 and abs(w1[0]) < 1e-4 and ev.value == pytest.approx(w1[0] ** 2 / 2, rel=1e-9)
                continue
            assert w1[-1] * w1[0] < 0 and w1[-1] ** 2 == pytest.approx((e * w1[0]) ** 2, rel=1e-9, abs=1e-8)
            # to the work of the spring over the restart's nudge (1e-12 rad, < 100 N m): 1e-10 J
            assert ev.value == pytest.approx((1 - e ** 2) * 1.0 * w1[0] ** 2 / 2, rel=1e-10, abs=1e-10)
        books, scale = _books(res, sources=(), bodies=("J1", "J2"), stored=("k",))
        # measured: DOP853 < 1e-9, IDA 8.5e-9 of the scale (its global error over 3 s and 40 restarts at rtol 1e-10;
        # the impacts' books are exact: every jump of the kinetic energy is in stop.heat)
        assert np.abs(books).max() <= (2e-8 if name == "ida" else 2e-9) * scale, name
        assert res["stop.heat"][-1] > 0.3 * scale            # a large part of the energy went into the impacts
        assert not energy_checks(res, _spring_pair(e), rel=1e-8), name
    a, b = runs["ida"], runs["dop"]
    ta = [ev.t for ev in a.events if ev.kind == "impact"]
    tb = [ev.t for ev in b.events if ev.kind == "impact"]
    assert len(ta) == len(tb)
    np.testing.assert_allclose(ta, tb, rtol=0, atol=5e-7)        # measured: 1.04e-7 s at most (the 7th impact)
    for sig in ("J1.phi", "J2.phi", "J2.w", "stop.heat"):
        np.testing.assert_allclose(a.at(sig, [0.5, 1.5, 2.5]), b.at(sig, [0.5, 1.5, 2.5]), rtol=1e-6, atol=1e-7)


def test_impulse_through_a_gear():
    """A rigid gear (phi_a = 3 phi_b) between the stop's inertia and a second one: the impulse moves both, the
    gear stays exact (w_a = 3 w_b after the impact), the loss is that of the reflected inertia J_a + J_b / 9."""
    e = 0.5
    m = rm.Model("geared")
    ja = m.add(Inertia("Ja", J=1.0, phi0=0.0, w0=1.5))
    g = m.add(IdealGear("g", ratio=3.0))
    jb = m.add(Inertia("Jb", J=0.5))
    stop = m.add(HardStop("stop", lower=-0.2, upper=0.3, e=e))
    m.connect(ja.flange_b, g.flange_a)
    m.connect(g.flange_b, jb.flange_a)
    m.connect(ja.flange_a, stop.flange)
    for kw in (IDA, DOP):
        res = m.simulate(t_end=1.0, dt_out=1e-3, **kw)
        ev = [x for x in res.events if x.kind == "impact"]
        assert [x.new_mode for x in ev] == [1, -1]
        assert ev[0].t == pytest.approx(0.3 / 1.5, abs=1e-9)
        wa, wb = _rows_at(res, "Ja.w", ev[0].t), _rows_at(res, "Jb.w", ev[0].t)
        assert wa[-1] == pytest.approx(-e * 1.5, rel=1e-12) and wb[-1] == pytest.approx(wa[-1] / 3, rel=1e-12)
        assert wa[0] == pytest.approx(1.5, rel=1e-12) and wb[0] == pytest.approx(0.5, rel=1e-12)
        assert ev[0].value == pytest.approx((1 - e ** 2) * (1.0 + 0.5 / 9) * 1.5 ** 2 / 2, rel=1e-10)
        assert ev[1].t == pytest.approx(ev[0].t + 0.5 / (e * 1.5), abs=1e-9)


@pytest.mark.parametrize("run", ["ida", "dop853"])
def test_zeno_bounces_end_in_contact_at_the_series_limit(run):
    """e = 0.5 under a constant torque: infinitely many impacts in finite time. The stop goes to contact once the
    rebound is below 1e-6 of the first impact speed (at most ~21 impacts), at t1 + 2 e w1 / (a (1 - e)), and holds
    the applied torque from then on."""
    e = 0.5
    res = _inertia_model(e).simulate(t_end=3.0, dt_out=1e-2, **RUNS[run])
    impacts = [ev for ev in res.events if ev.kind == "impact"]
    contacts = [ev for ev in res.events if ev.kind == "contact"]
    t1 = math.sqrt(2 * UPPER / A)
    t_rest = t1 + 2 * e * A * t1 / (A * (1 - e))
    assert 15 <= len(impacts) <= 25
    assert len(contacts) == 1 and contacts[0].new_mode == 1
    # the sequence stops at a rebound w_r below ZENO_SPEED = 1e-6 of the first impact speed w1 or one that cannot
    # rise above the restart's nudge delta = 1e-12 rad (w_r <= sqrt(2 a delta) = 2e-6 rad/s): the flights left
    # out last 2 w_r / (a (1 - e)) = 4e-6 s in all, the nudges' work shortens the last ones by up to as much
    # again (the documented bound 4 w_r / (a (1 - e)) = 8e-6 s; measured 3.5e-6 s)
    w_r = max(HardStop.ZENO_SPEED * A * t1, math.sqrt(2 * A * 1e-12))
    assert t_rest - 4 * w_r / (A * (1 - e)) - 1e-9 <= contacts[0].t <= t_rest + 1e-9
    assert impacts[-1].t <= contacts[0].t
    after = res.t > t_rest + 1e-3
    np.testing.assert_allclose(res["stop.tau"][after], TAU, rtol=1e-9)
    assert np.all(res["J.w"][after] == 0.0) or np.abs(res["J.w"][after]).max() < 1e-9
    # all the kinetic energy of the first impact speed is dissipated in the end
    assert res["stop.heat"][-1] == pytest.approx(J * (A * t1) ** 2 / 2, rel=1e-9)
    books, scale = _books(res)
    assert np.abs(books).max() <= 1e-9 * scale


@pytest.mark.parametrize("form", ["class", "domain"])
def test_translational_hard_stop(form):
    """A 3 kg mass pushed up by 6 N (a = 2 m/s^2), starting at s = 0 with v = -1 m/s: it hits the lower limit
    (-0.2 m) at t = (1 - sqrt(0.2)) / 2 with v = -sqrt(0.2), rebounds at +e sqrt(0.2) and hits the upper one
    (0.25 m) after the time of s = -0.2 + v t + t^2 = 0.25."""
    e, m_, f = 0.6, 3.0, 6.0
    mod = rm.Model("linear_stop")
    body = mod.add(Mass("body", m=m_, s0=0.0, v0=-1.0))
    push = mod.add(Force("push", f=f))
    if form == "class":
        stop = mod.add(LinearHardStop("stop", lower=-0.2, upper=0.25, e=e))
    else:
        stop = mod.add(HardStop("stop", lower=-0.2, upper=0.25, e=e, domain="translational"))
    mod.connect(push.flange, body.flange_a)
    mod.connect(body.flange_b, stop.flange)
    t1 = (1 - math.sqrt(0.2)) / 2
    v1 = -math.sqrt(0.2)
    vr = -e * v1
    tau = (-vr + math.sqrt(vr ** 2 + 4 * 0.45)) / 2
    t2, v2 = t1 + tau, vr + 2 * tau
    for kw in (IDA, DOP):
        res = mod.simulate(t_end=t2 + 0.1, dt_out=1e-3, **kw)
        ev = [x for x in res.events if x.kind == "impact"]
        assert [x.new_mode for x in ev] == [-1, 1]
        assert ev[0].t == pytest.approx(t1, abs=1e-9) and ev[1].t == pytest.approx(t2, abs=1e-9)
        v = _rows_at(res, "body.v", ev[0].t)
        assert v[0] == pytest.approx(v1, rel=1e-9) and v[-1] == pytest.approx(vr, rel=1e-9)
        v = _rows_at(res, "body.v", ev[1].t)
        assert v[0] == pytest.approx(v2, rel=1e-9) and v[-1] == pytest.approx(-e * v2, rel=1e-9)
        assert res.unit("stop.f") == "N" and res.unit("stop.heat") == "J"
        assert res["stop.heat"][-1] == pytest.approx((1 - e ** 2) * m_ * (v1 ** 2 + v2 ** 2) / 2, rel=1e-9)
        books, scale = _books(res, sources=("push",), bodies=("body",))
        assert np.abs(books).max() <= 1e-9 * scale


def test_bad_parameters_and_starts_are_refused_by_name():
    for e in (-0.1, 1.5):
        with pytest.raises(ParameterError, match=r"HardStop 's'.*restitution e must lie in \[0, 1\]"):
            HardStop("s", lower=0.0, upper=1.0, e=e)
    for lo, hi in ((0.1, 0.1), (0.2, 0.1)):
        with pytest.raises(ParameterError, match="HardStop 's'.*lower < upper"):
            HardStop("s", lower=lo, upper=hi, e=0.5)
    with pytest.raises(ParameterError, match="LinearHardStop 's'.*lower < upper"):
        LinearHardStop("s", lower=1.0, upper=0.0, e=0.5)
    # a stop whose flange carries no mass
    m = rm.Model("massless")
    body = m.add(Inertia("J", J=1.0))
    drive = m.add(Torque("drive", tau=1.0))
    ground = m.add(Fixed("ground"))
    stop = m.add(HardStop("stop", lower=-1.0, upper=1.0, e=0.5))
    m.connect(drive.flange, body.flange_a)
    m.connect(stop.flange, ground.flange)
    with pytest.raises(ModelError, match="HardStop 'stop'.*carries no mass"):
        m.simulate(t_end=0.1, solver="ida")
    m = rm.Model("loose")
    m.add(Inertia("J", J=1.0))
    m.add(HardStop("stop", lower=-1.0, upper=1.0, e=0.5))
    with pytest.raises(RegmechError, match="stop.flange"):
        m.simulate(t_end=0.1, solver="ida")
    # start values outside the limits, or at a limit moving into it
    for phi0, w0, what in ((0.7, 0.0, "outside its limits"), (0.5, 1.0, "moving into it")):
        m = rm.Model("start")
        body = m.add(Inertia("J", J=1.0, phi0=phi0, w0=w0))
        stop = m.add(HardStop("stop", lower=-1.0, upper=0.5, e=0.5))
        m.connect(body.flange_b, stop.flange)
        for solver in ("ida", "scipy:DOP853"):
            with pytest.raises(SimulationError, match=f"HardStop 'stop'.*{what}"):
                m.simulate(t_end=0.1, solver=solver)
    # a translational stop names its coordinate and unit (the fuzz family hard_stop: "phi_rel" on a mass)
    m = rm.Model("start_linear")
    body = m.add(Mass("M", m=1.0, s0=0.7))
    stop = m.add(LinearHardStop("stop", lower=-1.0, upper=0.5, e=0.5))
    m.connect(body.flange_b, stop.flange)
    with pytest.raises(SimulationError, match=r"LinearHardStop 'stop' starts at s_rel = 0\.7 m, outside its limits"):
        m.simulate(t_end=0.1, solver="ida")


@pytest.mark.parametrize("solver", ["expm", "convolution", "rk4", "euler", "abm"])
def test_solvers_without_impacts_refuse_by_name(solver):
    with pytest.raises(SimulationError, match=f"solver '{solver}'.*HardStop 'stop'.*rigid impacts"):
        _inertia_model(0.8).simulate(t_end=1.0, dt_out=1e-2, solver=solver)


def test_a_hard_stop_added_after_a_run_is_refused_too():
    # the devices with impacts are found once per compiled system (a model change compiles it again)
    m = rm.Model("late_stop")
    body = m.add(Inertia("J", J=1.0, w0=1.0))
    m.simulate(t_end=0.1, dt_out=1e-2, solver="rk4", h=1e-2, tol=None)
    stop = m.add(HardStop("stop", lower=-1.0, upper=0.5, e=0.5))
    m.connect(body.flange_b, stop.flange)
    with pytest.raises(SimulationError, match="solver 'rk4'.*HardStop 'stop'.*rigid impacts"):
        m.simulate(t_end=0.1, dt_out=1e-2, solver="rk4", h=1e-2, tol=None)


def test_auto_never_picks_a_solver_that_refuses():
    res = _inertia_model(0.8).simulate(t_end=1.0, dt_out=1e-2)
    assert res.stats.solver in ("ida", "scipy:Radau", "scipy:DOP853")
    assert [ev.kind for ev in res.events] == ["impact"]


@pytest.mark.parametrize("kw", [IDA, DOP], ids=["ida", "dop853"])
def test_support_on_a_moving_body_momentum(kw):
    """The support on a free inertia: the impulse acts on both bodies, the total momentum J_A w_A + J_B w_B is
    unchanged by every impact, the relative speed jumps to -e times its value, kinetic energy + stop.heat stays
    at its start value. Relative motion 3 rad/s from phi_rel = 0: first impact at 0.2 / 3 s (upper), the
    next after (0.2 + 0.1) / (e 3) s (lower)."""
    e = 0.6
    m = rm.Model("free_pair")
    a = m.add(Inertia("A", J=1.0, phi0=0.0, w0=3.0))
    b = m.add(Inertia("B", J=2.0, phi0=0.0, w0=0.0))
    stop = m.add(HardStop("stop", lower=-0.1, upper=0.2, e=e))
    m.connect(a.flange_b, stop.flange)
    m.connect(stop.support, b.flange_a)
    res = m.simulate(t_end=1.0, dt_out=1e-3, **kw)
    ev = [x for x in res.events if x.kind == "impact"]
    assert [x.new_mode for x in ev] == [1, -1, 1, -1]
    assert ev[0].t == pytest.approx(0.2 / 3, abs=1e-9) and ev[1].t == pytest.approx(0.2 / 3 + 0.3 / (e * 3), abs=1e-9)
    p = res["A.w"] + 2.0 * res["B.w"]
    assert np.ptp(p) <= 1e-12 * 3
    for x in ev:
        w = _rows_at(res, "stop.w_rel", x.t)
        assert w[-1] == pytest.approx(-e * w[0], rel=1e-9)
        m_eff = 1.0 * 2.0 / 3.0
        assert x.value == pytest.approx((1 - e ** 2) * m_eff * w[0] ** 2 / 2, rel=1e-9)
    energy = res["A.kinetic"] + res["B.kinetic"] + res["stop.heat"]
    assert np.ptp(energy) <= 1e-10 * energy[0]


@pytest.mark.parametrize("kw", [IDA, DOP], ids=["ida", "dop853"])
def test_impact_reverses_a_sliding_brake(kw):
    """A brake (1 N m) and a hard stop (e = 0.3) on one inertia starting at the upper limit, pushed into it by
    2 N m: the brake gives its 1 N m and the stop holds the rest (holding in turn). At t = 0.5 s the drive turns
    to -4 N m: the stop releases, the body falls at -3 rad/s^2 and hits the lower limit at t = 1.5 s with
    -3 rad/s; the impulse reverses its slip, so the brake turns Forward at once (a = -5 rad/s^2), sticks
    for no time at 1.68 s and slides Backward; the second impact is sqrt(2 h / 3) later with h the rise."""
    from regmech.components import Brake
    from regmech.signals import Step
    e = 0.3
    m = rm.Model("brake_stop")
    j = m.add(Inertia("J", J=1.0, phi0=0.5, w0=0.0))
    drive = m.add(Torque("drive", tau=Step(height=-6.0, start_time=0.5, offset=2.0)))
    brake = m.add(Brake("brake", mu=0.5, fn_max=2.0, f_normalized=1.0))
    stop = m.add(HardStop("stop", lower=-1.0, upper=0.5, e=e))
    m.connect(drive.flange, j.flange_a)
    m.connect(j.flange_b, stop.flange)
    m.connect(j.flange_b, brake.flange)
    res = m.simulate(t_end=2.0, dt_out=1e-3, **kw)
    assert res.at("stop.tau", 0.2) == pytest.approx(1.0, rel=1e-9)
    assert res.at("brake.tau", 0.2) == pytest.approx(1.0, rel=1e-9)
    w_r = e * 3.0
    t_top = 1.5 + w_r / 5.0
    h = w_r ** 2 / (2 * 5.0)
    t2 = t_top + math.sqrt(2 * h / 3.0)
    got = [(x.component, x.kind, x.old_mode, x.new_mode) for x in res.events]
    assert got == [("brake", "mode", 1, -1), ("stop", "contact", 1, 0), ("stop", "impact", 0, -1),
                   ("brake", "mode", -1, 1), ("brake", "mode", 1, -1), ("stop", "impact", 0, -1),
                   ("brake", "mode", -1, 1), ("brake", "mode", 1, -1)]
    times = [x.t for x in res.events]
    np.testing.assert_allclose(times[:7], [0.5, 0.5, 1.5, 1.5, t_top, t2, t2], rtol=0, atol=1e-8)
    w = _rows_at(res, "J.w", 1.5)
    assert w[0] == pytest.approx(-3.0, rel=1e-9) and w[-1] == pytest.approx(w_r, rel=1e-9)


def test_two_stops_on_one_limit_the_first_takes_the_impact():
    """Two hard stops at the same limit of one inertia reach it at one instant: the first in model order takes the
    impact (w -> -e1 w); the second finds the body moving away and gives no impact (documented rule)."""
    m = rm.Model("two")
    body = m.add(Inertia("J", J=1.0, phi0=0.0, w0=1.0))
    s1 = m.add(HardStop("s1", lower=-1.0, upper=0.5, e=0.5))
    s2 = m.add(HardStop("s2", lower=-1.0, upper=0.5, e=0.9))
    m.connect(body.flange_b, s1.flange)
    m.connect(body.flange_b, s2.flange)
    for kw in (IDA, DOP):
        res = m.simulate(t_end=2.0, dt_out=1e-3, **kw)
        assert [(x.component, x.kind, x.t) for x in res.events] == [("s1", "impact", pytest.approx(0.5, abs=1e-9))]
        assert res.at("J.w", 1.0) == pytest.approx(-0.5, rel=1e-9)
        assert res["s2.heat"][-1] == 0.0 and res["s1.heat"][-1] == pytest.approx(0.375, rel=1e-9)


@pytest.mark.parametrize("kw", [IDA, DOP], ids=["ida", "dop853"])
def test_start_at_a_limit_holds_or_releases(kw):
    """Starting at rest on the upper limit: pushed into it (3 N m) the stop holds 3 N m from t = 0 (Stuck); pulled
    away (-3 N m) it lets go at once and the body (J = 1) reaches the lower limit 1.5 rad away at t = 1 s."""
    for tau, holds in ((3.0, True), (-3.0, False)):
        m = rm.Model("start_at_limit")
        body = m.add(Inertia("J", J=1.0, phi0=0.5, w0=0.0))
        drive = m.add(Torque("drive", tau=tau))
        stop = m.add(HardStop("stop", lower=-1.0, upper=0.5, e=0.5))
        m.connect(drive.flange, body.flange_a)
        m.connect(body.flange_b, stop.flange)
        res = m.simulate(t_end=1.2, dt_out=1e-2, **kw)
        if holds:
            assert not res.events and np.all(res["stop.tau"] == pytest.approx(3.0, rel=1e-12))
            assert np.all(res["J.phi"] == pytest.approx(0.5, abs=1e-12))
        else:
            assert res["stop.tau"][0] == 0.0 and res["stop.mode"][0] == 2
            ev = [(x.kind, x.new_mode) for x in res.events]
            assert ev == [("impact", -1)] and res.events[0].t == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("solver", ["scipy:RK45", "scipy:RK23", "scipy:Radau", "scipy:BDF", "scipy:LSODA"])
def test_every_scipy_solver_locates_the_impacts(solver):
    """The other ODE-form solvers share the driver's event location and impulse: the first three impact times of
    the e = 0.8 bounce within 1e-6 s at rtol 1e-9 (at their default rtol 1e-6: BDF up to 5.7e-6 s, LSODA 2.3e-6 s off)."""
    res = _inertia_model(0.8).simulate(t_end=3.0, dt_out=1e-2, solver=solver, rtol=1e-9, atol=1e-11)
    times, _ = _closed_form_bounces(0.8, 3)
    np.testing.assert_allclose([ev.t for ev in res.events if ev.kind == "impact"], times, rtol=0, atol=1e-6)
