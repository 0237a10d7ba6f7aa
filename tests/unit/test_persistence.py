"""``res.save(path)`` / ``regmech.load_result(path)``: a MATLAB .mat file that keeps every signal, its unit,
the events and the statistics, readable with plain scipy (persistence)."""

import pickle

import numpy as np
import pytest
import scipy.io

import regmech as rm
from regmech.errors import RegmechError
from regmech.library import SCENES

#: short runs that still reach a mode change where the scene has one early
T_END = {"one_way_clutch": 0.3, "vehicle_launch": 0.3, "excavator_swing": 0.3, "gear_shift": 0.3}


def _run(name):
    return SCENES[name]().simulate(T_END.get(name, 0.1))


def _assert_same(a, b):
    assert b.model_name == a.model_name
    assert b.names == a.names
    np.testing.assert_array_equal(b.t, a.t)
    for n in a.names:
        np.testing.assert_array_equal(b[n], a[n], err_msg=n)
        assert b.unit(n) == a.unit(n), n
    assert b.events == a.events
    assert b.stats == a.stats
    assert str(b.stats) == str(a.stats)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SCENES))
def test_round_trip_of_every_library_scene(name, tmp_path):
    res = _run(name)
    path = res.save(tmp_path / f"{name}.mat")
    back = rm.load_result(path)
    _assert_same(res, back)
    some = res.names[0]
    t_mid = 0.5 * (res.t[0] + res.t[-1])
    assert back.at(some, t_mid) == res.at(some, t_mid)
    assert back.final() == res.final()
    assert back.path == str(path) and back.regmech_version == rm.__version__


def test_events_and_error_estimates_survive(tmp_path):
    res = SCENES["vehicle_launch"]().simulate(1.0, accuracy=1e-3)
    assert any(ev.component == "clutch" for ev in res.events)
    back = rm.load_result(res.save(tmp_path / "launch.mat"))
    _assert_same(res, back)
    assert back.stats.error_estimate == res.stats.error_estimate is not None
    assert [e.t_error for e in back.events] == [e.t_error for e in res.events]


def test_file_opens_with_plain_scipy_and_shows_named_signals_with_units(tmp_path):
    res = SCENES["vehicle_launch"]().simulate(0.3)
    res.save(tmp_path / "run.mat")
    raw = scipy.io.loadmat(tmp_path / "run.mat")          # no regmech involved
    names = [str(x[0]) for x in raw["names"].ravel()]
    units = [str(x[0]) if x.size else "" for x in raw["units"].ravel()]
    assert str(raw["format"][0]) == "regmech result" and str(raw["model_name"][0]) == "vehicle_launch"
    j = names.index("flywheel.w")
    assert units[j] == "rad/s" and units[names.index("clutch.tau")] == "N m"
    np.testing.assert_array_equal(raw["data"][:, j], res["flywheel.w"])
    np.testing.assert_array_equal(raw["time"].ravel(), res.t)
    ev = raw["events"][0, 0]
    devices = [str(x[0]) for x in ev["device"].ravel()]
    assert devices == [e.component for e in res.events]
    assert [str(x[0]) for x in ev["old_name"].ravel()] == ["Free"]          # the clutch engages at 0.2 s
    assert [str(x[0]) for x in ev["new_name"].ravel()] == ["Backward"]
    assert str(raw["stats"][0, 0]["solver"][0]) == res.stats.solver


def test_loaded_result_tables_plots_and_pickle(tmp_path):
    res = SCENES["coupled_clutches"]().simulate(0.2)
    back = rm.load_result(res.save(tmp_path / "cc.mat"))
    pd = pytest.importorskip("pandas")
    a, b = res.to_dataframe(units={"w": "rpm"}), back.to_dataframe(units={"w": "rpm"})
    pd.testing.assert_frame_equal(a, b)
    assert back.get("J1.w", unit="rpm")[-1] == pytest.approx(res.get("J1.w", unit="rpm")[-1])
    again = pickle.loads(pickle.dumps(back))
    _assert_same(res, again)
    pytest.importorskip("matplotlib")
    back.plot(["J1.w", "J2.w"], path=tmp_path / "cc.png")
    assert (tmp_path / "cc.png").stat().st_size > 0


