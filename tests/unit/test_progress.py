"""simulate(progress=...): a bar over the simulated time with the run's solver, step attempts and events."""

import pytest

import regmech as rm
from regmech.library import coupled_clutches


@pytest.mark.parametrize("solver", ["ida", "dop853"])
def test_progress_shows_simulated_time_steps_and_events(solver, capsys):
    res = coupled_clutches().simulate(1.5, 1e-3, solver=solver, progress=True)
    err = capsys.readouterr().err
    assert "CoupledClutches" in err and "t=" in err and " steps" in err and " events" in err
    assert solver in err
    assert len(res.events) > 0


def test_progress_is_off_by_default_in_tests(capsys):
    coupled_clutches().simulate(1.5, 1e-3)
    assert "steps" not in capsys.readouterr().err


def test_progress_takes_true_false_or_none():
    with pytest.raises(rm.ParameterError, match="progress"):
        coupled_clutches().simulate(1.5, 1e-3, progress="yes")
    from regmech.solvers import check_options
    assert check_options(1.0, solver="ida", progress=False)["progress"] is False
