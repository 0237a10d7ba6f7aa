"""Units of every signal and display units; an API that shows itself (signatures, the
positional-parameter error, res.at/final, the check and summary reports, `regmech check`, IDA's step
count, the mode tables' numbering)."""

from __future__ import annotations

import csv
import inspect
import math
import warnings

import numpy as np
import pytest

import regmech as rm
import regmech.components as comps
from regmech import units
from regmech.components import Damper, Fixed, Inertia, Spring, SpringDamper, Torque

PUBLIC = [getattr(comps, n) for n in comps.__all__]


def _library_classes():
    import regmech.library.chains as chains
    return [chains.ChainJoint]          # the excavator's armature is the library's SeriesDCMotors now


# ------------------------------------------------------------------------------------------ signatures
@pytest.mark.parametrize("cls", PUBLIC + _library_classes(), ids=lambda c: c.__name__)
def test_every_component_class_has_a_real_signature(cls):
    sig = inspect.signature(cls)
    params = list(sig.parameters.values())
    assert params[0].name == "name"
    specs = cls.param_specs()
    for pname, spec in specs.items():
        p = sig.parameters[pname]
        assert p.kind is inspect.Parameter.KEYWORD_ONLY
        if spec.default is rm.component.REQUIRED:
            assert p.default is inspect.Parameter.empty
        else:
            assert p.default is spec.default or p.default == spec.default
        if spec.unit and spec.unit != "1":
            assert f"[{spec.unit}]" in repr(p.annotation)
    assert "**" not in str(sig), f"{cls.__name__}{sig} hides its parameters behind **params"
    if specs and cls.__doc__:
        assert "Parameters (keywords, SI units)" in cls.__doc__
        for pname in specs:
            assert f"\n{pname} : " in cls.__doc__


#: every parameter declares its unit; dimensionless ones (mu, peak, f_normalized, LossyGear.ratio) declare '1'
@pytest.mark.parametrize("cls", PUBLIC + _library_classes(), ids=lambda c: c.__name__)
def test_every_parameter_declares_its_unit(cls):
    missing = [n for n, s in cls.param_specs().items()
               if not s.unit and s.check not in ("choice", "any")]
    assert not missing, f"{cls.__name__}: parameters {missing} declare no unit (unit='1' when dimensionless)"


def vars_owner(cls, name):
    """The class that declares parameter ``name``."""
    return next(k for k in cls.__mro__ if name in vars(k))


def test_signature_shows_required_first_and_domain_where_it_is_chosen():
    assert str(inspect.signature(Inertia)) == \
        "(name: str, *, J: float > 0 [kg m^2], phi0: float [rad] | None = None, w0: float [rad/s] | None = None)"
    assert "domain" in inspect.signature(Spring).parameters
    assert "domain" not in inspect.signature(Inertia).parameters
    assert "s0" in inspect.signature(Fixed).parameters         # Fixed's own keyword


def test_user_subclass_gets_signature_and_doc():
    class Stop(rm.Device):
        """An end stop."""
        c = rm.Param(check="positive", unit="N m/rad", doc="contact stiffness")
        gap = rm.Param(0.1, unit="rad")
        flanges = (("flange_a", "rotational"), ("flange_b", "rotational"))

    assert list(inspect.signature(Stop).parameters) == ["name", "c", "gap"]
    assert "c : float > 0 [N m/rad], required" in Stop.__doc__


@pytest.mark.parametrize("cls", PUBLIC, ids=lambda c: c.__name__)
def test_positional_parameters_are_a_parameter_error_naming_the_class(cls):
    with pytest.raises(rm.ParameterError) as info:
        cls("x", 1.0)
    msg = str(info.value)
    assert cls.__name__ in msg and "keyword" in msg
    names = [p for p in inspect.signature(cls).parameters if p != "name"]
    if names:
        assert f"{names[0]}=1.0" in msg


def test_positional_error_lists_parameters_in_order():
    with pytest.raises(rm.ParameterError) as info:
        Inertia("x", 1.0)
    msg = str(info.value)
    assert "Inertia('x', J=1.0)" in msg
    assert msg.index("J") < msg.index("phi0") < msg.index("w0")
    assert not isinstance(info.value, TypeError)


def test_parameter_units_follow_the_flange_kind():
    s = Spring("s", c=3.0, domain="translational")
    assert s.param_unit("c") == "N/m" and Spring("r", c=3.0).param_unit("c") == "N m/rad"
    with pytest.raises(rm.ParameterError, match=r"\[N/m\]"):
        Spring("s", c=-1.0, domain="translational")
    assert Fixed("g", s0=0.5).param_unit("phi0") == "m"


