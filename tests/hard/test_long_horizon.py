"""Long horizons: an undamped 4-mass chain over 10^4 steps (CI; 10^6 in the benchmark); energy drift."""

import pytest

from hard_helpers import assert_passes, outcome


@pytest.mark.parametrize("solver", ["ida", "scipy:DOP853", "expm"])
def test_energy_is_kept_over_a_long_horizon(solver):
    assert_passes(outcome("long_horizon", solver))


def test_fixed_step_rk4_reports_its_energy_loss_honestly():
    # no error control: rk4 at h = 0.01 s (omega_max h = 0.19) loses energy like (omega h)^6 per step;
    # the check reports the drift instead of passing it off as correct
    out = outcome("long_horizon", "rk4")
    assert out.verdict == "fail" and "inaccurate" in out.reason
    assert 1e-4 < out.value < 1e-1
