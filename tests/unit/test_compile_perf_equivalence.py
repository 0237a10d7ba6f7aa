"""The optimised residual and Jacobian (``compile.evaluation``) against
finite differences and against a straightforward reference written from the
equations of ``compile.system``'s docstring, on fixed and random models.

The reference evaluates each compliant device by calling its class's
``laws``/``derivatives`` with plain numbers (no templates, no folding of
affine devices into matrices), and assembles

    x' - v;  G_p x + e0_p - g_p;  G_pv v - g';  M a + S^T tau + G^T lam;
    G_pv a - g'';  friction rows;  z' - dz

with dense matrices.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp
import sympy

import regmech as rm
import regmech.compile.evaluation as evaluation
from regmech.compile.assembly import outer_pairs, ragged_arange, Ragged
from regmech.compile.kernels import SignalBank
from regmech.component import Device, Param
from regmech.components import (Damper, Fixed, IdealGear, Inertia, Position, Shaft, Speed, Spring,
                                SpringDamper, Torque, TwoFlangeCompliant)
from regmech.signals import Constant, Ramp, Sine, Step
from regmech.library import coupled_clutches, first


# -- user-defined devices -------------------------------------------------------------------
class CubicSpring(TwoFlangeCompliant):
    """Hardening spring ``tau = c rel + c3 rel^3``."""

    c = Param(check="positive", unit="N m/rad")
    c3 = Param(check="real", unit="N m/rad^3")

    def law(self, rel, rel_dot):
        return self.c * rel + self.c3 * rel ** 3


class Maxwell(TwoFlangeCompliant):
    """Spring ``c`` in series with a damper ``d``; state ``q`` = damper stroke (plus a nonlinear drift)."""

    c = Param(check="positive")
    d = Param(check="positive")
    q0 = Param(0.0)
    states = {"q": "q0"}

    def law(self, rel, rel_dot):
        return self.c * (rel - self.q)

    def derivatives(self, e, de):
        return [self.c * (e[0] - self.q) / self.d + 0.1 * sympy.sin(self.q)]


class Coupler3(Device):
    """Three flanges, two rows, nonlinear coupling modulated by an input signal."""

    kind = "compliant"
    flanges = (("flange_a", None), ("flange_b", None), ("flange_c", None))
    c = Param(check="positive")
    k = Param(check="real")
    g = Param(check="signal")

    def rows(self):
        return [{"flange_a": -1.0, "flange_b": 1.0}, {"flange_b": -1.0, "flange_c": 2.0}]

    def laws(self, e, de):
        return [self.c * e[0] + 2 * self.k * e[0] * e[1] ** 2 + 0.3 * de[0] * self.g,
                self.c * e[1] + 2 * self.k * e[0] ** 2 * e[1] + 0.2 * de[1] ** 3]


class LoadedSpring(TwoFlangeCompliant):
    """Spring with a torque ``k u(t) + b`` added: an offset linear in its signal, coefficient and constant
    from the parameters (the residual multiplies the signal value itself)."""

    c = Param(check="positive")
    k = Param(check="real")
    b = Param(check="real")
    u = Param(check="signal")

    def law(self, rel, rel_dot):
        return self.c * rel + self.k * self.u + self.b


class Lag(TwoFlangeCompliant):
    """A state ``q`` lagging behind ``k u(t)`` with time constant ``T``: a state offset linear in the signal."""

    c = Param(check="positive")
    k = Param(check="real")
    T = Param(check="positive")
    u = Param(check="signal")
    q0 = Param(0.0)
    states = {"q": "q0"}

    def law(self, rel, rel_dot):
        return self.c * rel + self.q

    def derivatives(self, e, de):
        return [(self.k * self.u - self.q) / self.T]


class SquareDrive(TwoFlangeCompliant):
    """Spring with a torque ``u(t)^2 + 0.1 sin(time)``: an offset not linear in the signal, and using time."""

    c = Param(check="positive")
    u = Param(check="signal")

    def law(self, rel, rel_dot):
        return self.c * rel + self.u ** 2 + 0.1 * sympy.sin(self.time)


# -- models ---------------------------------------------------------------------------------
def input_offsets():
    """Affine devices whose offsets follow their signals: linearly (LoadedSpring, Lag, Torque) and not
    (SquareDrive)."""
    m = rm.Model("input_offsets")
    f = m.add(Fixed("fixed"))
    J = [m.add(Inertia(f"J{i}", J=1.0 + 0.3 * i)) for i in range(4)]
    devs = [LoadedSpring("ls1", c=40, k=2.5, b=0.3, u=Sine(amplitude=2, freq_hz=1.5, offset=0.2)),
            LoadedSpring("ls2", c=25, k=-1.5, b=0.0, u=Step(height=1.0, start_time=0.4)),
            Lag("lag", c=30, k=3.0, T=0.2, u=Ramp(height=2.0, duration=0.5), q0=0.1),
            SquareDrive("sq", c=20, u=Sine(amplitude=1, freq_hz=2))]
    for i, d in enumerate(devs):
        m.add(d)
        m.connect((J[i - 1].flange_b if i else f.flange), d.flange_a)
        m.connect(d.flange_b, J[i].flange_a)
    tq = m.add(Torque("tq", tau=Sine(amplitude=3, freq_hz=2)))
    m.connect(tq.flange, J[3].flange_b)
    return m


def gear_chain():
    """Gears and rigid shafts between compliant links, a cubic spring, a shifted ground."""
    m = rm.Model("gears")
    f = m.add(Fixed("fixed", phi0=0.3))
    tq = m.add(Torque("tq", tau=Sine(amplitude=3, freq_hz=2, offset=1.0)))
    J = [m.add(Inertia(f"J{i}", J=0.5 + 0.2 * i)) for i in range(7)]
    devs = [IdealGear("g1", ratio=2.5), Shaft("s1"), SpringDamper("sd", c=300, d=2),
            Shaft("s2", stiffness=100, damping=1), IdealGear("g2", ratio=-0.5)]
    m.connect(tq.flange, J[0].flange_a)
    m.connect(tq.support, f.flange)
    for i, d in enumerate(devs):
        m.add(d)
        m.connect(J[i].flange_b, d.flange_a)
        m.connect(d.flange_b, J[i + 1].flange_a)
    gs = m.add(Spring("gs", c=50, phi_rel0=0.1))
    m.connect(J[5].flange_b, gs.flange_a)
    m.connect(gs.flange_b, f.flange)
    cs = m.add(CubicSpring("cub", c=20, c3=5.0))
    m.connect(J[5].flange_a, cs.flange_a)
    m.connect(cs.flange_b, J[6].flange_a)
    return m


def state_devices():
    """Position and Speed sources, a state-carrying device and a two-row device."""
    m = rm.Model("devices")
    f = m.add(Fixed("fixed"))
    J = [m.add(Inertia(f"J{i}", J=1.0 + i)) for i in range(5)]
    pos = m.add(Position("pos", phi_ref=Sine(amplitude=0.5, freq_hz=2, offset=0.1)))
    spd = m.add(Speed("spd", w_ref=Sine(amplitude=1, freq_hz=1)))
    mx = m.add(Maxwell("mx", c=100, d=5, q0=0.05))
    cp = m.add(Coupler3("cp", c=40, k=3, g=Sine(amplitude=2, freq_hz=3, offset=1)))
    d = m.add(Damper("d", d=0.7))
    s = m.add(Spring("sp", c=10))
    m.connect(pos.flange, J[0].flange_a)
    m.connect(J[0].flange_b, mx.flange_a)
    m.connect(mx.flange_b, J[1].flange_a)
    m.connect(J[1].flange_b, cp.flange_a)
    m.connect(cp.flange_b, J[2].flange_a)
    m.connect(cp.flange_c, J[3].flange_a)
    m.connect(spd.flange, J[4].flange_a)
    m.connect(J[4].flange_b, d.flange_a)
    m.connect(d.flange_b, J[3].flange_b)
    m.connect(J[2].flange_b, s.flange_a)
    m.connect(s.flange_b, f.flange)
    return m


def random_model(seed: int):
    """A random tree of inertias joined by random devices, some grounded, one or two torques."""
    rng = np.random.default_rng(seed)
    m = rm.Model(f"random{seed}")
    f = m.add(Fixed("fixed", phi0=float(rng.uniform(-1, 1))))
    n = int(rng.integers(3, 9))
    J = [m.add(Inertia(f"J{i}", J=float(rng.uniform(0.2, 3.0)))) for i in range(n)]
    for i in range(1, n):
        j = int(rng.integers(0, i))
        kind = int(rng.integers(0, 8))
        name = f"d{i}"
        dev = [Spring(name, c=float(rng.uniform(1, 100)), phi_rel0=float(rng.uniform(-0.2, 0.2))),
               Damper(name, d=float(rng.uniform(0, 5))),
               SpringDamper(name, c=float(rng.uniform(1, 100)), d=float(rng.uniform(0, 5))),
               Shaft(name, stiffness=float(rng.uniform(10, 100)), damping=float(rng.uniform(0, 1))),
               Shaft(name),
               IdealGear(name, ratio=float(rng.choice([-2.0, 0.5, 3.0]))),
               CubicSpring(name, c=float(rng.uniform(1, 50)), c3=float(rng.uniform(-5, 5))),
               Maxwell(name, c=float(rng.uniform(5, 50)), d=float(rng.uniform(1, 5)),
                       q0=float(rng.uniform(-0.1, 0.1)))][kind]
        m.add(dev)
        m.connect(J[j].flange_b, dev.flange_a)
        m.connect(dev.flange_b, J[i].flange_a)
    for k in rng.choice(n, size=2, replace=False):
        g = m.add(SpringDamper(f"ground{k}", c=float(rng.uniform(1, 50)), d=float(rng.uniform(0, 1))))
        m.connect(J[int(k)].flange_a, g.flange_a)
        m.connect(g.flange_b, f.flange)
    tq = m.add(Torque("tq", tau=Sine(amplitude=float(rng.uniform(1, 5)), freq_hz=float(rng.uniform(0.5, 3)))))
    m.connect(tq.flange, J[0].flange_a)
    if n >= 4:
        tq2 = m.add(Torque("tq2", tau=Step(height=2.0, start_time=0.3, offset=0.5)))
        m.connect(tq2.flange, J[n - 1].flange_b)
        m.connect(tq2.support, J[1].flange_b)
        cp = m.add(Coupler3("cp", c=float(rng.uniform(5, 30)), k=float(rng.uniform(-2, 2)), g=Constant(1.5)))
        m.connect(cp.flange_a, J[0].flange_b)
        m.connect(cp.flange_b, J[2].flange_b)
        m.connect(cp.flange_c, J[3].flange_b)
    return m


MODELS = {"first": first, "gear_chain": gear_chain, "state_devices": state_devices,
          "coupled_clutches": coupled_clutches, "input_offsets": input_offsets}


# -- the reference --------------------------------------------------------------------------
class _NumericSelf:
    """``self`` of a device with numbers: parameters, signals at t, states, time."""

    def __init__(self, dev, t, left, states):
        self._dev, self._t, self._left, self._states = dev, t, left, states

    def __getattr__(self, name):
        if name == "time":
            return self._t
        if name in self._states:
            return self._states[name]
        val = self._dev._values.get(name, None)
        if name in self._dev._values:
            return val.value(self._t, self._left) if isinstance(val, rm.signals.Signal) else val
        attr = getattr(type(self._dev), name)
        return attr.__get__(self) if callable(attr) else attr


def _num(x):
    return float(sympy.N(x)) if isinstance(x, sympy.Basic) else float(x)


def reference_residual(c, t, y, yp, modes):
    st = c.structure
    left = t >= c._t_right
    x, v = y[c.ix], y[c.iv]
    a = yp[c.iv].copy()
    a[c.Dv] = y[c.iad]
    lam, z = y[c.ilam], y[c.iz]
    Sc = c.Sc.toarray()
    e = Sc @ x + c.e0c
    de = Sc @ v
    row_of = {id(r): i for i, r in enumerate(st.compliant)}
    state_of = {name: i for i, name in enumerate(c.state_names)}
    tau = np.zeros(len(e))
    dz = np.zeros(c.nz)
    for dev in st.devices:
        if dev.device_kind() != "compliant":
            continue
        rows = [row_of[id(r)] for r in st.rows[dev.name]]
        sidx = [state_of[f"{dev.name}.{s}"] for s in type(dev).states]
        me = _NumericSelf(dev, t, left, {s: z[i] for s, i in zip(type(dev).states, sidx)})
        ev, dev_ = [float(e[r]) for r in rows], [float(de[r]) for r in rows]
        for r, val in zip(rows, type(dev).laws(me, ev, dev_)):
            tau[r] = _num(val)
        for i, val in zip(sidx, type(dev).derivatives(me, ev, dev_)):
            dz[i] = _num(val)
    gp, gv = c._refs(t)
    Gp, Gv, Gall = c.Gp.toarray(), c.Gv.toarray(), c.Gall.toarray()
    Gpv = np.vstack([Gp, Gv])
    res = np.zeros(c.N)
    res[c.r_kin] = yp[c.ix[c.Kx]] - v[c.Kx]
    res[c.r_pos] = Gp @ x + c.e0p - gp[0]
    res[c.r_vel] = Gpv @ v - np.concatenate([gp[1], gv[0]])
    res[c.r_mot] = c.mass * a + Sc.T @ tau + Gall.T @ lam
    res[c.r_acc] = Gpv @ a - np.concatenate([gp[2], gv[1]])
    if c.mf:
        res[c.r_fric] = c.friction.residual_rows(t, v, a, lam[c.mp + c.mv:], modes)
    res[c.r_z] = yp[c.iz] - dz
    return res, tau, dz


def fd_iteration_matrix(c, t, y, yp, cj, modes):
    """dF/dy + cj dF/dy' by central differences of the optimised residual."""
    N = c.N
    J = np.zeros((N, N))
    rp, rm_ = np.zeros(N), np.zeros(N)
    for k in range(N):
        h = 1e-6 * max(1.0, abs(y[k]), abs(yp[k]))
        dy = np.zeros(N)
        dy[k] = h
        c.residual(t, y + dy, yp + cj * dy, rp, modes)
        c.residual(t, y - dy, yp - cj * dy, rm_, modes)
        J[:, k] = (rp - rm_) / (2 * h)
    return J