# ------------------------------------------------------------------------------------------- units
def _run(scene, t_end=0.02, **options):
    from regmech.library import SCENES
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rm.RegularityWarning)
        return SCENES[scene]().simulate(t_end, dt_out=t_end / 4, solver="ida", **options)


def _scenes():
    from regmech.library import SCENES
    return list(SCENES)


@pytest.mark.slow
@pytest.mark.parametrize("scene", _scenes())
def test_every_signal_of_every_library_scene_has_a_unit_that_converts(scene):
    res = _run(scene)
    extra = {"1", "A"}                     # modes; the excavator's armature current
    for name in res.names:
        unit = res.unit(name)
        assert unit is not None, f"{scene}: no unit for {name}"
        assert unit in units.DISPLAY_UNITS or unit in extra, f"{scene}: {name} in {unit!r}"
        for choice, size in units.DISPLAY_UNITS.get(unit, {}).items():
            np.testing.assert_allclose(res.get(name, unit=choice), res[name] / size, rtol=1e-15)


def test_units_by_kind_of_signal():
    res = _run("vehicle_launch")
    expect = {"flywheel.w": "rad/s", "flywheel.phi": "rad", "flywheel.a": "rad/s^2", "clutch.tau": "N m",
              "clutch.w_rel": "rad/s", "clutch.mode": "1", "clutch.power": "W", "flywheel.kinetic": "J",
              "wheel_left.axle.v": "m/s", "wheel_left.axle.a": "m/s^2", "wheel_left.axle.s": "m",
              "wheel_left.tyre.f": "N", "wheel_left.tyre.s_rel": "m", "clutch.flange_a.tau": "N m",
              "wheel_left.tyre.flange_a.v": "m/s"}
    for name, unit in expect.items():
        assert res.unit(name) == unit, name
    ex = _run("excavator_swing")
    assert ex.unit("armature.i") == "A"          # an internal state takes its start parameter's unit


def test_display_units_convert_and_a_wrong_unit_names_signal_unit_and_choices():
    res = _run("coupled_clutches", 0.1)
    w = res["J1.w"]
    np.testing.assert_allclose(res.get("J1.w", unit="rpm"), w * 60 / (2 * math.pi), rtol=1e-15)
    np.testing.assert_allclose(res.get("J1.phi", unit="deg"), np.degrees(res["J1.phi"]), rtol=1e-15)
    np.testing.assert_allclose(res.get("clutch1.tau", unit="kN m"), res["clutch1.tau"] / 1e3, rtol=1e-15)
    np.testing.assert_allclose(res.get("clutch1.tau", unit="Nm"), res["clutch1.tau"])     # a spelling variant
    with pytest.raises(rm.ParameterError) as info:
        res.get("J1.w", unit="km/h")
    msg = str(info.value)
    assert "J1.w" in msg and "rad/s" in msg and "'rpm'" in msg and "m/s signals" in msg
    with pytest.raises(rm.ParameterError, match="furlong"):
        res.get("J1.w", unit="furlong")
    with pytest.raises(rm.UnknownSignalError):
        res.unit("J9.w")


def test_to_csv_and_dataframe_with_units(tmp_path):
    res = _run("coupled_clutches", 0.1)
    path = tmp_path / "r.csv"
    res.to_csv(path, ["J1.w", "J1.phi", "clutch1.tau", "clutch1.mode"],
               units={"J1.w": "rpm", "rad": "deg", "tau": "kN m"})
    with open(path) as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["time [s]", "J1.w [rpm]", "J1.phi [deg]", "clutch1.tau [kN m]", "clutch1.mode"]
    col = np.array([float(r[1]) for r in rows[1:]])
    np.testing.assert_allclose(col, res["J1.w"] * 60 / (2 * math.pi), rtol=1e-15)
    res.to_csv(path, ["J1.w"])                                  # without units: as before
    with open(path) as fh:
        assert next(csv.reader(fh)) == ["time", "J1.w"]
    pytest.importorskip("pandas")
    df = res.to_dataframe(["J1.w", "clutch1.tau"], units="SI")
    assert list(df.columns) == ["time [s]", "J1.w [rad/s]", "clutch1.tau [N m]"]
    df = res.to_dataframe(["J1.w"], units={"w": "rpm"})
    np.testing.assert_allclose(df["J1.w [rpm]"], res.get("J1.w", unit="rpm"))
    with pytest.raises(rm.UnknownSignalError, match="W1"):
        res.to_dataframe(["J1.w"], units={"W1": "rpm"})         # a misspelt key is not ignored


