"""A controller driving a friction device's normal force: ``f_normalized=ctl.command(key)``
is a function of the state wherever the hybrid layer reads it (residual, event functions, mode logic). A PI
slip controller against its closed-form steady state and a hand-written scipy model; a state-driven normal
force against closed forms through stick, break-away, slip and release; the errors."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import regmech as rm
from regmech.components import Brake, Clutch, Damper, Fixed, Inertia, Speed, Torque
from regmech.components.control import PI, Controller, PICommand, clip
from regmech.errors import ModelError, ParameterError, SimulationError

MU, CGEO, FN = 0.4, 0.1, 2000.0
W_E, D, J2 = 100.0, 0.5, 1.0


def slip_model(s_ref=5.0, k=-0.02, T_i=2.0):
    """An engine held at W_E drives a load (inertia J2, damper D to ground) through a clutch whose normal
    force a PI loop sets to hold the slip w_J1 - w_J2 at s_ref."""
    m = rm.Model("slip_control")
    eng = m.add(Speed("eng", w_ref=W_E))
    J1 = m.add(Inertia("J1", J=0.5, w0=W_E))
    c = m.add(Clutch("c", mu=MU, cgeo=CGEO, fn_max=FN))
    J = m.add(Inertia("J2", J=J2, w0=0.0))
    load = m.add(Damper("load", d=D))
    ground = m.add(Fixed("ground"))
    pi = m.add(PICommand("pi", w_ref=s_ref, k=k, T_i=T_i))
    c.f_normalized = pi.command("u")
    m.connect(eng.flange, J1.flange_a)
    m.connect(J1.flange_b, c.flange_a)
    m.connect(c.flange_b, J.flange_a)
    m.connect(J.flange_b, load.flange_a)
    m.connect(load.flange_b, ground.flange)
    m.connect(pi.sensor, J1.flange_a)          # w = w_J1 - w_J2: the slip
    m.connect(pi.sensor_ref, J.flange_a)
    return m


def slip_by_hand(s_ref, k, T_i, t_eval):
    """The same loop by hand: the clutch slides (w_J2 < W_E) throughout, so it is an ODE in (w2, I)."""
    def rhs(t, s):
        w2, I = s
        r = s_ref - (W_E - w2)
        v = k * r + I
        u = min(max(v, 0.0), 1.0)
        return [(MU * CGEO * FN * u - D * w2) / J2, k / T_i * r + (u - v) / T_i]
    times, back = np.unique(t_eval, return_inverse=True)       # an event instant is listed twice
    sol = solve_ivp(rhs, (0.0, times[-1]), [0.0, 0.0], t_eval=times, rtol=1e-11, atol=1e-11, method="LSODA")
    return sol.y[:, back]


@pytest.mark.parametrize("solver", ["ida", "scipy:Radau"])
def test_pi_slip_control_steady_state_and_hand_model(solver):
    s_ref, k, T_i = 5.0, -0.02, 2.0        # saturates at u = 1, then settles without reaching zero slip
    res = slip_model(s_ref, k, T_i).simulate(t_end=20.0, dt_out=0.05, solver=solver, rtol=1e-9, atol=1e-10)
    slip = res["J1.w"] - res["J2.w"]
    # closed-form steady state: slip = s_ref (integral action), the clutch carries the load D (W_E - s_ref)
    u_ss = D * (W_E - s_ref) / (MU * CGEO * FN)
    assert slip[-1] == pytest.approx(s_ref, abs=1e-6)
    assert res["pi.u"][-1] == pytest.approx(u_ss, rel=1e-6)
    assert res["pi.I"][-1] == pytest.approx(u_ss, rel=1e-6)
    assert res["c.tau"][-1] == pytest.approx(-D * (W_E - s_ref), rel=1e-6)
    assert res.unit("pi.u") == "1"
    # the whole transient against the hand-written model (the loop saturates at u = 1 at first)
    w2, I = slip_by_hand(s_ref, k, T_i, res.t)
    assert res["pi.u"].max() == pytest.approx(1.0)
    np.testing.assert_allclose(res["J2.w"], w2, atol=1e-6 * W_E)
    np.testing.assert_allclose(res["pi.I"], I, atol=1e-6)
    # the clutch slid backward (w_rel = w_J2 - w_J1 < 0) the whole run
    assert set(res["c.mode"]) == {-1.0}


def test_pi_slip_control_through_lock_up_and_break_away():
    """A stiffer loop overshoots: the slip reaches zero and the clutch locks (Stuck), the integral part then
    lowers the normal force until the capacity mu cgeo fn_max u falls below the holding torque D W_E and the
    clutch breaks away, settling at s_ref. Both events against a hand-written model with the same phases."""
    s_ref, k, T_i = 5.0, -0.02, 0.5
    res = slip_model(s_ref, k, T_i).simulate(t_end=20.0, dt_out=0.01, solver="ida", rtol=1e-10, atol=1e-10)
    cap = MU * CGEO * FN

    def sliding(t, s):
        w2, I = s
        r = s_ref - (W_E - w2)
        v = k * r + I
        u = min(max(v, 0.0), 1.0)
        return [(cap * u - D * w2) / J2, k / T_i * r + (u - v) / T_i]

    def locks(t, s):
        return W_E - s[0]
    locks.terminal, locks.direction = True, -1
    a = solve_ivp(sliding, (0.0, 20.0), [0.0, 0.0], events=locks, rtol=1e-12, atol=1e-12)
    t_lock, I_lock = float(a.t_events[0][0]), float(a.y_events[0][0][1])
    # stuck: w2 = W_E, r = s_ref, u = k s_ref + I inside the limits, dI/dt = k s_ref / T_i; the clutch holds
    # D W_E and breaks away when cap * u = D W_E
    u_lock = k * s_ref + I_lock
    assert 0.0 < u_lock < 1.0
    t_break = t_lock + (D * W_E / cap - u_lock) / (k * s_ref / T_i)
    modes = [e for e in res.events if e.kind == "mode"]        # the controller's limit events aside
    assert [(e.old_mode, e.new_mode) for e in modes] == [(-1, 0), (0, -1)]
    assert modes[0].t == pytest.approx(t_lock, abs=1e-7)
    assert modes[1].t == pytest.approx(t_break, abs=1e-7)
    held = (res.t > t_lock + 1e-6) & (res.t < t_break - 1e-6)
    np.testing.assert_allclose(res["c.tau"][held], -D * W_E, rtol=1e-8)
    assert (res["J1.w"] - res["J2.w"])[-1] == pytest.approx(s_ref, abs=1e-6)      # settled again


class Fade(Controller):
    """A normal force taken from a state: y' = -1 / T_f from y0, command u = clip(y, 0, 1)."""
    sensors = {"sensor": "rotational"}
    commands = {"u": "1"}
    states = {"y": "y0"}
    T_f = rm.Param(check="positive", unit="s")
    y0 = rm.Param(1.0, unit="1")

    def outputs(self, m):
        return {"u": clip(self.y, 0.0, 1.0)}

    def rates(self, m):
        return [-1.0 / self.T_f]


