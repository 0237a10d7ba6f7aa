"""Parameter studies (regmech.sweep): sampling, executors, failures, resume, CLI.

Small studies of the CoupledClutches scene with short end times; the
executors must agree to the last bit, failed runs must be recorded, and a
rerun with the same out file must compute only the missing rows.
"""

from __future__ import annotations

import csv
import math
import warnings

import numpy as np
import pytest

import regmech as rm
from regmech.components import Fixed, Inertia, Spring
from regmech.library import coupled_clutches
from regmech.study import executors as study_executors
from regmech.study.outputs import SignalSummary, scene_defaults
from regmech.study.sampling import grid, latin_hypercube, runs_from, scatter

pd = pytest.importorskip("pandas")

FAST = dict(t_end=0.6, dt_out=0.01, solver="ida", rtol=1e-6, atol=1e-8, progress=False)
OUTPUTS = SignalSummary(final=["J1.w", "J3.w"], peak=["clutch2.tau"])


def _numbers(table):
    """The table without the wall-clock column (the only one allowed to differ between executors)."""
    return table.drop(columns=["wall_time"])


# -- sampling --------------------------------------------------------------------------------------
def test_grid_is_full_factorial_or_zipped():
    g = grid({"a": [1, 2], "b": [10, 20, 30]})
    assert len(g) == 6 and g[0] == {"a": 1, "b": 10} and g[1] == {"a": 1, "b": 20} and g[-1] == {"a": 2, "b": 30}
    assert grid({"a": [1, 2], "b": [3, 4]}, zipped=True) == [{"a": 1, "b": 3}, {"a": 2, "b": 4}]
    with pytest.raises(rm.ParameterError, match="equal lengths"):
        grid({"a": [1, 2], "b": [3]}, zipped=True)
    frame = pd.DataFrame({"a": np.array([1.5, 2.5]), "b": np.array([3, 4])})
    runs = runs_from(frame)
    assert runs == [{"a": 1.5, "b": 3}, {"a": 2.5, "b": 4}] and type(runs[0]["b"]) is int
    with pytest.raises(rm.ParameterError, match="status"):
        runs_from([{"status": 1}])


def test_latin_hypercube_fills_every_stratum_once_and_is_seeded():
    n = 20
    s = latin_hypercube({"x": (0.0, 2.0), "y": (-1.0, 1.0)}, n=n, seed=3)
    assert s == latin_hypercube({"x": (0.0, 2.0), "y": (-1.0, 1.0)}, n=n, seed=3)
    assert s != latin_hypercube({"x": (0.0, 2.0), "y": (-1.0, 1.0)}, n=n, seed=4)
    for name, (lo, hi) in (("x", (0.0, 2.0)), ("y", (-1.0, 1.0))):
        strata = sorted(int((p[name] - lo) / (hi - lo) * n) for p in s)
        assert strata == list(range(n))


def test_scatter_spread_matches_the_standard_deviation():
    nominal = {"J": 2.0, "c": 100.0}
    normal = scatter(nominal, rel_sd={"J": 0.1}, n=4000, seed=1)
    J = np.array([p["J"] for p in normal])
    assert abs(J.mean() - 2.0) < 0.02 and abs(J.std() - 0.2) < 0.01
    assert all(p["c"] == 100.0 for p in normal)               # no sd given: stays nominal
    uniform = scatter(nominal, abs_sd=5.0, n=4000, seed=1, dist="uniform")
    c = np.array([p["c"] for p in uniform])
    assert c.min() >= 100 - 5 * math.sqrt(3) and c.max() <= 100 + 5 * math.sqrt(3)
    assert abs(c.std() - 5.0) < 0.2
    with pytest.raises(rm.ParameterError, match="exactly one"):
        scatter(nominal, n=3)


def test_rm_sweep_is_callable_and_exports_helpers():
    import regmech.sweep as module
    assert rm.sweep is module and callable(rm.sweep)
    assert rm.latin_hypercube is latin_hypercube and rm.scatter is scatter


# -- executors -------------------------------------------------------------------------------------
def _sample():
    runs = latin_hypercube({"fn_max": (5.0, 40.0), "t2": (0.2, 0.5)}, n=6, seed=7)
    runs.insert(2, {"fn_max": -1.0, "t2": 0.3})                 # a bad parameter set
    return runs


