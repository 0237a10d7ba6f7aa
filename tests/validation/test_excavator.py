"""EKG-5A two-motor swing drive (REFERENCES.md [004]): start to 10 % of nominal speed.

Checks the scene against an independent scipy model of the paper's equations,
the qualitative result of the paper (the play closes, the elastic torques
oscillate and settle, the play opens and closes again, the speed settles at the
target) and the energy balance from the electrical input to the mechanical sinks.
"""

import warnings

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid, solve_ivp

from regmech.library import SCENES
from regmech.library.excavator import W_NOMINAL, excavator_swing

T_END = 3.0
# the defaults of excavator_swing, restated for the independent reference model
J_M, J_2, C_S, DPHI, BETA, M_C2, PEAK, R_A, T_A, C_M = 2.5, 50.0, 1500.0, 0.08, 10.0, 400.0, 1.1, 0.2, 0.05, 5.35
W_TARGET = 0.1 * W_NOMINAL
U_TARGET = 2 * C_M * W_TARGET + R_A * M_C2 / (2 * C_M)


@pytest.fixture(scope="module")
def run():
    model = excavator_swing()
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # default IDA settings must run without any warning
        res = model.simulate(T_END, dt_out=1e-3)
    return model, res


def dead_zone(phi):
    return np.where(np.abs(phi) <= DPHI / 2, 0.0, phi - np.sign(phi) * DPHI / 2)


def reference(t_eval):
    """The paper's equations with scipy: turntable held until the shafts' torque on it
    exceeds the break-away torque PEAK*M_C2, then sliding forward (it never stops)."""
    def u(t):
        return U_TARGET * min(t / 0.5, 1.0)

    def rhs(t, y, held):
        i, p1, w1, p2, w2, p0, w0 = y
        m1, m2 = C_S * dead_zone(p1 - p0), C_S * dead_zone(p2 - p0)
        d1, d2 = BETA * (w1 - w0), BETA * (w2 - w0)
        di = ((u(t) - C_M * w1 - C_M * w2) / R_A - i) / T_A
        dw0 = 0.0 if held else (m1 + m2 + d1 + d2 - M_C2) / J_2
        return [di, w1, (C_M * i - m1 - d1) / J_M, w2, (C_M * i - m2 - d2) / J_M, w0, dw0]

    def breaks_away(t, y, held):
        i, p1, w1, p2, w2, p0, w0 = y
        return C_S * (dead_zone(p1 - p0) + dead_zone(p2 - p0)) + BETA * (w1 + w2 - 2 * w0) - PEAK * M_C2
    breaks_away.terminal, breaks_away.direction = True, 1
    opts = dict(method="DOP853", rtol=1e-11, atol=1e-11, max_step=1e-3)
    first = solve_ivp(rhs, (0, T_END), np.zeros(7), args=(True,), events=breaks_away, dense_output=True, **opts)
    t_break = first.t_events[0][0]
    second = solve_ivp(rhs, (t_break, T_END), first.y_events[0][0], args=(False,), dense_output=True, **opts)
    y = np.where(t_eval <= t_break, first.sol(np.minimum(t_eval, t_break)), second.sol(np.maximum(t_eval, t_break)))
    return t_break, y


def test_registered_as_scene():
    assert SCENES["excavator_swing"] is excavator_swing


def test_matches_the_papers_equations_solved_by_scipy(run):
    model, res = run
    t_break, y = reference(res.t)
    ev = [e for e in res.events if e.component == "swing_friction"]
    assert [(e.old_mode, e.new_mode) for e in ev] == [(0, 1)]       # held, then slides forward for good
    assert ev[0].t == pytest.approx(t_break, abs=1e-6)
    assert np.max(np.abs(res["armature.i"] - y[0])) < 0.01           # A, of ~150 A peak (measured 1.2e-3)
    for k, j in ((1, 2), (2, 4)):
        assert np.max(np.abs(res[f"motor_{k}.w"] - y[j])) < 5e-4     # rad/s, of ~9 rad/s (5.7e-5)
        assert np.max(np.abs(res[f"backlash_{k}.tau"] - C_S * dead_zone(y[j - 1] - y[5]))) < 0.02   # N m (1.7e-3)
    assert np.max(np.abs(res["turntable.w"] - y[6])) < 5e-5    # (2.9e-6)


def test_play_closes_torques_oscillate_and_settle_at_the_target_speed(run):
    model, res = run
    t = res.t
    w2, tau, phi = res["turntable.w"], res["backlash_1.tau"], res["backlash_1.phi_rel"]
    assert np.allclose(res["motor_1.w"], res["motor_2.w"]) and np.allclose(tau, res["backlash_2.tau"])
    # contact changes: |phi_rel| crossing the half play
    contact = np.abs(phi) > DPHI / 2
    changes = t[1:][np.diff(contact.astype(int)) != 0]
    assert len(changes) >= 3                                         # closes, opens, closes again
    assert changes[0] < 0.2                                          # the motors first cross the play
    opened = (t > changes[1]) & (t < changes[2])
    assert np.all(tau[opened] == 0.0) and contact[-1]               # no torque while open; in contact at the end
    t_break = next(e.t for e in res.events if e.component == "swing_friction")
    assert changes[0] < t_break                                      # the turntable is held while the play closes
    assert np.max(np.abs(w2[t < t_break])) < 1e-12
    # elastic torques: a peak far above the end value, decaying oscillation, end at M_c2/2 each
    m_end = M_C2 / 2
    assert tau.max() > 3 * m_end
    early, late = (t > 0.5) & (t < 1.5), t > T_END - 0.5
    assert np.ptp(tau[late]) < 0.2 * np.ptp(tau[early])
    assert tau[-1] == pytest.approx(m_end, rel=0.02)
    assert res["armature.i"][-1] == pytest.approx(M_C2 / (2 * C_M), rel=0.02)
    assert w2[-1] == pytest.approx(W_TARGET, rel=0.01)
    assert np.all(w2[t > t_break] > 0)


