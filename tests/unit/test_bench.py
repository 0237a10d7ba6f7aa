"""regmech.bench: error metrics, reference cache, runner bookkeeping, report, CLI."""

import json
import time
from dataclasses import replace

import numpy as np
import pytest

import regmech as rm
from regmech.bench import metrics
from regmech.bench.guard import RunTimeout, WorkBudgetExceeded, classify_error, time_limit, work_budget
from regmech.bench.linear_ref import LinearChain
from regmech.bench.metrics import Trace, compare, sample, switch_time_error
from regmech.bench.reference import get_reference, reference_key
from regmech.bench.runner import RunRecord, Setting, run_setting, run_solver, settings_for
from regmech.bench.scenes import BenchScene, all_scenes, select


# ----------------------------------------------------------------------------- metrics
def test_sample_takes_right_limits_at_events_and_interpolates_off_grid():
    t = np.array([0.0, 0.5, 1.0, 1.0, 1.5, 2.0])      # an event at t = 1 (two rows)
    y = np.array([0.0, 1.0, 2.0, 7.0, 8.0, 9.0])
    grid = np.array([0.0, 0.5, 1.0, 1.25, 2.0])
    assert sample(t, y, grid).tolist() == [0.0, 1.0, 7.0, 7.5, 9.0]


def _trace(values, events=(), grid=None):
    grid = np.linspace(0.0, 1.0, len(next(iter(values.values())))) if grid is None else grid
    return Trace(grid, {k: np.asarray(v, float) for k, v in values.items()},
                 {k: float(v[-1]) for k, v in values.items()}, list(events))


def test_max_rel_error_is_relative_to_each_signals_range():
    ref = _trace({"a": [0.0, 10.0, 5.0], "b": [100.0, 100.5, 101.0]})   # ranges 10 and 1
    run = _trace({"a": [0.0, 10.1, 5.0], "b": [100.0, 100.5, 101.02]})
    e = compare(run, ref)
    assert e.max_rel == pytest.approx(0.02)            # b: 0.02 / 1 beats a: 0.1 / 10
    assert e.worst_signal == "b"
    assert e.final == pytest.approx(0.02)
    assert e.switch is None


def test_constant_signal_is_compared_relative_to_its_size():
    ref = _trace({"c": [50.0, 50.0, 50.0]})
    run = _trace({"c": [50.0, 50.0, 50.0 + 5e-5]})
    assert compare(run, ref).max_rel == pytest.approx(5e-5 / (metrics.SCALE_FLOOR * 50.0))


def test_non_finite_run_gives_infinite_error():
    ref = _trace({"a": [0.0, 1.0, 2.0]})
    run = _trace({"a": [0.0, np.nan, 2.0]})
    assert compare(run, ref).max_rel == np.inf


def test_switch_times_are_matched_by_component_modes_and_order():
    ref = [(0.10, "c1", -1, 0), (0.30, "c1", 0, 1), (0.50, "c1", 1, 0), (0.20, "c2", 2, 1)]
    run = [(0.11, "c1", -1, 0), (0.30, "c1", 0, 1), (0.52, "c1", 1, 0), (0.20, "c2", 2, 1), (0.9, "c2", 1, 0)]
    sw = switch_time_error(run, ref)
    assert sw.max_dt == pytest.approx(0.02)
    assert sw.matched == 4 and sw.unmatched == 1 and not sw.consistent
    none = switch_time_error([], ref)
    assert np.isnan(none.max_dt) and none.unmatched == 4


def test_compare_refuses_different_grids():
    with pytest.raises(ValueError, match="grid"):
        compare(_trace({"a": [0, 1, 2]}), _trace({"a": [0, 1, 2]}, grid=np.array([0.0, 0.4, 1.0])))


def test_trace_round_trips_through_arrays():
    tr = _trace({"a": [0.0, 1.0], "b": [2.0, 3.0]}, events=[(0.5, "clutch", -1, 0)])
    back = Trace.from_arrays(tr.to_arrays())
    assert back.events == tr.events and back.final == tr.final
    assert all(np.array_equal(back.values[k], tr.values[k]) for k in tr.values)


# ----------------------------------------------------------------------------- scenes and references
def _small_first(**kw):
    base = next(s for s in all_scenes() if s.key == "first")
    return replace(base, key="first_short", t_end=0.2, dt_out=2e-3, tolerances=(1e-4, 1e-7), steps=(2e-3, 1e-3),
                   **kw)


