"""Random drivetrains with the components of issue 17 (end stops, gaps, speed-dependent loads, Stribeck
clutches and brakes, LinearBrake, VehicleLoad, Gearbox, TorqueConverter): the property of
``test_fuzz.py`` (no finding of ``regmech.bench.fuzz.evaluate``) on models drawn from these families.

A file of its own: hypothesis derives its derandomized examples from the test module, so adding a group to
``test_fuzz.py`` changed the models its other groups draw."""

import pytest

hypothesis = pytest.importorskip("hypothesis")

from hypothesis import given, strategies as st  # noqa: E402

from test_fuzz import SOURCES, _check, _settings, GROUPS, EXAMPLES  # noqa: E402

GROUPS["driveline"] = ["end_stop", "elasto_gap", "speed_load", "stribeck_clutch", "linear_brake", "vehicle_load",
                       "gearbox", "torque_converter", "spring_damper"]
EXAMPLES["driveline"] = 8
assert SOURCES


@_settings("driveline")
@given(rng=st.randoms(use_true_random=False))
def test_random_drivelines_with_stops_loads_and_transmissions(rng):
    _check(rng, "driveline")
