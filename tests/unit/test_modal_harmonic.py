"""Forced harmonic response: closed forms, superposition, and a long IDA transient."""

import numpy as np
import pytest

import regmech as rm
from regmech.analysis import harmonic_response, multi_harmonic_response, order_sweep
from regmech.components import Damper, Fixed, Inertia, Position, Speed, Spring, SpringDamper, Torque
from regmech.signals import Sine


def damped_pair(tau=1.0):
    """ground -(c1, d1)- J1 -(c2, d2)- J2 -d3- ground; a torque drives J1."""
    m = rm.Model("pair")
    fixed = m.add(Fixed("fixed"))
    j1, j2 = m.add(Inertia("J1", J=1.0)), m.add(Inertia("J2", J=0.5))
    k1 = m.add(SpringDamper("k1", c=400.0, d=8.0))
    k2 = m.add(SpringDamper("k2", c=250.0, d=6.0))
    d3 = m.add(Damper("d3", d=5.0))
    drive = m.add(Torque("drive", tau=tau))
    m.connect(fixed.flange, k1.flange_a)
    m.connect(k1.flange_b, j1.flange_a)
    m.connect(j1.flange_b, k2.flange_a)
    m.connect(k2.flange_b, j2.flange_a)
    m.connect(j2.flange_b, d3.flange_a)
    m.connect(d3.flange_b, fixed.flange)
    m.connect(drive.flange, j1.flange_b)
    return m


def test_harmonic_response_equals_steady_state_of_long_simulation():
    f, amp = 3.0, 2.0
    model = damped_pair(Sine(amplitude=amp, freq_hz=f))
    outputs = ["J2.w", "J1.phi", "k2.tau", "k2.w_rel"]
    # amp sin(w t) = amp cos(w t - pi/2)
    resp = harmonic_response(model.linearize(), outputs, [f], inputs={"drive": (amp, -np.pi / 2)})
    t_end = 8.0      # slowest decay rate 5.4 1/s (damped modes): the start transient is down by e^-38
    res = model.simulate(t_end, dt_out=1e-3, solver="ida", rtol=1e-10, atol=1e-12)
    last = res.t >= t_end - 1.0 / f
    t = res.t[last]
    for j, name in enumerate(outputs):
        Y = resp.values[0, j]
        steady = np.real(Y * np.exp(1j * 2 * np.pi * f * t))
        err = np.abs(res[name][last] - steady).max()
        assert err <= 1e-4 * abs(Y), (name, err, abs(Y))


def sdof_base(kind):
    m = rm.Model("base")
    src = m.add(Position("src", phi_ref=0.0) if kind == "position" else Speed("src", w_ref=0.0))
    hub = m.add(Inertia("hub", J=1.0))
    s = m.add(SpringDamper("s", c=100.0, d=2.0))
    body = m.add(Inertia("J", J=4.0))
    m.connect(src.flange, hub.flange_a)
    m.connect(hub.flange_b, s.flange_a)
    m.connect(s.flange_b, body.flange_a)
    return m


@pytest.mark.parametrize("kind", ["position", "speed"])
def test_kinematic_excitation_closed_form(kind):
    lin = sdof_base(kind).linearize()
    freqs = np.array([0.3, 0.8, 2.0])
    w = 2 * np.pi * freqs
    resp = harmonic_response(lin, ["J.phi", "hub.phi", "s.tau"], freqs)
    G = np.ones_like(w, complex) if kind == "position" else 1.0 / (1j * w)   # base displacement per unit input
    X = (100.0 + 2j * w) / (100.0 - 4.0 * w ** 2 + 2j * w) * G
    np.testing.assert_allclose(resp["J.phi"], X, rtol=1e-12)
    np.testing.assert_allclose(resp["hub.phi"], G, rtol=1e-12)
    np.testing.assert_allclose(resp["s.tau"], (100.0 + 2j * w) * (X - G), rtol=1e-12)


