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