def test_serial_process_and_dask_give_identical_tables():
    distributed = pytest.importorskip("dask.distributed")
    sample = _sample()
    serial = rm.sweep(coupled_clutches, sample, OUTPUTS, executor="serial", **FAST)
    process = rm.sweep(coupled_clutches, sample, OUTPUTS, executor="process", workers=2, batch_size=2, **FAST)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        dask = rm.sweep(coupled_clutches, sample, OUTPUTS, executor=client, **FAST)
    assert list(serial["run_id"]) == list(range(len(sample)))
    assert list(serial["status"]) == ["ok", "ok", "failed", "ok", "ok", "ok", "ok"]
    assert process.attrs["executor"] == "process" and dask.attrs["executor"] == "dask"
    pd.testing.assert_frame_equal(_numbers(serial), _numbers(process), check_exact=True)
    pd.testing.assert_frame_equal(_numbers(serial), _numbers(dask), check_exact=True)
    # the table holds the simulation's numbers, not something else
    res = coupled_clutches(**sample[0]).simulate(0.6, dt_out=0.01, rtol=1e-6, atol=1e-8, solver="ida")
    assert serial.loc[0, "J3.w.final"] == res.final("J3.w")
    assert serial.loc[0, "clutch2.tau.max_abs"] == np.max(np.abs(res["clutch2.tau"]))


def _spring(c):
    m = rm.Model("spring")
    fixed = m.add(Fixed("fixed"))
    J = m.add(Inertia("J", J=1.0, phi0=0.1, w0=0.0))
    spring = m.add(Spring("spring", c=c))
    m.connect(fixed.flange, spring.flange_a)
    m.connect(spring.flange_b, J.flange_a)
    return m


def test_failed_runs_are_recorded_and_the_study_goes_on():
    # c < 0: the Spring rejects it (ParameterError); c = 1e9: rk4 with h = 1e-2 blows up (SimulationError)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)       # numpy overflow on the way to the blow-up
        table = rm.sweep(_spring, {"c": [100.0, -5.0, 1e9, 400.0]}, ["J.phi"], executor="serial", progress=False,
                         t_end=1.0, dt_out=0.1, solver="rk4", h=1e-2)
    assert list(table["status"]) == ["ok", "failed", "failed", "ok"]
    assert table.loc[1, "error"].startswith("ParameterError") and "'c'" in table.loc[1, "error"]
    assert table.loc[2, "error"].startswith("SimulationError") and "rk4" in table.loc[2, "error"]
    assert np.isnan(table.loc[1, "J.phi.final"]) and np.isfinite(table.loc[3, "J.phi.final"])
    assert table.attrs["failed"] == 2 and pd.isna(table.loc[0, "error"])


def test_bad_outputs_are_reported_per_run():
    with pytest.warns(RuntimeWarning, match="all 1 runs failed") as caught:
        table = rm.sweep(coupled_clutches, {"fn_max": [20.0]}, lambda res: {"w": res["J1.w"]}, executor="serial",
                         **FAST)
    assert caught[0].filename == __file__                      # the warning points at the caller
    assert table.loc[0, "status"] == "failed" and "array of shape" in table.loc[0, "error"]
    with pytest.warns(RuntimeWarning, match="all 1 runs failed"):
        rm.sweep(coupled_clutches, {"fn_max": [20.0]}, ["J9.w"], executor="serial", **FAST)


# -- incremental output and resume -----------------------------------------------------------------
BUILT: list = []


def _counting_clutches(**p):
    BUILT.append(p)
    return coupled_clutches(**p)


def test_rerun_with_the_same_out_file_computes_only_missing_rows(tmp_path):
    out = tmp_path / "study.csv"
    study = grid({"fn_max": [10.0, 20.0, 40.0], "t2": [0.3, 0.5]})
    BUILT.clear()
    rm.sweep(_counting_clutches, study[:4], OUTPUTS, executor="serial", out=out, **FAST)   # the part that finished
    assert len(BUILT) == 4
    with open(out) as fh:
        assert [int(r["run_id"]) for r in csv.DictReader(fh)] == [0, 1, 2, 3]
    BUILT.clear()
    table = rm.sweep(_counting_clutches, study, OUTPUTS, executor="serial", out=out, **FAST)
    assert BUILT == study[4:]                                  # only the missing rows ran
    assert table.attrs["skipped"] == 4 and table.attrs["runs"] == 2
    fresh = rm.sweep(coupled_clutches, study, OUTPUTS, executor="serial", **FAST)
    pd.testing.assert_frame_equal(_numbers(table), _numbers(fresh), check_exact=True)   # CSV round trip is exact
    with open(out) as fh:
        assert [int(r["run_id"]) for r in csv.DictReader(fh)] == list(range(6))
    BUILT.clear()
    rm.sweep(_counting_clutches, study, OUTPUTS, executor="serial", out=out, **FAST)
    assert BUILT == []
    with pytest.raises(rm.ParameterError, match="another study"):
        rm.sweep(coupled_clutches, grid({"fn_max": [11.0], "t2": [0.3]}), OUTPUTS, executor="serial", out=out, **FAST)