def test_scene_registry_has_the_required_scenes_and_train_sizes():
    keys = {s.key for s in all_scenes()}
    assert {"first", "coupled_clutches", "vehicle_launch", "train_10", "train_100", "train_1000",
            "train_10000"} <= keys
    assert [s.key for s in select(quick=True)] == ["first", "coupled_clutches", "train_10"]
    with pytest.raises(rm.ParameterError, match="unknown benchmark scene"):
        select(["no_such_scene"])


def test_every_scene_signal_exists_in_a_short_run():
    for sc in [s for s in all_scenes() if s.key in ("first", "coupled_clutches", "train_10")]:
        res = sc.build().simulate(0.01, dt_out=0.005)
        missing = [n for n in sc.signal_names() if n not in res]
        assert not missing, (sc.key, missing)


def test_reference_key_depends_on_parameters_horizon_signals_and_version(monkeypatch):
    sc = _small_first()
    k0 = reference_key(sc)
    assert reference_key(replace(sc, params=(("damping", 5.0),))) != k0
    assert reference_key(replace(sc, t_end=0.3)) != k0
    assert reference_key(replace(sc, signals=sc.signals[:2])) != k0
    monkeypatch.setattr(rm, "__version__", "9.9.9")
    assert reference_key(sc) != k0


def test_reference_is_cross_checked_and_cached(tmp_path):
    sc = _small_first()
    ref = get_reference(sc, cache_dir=tmp_path)
    assert not ref.cached and ref.primary.startswith("scipy:DOP853") and ref.check.startswith("ida")
    assert 0 < ref.cross.max_rel < 1e-6 and not ref.in_doubt
    files = list(tmp_path.glob("first_short-*.npz"))
    assert len(files) == 1
    again = get_reference(sc, cache_dir=tmp_path)
    assert again.cached and again.cross.max_rel == ref.cross.max_rel
    assert all(np.array_equal(again.trace.values[k], ref.trace.values[k]) for k in ref.trace.values)


def test_disagreeing_reference_is_flagged(tmp_path):
    sc = _small_first(reference=(("scipy:DOP853", {"rtol": 1e-12}), ("scipy:RK23", {"rtol": 1e-3})))
    ref = get_reference(sc, cache_dir=tmp_path, use_cache=False)
    assert ref.in_doubt and "DISAGREE" in ref.summary()
    assert not list(tmp_path.iterdir())          # use_cache=False writes nothing


# ----------------------------------------------------------------------------- runner
def test_settings_ladders():
    sc = _small_first()
    assert [s.label for s in settings_for(sc, "ida")] == ["rtol=0.0001", "rtol=1e-07"]
    assert [s.option for s in settings_for(sc, "rk4")] == ["h", "h"]


def test_run_records_errors_times_and_msl_comparison(tmp_path, reference_dir, monkeypatch):
    monkeypatch.setenv("REGMECH_MSL_REFERENCE", str(reference_dir))
    sc = _small_first()
    ref = get_reference(sc, cache_dir=tmp_path)
    recs = run_solver(sc, "ida", ref, repeats=2, limit=60)
    assert [r.status for r in recs] == ["ok", "ok"]
    loose, tight = recs
    assert tight.err_max_rel < loose.err_max_rel < 1e-2
    assert tight.runs == 5 and tight.wall_s > 0 and tight.compile_s > 0 and tight.rhs_calls > 0   # cheap: 5 runs
    assert np.isfinite(tight.msl_max_rel) and tight.msl_max_rel < 2e-3   # the MSL tube


def test_a_refusing_solver_is_recorded_not_raised(tmp_path):
    sc = _small_first()
    model = sc.build()
    rec = run_setting(model, sc, Setting("ida", "linsolver", "no-such-linear-solver"), None, 1, 30, 0.0, 0.0)
    # a bad option value is refused before the run, by the shared option check (regmech.solvers.options)
    assert rec.status == "error" and "ParameterError" in rec.reason and "linsolver" in rec.reason


def test_a_non_regmech_exception_is_a_crash():
    class Boom:
        components = {}
    status, reason = classify_error(ZeroDivisionError("x"), Boom())
    assert status == "crash" and "not a regmech error" in reason
    assert classify_error(RunTimeout("stopped"), Boom())[0] == "timeout"


def test_time_limit_stops_a_busy_loop():
    t0 = time.perf_counter()
    with pytest.raises(RunTimeout):
        with time_limit(0.2):
            while True:
                pass
    assert time.perf_counter() - t0 < 5.0


