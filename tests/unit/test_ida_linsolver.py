"""IDA's choice of linear solver (regmech.solvers.ida.choose_linsolver) and agreement of the three."""

import numpy as np

from regmech.bench.hard_models import satellite_hub
from regmech.library import train
from regmech.solvers.ida import choose_linsolver


def _hub(n):
    """A hub joined to n satellites: no ordering gives a narrow band."""
    return satellite_hub(n)


def test_small_dense_narrow_band_wide_dense_then_sparse():
    assert choose_linsolver(train(10, c_r=0.0).compile())[0] == "dense"
    assert choose_linsolver(train(100, c_r=0.0).compile())[0] == "band"
    assert choose_linsolver(_hub(40).compile())[0] == "dense"      # N = 82, bandwidth 2N - 1
    assert choose_linsolver(_hub(250).compile())[0] == "sparse"    # N = 502


def test_the_three_linear_solvers_give_the_same_answer():
    model = _hub(30)
    runs = {ls: model.simulate(1.0, dt_out=0.01, solver="ida", rtol=1e-8, linsolver=ls)
            for ls in ("dense", "band", "sparse")}
    ref = runs["dense"]["sat7.w"]
    for ls in ("band", "sparse"):
        assert np.max(np.abs(runs[ls]["sat7.w"] - ref)) < 1e-5 * np.ptp(ref)