def _interrupt_at_fourth(res):
    if res.final("J1.w") == STOP_AT[0]:
        raise KeyboardInterrupt
    return OUTPUTS(res)


STOP_AT: list = []


def test_ctrl_c_returns_finished_rows_and_resume_completes(tmp_path):
    out = tmp_path / "study.csv"
    study = grid({"fn_max": [10.0, 20.0, 40.0], "t2": [0.3, 0.5]})
    STOP_AT[:] = [coupled_clutches(**study[3]).simulate(0.6, dt_out=0.01, rtol=1e-6, atol=1e-8,
                                                        solver="ida").final("J1.w")]
    with pytest.warns(RuntimeWarning, match="interrupted: 3 of 6"):
        part = rm.sweep(coupled_clutches, study, _interrupt_at_fourth, executor="serial", out=out, **FAST)
    assert part.attrs["interrupted"] and list(part["run_id"]) == [0, 1, 2]
    BUILT.clear()
    table = rm.sweep(_counting_clutches, study, OUTPUTS, executor="serial", out=out, **FAST)
    assert BUILT == study[3:] and list(table["status"]) == ["ok"] * 6


def test_interrupted_process_pool_keeps_finished_batches(tmp_path, monkeypatch):
    out = tmp_path / "study.csv"
    study = grid({"fn_max": [10.0, 20.0, 40.0, 80.0], "t2": [0.3, 0.5]})
    plain_run = study_executors.ProcessBackend.run

    def run_then_ctrl_c(self, batches):
        gen = plain_run(self, batches)
        yield next(gen)
        raise KeyboardInterrupt          # as if Ctrl-C arrived while waiting for the next batch

    monkeypatch.setattr(study_executors.ProcessBackend, "run", run_then_ctrl_c)
    with pytest.warns(RuntimeWarning, match="interrupted"):
        part = rm.sweep(coupled_clutches, study, OUTPUTS, executor="process", workers=2, batch_size=2, out=out, **FAST)
    assert part.attrs["interrupted"] and 2 <= len(part) < len(study)
    assert (part["status"] == "ok").all()
    monkeypatch.setattr(study_executors.ProcessBackend, "run", plain_run)
    done = set(part["run_id"])
    table = rm.sweep(coupled_clutches, study, OUTPUTS, executor="process", workers=2, out=out, **FAST)
    assert table.attrs["skipped"] == len(done) and table.attrs["runs"] == len(study) - len(done)
    fresh = rm.sweep(coupled_clutches, study, OUTPUTS, executor="serial", **FAST)
    pd.testing.assert_frame_equal(_numbers(table), _numbers(fresh), check_exact=True)


def _crashing_clutches(fn_max, t2=0.4):
    if fn_max < 0:
        import os
        os._exit(3)                      # the worker process dies (as on a segfault), not just the run
    return coupled_clutches(fn_max=fn_max, t2=t2)


def test_runs_lost_with_a_dead_worker_are_recorded_and_rerun_on_resume(tmp_path):
    out = tmp_path / "study.csv"
    study = [{"fn_max": 10.0, "t2": 0.3}, {"fn_max": -999.0, "t2": 0.3}, {"fn_max": 20.0, "t2": "0012"}]
    table = rm.sweep(_crashing_clutches, study[:2], OUTPUTS, executor="process", workers=1, out=out, **FAST)
    lost = table[table["error"].fillna("").str.startswith("the worker lost")]
    assert 1 in set(lost["run_id"]) and (table["status"] == "failed").sum() == len(lost)
    assert "worker process died (exit code 3)" in lost["error"].iloc[-1]

    def build(fn_max, t2):          # same parameters; this time the bad set is an ordinary failure
        return coupled_clutches(fn_max=fn_max, t2=float(t2))

    BUILT.clear()
    again = rm.sweep(lambda **p: BUILT.append(p) or build(**p), study, OUTPUTS, executor="serial", out=out, **FAST)
    assert [p["fn_max"] for p in BUILT] == [r["fn_max"] for r in study if r["fn_max"] in set(lost["fn_max"]) |
                                            {20.0}]
    assert list(again["status"]) == ["ok", "failed", "ok"] and again.loc[1, "error"].startswith("ParameterError")
    BUILT.clear()
    rm.sweep(lambda **p: BUILT.append(p) or build(**p), study, OUTPUTS, executor="serial", out=out, **FAST)
    assert BUILT == []                   # "0012" matched as text, 10.0 as a number


