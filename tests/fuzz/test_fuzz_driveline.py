"""Random drivetrains with the components of issue 17 (end stops, gaps, speed-dependent loads, Stribeck
clutches and brakes, LinearBrake, VehicleLoad, Gearbox, TorqueConverter): the property of
``test_fuzz.py`` (no finding of ``regmech.bench.fuzz.evaluate``) on models drawn from these families.

Fixed seeds as in ``test_fuzz.py`` (the same models on every machine); ``FUZZ_HYPOTHESIS=N`` explores."""

import random

import pytest

hypothesis = pytest.importorskip("hypothesis")

from hypothesis import given, strategies as st  # noqa: E402

from test_fuzz import EXAMPLES, EXPLORE, GROUPS, SOURCES, _check, _settings, seeds  # noqa: E402

GROUPS["driveline"] = ["end_stop", "elasto_gap", "speed_load", "stribeck_clutch", "linear_brake", "vehicle_load",
                       "gearbox", "torque_converter", "spring_damper"]
EXAMPLES["driveline"] = 8
assert SOURCES


SEEDS = seeds("driveline", base=9000, count=EXAMPLES["driveline"])


@pytest.mark.parametrize("seed", SEEDS)
def test_random_drivelines_with_stops_loads_and_transmissions(seed):
    _check(random.Random(seed), "driveline")


@pytest.mark.skipif(not EXPLORE, reason="exploration: set FUZZ_HYPOTHESIS=N")
def test_hypothesis_exploration_driveline():
    @_settings("driveline")
    @given(rng=st.randoms(use_true_random=False))
    def run(rng):
        _check(rng, "driveline")
    run()
