"""FrictionContact's sign convention, as its docstring states it: the mode is the sign of
v_rel = v_b - v_a, so the side the ground is on flips Forward and Backward; the force on the
block opposes its motion in both wirings."""

import pytest

import regmech as rm
from regmech.components import Fixed, FrictionContact, Mass


@pytest.mark.parametrize("ground_on_b, mode", [(True, -1), (False, 1)])
def test_mode_follows_v_rel_and_the_force_brakes_the_block(ground_on_b, mode):
    m = rm.Model("fc")
    M = m.add(Mass("M", m=1.0, s0=0.0, v0=2.0))
    wall = m.add(Fixed("wall", domain="translational"))
    c = m.add(FrictionContact("c", mu=0.5, fn=1.0))
    if ground_on_b:
        m.connect(M.flange_b, c.flange_a)
        m.connect(c.flange_b, wall.flange)
    else:
        m.connect(wall.flange, c.flange_a)
        m.connect(c.flange_b, M.flange_a)
    res = m.simulate(0.1, dt_out=0.05, solver="ida", rtol=1e-10)
    assert res["c.mode"][-1] == mode
    assert res["c.v_rel"][-1] * mode > 0
    assert res["c.f"][-1] == pytest.approx(mode * 0.5)
    assert res["M.a"][-1] == pytest.approx(-0.5)        # braking either way


@pytest.mark.parametrize("ground_on_a", [True, False])
def test_the_docstring_example_stops_at_the_closed_form_time(ground_on_a):
    """The docstring's block (2 kg at 1 m/s, mu 0.3, fn = m g): Forward with the ground on flange_a, Backward
    with it on flange_b; either way it stops at v0 / (mu g), one event from sliding to Stuck."""
    m = rm.Model("floor")
    floor = m.add(Fixed("floor", domain="translational"))
    c = m.add(FrictionContact("c", mu=0.3, fn=9.81 * 2.0))
    M = m.add(Mass("M", m=2.0, v0=1.0))
    if ground_on_a:
        m.connect(floor.flange, c.flange_a)
        m.connect(c.flange_b, M.flange_a)
    else:
        m.connect(M.flange_b, c.flange_a)
        m.connect(c.flange_b, floor.flange)
    r = m.simulate(0.5, 0.05, solver="ida", rtol=1e-8)
    sign = 1 if ground_on_a else -1
    assert r["c.mode"][0] == sign
    assert r["c.f"][0] == pytest.approx(sign * 0.3 * 9.81 * 2.0, rel=1e-9)
    (ev,) = r.events
    assert (ev.old_mode, ev.new_mode) == (sign, 0)
    assert ev.t == pytest.approx(1.0 / (0.3 * 9.81), rel=1e-6)