def test_a_line_cut_short_by_a_crash_is_computed_again(tmp_path):
    out = tmp_path / "study.csv"
    study = grid({"fn_max": [10.0, 20.0, 40.0]})
    rm.sweep(coupled_clutches, study, OUTPUTS, executor="serial", out=out, **FAST)
    text = out.read_text()
    out.write_text(text[: text.rindex("\n", 0, len(text) - 2) + 12])      # the last row torn mid-line
    BUILT.clear()
    table = rm.sweep(_counting_clutches, study, OUTPUTS, executor="serial", out=out, **FAST)
    assert BUILT == study[2:] and list(table["status"]) == ["ok"] * 3
    with open(out) as fh:
        assert [r["status"] for r in csv.DictReader(fh)] == ["ok"] * 3


def test_parquet_output_resumes(tmp_path):
    pytest.importorskip("pyarrow")
    out = tmp_path / "study.parquet"
    study = grid({"fn_max": [10.0, 20.0, 40.0]})
    rm.sweep(coupled_clutches, study[:2], OUTPUTS, executor="serial", out=out, **FAST)
    table = rm.sweep(coupled_clutches, study, OUTPUTS, executor="serial", out=out, **FAST)
    assert table.attrs["skipped"] == 2 and len(pd.read_parquet(out)) == 3


def test_without_pandas_a_list_of_rows_with_to_csv(tmp_path, monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "pandas", None)          # import pandas now raises ImportError
    table = rm.sweep(coupled_clutches, {"fn_max": [10.0, -1.0]}, ["J1.w"], executor="serial", **FAST)
    assert isinstance(table, list) and table.columns[:2] == ["run_id", "fn_max"]
    assert [r["status"] for r in table] == ["ok", "failed"] and table[1]["J1.w.final"] is None
    table.to_csv(tmp_path / "t.csv")
    with open(tmp_path / "t.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert float(rows[0]["J1.w.final"]) == table[0]["J1.w.final"]


# -- command line ----------------------------------------------------------------------------------
def test_cli_sweeps_a_scene_with_default_outputs_and_resumes(tmp_path, capsys):
    from regmech.cli import main
    out = tmp_path / "cli.csv"
    argv = ["sweep", "coupled_clutches", "--param", "fn_max=10,20", "--param", "t2=0.3", "--t-end", "0.4",
            "--dt-out", "0.01", "--out", str(out), "--executor", "serial", "--no-progress"]
    assert main(argv) == 0
    with open(out) as fh:
        rows = list(csv.DictReader(fh))
    assert [r["fn_max"] for r in rows] == ["10", "20"]
    expected = scene_defaults(coupled_clutches()).columns()
    assert "J4.w.final" in expected and "clutch3.tau.max_abs" in expected and "torque.tau.max_abs" not in expected
    assert all(c in rows[0] for c in expected)
    assert main(argv) == 0 and "2 found in" in capsys.readouterr().out
    assert main(["sweep", "coupled_clutches", "--param", "nope=1", "--t-end", "0.4", "--out", str(out)]) == 2
    assert "has no parameter 'nope'" in capsys.readouterr().err


def test_a_dask_sweep_in_a_script_without_the_main_guard_is_named(tmp_path):
    """Dask's local workers run the main script again: without ``if __name__ == "__main__":`` the sweep died with
    40 lines ending "RuntimeError: Nanny failed to start". Now a ParameterError names the guard and the line."""
    pytest.importorskip("dask.distributed")
    import subprocess
    import sys
    script = tmp_path / "study.py"
    script.write_text("import regmech as rm\n"
                      "from regmech.library import coupled_clutches\n"
                      "table = rm.sweep(coupled_clutches, {'fn_max': [10, 20]}, ['J4.w'], executor='dask', workers=1,\n"
                      "                 progress=False, t_end=0.5)\n")
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert out.returncode != 0
    assert "Nanny failed to start" not in out.stderr
    last = out.stderr.strip().splitlines()[-1]
    assert last.startswith("regmech.errors.ParameterError") and "__name__ == \"__main__\"" in last and "line 3" in last
