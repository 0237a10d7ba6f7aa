"""Every run can be stopped: ``simulate(timeout_s=...)``, ``sweep(timeout_s=...)``, and a study's worker
processes end with the study's process.

The runs that must be stopped use a callable torque that sleeps at every call
(each residual or right-hand side evaluation costs 20 ms, so no solver gets
anywhere near the end time within the limit) or a build function that never
returns. No wall time is asserted: only what the runs report.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import regmech as rm
from regmech.components import Fixed, Inertia, Spring, Torque
from regmech.solvers.common import time_limit
from regmech.study import pool

pd = pytest.importorskip("pandas")


def _sleepy(t):
    time.sleep(0.02)
    return 0.1


def _spring(slow=False, hang=False, c=100.0):
    """J = 1 kg m^2 on a spring to the ground, driven by a small torque (a slow callable when ``slow``)."""
    if hang:
        time.sleep(3600)              # a build that never comes back (killed by the hard stop)
    m = rm.Model("spring")
    fixed = m.add(Fixed("fixed"))
    J = m.add(Inertia("J", J=1.0, phi0=0.1, w0=0.0))
    spring = m.add(Spring("spring", c=c))
    drive = m.add(Torque("drive", tau=_sleepy if slow else 0.1))
    m.connect(fixed.flange, spring.flange_a)
    m.connect(spring.flange_b, J.flange_a)
    m.connect(drive.flange, J.flange_b)
    return m


# -- simulate(timeout_s=...) -------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("solver, options", [
    ("ida", {}), ("rk4", {"h": 1e-3}), ("expm", {"h": 1e-3}), ("scipy:RK45", {}), ("scipy:Radau", {}),
    ("convolution", {})])
def test_every_solver_stops_at_its_time_limit(solver, options):
    with pytest.raises(rm.SimulationTimeout, match=r"timed out after 0\.5 s \(simulate\(timeout_s=\.\.\.\)\)") as exc:
        _spring(slow=True).simulate(t_end=100.0, solver=solver, timeout_s=0.5, **options)
    assert f"solver '{solver}'" in str(exc.value) and "model 'spring'" in str(exc.value)
    assert isinstance(exc.value, rm.SimulationError)


def test_ida_stops_a_run_that_is_merely_long():
    # 1e4 s of a 1.6 Hz oscillation at rtol 1e-10: millions of steps, no slow user code involved
    with pytest.raises(rm.SimulationTimeout, match=r"timed out after 0\.5 s.*of t_end=10000 s"):
        _spring().simulate(t_end=1e4, dt_out=0.1, rtol=1e-10, timeout_s=0.5, solver="ida")


@pytest.mark.parametrize("solver, options", [("ida", {}), ("rk4", {"h": 1e-3}), ("scipy:DOP853", {})])
def test_a_limit_that_is_not_reached_changes_nothing(solver, options):
    plain = _spring().simulate(t_end=1.0, solver=solver, **options)
    limited = _spring().simulate(t_end=1.0, solver=solver, timeout_s=600, **options)
    for name in plain.names:
        np.testing.assert_array_equal(plain[name], limited[name], err_msg=name)


@pytest.mark.parametrize("bad", [0, -1.0, math.nan, math.inf, "1", True])
def test_bad_time_limits_are_refused(bad):
    with pytest.raises(rm.ParameterError, match="timeout_s must be a positive number"):
        _spring().simulate(t_end=0.1, timeout_s=bad)
    with pytest.raises(rm.ParameterError, match="timeout_s must be a positive number"):
        rm.sweep(_spring, {"c": [1.0]}, ["J.phi"], executor="serial", progress=False, t_end=0.1, timeout_s=bad)


def test_nested_limits_keep_the_earliest_end():
    with time_limit(600, "outer"):
        with pytest.raises(rm.SimulationTimeout, match=r"after 0\.3 s \(simulate"):
            _spring(slow=True).simulate(t_end=100.0, timeout_s=0.3)
    with time_limit(0.3, "outer"):
        with pytest.raises(rm.SimulationTimeout, match=r"after 0\.3 s \(outer\)"):
            _spring(slow=True).simulate(t_end=100.0, timeout_s=600)
    assert _spring().simulate(t_end=0.1).t[-1] == 0.1      # no limit left behind


# -- sweep(timeout_s=...) ----------------------------------------------------------------------------
STUDY = [{"slow": False, "c": 100.0}, {"slow": True, "c": 100.0}, {"slow": False, "c": 400.0}]
TIMEOUT = 3.0


def _check_one_timed_out(table, timeout=TIMEOUT):
    assert list(table["status"]) == ["ok", "failed", "ok"]
    assert table.loc[1, "error"].startswith(f"SimulationTimeout: timed out after {timeout:g} s (sweep(timeout_s=...))")
    assert (table.loc[table["status"] == "ok", "wall_time"] <= timeout).all()   # an ok row kept its limit
    assert np.isfinite(table.loc[[0, 2], "J.phi.final"]).all() and table.attrs["failed"] == 1


@pytest.mark.slow
@pytest.mark.parametrize("executor", ["serial", "process", "dask", "threads"])
def test_a_hanging_run_becomes_a_failed_row_and_the_study_goes_on(executor):
    _spring().simulate(t_end=1.0)           # kernel templates warm here (forked workers inherit them)
    options = dict(progress=False, t_end=1.0, timeout_s=TIMEOUT, solver="ida")
    if executor == "dask":
        distributed = pytest.importorskip("dask.distributed")
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                      dashboard_address=None) as cluster, distributed.Client(cluster) as client:
            table = rm.sweep(_spring, STUDY, ["J.phi"], executor=client, **options)
    elif executor == "threads":                 # any concurrent.futures executor: the limit holds per thread
        from concurrent.futures import ThreadPoolExecutor
        with ThreadPoolExecutor(2) as threads:
            table = rm.sweep(_spring, STUDY, ["J.phi"], executor=threads, batch_size=1, **options)
    else:
        table = rm.sweep(_spring, STUDY, ["J.phi"], executor=executor, workers=2, **options)
    _check_one_timed_out(table)
    assert "solver 'ida'" in table.loc[1, "error"]          # stopped by the solver's own check


@pytest.mark.slow
def test_a_run_that_never_reaches_a_check_is_stopped_by_killing_its_worker():
    _spring().simulate(t_end=1.0)
    study = [{"hang": False, "c": 100.0}, {"hang": True, "c": 100.0}, {"hang": False, "c": 400.0}]
    # one worker, one batch: the rest of the batch goes on in a new worker
    table = rm.sweep(_spring, study, ["J.phi"], executor="process", workers=1, batch_size=3, progress=False,
                     t_end=1.0, timeout_s=1.0)
    _check_one_timed_out(table, timeout=1.0)
    assert "its worker process was stopped" in table.loc[1, "error"]
    assert table.loc[1, "wall_time"] >= pool.hard_stop(1.0)
    import multiprocessing
    assert multiprocessing.active_children() == []           # nothing left running


def test_cli_takes_a_time_limit(tmp_path, capsys):
    from regmech.cli import main
    argv = ["sweep", "coupled_clutches", "--param", "fn_max=10,20", "--t-end", "0.4", "--out",
            str(tmp_path / "cli.csv"), "--executor", "serial", "--no-progress", "--timeout-s", "0.001"]
    with pytest.warns(RuntimeWarning, match="all 2 runs failed"):
        assert main(argv) == 1                  # no run builds, compiles and simulates within 1 ms
    assert "failed: SimulationTimeout: timed out after 0.001 s" in capsys.readouterr().out


# -- workers end with the study's process ------------------------------------------------------------
PARENT = """
import sys
import regmech as rm
from regmech.study import pool
sys.path.insert(0, {tests!r})
from test_timeouts import _spring
pool.KERNEL_PARENT_DEATH = {kernel}
rm.sweep(_spring, [{{"slow": True}}] * 4, ["J.phi"], executor="process", workers=2, progress=False, t_end=100.0)
"""


@pytest.mark.slow
@pytest.mark.parametrize("kernel", [True, False], ids=["pdeathsig", "polling"])
def test_workers_exit_when_the_study_process_is_killed(kernel):
    psutil = pytest.importorskip("psutil")
    if kernel and not sys.platform.startswith("linux"):
        pytest.skip("PR_SET_PDEATHSIG is Linux only")
    script = PARENT.format(tests=os.path.dirname(__file__), kernel=kernel)
    parent = subprocess.Popen([sys.executable, "-c", textwrap.dedent(script)], stderr=subprocess.PIPE)
    workers = []
    try:
        limit = time.monotonic() + 300          # imports take long on a loaded machine
        while len(workers) < 2 and time.monotonic() < limit and parent.poll() is None:
            time.sleep(0.2)
            workers = [p for p in psutil.Process(parent.pid).children() if "python" in p.name().lower()]
        assert len(workers) == 2, f"the study did not start its workers: {parent.stderr.read()[-2000:]!r}"
        parent.send_signal(signal.SIGKILL)      # no clean-up code runs in the parent
        parent.wait()
        gone_by = time.monotonic() + 15 * pool.PARENT_POLL + 5
        while time.monotonic() < gone_by and any(_running(psutil, w) for w in workers):
            time.sleep(0.1)
        assert not any(_running(psutil, w) for w in workers)
    finally:                                    # whatever failed above, leave no process behind
        if parent.poll() is None:
            parent.kill()
            parent.wait()
        for w in workers:
            try:
                w.kill()
            except psutil.NoSuchProcess:
                pass


def _running(psutil, proc) -> bool:
    try:
        return proc.status() != psutil.STATUS_ZOMBIE     # a dead worker that no one has reaped yet is gone
    except psutil.NoSuchProcess:
        return False
