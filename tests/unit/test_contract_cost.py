"""What the accuracy contract costs: its state signals read from the stored rows, its first tolerance (issue
14/15, regmech.solvers.accuracy)."""

import numpy as np
import pytest

from regmech.bench.calibration import all_cases
from regmech.solvers.accuracy import result_state_labels, state_columns, state_matrix
from regmech.solvers.common import output_grid

CASES = {c.key: c for c in all_cases()}


@pytest.mark.parametrize("key", ["coupled_clutches", "electric_car", "train_10", "gear_shift", "excavator_swing",
                                 "near_rigid_shaft"])
def test_state_columns_read_what_the_named_signals_hold(key):
    """The contract reads its state signals from the trajectory's columns (``state_columns``); they must be
    exactly the named signals (positions and speeds of the masses, device states) the user reads."""
    case = CASES[key]
    m = case.build()
    c = m.compile()
    t_end = min(case.t_end, 0.3)
    res = m.simulate(t_end, case.dt_out, solver="ida", rtol=1e-5)
    labels = result_state_labels(c)
    grid = output_grid(0.0, t_end, case.dt_out)
    fast = state_matrix(res, labels, grid, state_columns(c))
    named = state_matrix(res, labels, grid)
    assert fast.shape == named.shape == (len(grid), len(labels))
    np.testing.assert_array_equal(fast, named)