def jacobian_dense(c, data):
    return sp.csc_matrix((data, c.jac.pattern.indices, c.jac.pattern.indptr), shape=(c.N, c.N)).toarray()


def random_point(c, rng):
    y, yp = rng.standard_normal(c.N), rng.standard_normal(c.N)
    modes = rng.integers(-1, 3, size=c.mf) if c.mf else c.modes0
    return float(rng.uniform(0.05, 0.95)), y, yp, float(rng.uniform(1.0, 50.0)), modes


def check_model(model, rng, points=2):
    c = model.compile()
    for _ in range(points):
        t, y, yp, cj, modes = random_point(c, rng)
        res = np.full(c.N, np.nan)
        c.residual(t, y, yp, res, modes)
        ref, tau_ref, dz_ref = reference_residual(c, t, y, yp, modes)
        scale = max(1.0, np.abs(ref).max())
        np.testing.assert_allclose(res, ref, rtol=0, atol=1e-12 * scale)
        # the general kernel path agrees with the reference too
        x, v, a, lam, z = c.unpack(y, yp)
        _, _, tau, dz, w = c.kernel_outputs(x, v, z, t)
        np.testing.assert_allclose(tau, tau_ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(dz, dz_ref, rtol=1e-12, atol=1e-12)
        # Jacobian: against finite differences, and the optimised plan against the plain assembly
        data = c.jacobian_data(t, y, yp, cj, modes)
        J = jacobian_dense(c, data)
        Jfd = fd_iteration_matrix(c, t, y, yp, cj, modes)
        jscale = max(1.0, np.abs(Jfd).max())
        np.testing.assert_allclose(J, Jfd, rtol=0, atol=2e-6 * jscale)
        if c.mf:
            w = np.concatenate([w, c.friction.weights(t, v, cj, modes)])
        np.testing.assert_allclose(data, c.jac.data(cj, w), rtol=1e-12, atol=1e-12 * jscale)
    return c


# -- tests ----------------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(MODELS))
def test_fixed_models_match_reference_and_finite_differences(name):
    check_model(MODELS[name](), np.random.default_rng(7))


@pytest.mark.parametrize("seed", range(8))
def test_random_models_match_reference_and_finite_differences(seed):
    check_model(random_model(seed), np.random.default_rng(100 + seed))


@pytest.mark.parametrize("dense_max", [0, 10 ** 9])
def test_dense_and_sparse_plans_agree(monkeypatch, dense_max):
    monkeypatch.setattr(evaluation, "DENSE_MAX", dense_max)
    c = check_model(state_devices(), np.random.default_rng(3), points=1)
    assert isinstance(c._plan.L, np.ndarray) == (dense_max > 0)


def test_affine_classes_are_folded_and_nonlinear_ones_evaluated():
    c = gear_chain().compile()
    kinds = {g.tpl.cls.__name__: g.tpl.affine for g in c.groups}
    assert kinds == {"Torque": True, "SpringDamper": True, "Shaft": True, "Spring": True, "CubicSpring": False}
    assert [g.tpl.cls.__name__ for g in c._plan.nonlinear] == ["CubicSpring"]
    # the Torque's sine is the only time-varying offset; tau(0) = tau is linear in the signal, so the
    # residual multiplies the signal value itself (an input slot)
    assert [g.tpl.cls.__name__ for g, *_ in c._plan.input_slots] == ["Torque"]
    assert c._plan.offset_slots == []


def test_offsets_linear_in_their_signals_take_the_signal_values():
    """Offsets ``const + coef u(t)`` (coefficients of the parameters) go through input slots, any other
    varying offset through the offset function; both agree with the reference (``check_model``)."""
    c = check_model(input_offsets(), np.random.default_rng(11), points=3)
    slots = {g.tpl.cls.__name__: g for g, *_ in c._plan.input_slots}
    assert sorted(slots) == ["Lag", "LoadedSpring", "Torque"]
    assert [g.tpl.cls.__name__ for g, _ in c._plan.offset_slots] == ["SquareDrive"]
    coef = {g.tpl.cls.__name__: cf for g, _, cf, _ in c._plan.input_slots}
    np.testing.assert_array_equal(coef["LoadedSpring"][0][0], [2.5, -1.5])
    np.testing.assert_allclose(coef["Lag"][1][0], [3.0 / 0.2])        # the state's offset k u / T
    # and a run through the ODE form (device outputs) and through IDA (residual) agree
    m = input_offsets()
    a = m.simulate(1.0, dt_out=0.05, solver="ida", rtol=1e-9, atol=1e-11)
    b = m.simulate(1.0, dt_out=0.05, solver="scipy:DOP853", rtol=1e-10, atol=1e-12)
    for name in ("J0.w", "J3.phi", "lag.q"):
        scale = max(1.0, float(np.abs(b[name]).max()))
        np.testing.assert_allclose(a[name], b[name], rtol=0, atol=1e-6 * scale)


def test_residual_at_the_right_end_of_a_piece_uses_left_limits():
    m = rm.Model("step")
    J = m.add(Inertia("J", J=2.0))
    tq = m.add(Torque("tq", tau=Step(height=3.0, start_time=0.5)))
    m.connect(tq.flange, J.flange_a)
    c = m.compile()
    y, yp = np.zeros(c.N), np.zeros(c.N)
    res = np.zeros(c.N)
    c._t_right = 0.5
    c.residual(0.5, y, yp, res)
    assert res[c.r_mot[0]] == 0.0            # left limit: the step is not on yet
    c._t_right = np.inf
    c.residual(0.5, y, yp, res)
    assert res[c.r_mot[0]] == -3.0           # flange.tau = -tau: the motion row is J a - tau


def test_ragged_helpers_match_loops():
    starts, lengths = np.array([5, 0, 9, 2]), np.array([2, 0, 3, 1])
    expect = np.concatenate([np.arange(s, s + n) for s, n in zip(starts, lengths)])
    np.testing.assert_array_equal(ragged_arange(starts, lengths), expect)
    a = Ragged(np.array([0, 0, 2]), np.array([10, 11, 12]), np.ones(3), np.array([2, 0, 1]))
    b = Ragged(np.array([0, 1, 2, 2]), np.array([20, 21, 22, 23]), np.ones(4), np.array([1, 1, 2]))
    ia, ib, inst = outer_pairs(a, b)
    got = sorted(zip(a.index[ia], b.index[ib], inst))
    assert got == [(10, 20, 0), (11, 20, 0), (12, 22, 2), (12, 23, 2)]


@pytest.mark.parametrize("left", [False, True])
def test_signal_bank_matches_signal_values(left):
    sigs = [Sine(amplitude=1 + i, freq_hz=0.5 + 0.1 * i, phase=0.2 * i, offset=0.1 * i, start_time=0.05 * i)
            for i in range(10)] + [Step(height=i, start_time=0.1 * i) for i in range(10)] + \
           [Constant(4.0), Ramp(height=2.0, duration=0.5)]
    bank = SignalBank(sigs)
    for t in (0.0, 0.1, 0.25, 0.45, 0.9):
        expect = np.array([s.value(t, left) for s in sigs])
        np.testing.assert_allclose(bank.at(t, left), expect, rtol=1e-14, atol=1e-14)


def test_simulation_of_first_is_unchanged_by_the_fast_path():
    """The MSL First model still follows its own energy balance after integration with IDA."""
    res = first().simulate(0.3, solver="ida", rtol=1e-8, atol=1e-10)
    w2 = res["inertia2.w"]
    assert np.all(np.isfinite(w2)) and math.isfinite(float(w2[-1]))
    assert abs(res["inertia1.w"][-1] - 10.0 * w2[-1]) < 1e-6 * max(1.0, abs(res["inertia1.w"]).max())


def test_kernel_printer_writes_integer_powers_as_products():
    import inspect

    from regmech.compile.kernels import _lambdify
    x, y = sympy.symbols("x y")
    exprs = [x ** 3 + y, (x + y) ** 4 * 2, -x ** 2, x ** -2, sympy.sqrt(x), (x * y) ** 3, x ** 2.5,
             sympy.sin(x) ** 3, x ** 9]
    fast = _lambdify([x, y], exprs)
    plain = sympy.lambdify([x, y], exprs, modules="numpy")
    a, b = np.array([0.3, 1.7, 2.5]), np.array([-0.2, 2.0, 0.4])
    for u, v in zip(fast(a, b), plain(a, b)):
        np.testing.assert_allclose(u, v, rtol=1e-14)
    src = inspect.getsource(fast)
    assert "x**3" not in src and "(x*x*x)" in src


def test_banded_ordering_narrows_a_chain_with_gears_and_shafts():
    from regmech.compile.assembly import banded_ordering
    c = gear_chain().compile()
    perm, lb, ub = banded_ordering(c.jac.pattern)
    assert sorted(perm.tolist()) == list(range(c.N))
    P = c.jac.pattern.toarray() != 0
    Q = P[np.ix_(perm, perm)]
    rows, cols = np.nonzero(Q)
    assert (rows - cols).max() == lb and (cols - rows).max() == ub
    r0, c0 = np.nonzero(P)
    assert lb + ub < (r0 - c0).max() + (c0 - r0).max()     # narrower than the natural layout
