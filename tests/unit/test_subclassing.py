"""A user-defined device in a few lines: a cubic hardening spring, checked against scipy."""

import numpy as np
from scipy.integrate import solve_ivp

import regmech as rm
from regmech.components import Fixed, Inertia, Torque, TwoFlangeCompliant


class CubicSpring(TwoFlangeCompliant):
    """tau = c*phi_rel + c3*phi_rel**3 (hardening)."""

    c = rm.Param(check="positive", unit="N m/rad")
    c3 = rm.Param(check="nonnegative", unit="N m/rad^3")

    def law(self, rel, rel_dot):
        return self.c * rel + self.c3 * rel**3

    def potential(self, e):
        return self.c * e[0] ** 2 / 2 + self.c3 * e[0] ** 4 / 4


def test_cubic_spring_subclass_simulates_like_the_ode():
    m = rm.Model("cubic")
    f = m.add(Fixed("f"))
    k = m.add(CubicSpring("k", c=20.0, c3=400.0))
    J = m.add(Inertia("J", J=0.5, phi0=0.3, w0=0.0))
    drive = m.add(Torque("drive", tau=lambda t: 2.0 * np.sin(3.0 * t)))
    m.connect(f.flange, k.flange_a)
    m.connect(k.flange_b, J.flange_a)
    m.connect(drive.flange, J.flange_b)
    res = m.simulate(3.0, dt_out=1e-2, rtol=1e-10, atol=1e-12, solver="ida")

    def rhs(t, y):
        return [y[1], (2.0 * np.sin(3.0 * t) - 20.0 * y[0] - 400.0 * y[0] ** 3) / 0.5]
    ref = solve_ivp(rhs, (0, 3), [0.3, 0.0], t_eval=res.t, rtol=1e-12, atol=1e-12, method="DOP853")
    assert np.max(np.abs(res["J.phi"] - ref.y[0])) < 1e-7
    assert np.allclose(res["k.potential"], 10.0 * res["J.phi"] ** 2 + 100.0 * res["J.phi"] ** 4)
    with np.testing.assert_raises(rm.ParameterError):
        CubicSpring("bad", c=1.0, c3=-1.0)
