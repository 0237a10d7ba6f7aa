"""Solver options, times and result look-ups: every bad input is a regmech error that names the argument
and the fix, checked once for all solvers (regmech.solvers.options)."""

import inspect

import numpy as np
import pytest

import regmech as rm
from regmech.components import Fixed, Inertia, Position, Spring, Torque
from regmech.signals import Sine
from regmech.solvers import SOLVERS, _load, check_options
from regmech.solvers.options import MAX_POINTS, RTOL_MIN, output_points

_load()
ALL = sorted(SOLVERS)
ADAPTIVE = [s for s in ALL if "rtol" in SOLVERS[s].options]           # ida, convolution, scipy:*
FIXED_STEP = [s for s in ALL if "rtol" not in SOLVERS[s].options]      # euler, rk4, abm, expm
#: the solvers run on a model in the tests below (one per family, to keep the suite short)
RUN = ["ida", "scipy:RK45", "scipy:Radau", "convolution", "rk4", "expm"]


def two_masses(J1=1.0, name="two_masses"):
    m = rm.Model(name)
    drive = m.add(Torque("drive", tau=Sine(amplitude=1.0, freq_hz=1.0)))
    a = m.add(Inertia("J1", J=J1, w0=1.0))
    k = m.add(Spring("spring", c=100.0))
    b = m.add(Inertia("J2", J=1.0))
    m.connect(drive.flange, a.flange_a)
    m.connect(a.flange_b, k.flange_a)
    m.connect(k.flange_b, b.flange_a)
    return m


def small_step(solver):
    return {"h": 1e-3} if solver in FIXED_STEP else {}


# ------------------------------------------------------------------ the declared option sets
@pytest.mark.parametrize("solver", ALL)
def test_declared_options_are_the_solver_function_s_keywords(solver):
    fn = SOLVERS[solver]
    params = set(inspect.signature(fn.__wrapped__).parameters) - {"model", "t_start", "t_end", "dt_out"}
    assert set(fn.options) == params


@pytest.mark.parametrize("solver", ALL)
def test_every_option_refuses_a_string_and_nan_naming_itself(solver):
    """No option reaches a solver unchecked: a str or a NaN is refused by name (before any model is built)."""
    for name in SOLVERS[solver].options:
        for bad in ("x", float("nan")):
            with pytest.raises(rm.ParameterError, match=f"solver '{solver}': {name} must be"):
                check_options(t_end=1.0, solver=solver, **{name: bad})


# ------------------------------------------------------------------ unknown and misspelt options
@pytest.mark.parametrize("solver", ALL)
def test_a_misspelt_option_lists_the_valid_ones_and_the_closest(solver):
    opts = SOLVERS[solver].options
    with pytest.raises(rm.ParameterError) as err:
        two_masses().simulate(0.1, solver=solver, rtoll=1e-6)
    msg = str(err.value)
    assert f"solver '{solver}' has no option 'rtoll'" in msg
    assert "Its options: " + ", ".join(opts) in msg
    closest = "rtol" if solver in ADAPTIVE else "tol"
    assert f"did you mean '{closest}'" in msg


@pytest.mark.parametrize("solver", FIXED_STEP)
def test_rtol_on_a_fixed_step_solver_says_which_solvers_take_it(solver):
    with pytest.raises(rm.ParameterError) as err:
        two_masses().simulate(0.1, solver=solver, rtol=1e-6)
    msg = str(err.value)
    assert "'rtol' is an option of convolution, dop853, dopri5, ida, scipy:*" in msg and "step h" in msg and "tol" in msg


def test_a_misspelt_time_argument_is_suggested_too():
    with pytest.raises(rm.ParameterError, match="did you mean 'dt_out'"):
        two_masses().simulate(0.1, dt_ou=1e-3)


def test_an_unknown_solver_suggests_the_closest():
    with pytest.raises(rm.ParameterError, match=r"unknown solver 'idaa' \(did you mean 'ida'\?\)"):
        two_masses().simulate(0.1, solver="idaa")