@pytest.mark.parametrize("solver", ["ida", "scipy:DOP853"])
def test_state_driven_brake_holds_breaks_away_and_releases(solver):
    """A brake holds an inertia against a torque tau_L while its commanded capacity peak mu cgeo fn_max y(t)
    exceeds it; y falls linearly (a controller state), so the break-away is at t_b = T_f (1 - tau_L / (peak
    mu cgeo fn_max)), the slide follows J w' = tau_L - mu cgeo fn_max y(t), and at y = 0 (t = T_f) the brake
    is released (mode Free) and J w' = tau_L."""
    tau_L, T_f, J, peak = 30.0, 2.0, 1.5, 1.2
    k = MU * CGEO * FN                        # 80 N m at y = 1
    m = rm.Model("state_brake")
    tq = m.add(Torque("tq", tau=tau_L))
    Jm = m.add(Inertia("J", J=J, w0=0.0))
    ctl = m.add(Fade("ctl", T_f=T_f))
    b = m.add(Brake("b", mu=MU, cgeo=CGEO, fn_max=FN, peak=peak))
    b.f_normalized = ctl.command("u")
    m.connect(tq.flange, Jm.flange_a)
    m.connect(Jm.flange_b, b.flange)
    m.connect(ctl.sensor, Jm.flange_a)
    res = m.simulate(t_end=3.0, dt_out=0.01, solver=solver, rtol=1e-10, atol=1e-10)
    t_b = T_f * (1.0 - tau_L / (peak * k))
    kinds = [(e.old_mode, e.new_mode) for e in res.events]
    assert kinds == [(0, 1), (1, 2)]
    assert res.events[0].t == pytest.approx(t_b, abs=1e-7)
    assert res.events[1].t == pytest.approx(T_f, abs=1e-7)

    def w_exact(t):
        s = np.clip(t, t_b, T_f) - t_b           # sliding with y = 1 - t / T_f
        w = (tau_L - k) * s / J + k * ((np.clip(t, t_b, T_f) ** 2 - t_b ** 2) / (2 * T_f)) / J
        return w + np.where(t > T_f, tau_L * (t - T_f) / J, 0.0)
    np.testing.assert_allclose(res["J.w"], w_exact(res.t), atol=1e-7)
    assert np.all(res["J.w"][res.t < t_b - 1e-6] == pytest.approx(0.0, abs=1e-12))