def test_multi_harmonic_superposition_and_order_sweep():
    lin = damped_pair().linearize()
    spec = [(1.0, 3.0, 0.2), (2.0, 1.5, -0.4), (4.0, 0.5, 1.0)]
    base = 1.7
    mh = multi_harmonic_response(lin, ["J2.w", "k1.tau"], spec, base_hz=base)
    single = harmonic_response(lin, ["J2.w", "k1.tau"], [o * base for o, _, _ in spec])
    amps = np.array([a * np.exp(1j * p) for _, a, p in spec])
    np.testing.assert_allclose(mh.values, single.values * amps[:, None], rtol=1e-12)
    t = np.linspace(0, 2.0, 50)
    expect = sum(np.real(mh.values[h, 0] * np.exp(1j * 2 * np.pi * mh.freqs_hz[h] * t)) for h in range(3))
    np.testing.assert_allclose(mh.time_series(t)[:, 0], expect, rtol=1e-12, atol=1e-15)
    assert mh.period == pytest.approx(1.0 / base)
    assert mh.peak("J2.w") <= np.abs(mh.values[:, 0]).sum() + 1e-12
    sweep = order_sweep(lin, "J2.w", [(1.0, 1.0, 0.0), (1.5, 0.5, 0.0)], np.linspace(0.5, 8.0, 16))
    assert sweep.amplitude.shape == (16, 2, 1) and sweep.peak.shape == (16, 1)
    assert np.all(sweep.peak[:, 0] <= sweep.amplitude[:, :, 0].sum(axis=1) + 1e-12)
    assert np.all(sweep.peak[:, 0] >= sweep.amplitude[:, :, 0].max(axis=1) - 1e-12)


def test_sparse_and_dense_responses_agree():
    from regmech.compile.linear import linearize
    lin_dense = linearize(damped_pair().compile(), sparse=False)
    lin_sparse = linearize(damped_pair().compile(), sparse=True)
    assert not lin_dense.sparse and lin_sparse.sparse
    f = np.linspace(0.5, 6.0, 7)
    a = harmonic_response(lin_dense, ["J1.w", "k2.tau"], f)
    b = harmonic_response(lin_sparse, ["J1.w", "k2.tau"], f)
    np.testing.assert_allclose(a.values, b.values, rtol=1e-12)


def test_errors_and_plots(tmp_path):
    lin = damped_pair().linearize()
    with pytest.raises(rm.ParameterError, match="no input"):
        harmonic_response(lin, "J1.w", [1.0], inputs="nope")
    with pytest.raises(rm.ParameterError, match="freqs_hz"):
        harmonic_response(lin, "J1.w", [-1.0])
    # undamped free mass at 0 Hz: singular dynamic stiffness is an error, not inf/NaN
    m = rm.Model("free")
    body = m.add(Inertia("J", J=1.0))
    drive = m.add(Torque("drive", tau=1.0))
    m.connect(drive.flange, body.flange_a)
    with pytest.raises(rm.StructureError, match="singular"):
        harmonic_response(m.linearize(), "J.phi", [0.0])
    with pytest.raises(rm.ParameterError, match="unbounded"):
        harmonic_response(sdof_base("speed").linearize(), "J.phi", [0.0])
    pytest.importorskip("matplotlib")
    resp = harmonic_response(lin, ["J1.w", "J2.w"], np.linspace(0.1, 10, 50))
    resp.plot(tmp_path / "r.png")
    multi_harmonic_response(lin, "J2.w", [(1, 1.0, 0.0), (2, 0.3, 0.0)], base_hz=2.0).plot(tmp_path / "m.png")
    order_sweep(lin, ["J2.w"], [(1, 1.0, 0.0)], [1.0, 2.0]).plot(tmp_path / "o.png")
    for name in ("r.png", "m.png", "o.png"):
        assert (tmp_path / name).stat().st_size > 1000


def test_kinematic_input_through_a_stuck_clutch():
    # Position source -> hub =stuck clutch= J2 -spring- J3: J2 follows the source, J3 is the only freedom
    from regmech.components import Clutch
    m = rm.Model("stuck_drive")
    pos = m.add(Position("pos", phi_ref=0.0))
    hub, j2, j3 = m.add(Inertia("hub", J=1.0)), m.add(Inertia("J2", J=2.0)), m.add(Inertia("J3", J=0.5))
    cl = m.add(Clutch("clutch", fn_max=50.0))
    s = m.add(Spring("s", c=200.0))
    m.connect(pos.flange, hub.flange_a)
    m.connect(hub.flange_b, cl.flange_a)
    m.connect(cl.flange_b, j2.flange_a)
    m.connect(j2.flange_b, s.flange_a)
    m.connect(s.flange_b, j3.flange_a)
    lin = m.linearize(modes={"clutch": "Stuck"})
    assert lin.coords == ["J3"]
    w = 2 * np.pi * np.array([0.5, 1.5, 4.0])
    resp = harmonic_response(lin, ["J2.phi", "J3.phi", "clutch.w_rel"], w / (2 * np.pi))
    np.testing.assert_allclose(resp["J2.phi"], 1.0, rtol=1e-12)
    np.testing.assert_allclose(resp["J3.phi"], 200.0 / (200.0 - 0.5 * w ** 2), rtol=1e-12)
    np.testing.assert_allclose(resp["clutch.w_rel"], 0.0, atol=1e-12)