# ------------------------------------------------------------------ values
@pytest.mark.parametrize("solver", ADAPTIVE)
@pytest.mark.parametrize("bad", [0.0, -1e-6, float("nan"), 1e-20, 1.0, float("inf")])
def test_rtol_out_of_range_states_the_real_bounds(solver, bad):
    with pytest.raises(rm.ParameterError) as err:
        check_options(t_end=1.0, solver=solver, rtol=bad)
    assert f"rtol must be a number in [{RTOL_MIN:.3g}, 1)" in str(err.value)


@pytest.mark.parametrize("solver", ADAPTIVE)
def test_rtol_as_a_string_is_refused_with_the_number_to_pass(solver):
    with pytest.raises(rm.ParameterError, match=r"Pass the number itself: rtol=1e-06, not the string '1e-6'"):
        check_options(t_end=1.0, solver=solver, rtol="1e-6")


@pytest.mark.parametrize("solver", ADAPTIVE)
@pytest.mark.parametrize("bad", [-1e-8, 0.0, float("nan"), [1e-8, -1.0]])
def test_atol_must_be_positive(solver, bad):
    with pytest.raises(rm.ParameterError, match="atol must be a positive number"):
        check_options(t_end=1.0, solver=solver, atol=bad)


@pytest.mark.parametrize("solver", ["ida", "scipy:RK45", "convolution"])
def test_an_atol_array_needs_one_entry_per_unknown(solver):
    m = two_masses()
    c = m.compile()
    size = c.N if solver == "ida" else c.ode_size()
    with pytest.raises(rm.ParameterError, match=f"has {size + 1} entries but model 'two_masses' needs {size}, one"):
        m.simulate(0.1, solver=solver, atol=np.full(size + 1, 1e-8))
    res = m.simulate(0.1, solver=solver, atol=np.full(size, 1e-8))
    assert np.all(np.isfinite(res["J1.w"]))


@pytest.mark.parametrize("solver", ["ida", "scipy:RK45", "scipy:Radau", "convolution"])
@pytest.mark.parametrize("bad", [0, -3, 2.5, True])
def test_max_steps_must_be_a_whole_number_of_at_least_one(solver, bad):
    with pytest.raises(rm.ParameterError, match="max_steps must be a whole number >= 1"):
        two_masses().simulate(0.1, solver=solver, max_steps=bad)


def test_ida_max_steps_zero_used_to_leak_a_value_error():
    with pytest.raises(rm.ParameterError, match="solver 'ida': max_steps must be a whole number >= 1, got 0"):
        two_masses().simulate(0.1, max_steps=0)


# ------------------------------------------------------------------ output points
@pytest.mark.parametrize("solver", ALL)
def test_a_huge_output_grid_is_refused_before_anything_is_allocated(solver):
    with pytest.raises(rm.ParameterError) as err:
        two_masses().simulate(10.0, dt_out=1e-9, solver=solver)
    msg = str(err.value)
    assert "asks for 10,000,000,001 output points" in msg and f"max_points={MAX_POINTS}" in msg
    assert "Use dt_out >= 2e-05 s" in msg


@pytest.mark.parametrize("solver", ["ida", "rk4"])
def test_max_points_raises_the_cap(solver):
    m = two_masses()
    with pytest.raises(rm.ParameterError, match="asks for 1,001 output points, more than max_points=500"):
        m.simulate(1.0, dt_out=1e-3, solver=solver, max_points=500)
    res = m.simulate(1.0, dt_out=1e-3, solver=solver, max_points=1001)
    assert len(res.t) == 1001


def test_output_points_counts_the_grid():
    from regmech.solvers.common import output_grid
    for t0, t1, dt in [(0.0, 1.0, 1e-3), (0.0, 1.0, 0.3), (2.0, 3.7, 0.1), (0.0, 10.0, 0.7)]:
        assert output_points(t0, t1, dt) == len(output_grid(t0, t1, dt))


def test_max_points_must_be_a_whole_number():
    with pytest.raises(rm.ParameterError, match="max_points"):
        two_masses().simulate(1.0, max_points=1.5)