def test_work_budget_counts_equation_evaluations_and_unwraps():
    from regmech.library import first
    m = first()
    with pytest.raises(WorkBudgetExceeded):
        with work_budget(m, 50):
            m.simulate(0.5, solver="scipy:RK45")
    c = m.compile()
    assert "residual" not in c.__dict__ and "ode_rhs" not in c.__dict__
    with work_budget(m, 100000) as count:
        m.simulate(0.05, solver="ida")
    assert 0 < count[0] < 100000


def test_timeout_skips_the_finer_settings(monkeypatch):
    from regmech.bench import runner
    sc = _small_first()
    calls = []

    def fake(model, scene, setting, reference, repeats, limit, build_s, compile_s):
        calls.append(setting.value)
        return RunRecord(scene.key, setting.solver, setting.option, setting.value, status="timeout", reason="slow")
    monkeypatch.setattr(runner, "run_setting", fake)
    recs = run_solver(sc, "ida", None, repeats=1, limit=1)
    assert calls == [1e-4] and [r.status for r in recs] == ["timeout", "skipped"]


# ----------------------------------------------------------------------------- report and CLI
def test_report_ratios_against_the_best_scipy_method():
    from regmech.bench.report import best_scipy, matched_accuracy

    def rec(solver, wall, err):
        return RunRecord("s", solver, "rtol", 1e-6, wall_s=wall, err_max_rel=err)
    recs = [rec("ida", 0.1, 1e-5), rec("ida", 0.3, 1e-7), rec("scipy:RK45", 0.5, 1e-5), rec("scipy:BDF", 0.4, 1e-3),
            rec("scipy:BDF", 2.0, 1e-7)]
    assert best_scipy(recs, 1e-4, False) == (0.5, "scipy:RK45")
    rows, used = matched_accuracy(recs, False, levels=(1e-2, 1e-4, 1e-6, 1e-8))
    assert used == [1e-2, 1e-4, 1e-6]
    ida = next(r for r in rows if r["solver"] == "ida")
    assert ida[1e-2][1] == pytest.approx(0.25) and ida[1e-6][1] == pytest.approx(0.15)


@pytest.mark.slow
def test_cli_quick_run_writes_csv_markdown_and_plot(tmp_path, capsys):
    from regmech.bench.cli import main
    out = tmp_path / "out"
    code = main(["--quick", "--scenes", "coupled_clutches", "--solvers", "ida", "scipy:RK45", "--repeats", "1",
                 "--out", str(out), "--cache", str(tmp_path / "cache"), "--no-progress"])
    assert code == 0
    md = (out / "work_precision.md").read_text()
    assert "CoupledClutches at rtol 1e-6" in md and "`scipy:RK45`" in md and "Machine:" in md
    assert (out / "wp_coupled_clutches.png").stat().st_size > 1000
    rows = (out / "work_precision.csv").read_text().splitlines()
    assert len(rows) == 1 + 6 and rows[0].startswith("scene,solver,option,value,status")


def test_cli_rejects_unknown_scenes_and_solvers(capsys):
    from regmech.bench.cli import main
    assert main(["--scenes", "nope"]) == 2
    assert main(["--solvers", "nope"]) == 2
    assert main(["--list"]) == 0
    assert "coupled_clutches" in capsys.readouterr().out


def test_regmech_command_dispatches_bench():
    from regmech.cli import main
    assert main(["bench", "--list"]) == 0


# ----------------------------------------------------------------------------- linear reference
def test_linear_reference_matches_closed_form_of_one_oscillator():
    ch = LinearChain("one", [2.0], [(0, None, 50.0, 0.0)], 0, [(0.0, 3.0, 0.0)])
    t = np.linspace(0.0, 3.0, 301)
    x, v = ch.exact(t)
    assert np.max(np.abs(x[:, 0] - 0.06 * (1 - np.cos(5 * t)))) < 1e-14
    assert np.max(np.abs(v[:, 0] - 0.3 * np.sin(5 * t))) < 1e-13