def test_plot_labels_the_y_axis_with_the_units_shown():
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    res = _run("coupled_clutches", 0.1)
    fig = res.plot(["J1.w", "J2.w"], units={"w": "rpm"}, modes=False)
    (ax,) = fig.axes
    assert ax.get_ylabel() == "speed [rpm]"
    np.testing.assert_allclose(ax.lines[0].get_ydata(), res.get("J1.w", unit="rpm"))
    fig2 = res.plot(["J1.w", "clutch1.tau"], modes=False)          # one axis per unit
    assert [a.get_ylabel() for a in fig2.axes] == ["speed [rad/s]", "torque [N m]"]
    _, one = plt.subplots()
    assert res.plot(["J1.w", "clutch1.tau"], ax=one) is one          # a given axis holds them all
    assert one.get_ylabel() == "speed [rad/s], torque [N m]"
    plt.close("all")


# ------------------------------------------------------------------------------------ at and final
def test_at_and_final():
    res = _run("coupled_clutches", 1.0)
    t = np.array([0.1, 0.25, 0.5])
    vals = res.at("J1.w", t)
    assert vals.shape == (3,)
    np.testing.assert_allclose(vals, [res.at("J1.w", x) for x in t])
    assert isinstance(res.at("J1.w", 0.1), float)
    np.testing.assert_allclose(res.at("J1.w", t, unit="rpm"), vals * 60 / (2 * math.pi))
    ev = res.events[0]
    k = np.nonzero(res.t == ev.t)[0]
    assert len(k) == 2                                        # the instant is stored before and after
    assert res.at(f"{ev.component}.mode", ev.t) == ev.new_mode     # after the event
    assert res.final("J1.w") == res["J1.w"][-1]
    assert res.final("J1.w", unit="rpm") == pytest.approx(res["J1.w"][-1] * 60 / (2 * math.pi))
    finals = res.final()
    assert set(finals) == set(res.names) and finals["J2.w"] == res["J2.w"][-1]
    with pytest.raises(rm.RegmechError):
        res.at("J1.w", float("nan"))


# -------------------------------------------------------------------------------- check and summary
def test_check_returns_a_short_report_with_its_data():
    from regmech.library import coupled_clutches, vehicle_launch
    rep = coupled_clutches().check()
    text = repr(rep)
    assert len(text) < 1200 and len(text.splitlines()) <= 14
    assert "OK" in text and "friction devices: clutch1, clutch2, clutch3" in text
    assert "masses:" in text and "4 Inertia" in text
    assert rep.ok and rep.friction_devices == ["clutch1", "clutch2", "clutch3"]
    assert rep.families["masses"]["Inertia"] == ["J1", "J2", "J3", "J4"]
    assert rep.states == 8 and rep.constraints["friction"] == 3
    assert rep.masses == 4                                   # the regularity report reads through
    big = vehicle_launch().check()
    assert len(repr(big).splitlines()) <= 16 and big.dof == 7
    assert "friction:" in repr(big) and "Clutch" in repr(big)


def test_check_report_lists_a_stretched_spectrum_as_a_problem():
    m = rm.Model("stretched")
    f = m.add(Fixed("f"))
    J = [m.add(Inertia(f"J{i}", J=1.0)) for i in range(3)]
    k1 = m.add(Spring("k1", c=1.0))
    k2 = m.add(Spring("k2", c=1e9))
    k3 = m.add(Spring("k3", c=1.0))
    m.connect(f.flange, k1.flange_a)
    m.connect(k1.flange_b, J[0].flange_a)
    m.connect(J[0].flange_b, k2.flange_a)
    m.connect(k2.flange_b, J[1].flange_a)
    m.connect(J[1].flange_b, k3.flange_a)
    m.connect(k3.flange_b, J[2].flange_a)
    with pytest.warns(rm.RegularityWarning):
        rep = m.check()
    assert rep.problems and "stretched spectrum" in rep.problems[0] and "problem:" in str(rep)
    # a report with problems is not ok, and its text does not say OK (before: ok was always True)
    assert not rep.ok and "OK" not in str(rep) and "with 1 problem (below)" in str(rep)


def test_summary_names_components_and_spectrum():
    from regmech.library import first
    s = first().summary()
    text = str(s)
    assert "Inertia inertia1, inertia2, inertia3" in text
    assert "link frequencies" in text and "Hz" in text
    assert s.link_hz is not None and 0 < s.link_hz[0] <= s.link_hz[1]
    assert len(text.splitlines()) <= 14


