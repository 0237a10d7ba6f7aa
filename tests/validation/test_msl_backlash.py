"""MSL ``Rotational.Examples.Backlash`` rebuilt with the public API, compared
with the Dymola reference and with an event-located solution of the same law.

The example: two inertias J = 5 kg m^2, each starting at rest at 90 deg and
tied to the ground, one by a spring-damper (c = 2e4 N m/rad, d = 50 N m s/rad),
the other by an ElastoBacklash (same c, d, total backlash b = 45 deg); 1 s.
The reference file holds ``elastoBacklash.phi_rel/w_rel`` and
``springDamper.phi_rel/w_rel`` (the example's third branch, ElastoBacklash2,
is not in the file).

Tolerances. The MSL regression tube is 2e-3 (relative to the signal's
range). The Dymola reference itself (DASSL, tolerance 1e-6) is off the exact
solution by 2.1e-5 rad in phi_rel (7e-6 of the range) and 1.3e-3 rad/s in
w_rel (1.1e-5 of the range), measured here for the backlash against an
event-located solution and for the spring-damper against its closed form
(1.7e-5 rad, 9.7e-4 rad/s). So we ask 1e-4 of the range against the
reference (20 times inside the MSL tube, about 10 times the reference's own
error) and 1e-5 of the range against the exact solution.

Kinks. The backlash law is continuous with a kink at contact; IDA does not
stop there (compliant devices have no events), step control resolves the
kink. Measured max errors against the exact solutions (rtol = 1e-6 / 1e-8 /
1e-10, atol = rtol/100, output every 5e-4 s): backlash phi_rel 4.9e-5 /
2.3e-6 / 6.1e-9 rad, w_rel 2.5e-3 / 1.3e-4 / 2.3e-7 rad/s; spring-damper
phi_rel 4.3e-6 / 1.8e-7 / 3.2e-9 rad. The kinks cost a factor 10-13 in
error at rtol 1e-6..1e-8 and 2 at 1e-10; the error falls with the
tolerance. At rtol 1e-8 (used here) the backlash error is 8e-7 of the
range, 9 times below the reference's.
"""

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import solve_ivp

import regmech as rm
from regmech.components import Fixed, Inertia, SpringDamper
from regmech.components.backlash import ElastoBacklash

C, D, J, B, PHI0 = 20e3, 50.0, 5.0, np.pi / 4, np.pi / 2
RTOL = 1e-8


def build_backlash_example() -> rm.Model:
    m = rm.Model("Backlash")
    fixed1 = m.add(Fixed("fixed1"))
    fixed2 = m.add(Fixed("fixed2"))
    spring_damper = m.add(SpringDamper("springDamper", c=C, d=D))
    inertia1 = m.add(Inertia("inertia1", J=J, phi0=PHI0, w0=0.0))
    backlash = m.add(ElastoBacklash("elastoBacklash", c=C, d=D, b=B))
    inertia2 = m.add(Inertia("inertia2", J=J, phi0=PHI0, w0=0.0))
    m.connect(fixed1.flange, spring_damper.flange_a)
    m.connect(spring_damper.flange_b, inertia1.flange_a)
    m.connect(fixed2.flange, backlash.flange_a)
    m.connect(backlash.flange_b, inertia2.flange_a)
    return m


# ----------------------------------------------------------------- exact solutions
def spring_damper_exact(t):
    wn = np.sqrt(C / J)
    zeta = D / (2 * np.sqrt(C * J))
    wd = wn * np.sqrt(1 - zeta ** 2)
    env = PHI0 * np.exp(-zeta * wn * t)
    phi = env * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t))
    w = -env * (wn ** 2 / wd) * np.sin(wd * t)
    return phi, w


def _branch(p, w):
    """Active branch of the ElastoBacklash law: (side, kind) with kind 0 free, 1 separating
    (torque clipped to 0), 2 damping limited (2 tau_c), 3 spring + damper."""
    bh = B / 2
    if abs(p) <= bh:
        return 0, 0
    side = 1 if p > 0 else -1
    tc, td = C * (p - side * bh), D * w
    if side * (tc + td) <= 0:
        return side, 1
    return side, 2 if side * (td - tc) >= 0 else 3


def _torque(branch, p, w):
    side, kind = branch
    tc = C * (p - side * B / 2)
    return {0: 0.0, 1: 0.0, 2: 2 * tc, 3: tc + D * w}[kind]