# ------------------------------------------------------------------ numpy numbers
@pytest.mark.parametrize("solver", RUN)
@pytest.mark.parametrize("t_end", [np.float32(0.5), np.int64(1), np.float64(0.5), np.array(0.5)])
def test_times_and_options_may_be_numpy_scalars(solver, t_end):
    opts = {"rtol": np.float32(1e-6)} if solver in ADAPTIVE else {"h": np.float64(1e-3)}
    res = two_masses().simulate(t_end, dt_out=np.float32(0.01) if solver in ADAPTIVE else None, solver=solver,
                                **opts)
    assert res.t[-1] == float(t_end) and np.all(np.isfinite(res["J2.w"]))


def test_integral_options_may_be_numpy_integers_or_whole_floats():
    res = two_masses().simulate(0.2, max_steps=np.int64(10_000), max_order=np.int32(4), max_events=1e5)
    assert np.all(np.isfinite(res["J1.w"]))


def test_parameters_may_be_numpy_scalars_and_are_stored_as_floats():
    for value in (np.float32(2.5), np.int64(2), np.array(2.0)):
        J = Inertia("J", J=value)
        assert type(J.J) is float and J.J == float(value)


@pytest.mark.parametrize("bad", [1e-310, 5e-324])
def test_a_subnormal_positive_parameter_is_refused(bad):
    with pytest.raises(rm.ParameterError, match="smallest normal double"):
        Inertia("J1", J=bad)


# ------------------------------------------------------------------ the model
def grounded():
    m = rm.Model("grounded")
    f = m.add(Fixed("fixed"))
    J = m.add(Inertia("J1", J=1.0))
    drive = m.add(Torque("drive", tau=Sine(amplitude=1.0, freq_hz=1.0)))
    m.connect(f.flange, J.flange_a)
    m.connect(drive.flange, J.flange_b)
    return m


@pytest.mark.parametrize("solver", ALL)
def test_a_model_with_nothing_to_integrate_is_refused_by_every_solver(solver):
    """IDA used to raise ValueError('Cannot create cython.array from NULL pointer'), "components most
    involved: []"; the ODE-form solvers returned a result of zeros."""
    with pytest.raises(rm.StructureError) as err:
        grounded().simulate(0.5, solver=solver, **small_step(solver))
    msg = str(err.value)
    assert "model 'grounded' has nothing to integrate" in msg and "'J1' is fixed to the ground" in msg


@pytest.mark.parametrize("solver", RUN)
def test_prescribed_motion_still_runs_and_fills_the_whole_grid(solver):
    """A Position source driving an inertia: no state, but unknowns (the torque the motion takes). The
    convolution method used to return only the two ends of the grid (a NaN first step)."""
    m = rm.Model("prescribed")
    src = m.add(Position("src", phi_ref=Sine(amplitude=1.0, freq_hz=1.0)))
    J = m.add(Inertia("J1", J=2.0))
    m.connect(src.flange, J.flange_a)
    res = m.simulate(1.0, dt_out=0.01, solver=solver, **small_step(solver))
    assert len(res.t) == 101
    w = 2 * np.pi
    np.testing.assert_allclose(res["J1.phi"], np.sin(w * res.t), atol=1e-6)
    np.testing.assert_allclose(res["J1.a"], -w ** 2 * np.sin(w * res.t), atol=2e-4 * w ** 2)


@pytest.mark.parametrize("solver", RUN)
def test_a_mass_too_light_to_resolve_is_named(solver):
    """J = 1e-300 beside J = 1: the acceleration solve used to fail with 'the mass matrix restricted to
    the constraints is singular', naming no component."""
    with pytest.raises(rm.StructureError) as err:
        two_masses(J1=1e-300).simulate(0.5, solver=solver, **small_step(solver))
    msg = str(err.value)
    assert "Inertia 'J1' (J = 1e-300 kg m^2) is 1e+300 times lighter than Inertia 'J2'" in msg
    assert "Give 'J1' a realistic value" in msg


