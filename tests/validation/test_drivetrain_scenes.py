"""The 6-speed car with torque converter and the dual-clutch car (library.drivetrains): they run,
their books close, each gear has its ratio once locked, the converter stalls and locks up, the
Gearbox interrupts the torque at a shift and the DCT does not."""

import numpy as np
import pytest

from regmech.bench.fuzz import energy_checks
from regmech.library import SCENES
from regmech.library.drivetrains import SEVEN_SPEED_DCT, SIX_SPEED


@pytest.fixture(scope="module")
def six():
    m = SCENES["six_speed_car"]()
    return m, m.simulate(12.0, dt_out=5e-3, solver="ida", rtol=1e-7, atol=1e-7)


@pytest.fixture(scope="module")
def dct():
    m = SCENES["dct_car"]()
    return m, m.simulate(10.0, dt_out=5e-3, solver="ida", rtol=1e-7, atol=1e-7)


def _at(res, t):
    return int(np.searchsorted(res.t, t))


@pytest.mark.slow
def test_six_speed_car_ratios_converter_and_books(six):
    m, res = six
    w_in, w_out = res["gearbox.input.w"], res["gearbox.output.w"]
    # locked gears: the ratio of the box (after each element's lock-up, before the next shift)
    for t, gear in ((2.5, 1), (5.5, 2), (9.0, 3), (11.5, 4)):
        k = _at(res, t)
        assert res[f"gearbox.shift{gear}.mode"][k] == 0
        assert w_in[k] / w_out[k] == pytest.approx(SIX_SPEED[gear - 1], rel=1e-6)
    # the converter slips (nu < 1) before the lock-up and not after it
    k = _at(res, 0.5)           # launch: the converter multiplies the torque at a low speed ratio
    assert res["converter.turbine.w"][k] < 0.5 * res["converter.pump.w"][k]
    assert -res["converter.fluid.turbine.tau"][k] > 1.3 * res["converter.fluid.tau"][k]
    k = _at(res, 8.5)
    assert res["converter.lockup.mode"][k] == 0
    assert res["converter.turbine.w"][k] == pytest.approx(res["converter.pump.w"][k], rel=1e-7)
    # torque interruption in each shift: between release (t_s + 0.1) and engagement (t_s + 0.15)
    for t_s, old, new in ((3.0, 1, 2), (6.0, 2, 3), (9.5, 3, 4)):
        gap = (res.t > t_s + 0.101) & (res.t < t_s + 0.149)
        assert np.all(res[f"gearbox.shift{old}.tau"][gap] == 0) and np.all(res[f"gearbox.shift{new}.tau"][gap] == 0)
    assert res["body.v"][-1] > 15.0
    assert not energy_checks(res, m, rel=1e-5)


@pytest.mark.slow
def test_dct_car_launch_handover_and_books(dct):
    m, res = dct
    # the launch clutch slips, then locks
    kinds = [(e.component, e.old_mode, e.new_mode) for e in res.events]
    assert kinds[0] == ("dct.K1", 2, -1)
    assert ("dct.K1", -1, 0) in kinds
    w_drum, w_out = res["dct.drum.w"], res["dct.output.w"]
    for t, gear in ((2.4, 1), (4.9, 2), (7.9, 3), (9.9, 4)):
        k = _at(res, t)
        assert w_drum[k] / w_out[k] == pytest.approx(SEVEN_SPEED_DCT[gear - 1], rel=1e-6)
    # no torque interruption: during every handover one of the clutches carries torque
    for t_s in (2.5, 5.0, 8.0):
        win = (res.t > t_s + 0.1) & (res.t < t_s + 0.4)
        carried = np.abs(res["dct.K1.tau"][win]) + np.abs(res["dct.K2.tau"][win])
        assert carried.min() > 20.0
    assert not energy_checks(res, m, rel=1e-5)