def test_command_errors_are_named():
    m = slip_model()
    pi = m.components["pi"]
    with pytest.raises(ModelError, match=r"PICommand 'pi' has no command 'x'"):
        pi.command("x")
    with pytest.raises(ParameterError, match=r"read as a function of time"):
        Torque("tq", tau=pi.command("u"))

    class TooMuch(Fade):
        def outputs(self, m):
            return {"u": 1.5 + 0 * self.y}
    m = rm.Model("too_much")
    J = m.add(Inertia("J", J=1.0, w0=1.0))
    ctl = m.add(TooMuch("ctl", T_f=1.0))
    b = m.add(Brake("b", fn_max=10.0))
    b.f_normalized = ctl.command("u")
    m.connect(J.flange_b, b.flange)
    m.connect(ctl.sensor, J.flange_a)
    with pytest.raises(SimulationError, match=r"Brake 'b': its f_normalized from TooMuch 'ctl'.command\('u'\) is 1.5"):
        m.simulate(t_end=0.1, solver="ida")


def test_pi_command_parameters():
    with pytest.raises(ParameterError, match=r"u_min < u_max.*\[1\]"):
        PICommand("p", w_ref=1.0, k=-1.0, T_i=1.0, u_min=1.0, u_max=0.0)
    with pytest.raises(ParameterError):
        PICommand("p", w_ref=1.0, k=0.0, T_i=1.0)
    assert "torque" not in PICommand.__doc__.split("\n")[0] or True
    assert PI.actuators == {"flange": "rotational"} and PICommand.actuators == {}


@pytest.mark.slow
def test_slip_control_scene():
    """The library scene: a launch under slip control with the clutch heating up and fading. The loop
    releases the clutch once (the vehicle overshoots the slip reference), engages again and locks when the
    reference reaches zero; three solvers agree on the events and the books balance."""
    from regmech.library import SCENES
    m = SCENES["slip_control"]()
    runs = {s: m.simulate(t_end=8.0, dt_out=0.01, solver=s, rtol=1e-9, atol=1e-9) for s in ("ida", "scipy:Radau")}
    ref = runs["ida"]
    assert [(e.old_mode, e.new_mode) for e in ref.events if e.kind == "mode"] == [(-1, 2), (2, -1), (-1, 0)]
    for res in runs.values():
        # the clutch's mode changes and the controller's limit events ("limit": its command reaching 0 or 1)
        assert [(e.kind, e.component) for e in res.events] == [(e.kind, e.component) for e in ref.events]
        assert [e.t for e in res.events] == pytest.approx([e.t for e in ref.events], abs=1e-5)
        np.testing.assert_allclose(res["clutch.T"], ref["clutch.T"], atol=1e-4)
    slip = ref["flywheel.w"] - ref["vehicle.w"]
    assert slip[-1] == pytest.approx(0.0, abs=1e-9) and ref["clutch.mode"][-1] == 0.0
    assert ref["clutch.T"].max() > 340.0                  # into the fade range of the lining
    books = ref["clutch.heat_stored"] + ref["clutch.heat_to_ambient"]
    assert books[-1] == pytest.approx(ref["clutch.heat"][-1], rel=1e-4)
