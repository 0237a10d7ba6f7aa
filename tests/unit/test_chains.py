"""Library scenes ``train`` and ``chain_drive``: they simulate with IDA, the
energy balance closes (work of the sources = kinetic + potential + dissipated,
the dissipation recomputed independently from the speeds), the train's
frequencies are those of a free-free chain, the chain's stiffness is
block-tridiagonal with non-diagonal 6 x 6 blocks."""

import numpy as np
import pytest

from regmech.library import SCENES, chains


def _integral(y, t):
    """Trapezoid rule on the output grid (event instants repeat a time: zero width)."""
    return float(np.sum(np.diff(t) * (y[1:] + y[:-1]) / 2))


def _stiffness(model):
    """K = S^T diag(k) S and the masses from the compiled model (linear scenes: k constant)."""
    c = model.compile()
    k = c.stiffness_estimate()
    S = c.Sc.toarray()
    return S.T @ np.diag(k) @ S, np.asarray(c.mass), list(c.structure.coord_names)


def test_scenes_are_registered():
    assert SCENES["train"] is chains.train
    assert SCENES["chain_drive"] is chains.chain_drive


def test_train_energy_balance():
    n, d, c_r, v_eps, m_car = 8, 5e4, 0.0015, 0.05, 60e3
    res = chains.train(n, d=d, c_r=c_r, v_eps=v_eps, m_car=m_car).simulate(20.0, dt_out=5e-3, rtol=1e-8, solver="ida")
    t = res.t
    work = -_integral(res["traction.power"], t)             # sources: absorbed power counts negative
    kinetic = sum(res[f"car{i}.kinetic"][-1] - res[f"car{i}.kinetic"][0] for i in range(n))
    potential = sum(res[f"coupler{i}.potential"][-1] - res[f"coupler{i}.potential"][0] for i in range(n - 1))
    # dissipation from the speeds, not from the devices' power signals
    f_roll = c_r * m_car * 9.80665
    dissipated = sum(_integral(d * res[f"coupler{i}.v_rel"] ** 2, t) for i in range(n - 1))
    dissipated += sum(_integral(f_roll * np.tanh(res[f"car{i}.v"] / v_eps) * res[f"car{i}.v"], t) for i in range(n))
    assert work > 1e6 and dissipated > 0.01 * work
    assert kinetic + potential + dissipated == pytest.approx(work, rel=1e-6)
    # the coupler potential agrees with c s_rel^2 / 2
    s_rel = res["coupler0.s_rel"]
    np.testing.assert_allclose(res["coupler0.potential"], 2e7 * s_rel ** 2 / 2, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("n", [2, 10, 25])
def test_train_frequencies_are_those_of_a_free_free_chain(n):
    K, mass, _ = _stiffness(chains.train(n, m_car=5e4, c=3e7))
    omega2 = np.sort(np.linalg.eigvals(np.diag(1 / mass) @ K).real)
    expected = np.array(sorted(chains.free_chain_frequencies(n, 3e7, 5e4)))
    np.testing.assert_allclose(np.sqrt(np.clip(omega2, 0, None)), expected, rtol=1e-9, atol=1e-6)
    assert expected[1] == pytest.approx(2 * np.sqrt(3e7 / 5e4) * np.sin(np.pi / (2 * n)))


def test_train_wave_reaches_the_last_car():
    res = chains.train(6).simulate(20.0, dt_out=0.01, rtol=1e-8, solver="ida")
    assert res["car5.v"][-1] > 1.0
    # at the end every car moves together (to within the coupler oscillation)
    speeds = np.array([res[f"car{i}.v"][-1] for i in range(6)])
    assert np.ptp(speeds) < 0.05 * speeds.mean()


def _joint_rates(res, j, pitch, ey, ez):
    """The six rates of joint j, from its flange speeds (small rotations: u + theta x r)."""
    def v(side, q):
        return res[f"joint{j}.{side}_{q}.{'v' if q in ('x', 'y', 'z') else 'w'}"]

    def d(q):
        return v("b", q) - v("a", q)
    h = pitch / 2
    return [d("x") + ez * d("ry") - ey * d("rz"),
            d("y") - h * (v("a", "rz") + v("b", "rz")) - ez * d("rx"),
            d("z") + h * (v("a", "ry") + v("b", "ry")) + ey * d("rx"),
            v("b", "rx") - v("a", "rx"),
            v("b", "ry") - v("a", "ry"),
            v("b", "rz") - v("a", "rz")]


@pytest.mark.parametrize("ey,ez", [(0.0, 0.0), (2e-3, -1e-3)])
def test_chain_drive_energy_balance(ey, ez):
    n_links, pitch, beta = 4, 0.0127, 1e-5
    params = dict(c_axial=5e7, c_shear=5e7, c_torsion=20.0, c_bend_y=20.0, c_bend_z=2.0)
    model = chains.chain_drive(n_links=n_links, pitch=pitch, beta=beta, offset_y=ey, offset_z=ez, **params)
    res = model.simulate(0.01, dt_out=2e-6, rtol=1e-8, solver="ida")
    t = res.t
    work = -_integral(res["axial_drive.power"] + res["lateral_drive.power"], t)
    kinetic = sum(res[n][-1] - res[n][0] for n in res.names if n.endswith(".kinetic"))
    potential = sum(res[n][-1] - res[n][0] for n in res.names if n.endswith(".potential"))
    k = [params["c_axial"], params["c_shear"], params["c_shear"], params["c_torsion"], params["c_bend_y"],
         params["c_bend_z"]]
    dissipated = sum(_integral(beta * kr * rate ** 2, t)
                     for j in range(n_links + 1) for kr, rate in zip(k, _joint_rates(res, j, pitch, ey, ez)))
    assert work > 0 and dissipated > 0.1 * work
    assert kinetic + potential + dissipated == pytest.approx(work, rel=1e-4)
    # the span moved sideways and along
    assert np.abs(res["link1_y.s"]).max() > 1e-6 and np.abs(res["link1_x.s"]).max() > 1e-8


@pytest.mark.parametrize("offset", [0.0, 2e-3])
def test_chain_drive_stiffness_is_block_tridiagonal(offset):
    n_links = 5
    K, mass, names = _stiffness(chains.chain_drive(n_links=n_links, offset_y=offset, offset_z=offset))
    index = {name: i for i, name in enumerate(names)}
    order = [index[f"link{i}_{q}"] for i in range(n_links) for q, _ in chains.LINK_COORDS]
    K = K[np.ix_(order, order)]
    np.testing.assert_allclose(K, K.T, rtol=1e-12, atol=1e-9)
    assert np.all(np.linalg.eigvalsh(K) > 0)                  # held at both sprockets: no rigid motion
    blocks = K.reshape(n_links, 6, n_links, 6).transpose(0, 2, 1, 3)
    def off_diagonal(block):
        return np.count_nonzero(np.abs(block - np.diag(np.diag(block))) > 1e-9 * np.abs(block).max())
    for i in range(n_links):
        for j in range(n_links):
            if abs(i - j) > 1:
                assert np.all(blocks[i, j] == 0)
        if i + 1 < n_links:
            assert off_diagonal(blocks[i, i + 1]) >= 4         # y-rz and z-ry between neighbours
        # within a link the shear couplings of its two joints cancel unless the joints are eccentric
        assert (off_diagonal(blocks[i, i]) >= 8) if offset else (off_diagonal(blocks[i, i]) == 0)
