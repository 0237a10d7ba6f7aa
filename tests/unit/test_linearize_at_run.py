"""Linearising where the run is: ``m.linearize(at=res, t=T)`` takes the state and the friction
modes of the run at T; the scene's start values do not get in the way; ``regmech modes SCENE --t T``."""

import numpy as np
import pytest

import regmech as rm
from regmech.analysis.cli import modes_main
from regmech.analysis.modal import modal
from regmech.components import Clutch, Inertia, Spring
from regmech.errors import ParameterError
from regmech.library import SCENES

C, J1, J2, J3 = 100.0, 1.0, 1.0, 2.0


def stuck_pair():
    """J1 (10 rad/s) drags J2 (at rest) through a clutch until they lock (about 1.5 s); J2 drives J3 through
    a spring. Locked: one rigid mode and w^2 = C (1/(J1 + J2) + 1/J3); clutch Free: two rigid modes and
    w^2 = C (1/J2 + 1/J3)."""
    m = rm.Model("stuck_pair")
    a = m.add(Inertia("J1", J=J1, phi0=0.0, w0=10.0))
    cl = m.add(Clutch("clutch", mu=1.0, peak=2.0, cgeo=1.0, fn_max=5.0))
    b = m.add(Inertia("J2", J=J2, phi0=0.0, w0=0.0))
    s = m.add(Spring("spring", c=C))
    d = m.add(Inertia("J3", J=J3, phi0=0.0, w0=0.0))
    m.connect(a.flange_b, cl.flange_a)
    m.connect(cl.flange_b, b.flange_a)
    m.connect(b.flange_b, s.flange_a)
    m.connect(s.flange_b, d.flange_a)
    return m


def test_stuck_clutch_of_the_run_against_the_closed_form():
    m = stuck_pair()
    res = m.simulate(6.0, dt_out=1e-3)
    lock = [ev.t for ev in res.events if ev.component == "clutch" and ev.new_mode == 0]
    assert lock and lock[-1] < 2.0 and res.final("clutch.mode") == 0
    lin = m.linearize(at=res, t=2.5)
    assert list(lin.modes) == [0]                     # the run's mode, not the start's (Free/sliding)
    for k, name in enumerate(lin.full_names):         # the run's state at 2.5 s
        if name in ("J1", "J2", "J3"):
            assert lin.v0[k] == pytest.approx(res.at(f"{name}.w", 2.5), rel=1e-6, abs=1e-9)
    stuck = modal(lin)
    w_stuck = np.sqrt(C * (1 / (J1 + J2) + 1 / J3))
    assert stuck.rigid.sum() == 1
    assert stuck.omega[~stuck.rigid] == pytest.approx([w_stuck], rel=1e-9)
    free = modal(m.linearize(at=res, t=2.5, modes={"clutch": "Free"}))
    assert free.rigid.sum() == stuck.rigid.sum() + 1
    assert free.omega[~free.rigid] == pytest.approx([np.sqrt(C * (1 / J2 + 1 / J3))], rel=1e-9)
    # the run itself oscillates at the linearised frequency once locked: upward zero crossings of the spring
    # torque (no damping, no external torque: it swings about 0)
    t, tau = res.t, res["spring.tau"]
    keep = t > lock[-1] + 0.1
    t, tau = t[keep], tau[keep]
    i = np.nonzero((tau[:-1] < 0) & (tau[1:] >= 0))[0]
    ups = t[i] - tau[i] * (t[i + 1] - t[i]) / (tau[i + 1] - tau[i])
    assert len(ups) >= 4
    assert np.mean(np.diff(ups)) == pytest.approx(2 * np.pi / w_stuck, rel=2e-3)


def test_a_loaded_result_gives_the_same_linearisation(tmp_path):
    m = stuck_pair()
    res = m.simulate(3.0)
    back = rm.load_result(res.save(tmp_path / "pair.mat"))
    a, b = m.linearize(at=res, t=2.5), m.linearize(at=back, t=2.5)
    assert list(a.modes) == list(b.modes) == [0]
    np.testing.assert_allclose(b.v0, a.v0, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(b.C, a.C, rtol=1e-12)


def test_modes_asked_against_the_start_values_warn_instead_of_failing():
    m = stuck_pair()
    with pytest.warns(UserWarning, match="contradict the modes asked for"):
        lin = m.linearize(t=0.0, modes={"clutch": "Stuck"})
    # mass-weighted: J1 and J2 share the momentum J1 * 10
    k1, k2 = lin.full_names.index("J1"), lin.full_names.index("J2")
    assert lin.v0[k1] == lin.v0[k2] == pytest.approx(10.0 * J1 / (J1 + J2))


def test_time_outside_the_run_and_a_foreign_result_are_refused():
    m = stuck_pair()
    res = m.simulate(1.0)
    with pytest.raises(ParameterError, match="must lie in the run"):
        m.linearize(at=res, t=2.0)
    other = SCENES["first"]().simulate(0.05)
    with pytest.raises(ParameterError, match="has no signal"):
        m.linearize(at=other, t=0.01)


def test_vehicle_launch_at_two_seconds_has_the_clutch_stuck():
    m = SCENES["vehicle_launch"]()
    res = m.simulate(2.0)
    stuck = m.linearize(at=res, t=2.0)
    names = [r.device.name for r in stuck.compiled.structure.friction]
    assert stuck.modes[names.index("clutch")] == 0
    free = m.linearize(at=res, t=2.0, modes={"clutch": "Free"})
    assert modal(free).rigid.sum() == modal(stuck).rigid.sum() + 1
    assert stuck.n == free.n - 1


def test_modes_command_runs_to_the_instant_and_says_which_modes(capsys):
    assert modes_main(["vehicle_launch", "--t", "2"]) == 0
    at_two = capsys.readouterr().out
    assert "the run to t=2 s" in at_two and "clutch Stuck (since 0.87" in at_two
    assert modes_main(["vehicle_launch"]) == 0
    at_zero = capsys.readouterr().out
    assert "start values" in at_zero and "clutch Free" in at_zero
    assert at_two.splitlines()[0] != at_zero.splitlines()[0]
    assert modes_main(["vehicle_launch", "--mode", "clutch=Stuck"]) == 0
    out = capsys.readouterr().out
    assert "clutch Stuck (asked)" in out and "note:" in out
    assert modes_main(["vehicle_launch", "--t", "-1"]) == 2


def test_only_rigid_body_modes_are_said_in_a_sentence(capsys):
    assert modes_main(["coupled_clutches"]) == 0
    out = capsys.readouterr().out
    assert "all 4 mode(s) are rigid-body modes" in out
    assert "mode 1        0" not in out and "undamped natural frequencies" not in out
