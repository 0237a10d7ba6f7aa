import math

import pytest

from regmech.errors import ParameterError
from regmech.signals import Constant, Ramp, Sine, Step, Table, as_signal


def test_step_left_and_right_limits():
    s = Step(height=2.0, start_time=0.4, offset=1.0)
    assert s(0.39) == 1.0 and s(0.4) == 3.0 and s(0.4, left=True) == 1.0
    assert s.breakpoints() == (0.4,)


def test_ramp_values_derivative_breakpoints():
    r = Ramp(height=3.0, duration=2.0, start_time=1.0, offset=-1.0)
    assert r(0.5) == -1.0 and r(2.0) == pytest.approx(0.5) and r(5.0) == 2.0
    assert r.derivative(2.0) == 1.5 and r.derivative(3.0) == 0.0 and r.derivative(3.0, left=True) == 1.5
    assert r.breakpoints() == (1.0, 3.0)


def test_sine_matches_msl_definition_and_derivatives():
    s = Sine(amplitude=2.0, freq_hz=5.0, phase=0.3, offset=1.0, start_time=0.1)
    t = 0.37
    w = 2 * math.pi * 5.0
    assert s(t) == pytest.approx(1.0 + 2.0 * math.sin(w * (t - 0.1) + 0.3))
    assert s.derivative(t) == pytest.approx(2.0 * w * math.cos(w * (t - 0.1) + 0.3))
    assert s.derivative(t, 2) == pytest.approx(-2.0 * w * w * math.sin(w * (t - 0.1) + 0.3))
    assert s(0.05) == 1.0


def test_table_interpolates_and_jumps():
    tab = Table([(0.0, 0.0), (1.0, 2.0), (1.0, 5.0), (2.0, 5.0)])
    assert tab(0.5) == 1.0 and tab(1.0) == 5.0 and tab(1.0, left=True) == 2.0 and tab(3.0) == 5.0
    assert tab.derivative(0.5) == 2.0
    with pytest.raises(ParameterError):
        Table([(1.0, 0.0), (0.0, 1.0)])
    with pytest.raises(ParameterError):
        Table([(0.0, float("nan"))])


def test_as_signal():
    assert isinstance(as_signal(3), Constant)
    assert as_signal(lambda t: t * t).derivative(3.0) == pytest.approx(6.0, rel=1e-6)
    with pytest.raises(ParameterError):
        as_signal(float("inf"))