def test_linear_reference_matches_regmech_on_a_damped_chain_with_a_ramp():
    from regmech.signals import Ramp
    ch = LinearChain("c3", [1.0, 2.0, 0.5], [(0, None, 100.0, 1.0), (1, 0, 300.0, 0.5), (2, 1, 50.0, 0.2)], 2,
                     [(0.0, 0.0, 5.0), (2.0, 10.0, 0.0)], x0=[0.01, 0, 0], v0=[0, 0.1, 0])
    res = ch.to_model(Ramp(height=10.0, duration=2.0)).simulate(3.0, dt_out=0.01, solver="scipy:DOP853", rtol=1e-12,
                                                                 atol=1e-14)
    grid = np.arange(301) * 0.01
    x, v = ch.exact(grid)
    for i, nm in enumerate(ch.names):
        assert np.max(np.abs(sample(res.t, res[f"{nm}.phi"], grid) - x[:, i])) < 1e-11
        assert np.max(np.abs(sample(res.t, res[f"{nm}.w"], grid) - v[:, i])) < 1e-10


def test_stretched_chain_hits_its_frequency_ratio():
    from regmech.bench.hard_models import stretched_chain
    for ratio in (1e3, 1e7):
        w = stretched_chain(ratio)[0].frequencies()
        assert w[-1] / w[0] == pytest.approx(ratio, rel=1e-4)


def test_machine_info_lists_versions():
    from regmech.bench.machine import machine_info
    info = machine_info()
    assert {"cpu", "cores (nproc)", "python", "numpy", "scipy", "scikit-sundae"} <= set(info)
    json.dumps(info)


# ----------------------------------------------------------------------------- hard-case machinery
def test_hard_case_verdicts_pass_refuse_inaccurate_and_budget():
    from regmech.bench.hard import CI, get_case, run_case
    ok = run_case(get_case("zero_speed_engagement"), "ida", CI, limit=None)
    assert ok.verdict == "pass" and ok.value < ok.tolerance
    refused = run_case(get_case("square_wave_throttle"), "expm", CI, limit=None)
    assert refused.verdict == "refuse" and "linear" in refused.reason
    # euler at h = 0.01 s is far off: its error estimate (tol = ANSWER_TOL) refuses it, naming the component;
    # the bare method (tol=None) returns the wrong answer, which the check reports
    rough = run_case(get_case("gear_1_1000"), "euler", CI, limit=None)
    assert rough.verdict == "refuse" and rough.reason.startswith("AccuracyError") and "'motor'" in rough.reason
    bare = get_case("gear_1_1000")
    bare.options = lambda solver, size: {"h": 0.01, "tol": None}
    rough = run_case(bare, "euler", CI, limit=None)
    assert rough.verdict == "fail" and rough.reason.startswith("inaccurate (no error control)")
    crawling = run_case(get_case("near_rigid_shaft"), "scipy:RK23", CI, limit=None, max_calls=2000)
    assert crawling.verdict == "fail" and "work budget" in crawling.reason


def test_hard_case_report_lists_every_solver_with_its_verdict():
    from regmech.bench.hard import CI, HardOutcome, all_cases, hard_markdown
    cases = all_cases()[:2]
    outs = [HardOutcome(cases[0].key, "ida", CI, "pass", "rtol=1e-08: fine", 1e-7, 1e-4),
            HardOutcome(cases[0].key, "rk4", CI, "fail", "time limit: stopped after 1 s"),
            HardOutcome(cases[1].key, "ida", CI, "refuse", "SimulationError: 'J1' | too stiff")]
    md = hard_markdown(cases, outs, ["ida", "rk4"], CI, {"cpu": "x"}, 60.0, 12.0)
    assert "| `ida` | pass |" in md and "**FAIL** (t)" in md and "too stiff" in md and "'J1' / too" in md


def test_records_round_trip_through_csv(tmp_path):
    from regmech.bench.report import read_csv, write_csv
    recs = [RunRecord("s", "ida", "rtol", 1e-6, wall_s=0.125, steps=12, err_max_rel=3e-7, worst_signal="J1.w"),
            RunRecord("s", "rk4", "h", 1e-3, status="error", reason="SimulationError: 'J1', boom")]
    write_csv(recs, tmp_path / "r.csv")
    back = read_csv(tmp_path / "r.csv")

    def same(a, b):
        return a == b or (isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b))
    assert len(back) == 2
    for a, b in zip(back, recs):
        assert all(same(a.row()[k], b.row()[k]) for k in b.row()), (a, b)
    text = (tmp_path / "r.csv").read_text().replace(",12,", ",,", 1)      # an unrecorded counter
    (tmp_path / "r.csv").write_text(text)
    assert read_csv(tmp_path / "r.csv")[0].steps == 0