def test_save_only_some_signals(tmp_path):
    res = SCENES["first"]().simulate(0.1)
    back = rm.load_result(res.save(tmp_path / "f.mat", names=["inertia1.w", "spring.tau"]))
    assert back.names == ["inertia1.w", "spring.tau"]
    with pytest.raises(rm.UnknownSignalError):
        back["inertia2.w"]


def test_errors_name_the_path_and_the_fix(tmp_path):
    res = SCENES["first"]().simulate(0.05)
    with pytest.raises(RegmechError, match=r"\.mat"):
        res.save(tmp_path / "run.csv")
    with pytest.raises(RegmechError, match="no file"):
        rm.load_result(tmp_path / "missing.mat")
    scipy.io.savemat(tmp_path / "other.mat", {"x": np.arange(3.0)})
    with pytest.raises(RegmechError, match="not a regmech result"):
        rm.load_result(tmp_path / "other.mat")
    (tmp_path / "junk.mat").write_text("not a mat file")
    with pytest.raises(RegmechError, match="not a MATLAB .mat file"):
        rm.load_result(tmp_path / "junk.mat")


@pytest.mark.parametrize("damage", ["nan_time", "no_events", "short_units"])
def test_a_damaged_file_is_a_regmech_error_naming_it(tmp_path, damage):
    # regression: past the format check, a missing variable was a bare KeyError and a NaN time loaded silently
    # (res.at then interpolated a wrong value)
    path = tmp_path / "run.mat"
    _run("first").save(path)
    raw = {k: v for k, v in scipy.io.loadmat(path).items() if not k.startswith("__")}
    if damage == "nan_time":
        raw["time"].flat[1] = np.nan
    elif damage == "no_events":
        del raw["events"]
    else:
        raw["units"] = raw["units"][..., :1]
    scipy.io.savemat(path, raw)
    with pytest.raises(RegmechError, match="damaged regmech result") as err:
        rm.load_result(path)
    assert str(path) in str(err.value)


def test_wrong_types_are_regmech_errors():
    res = _run("first")
    name = res.names[0]
    with pytest.raises(RegmechError, match="finite time"):
        res.at(name, "abc")
    with pytest.raises(rm.UnknownSignalError, match="a str"):
        res.unit(5)
    with pytest.raises(rm.ParameterError, match="display unit is a str"):
        res.get(name, unit=["rpm"])
    with pytest.raises(rm.ParameterError, match="needs a signal name"):
        res.final(unit="rpm")


def test_an_impacts_heat_and_a_sources_work_survive(tmp_path):
    """``Event.value`` (an impact's heat) and ``Event.work`` (a motion source's work through the impulse) are in the
    file (they were lost before), so a loaded result's books add up as the run's did (``impulse_work``)."""
    from regmech.components import HardStop, Inertia, Planetary, Speed, Torque
    m = rm.Model("stop_on_a_source_path")
    J1, J2, J3 = (m.add(Inertia(n, J=J)) for n, J in (("J1", 1.0), ("J2", 0.1), ("J3", 0.5)))
    pl = m.add(Planetary("pl", ratio=2.0))
    motor = m.add(Speed("motor", w_ref=1.0))
    drive = m.add(Torque("drive", tau=5.0))
    stop = m.add(HardStop("stop", lower=-0.2, upper=0.2, e=0.0))
    for a, b in [(pl.sun, J1.flange_b), (pl.carrier, J2.flange_b), (pl.ring, J3.flange_a),
                 (motor.flange, J2.flange_a), (drive.flange, J1.flange_a), (stop.flange, J3.flange_b)]:
        m.connect(a, b)
    res = m.simulate(1.0, dt_out=1e-3, solver="ida", rtol=1e-8)
    impacts = [e for e in res.events if e.kind == "impact"]
    assert impacts and all(e.value is not None and e.work for e in impacts)
    back = rm.load_result(res.save(tmp_path / "stop.mat"))
    assert back.events == res.events
    np.testing.assert_array_equal(back.impulse_work("motor"), res.impulse_work("motor"))
    # plain scipy sees them too
    raw = scipy.io.loadmat(tmp_path / "stop.mat")["events"][0, 0]
    k = [i for i, e in enumerate(res.events) if e.kind == "impact"][0]
    assert float(raw["value"][k, 0]) == res.events[k].value