def elasto_backlash_exact(t_out):
    """Event-located solution: each branch integrated with its own smooth law
    (DOP853, rtol 1e-13), stopping where any branch condition changes."""
    bh = B / 2
    conditions = [lambda t, y: y[0] - bh, lambda t, y: y[0] + bh,
                  lambda t, y: C * (y[0] - np.sign(y[0]) * bh) + D * y[1],
                  lambda t, y: D * y[1] - C * (y[0] - np.sign(y[0]) * bh)]
    for ev in conditions:
        ev.terminal = True
    t, y, pieces = 0.0, np.array([PHI0, 0.0]), []
    while t < t_out[-1]:
        branch = _branch(*y)
        sol = solve_ivp(lambda t, y: [y[1], -_torque(branch, *y) / J], (t, t_out[-1]), y, method="DOP853",
                        rtol=1e-13, atol=1e-13, events=conditions, dense_output=True)
        pieces.append(sol)
        t, y = sol.t[-1], sol.y[:, -1]
        if sol.status == 1:
            # step 1e-12 s past the switch with the new law (error ~1e-24) so that the
            # condition that fired is not found again at the start of the next piece
            dy = np.array([y[1], -_torque(_branch(*y), *y) / J])
            t, y = t + 1e-12, y + 1e-12 * dy
    out = np.empty((2, len(t_out)))
    for k, tk in enumerate(t_out):
        piece = next(p for p in pieces if tk <= p.t[-1] + 1e-12)
        out[:, k] = piece.sol(min(max(tk, piece.t[0]), piece.t[-1]))
    return out, len(pieces)


# ------------------------------------------------------------------------ tests
@pytest.fixture
def reference(reference_dir):
    ref = pd.read_csv(reference_dir / "Backlash.csv")
    # event instants appear twice in the file; compare on the regular output grid (5e-4 s)
    on_grid = np.isclose(ref["time"] / 5e-4, np.round(ref["time"] / 5e-4), rtol=0, atol=1e-6)
    return ref[on_grid].drop_duplicates("time").reset_index(drop=True)


@pytest.fixture(scope="module")
def result():
    return build_backlash_example().simulate(1.0, dt_out=5e-4, rtol=RTOL, atol=RTOL * 1e-2, solver="ida")


def _at(res, name, t):
    tt, first = np.unique(res.t, return_index=True)
    return np.interp(t, tt, res[name][first])


@pytest.mark.parametrize("column", ["elastoBacklash.phi_rel", "elastoBacklash.w_rel",
                                    "springDamper.phi_rel", "springDamper.w_rel"])
def test_against_msl_reference(reference, result, column):
    t = reference["time"].to_numpy()
    ref = reference[column].to_numpy()
    ours = _at(result, column, t)
    assert np.abs(ours - ref).max() < 1e-4 * np.ptp(ref)


def test_spring_damper_against_closed_form(reference, result):
    t = reference["time"].to_numpy()
    phi, w = spring_damper_exact(t)
    ref_err = np.abs(reference["springDamper.phi_rel"].to_numpy() - phi).max()
    ours_phi = np.abs(_at(result, "springDamper.phi_rel", t) - phi).max()
    ours_w = np.abs(_at(result, "springDamper.w_rel", t) - w).max()
    assert ours_phi < 1e-5 * np.ptp(phi) and ours_w < 1e-5 * np.ptp(w)
    assert ours_phi < ref_err


def test_elasto_backlash_against_event_located_solution(reference, result):
    t = reference["time"].to_numpy()
    exact, n_pieces = elasto_backlash_exact(t)
    assert n_pieces > 30                       # many contacts and separations in 1 s
    ref_err = np.abs(reference["elastoBacklash.phi_rel"].to_numpy() - exact[0]).max()
    ours_phi = np.abs(_at(result, "elastoBacklash.phi_rel", t) - exact[0]).max()
    ours_w = np.abs(_at(result, "elastoBacklash.w_rel", t) - exact[1]).max()
    assert ours_phi < 1e-5 * np.ptp(exact[0]) and ours_w < 1e-5 * np.ptp(exact[1])
    assert ours_phi < ref_err                   # closer to the exact solution than Dymola's file


def test_energy_audit_of_the_example(result):
    # nothing drives the example: the power the link absorbs is the kinetic energy lost,
    # and kinetic + stored energy only falls
    t = result.t
    for inertia, link in (("inertia1", "springDamper"), ("inertia2", "elastoBacklash")):
        kinetic = result[f"{inertia}.kinetic"]
        stored = kinetic + result[f"{link}.potential"]
        power = result[f"{link}.power"]
        absorbed = np.concatenate([[0.0], np.cumsum(np.diff(t) * (power[1:] + power[:-1]) / 2)])
        np.testing.assert_allclose(kinetic - kinetic[0], -absorbed, atol=2e-3 * stored[0])
        assert np.all(np.diff(stored) <= 1e-6 * stored[0])
        assert stored[-1] < 0.5 * stored[0]
