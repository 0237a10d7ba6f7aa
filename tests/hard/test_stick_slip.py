"""Stick/slip: a limit cycle with dozens (CI) to hundreds (benchmark) of lock/unlock events,
three clutches locking at one instant, engagement at exactly zero slip, a brake on a slope.

Answers: closed forms (phase durations of the belt oscillator, lock time and
momentum, constant accelerations, break-away time and the sliding motion).
"""

import pytest

from hard_helpers import assert_passes, outcome

# long-running (over 2 s on 2 cores): left out of the fast lane, pytest -m 'not slow'
pytestmark = pytest.mark.slow


@pytest.mark.parametrize("key, solver", [
    ("belt_limit_cycle", "ida"), ("belt_limit_cycle", "scipy:RK45"), ("belt_limit_cycle", "scipy:DOP853"),
    ("simultaneous_lock", "ida"),
    ("zero_speed_engagement", "ida"), ("zero_speed_engagement", "rk4"), ("zero_speed_engagement", "scipy:RK45"),
    ("zero_speed_engagement", "scipy:Radau"), ("zero_speed_engagement", "expm"),
    ("slope_hold", "ida"), ("slope_hold", "rk4"), ("slope_hold", "scipy:BDF"), ("slope_hold", "expm"),
])
def test_stick_slip_is_solved_within_tolerance(key, solver):
    assert_passes(outcome(key, solver))


@pytest.mark.parametrize("solver", ["scipy:RK45", "rk4", "expm"])
# (was xfail: a device already past zero slip by round-off at an event now locks with the others)
def test_simultaneous_locking_in_the_ode_form_solvers(solver):
    assert_passes(outcome("simultaneous_lock", solver))


@pytest.mark.parametrize("solver", ["scipy:RK45", "scipy:Radau", "rk4"])
def test_a_held_vehicle_does_not_drift_in_the_ode_form(solver):
    # the KKT solve leaves the held row's acceleration at round-off (4e-16 m/s^2), which integrated
    # over the full-size 10^4 s hold drifted 1.9e-8 m; the ODE form now projects it away exactly
    import numpy as np
    from regmech.bench.hard_models import slope_hold
    model, t_b, _ = slope_hold(t_hold=100.0)
    opts = {"h": 0.05} if solver == "rk4" else {"rtol": 1e-8}
    res = model.simulate(105.0, dt_out=0.05, solver=solver, **opts)
    held = res.t < 100.0
    assert np.all(res["vehicle.s"][held] == 0.0) and np.all(res["vehicle.v"][held] == 0.0)
    assert abs(res.events[0].t - t_b) < 1e-6