@pytest.mark.parametrize("solver", ALL)
def test_masses_at_scales_beyond_double_precision_give_a_regmech_error(solver):
    """Two 1e-300 kg m^2 inertias on a spring (1e150 rad/s): scipy's Radau used to raise RuntimeError('Factor
    is exactly singular'), expm OverflowError from 2.0 ** 1030 doublings; the convolution method stepped by 0."""
    m = rm.Model("tiny")
    drive = m.add(Torque("drive", tau=Sine(amplitude=10.0, freq_hz=5.0)))
    a = m.add(Inertia("J1", J=1e-300))
    k = m.add(Spring("spring", c=1.0))
    b = m.add(Inertia("J2", J=1e-300))
    m.connect(drive.flange, a.flange_a)
    m.connect(a.flange_b, k.flange_a)
    m.connect(k.flange_b, b.flange_a)
    import warnings
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(rm.SimulationError):
            m.simulate(1.0, solver=solver)
    # ... and nothing from numpy or scipy before it (overflow in a starting step estimate, LSODA's own warning)
    assert not [w for w in caught if issubclass(w.category, (RuntimeWarning, UserWarning))], \
        [str(w.message) for w in caught]


def test_a_light_mass_joined_rigidly_is_fine():
    from regmech.components import Shaft
    m = rm.Model("rigid_light")
    drive = m.add(Torque("drive", tau=Sine(amplitude=1.0, freq_hz=1.0)))
    a = m.add(Inertia("J1", J=1e-300))
    s = m.add(Shaft("shaft", stiffness=None))
    b = m.add(Inertia("J2", J=1.0))
    m.connect(drive.flange, a.flange_a)
    m.connect(a.flange_b, s.flange_a)
    m.connect(s.flange_b, b.flange_a)
    res = m.simulate(0.5, dt_out=0.01)
    t = res.t
    np.testing.assert_allclose(res["J2.w"], (1 - np.cos(2 * np.pi * t)) / (2 * np.pi), atol=1e-6)


# ------------------------------------------------------------------ result look-ups
@pytest.fixture(scope="module")
def result():
    return two_masses().simulate(0.1)


@pytest.mark.parametrize("key", [3, 1.5, None, ("J1", "w")])
def test_a_result_is_indexed_by_name(result, key):
    with pytest.raises(rm.UnknownSignalError, match=r"looked up by name, e.g. res\['J1.w'\]") as err:
        result[key]
    assert isinstance(err.value, KeyError) and isinstance(err.value, rm.RegmechError)
    assert key not in result


def test_an_unknown_signal_is_a_regmech_key_error_with_close_names(result):
    with pytest.raises(KeyError) as err:
        result["J1.ww"]
    assert isinstance(err.value, rm.UnknownSignalError)
    msg = str(err.value)
    assert msg.startswith("no signal 'J1.ww' in the result of model 'two_masses'; did you mean 'J1.w'")
    assert "'J1' has J1.a, J1.kinetic, J1.phi, J1.w" in msg
    with pytest.raises(rm.UnknownSignalError, match="no signal 'nope'"):
        result["nope"]
    with pytest.raises(KeyError):
        result.final("J3.w")


# ------------------------------------------------------------------ the command line and studies
def test_sweep_refuses_a_bad_option_before_any_run():
    calls = []

    def build(c=100.0):
        calls.append(c)
        return two_masses()
    with pytest.raises(rm.ParameterError, match="solver 'rk4' has no option 'rtol'"):
        rm.sweep(build, {"c": [1.0, 2.0]}, ["J1.w"], executor="serial", progress=False, t_end=0.1, solver="rk4",
                 rtol=1e-6)
    assert calls == []


def test_the_command_line_prints_the_refusal(capsys, tmp_path):
    from regmech.cli import main
    assert main(["demo", "--out", str(tmp_path), "--rtol", "0"]) == 2
    assert "regmech demo: solver 'ida': rtol must be a number in" in capsys.readouterr().err
    out = tmp_path / "study.csv"
    assert main(["sweep", "first", "--param", "j_motor=0.1,0.2", "--t-end", "0.1", "--solver", "rk4", "--rtol",
                 "1e-6", "--out", str(out), "--executor", "serial", "--no-progress"]) == 2
    assert "regmech sweep: solver 'rk4' has no option 'rtol'" in capsys.readouterr().err
    assert not out.exists()
