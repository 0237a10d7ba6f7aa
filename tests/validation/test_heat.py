"""Heat exported by friction and loss elements: ``heat_flow`` [W] and the accumulated ``heat`` [J], against
closed forms (a brake stopping an inertia, a clutch locking two inertias) and the energy books."""

import numpy as np
import pytest

import regmech as rm
from regmech.components import Brake, Clutch, Damper, Fixed, Inertia, Shaft, SpringDamper
from regmech.components.heat import accumulated

IDA = dict(solver="ida", rtol=1e-9, atol=1e-10)


def test_brake_turns_the_kinetic_energy_into_heat():
    """Constant kinetic torque T: w = w0 - T t / J, heat_flow = T w, heat = T (w0 t - T t^2 / (2 J)) until it
    sticks at t_s = J w0 / T, then J w0^2 / 2."""
    J, w0, mu, cgeo, fn = 2.0, 30.0, 0.4, 0.1, 500.0
    T = mu * cgeo * fn
    m = rm.Model("brake_heat")
    disc = m.add(Inertia("disc", J=J, phi0=0.0, w0=w0))
    brake = m.add(Brake("brake", mu=mu, cgeo=cgeo, fn_max=fn, peak=1.2))
    m.connect(disc.flange_b, brake.flange)
    res = m.simulate(t_end=4.0, dt_out=1e-2, **IDA)
    t_s = J * w0 / T
    tt = np.minimum(res.t, t_s)
    exact = T * (w0 * tt - T * tt ** 2 / (2 * J))
    assert res["brake.heat"][-1] == pytest.approx(J * w0 ** 2 / 2, rel=1e-6)
    assert np.max(np.abs(res["brake.heat"] - exact)) < 1e-6 * J * w0 ** 2 / 2
    assert np.all(res["brake.heat_flow"] >= -1e-9) and np.allclose(res["brake.heat_flow"], res["brake.power"])
    assert res.unit("brake.heat") == "J" and res.unit("brake.heat_flow") == "W"


def test_clutch_locking_two_inertias_dissipates_the_closed_form_energy():
    """Whatever the law: the energy lost when two inertias lock is J1 J2 / (J1 + J2) (w1 - w2)^2 / 2."""
    J1, J2, w1, w2 = 1.0, 3.0, 50.0, 10.0
    m = rm.Model("clutch_heat")
    a = m.add(Inertia("a", J=J1, phi0=0.0, w0=w1))
    b = m.add(Inertia("b", J=J2, phi0=0.0, w0=w2))
    c = m.add(Clutch("clutch", mu=0.3, cgeo=0.1, fn_max=2000.0, peak=1.1))
    m.connect(a.flange_b, c.flange_a)
    m.connect(c.flange_b, b.flange_a)
    res = m.simulate(t_end=1.0, dt_out=1e-3, **IDA)
    assert res["a.w"][-1] == pytest.approx(res["b.w"][-1])
    assert res["clutch.heat"][-1] == pytest.approx(J1 * J2 / (J1 + J2) * (w1 - w2) ** 2 / 2, rel=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["spring_damper", "shaft", "damper"])
def test_damping_heat_closes_the_energy_book(kind):
    """A free oscillation (or a damped spin-down): kinetic + stored + heat stays at its start value."""
    m = rm.Model("ring")
    ground = m.add(Fixed("ground"))
    J = m.add(Inertia("J", J=0.5, phi0=0.3, w0=4.0))
    link = {"spring_damper": SpringDamper("link", c=200.0, d=1.5),
            "shaft": Shaft("link", stiffness=200.0, damping=1.5),
            "damper": Damper("link", d=1.5)}[kind]
    m.add(link)
    m.connect(ground.flange, link.flange_a)
    m.connect(link.flange_b, J.flange_a)
    res = m.simulate(t_end=2.0, dt_out=1e-4, **IDA)
    stored = res["link.potential"] if "link.potential" in res else 0.0
    total = res["J.kinetic"] + stored + res["link.heat"]
    assert np.max(np.abs(total - total[0])) < 1e-5 * total[0]
    assert res["link.heat"][-1] > 0.5 * total[0]
    if kind != "damper":      # the spring's share of the power is stored, not heat
        assert np.max(np.abs(res["link.heat_flow"] - 1.5 * res["link.w_rel"] ** 2)) < 1e-9 * total[0]


def test_accumulated_integrates_jumps_at_duplicated_event_instants_exactly():
    t = np.array([0.0, 1.0, 1.0, 2.0])
    p = np.array([1.0, 1.0, 3.0, 3.0])                  # a jump at t = 1 (left and right limits)
    assert accumulated(t, p) == pytest.approx([0.0, 1.0, 1.0, 4.0])


def _clutch_run():
    J1, J2 = 1.0, 3.0
    m = rm.Model("clutch_heat")
    a = m.add(Inertia("a", J=J1, phi0=0.0, w0=50.0))
    b = m.add(Inertia("b", J=J2, phi0=0.0, w0=10.0))
    c = m.add(Clutch("clutch", mu=0.3, cgeo=0.1, fn_max=2000.0, peak=1.1))
    m.connect(a.flange_b, c.flange_a)
    m.connect(c.flange_b, b.flange_a)
    return m.simulate(t_end=3.0, dt_out=1e-3, **IDA)


def test_lumped_thermal_mass_matches_scipy_and_the_adiabatic_closed_form():
    from scipy.integrate import solve_ivp
    from regmech.components.heat import temperature
    res = _clutch_run()
    C, G, T0 = 400.0, 2.0, 25.0
    # adiabatic: the temperature rise is the heat over the capacity
    assert np.allclose(temperature(res, "clutch", C, 0.0, T0), T0 + res["clutch.heat"] / C, rtol=0, atol=1e-12)
    # with convection: against scipy on the same (linearly interpolated) heat flow
    T = temperature(res, "clutch", C, G, T0, T_amb=20.0)
    t, p = res.t, res["clutch.heat_flow"]
    tu, first = np.unique(t, return_index=True)            # the lock-up instant is recorded twice
    ref = solve_ivp(lambda s, y: [(np.interp(s, t, p) - G * (y[0] - 20.0)) / C], (0.0, t[-1]), [T0], t_eval=tu,
                    method="DOP853", rtol=1e-12, atol=1e-12, max_step=1e-3)
    assert np.max(np.abs(T[first] - ref.y[0])) < 1e-8
    assert T.max() > T0 + 1.0 and T[-1] < T.max()                 # heated while slipping, cooling after lock-up
    with pytest.raises(rm.errors.ParameterError, match="C must be a finite number > 0"):
        temperature(res, "clutch", 0.0)