def test_energy_balance_from_the_supply_to_the_sinks(run):
    model, res = run
    t = res.t
    el = {"p_in": res["armature.p_el"], "p_copper": res["armature.p_loss"], "magnetic": res["armature.magnetic"],
          "p_mech": res["armature.p_mech"]}
    assert np.allclose(el["p_mech"], -res["armature.power"], rtol=1e-12, atol=1e-9)   # the source's work

    def integral(p):
        return cumulative_trapezoid(p, t, initial=0.0)
    supplied = integral(el["p_in"]) - integral(el["p_copper"]) - el["magnetic"]      # to the shafts
    mechanical = integral(el["p_mech"])
    kinetic = sum(res[f"{n}.kinetic"] for n in ("motor_1", "motor_2", "turntable"))
    elastic = res["backlash_1.potential"] + res["backlash_2.potential"]
    dissipated = integral(res["damper_1.power"] + res["damper_2.power"] + res["swing_friction.power"])
    scale = integral(el["p_in"])[-1]
    assert scale > 1e4                                                               # J
    # electrical side: u i = R i^2 + d/dt(L i^2/2) + mechanical power; mechanical side: its sinks
    # measured 2.2e-7 and 3.3e-7 of the input: the trapezoidal quadrature on the 1 ms grid
    assert np.max(np.abs(supplied - mechanical)) < 2e-6 * scale
    assert np.max(np.abs(mechanical - kinetic - elastic - dissipated)) < 2e-6 * scale
    assert dissipated[-1] > 0.5 * mechanical[-1]                 # friction at 10 % speed takes most of it


def _user_written_scene():
    """The scene as it was before ``SeriesDCMotors`` existed: the armature a user-defined device in the
    paper's notation (T_a = L/R, C_k the motor constants)."""
    import regmech as rm
    from regmech.components import Backlash, BearingFriction, Damper, Inertia
    from regmech.ports import ROTATIONAL
    from regmech.signals import Ramp

    class ArmatureCircuit(rm.Device):
        kind = "compliant"
        is_source = True
        states = {"i": "i0"}
        flanges = (("motor_1", ROTATIONAL), ("motor_2", ROTATIONAL), ("support", ROTATIONAL, True))
        rel_names = {ROTATIONAL: (None, None, None, None)}
        u_a = rm.Param(check="signal", unit="V")
        R_a = rm.Param(check="positive", unit="Ohm")
        T_a = rm.Param(check="positive", unit="s")
        C_1 = rm.Param(check="positive", unit="V s/rad")
        C_2 = rm.Param(check="positive", unit="V s/rad")
        i0 = rm.Param(0.0, unit="A")

        def rows(self):
            return [{"motor_1": 1.0, "support": -1.0}, {"motor_2": 1.0, "support": -1.0}]

        def laws(self, e, de):
            return [-self.C_1 * self.i, -self.C_2 * self.i]

        def derivatives(self, e, de):
            return [((self.u_a - self.C_1 * de[0] - self.C_2 * de[1]) / self.R_a - self.i) / self.T_a]

    m = rm.Model("excavator_user_armature")
    m.add(ArmatureCircuit("armature", u_a=Ramp(height=U_TARGET, duration=0.5), R_a=R_A, T_a=T_A, C_1=C_M, C_2=C_M))
    turntable = m.add(Inertia("turntable", J=J_2, phi0=0.0, w0=0.0))
    friction = m.add(BearingFriction("swing_friction", tau_table=[(0.0, M_C2)], peak=PEAK))
    m.connect(turntable.flange_b, friction.flange)
    for k in (1, 2):
        motor = m.add(Inertia(f"motor_{k}", J=J_M, phi0=0.0, w0=0.0))
        shaft = m.add(Backlash(f"backlash_{k}", c=C_S, b=DPHI))
        damper = m.add(Damper(f"damper_{k}", d=BETA))
        m.connect(m["armature"].get_flange(f"motor_{k}"), motor.flange_a)
        for dev in (shaft, damper):
            m.connect(turntable.flange_a, dev.flange_a)
            m.connect(dev.flange_b, motor.flange_b)
    return m


def test_series_dc_motors_reproduce_the_user_written_armature(run):
    """SeriesDCMotors states the same equations as the scene's former user-written device: the two runs
    agree to the solver's tolerance (same events, same current and speeds)."""
    model, res = run
    old = _user_written_scene().simulate(T_END, dt_out=1e-3)

    def per_device(r):      # each device's sequence (the two backlashes touch at one instant, in either order)
        seq = {}
        for e in r.events:
            seq.setdefault(e.component, []).append((e.kind, e.old_mode, e.new_mode))
        return seq
    assert per_device(old) == per_device(res)

    def grid(r):            # the rows at the output instants (the events' rows lie between them)
        return np.abs(r.t / 1e-3 - np.round(r.t / 1e-3)) < 1e-9
    g_old, g_res = grid(old), grid(res)
    np.testing.assert_allclose(old.t[g_old], res.t[g_res], atol=1e-12)
    assert np.max(np.abs(old["armature.i"][g_old] - res["armature.i"][g_res])) < 0.01          # A, of ~150 A
    for name in ("motor_1.w", "motor_2.w", "turntable.w"):
        assert np.max(np.abs(old[name][g_old] - res[name][g_res])) < 5e-4                      # rad/s, of ~9 rad/s
    assert np.allclose(res["armature.tau_1"], C_M * res["armature.i"])
