"""FrictionContact's sign convention (issue 17, item 9): the mode names the direction of v_rel = v_b - v_a,
so it flips with the side the ground is on; the motion does not."""

import pytest

import regmech as rm
from regmech.components import Fixed, FrictionContact, Mass


@pytest.mark.parametrize("ground_on", ["flange_a", "flange_b"])
def test_block_on_a_floor_reads_forward_or_backward_by_the_ground_side(ground_on):
    m = rm.Model("floor")
    floor = m.add(Fixed("floor", domain="translational"))
    c = m.add(FrictionContact("c", mu=0.3, fn=9.81 * 2.0))
    M = m.add(Mass("M", m=2.0, v0=1.0))
    if ground_on == "flange_a":     # the docstring's example
        m.connect(floor.flange, c.flange_a)
        m.connect(c.flange_b, M.flange_a)
    else:
        m.connect(M.flange_b, c.flange_a)
        m.connect(c.flange_b, floor.flange)
    r = m.simulate(0.5, 0.05, solver="ida", rtol=1e-8)
    sign = 1 if ground_on == "flange_a" else -1
    assert r["c.mode"][0] == sign                       # Forward with the ground on flange_a
    assert r["c.f"][0] == pytest.approx(sign * 0.3 * 9.81 * 2.0, rel=1e-9)
    # the same physics either way: the block stops at v0 / (mu g)
    (ev,) = r.events
    assert (ev.old_mode, ev.new_mode) == (sign, 0)
    assert ev.t == pytest.approx(1.0 / (0.3 * 9.81), rel=1e-6)