def test_cli_check(tmp_path, capsys):
    from regmech.cli import main
    assert main(["check", "first"]) == 0
    out = capsys.readouterr().out
    assert "Model 'First' regular mechanical system: OK" in out
    bad = tmp_path / "bad.py"
    bad.write_text(
        "import regmech as rm\n"
        "from regmech.components import Fixed, Inertia, Spring\n"
        "m = rm.Model('bad')\n"
        "f = m.add(Fixed('f')); a = m.add(Spring('a', c=1.0)); b = m.add(Spring('b', c=2.0))\n"
        "J = m.add(Inertia('J', J=1.0))\n"
        "m.connect(f.flange, a.flange_a); m.connect(a.flange_b, b.flange_a); m.connect(b.flange_b, J.flange_a)\n"
        "if __name__ == '__main__':\n"
        "    raise SystemExit('the main part must not run')\n")
    assert main(["check", str(bad)]) == 1
    out = capsys.readouterr().out
    assert "PROBLEMS" in out and "Spring 'a'" in out and "Fix:" in out
    good = tmp_path / "good.py"
    good.write_text("from regmech.library import first\n\ndef build():\n    return first()\n")
    assert main(["check", str(good), "--summary"]) == 0
    assert "summary" in capsys.readouterr().out
    assert main(["check", "no_such_scene"]) == 2
    assert "neither a scene" in capsys.readouterr().err


# ------------------------------------------------------------------------------------------- stats
@pytest.mark.parametrize("options", [dict(native=False), dict()])
def test_ida_reports_its_steps(options):
    """The Python path counts step attempts, the compiled one (the default when numba is there) IDA's steps."""
    res = _run("coupled_clutches", 0.5, **options)
    kind = "step attempts" if res.stats.extra.get("native") is not True else "steps"
    assert res.stats.steps > 10 and "? steps" not in str(res.stats) and f" {kind}," in str(res.stats)
    # every output interval takes at least one step, and Newton needs at least one residual per step
    assert res.stats.steps <= res.stats.rhs_calls


# ------------------------------------------------------------------------------------------- modes
def test_damped_and_undamped_tables_number_modes_alike():
    from regmech.analysis import modal
    from regmech.library import first, vehicle_launch
    r = modal(first().linearize())
    labels = r.damped.table().index
    f2 = r.frequencies_hz[1]
    assert r.damped.table().row("mode 2")[0] == pytest.approx(f2, rel=1e-3)
    assert "mode 1 (real)" in labels                      # the rigid mode's decay root, explained
    v = modal(vehicle_launch().linearize())
    tab = v.damped.table()
    for k in (5, 6, 7):
        assert tab.row(f"mode {k}")[0] == pytest.approx(v.frequencies_hz[k - 1], rel=0.01)
    text = str(tab)
    assert "(real, unstable)" in text and "grows" in text  # the 'damping ratio -1' root is explained
    assert len(set(tab.index)) == len(tab.index)


def test_overdamped_mode_has_two_real_roots_under_one_number():
    from regmech.analysis import modal
    m = rm.Model("overdamped")
    f = m.add(Fixed("f"))
    J = m.add(Inertia("J", J=1.0))
    sd = m.add(SpringDamper("sd", c=1.0, d=10.0))
    m.connect(f.flange, sd.flange_a)
    m.connect(sd.flange_b, J.flange_a)
    tab = modal(m.linearize()).damped.table()
    assert tab.index == ["mode 1 (real)", "mode 1 (real 2)"]
    assert "decays without oscillating" in str(tab)


def test_modes_head_line_matches_the_tables(capsys):
    from regmech.analysis.cli import modes_main
    assert modes_main(["vehicle_launch"]) == 0
    head = capsys.readouterr().out.splitlines()[0]
    assert "7 degrees of freedom, so 7 modes" in head and "all 13 masses" in head


def test_scene_result_outputs_of_the_full_model_have_units_and_display_units():
    m = rm.Model("scene_units")
    f = m.add(Fixed("ground"))
    eng = m.add(Torque("engine", tau=30.0))
    J0 = m.add(Inertia("flywheel", J=0.3, phi0=0.0, w0=0.0))
    g = m.add(rm.components.IdealGear("gear", ratio=4.0))
    J1 = m.add(Inertia("out", J=0.5))
    s = m.add(rm.components.Shaft("shaft", stiffness=1e8, damping=1.0))
    J2 = m.add(Inertia("load", J=20.0))
    d = m.add(Damper("drag", d=5.0))
    for a, b in [(eng.flange, J0.flange_a), (J0.flange_b, g.flange_a), (g.flange_b, J1.flange_a),
                 (J1.flange_b, s.flange_a), (s.flange_b, J2.flange_a), (J2.flange_b, d.flange_a),
                 (d.flange_b, f.flange)]:
        m.connect(a, b)
    sc = rm.Scene(m, t_end=0.2, outputs=["load.w", "flywheel.w"], band_hz=20.0)
    res = sc.simulate()
    for n in ("load.w", "flywheel.w"):
        assert res.unit(n) == "rad/s"
        np.testing.assert_allclose(res.get(n, unit="rpm"), res[n] * 60 / (2 * math.pi))
        assert res.final(n) == res[n][-1]
