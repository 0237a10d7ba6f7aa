"""Stretched spectra: chains whose natural frequencies span 1e3, 1e5, 1e7, and a near-rigid shaft.

Answers: the exact response of the same chain from hand-assembled matrices
(``regmech.bench.linear_ref``; 30-digit arithmetic beyond a spread of 1e4).
"""

import pytest

from hard_helpers import assert_passes, outcome


@pytest.mark.parametrize("key, solver", [
    ("stretched_1e3", "ida"), ("stretched_1e3", "scipy:RK45"), ("stretched_1e3", "expm"),
    ("stretched_1e5", "ida"), ("stretched_1e5", "scipy:LSODA"), ("stretched_1e5", "expm"),
    ("stretched_1e7", "scipy:Radau"), ("stretched_1e7", "scipy:LSODA"),
    ("near_rigid_shaft", "ida"), ("near_rigid_shaft", "scipy:BDF"), ("near_rigid_shaft", "expm"),
])
def test_stiff_chain_is_solved_within_tolerance(key, solver):
    assert_passes(outcome(key, solver))


# (was xfail: IDA crawled; it now refuses up front, naming the stiff link)
def test_ida_on_frequency_ratio_1e7_finishes_or_names_the_stiff_link():
    out = outcome("stretched_1e7", "ida")
    assert out.verdict in ("pass", "refuse"), out.reason
    assert out.verdict == "pass" or "'link5'" in out.reason


@pytest.mark.xfail(strict=True, reason="expm loses accuracy to round-off at a frequency ratio of 1e7 "
                   "(error 1.7e-3 of the range at h = 0.01 s; the exact answer is reached to 1e-12 at 1e3)")
def test_expm_on_frequency_ratio_1e7_is_accurate_or_refuses():
    out = outcome("stretched_1e7", "expm")
    assert out.verdict in ("pass", "refuse"), out.reason


@pytest.mark.xfail(strict=True, reason="explicit adaptive scipy solvers have no step bound in regmech's ODE "
                   "driver: on a stiff chain they crawl at the stability limit instead of stopping with an "
                   "error that names the stiff link (no max_steps option)")
def test_explicit_adaptive_solver_on_stiff_chain_stops_clearly():
    out = outcome("stretched_1e5", "scipy:RK45", budget=20_000)
    assert out.verdict in ("pass", "refuse"), out.reason


@pytest.mark.xfail(strict=True, reason="the divergence error of the fixed-step explicit solvers names the model "
                   "and the spectral radius but not the component (the stiff link) responsible")
def test_fixed_step_blow_up_names_the_stiff_link():
    out = outcome("near_rigid_shaft", "rk4")
    assert out.verdict == "refuse", out.reason


def test_fixed_step_blow_up_is_a_regmech_error_not_a_nan():
    out = outcome("near_rigid_shaft", "rk4")
    assert out.verdict != "pass"
    assert "SimulationError" in out.reason and "near_rigid_shaft" in out.reason
