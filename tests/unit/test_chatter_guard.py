"""The chatter guard's refusals name what the device is and point to remedies that exist for it
(``hybrid.chatter.ChatterGuard``)."""

from types import SimpleNamespace

import pytest

from regmech.errors import ChatteringError
from regmech.hybrid.chatter import SILENT_MIN, ChatterGuard


def _guard(solver):
    devices = [SimpleNamespace(name="stop", impact=True), SimpleNamespace(name="clutch")]
    return ChatterGuard(1e-3, 5, devices, solver)


def test_a_chattering_hard_stop_is_not_told_about_friction():
    # a fuzz run (seed 90076): a HardStop was called a friction device and told to use peak > 1, which it has not
    with pytest.raises(ChatteringError) as err:
        g = _guard("ida")
        for k in range(5):
            g.record(1e-5 * k, "stop")
    msg = str(err.value)
    assert "hard stop 'stop'" in msg and "restitution" in msg and "peak" not in msg and "friction" not in msg
    with pytest.raises(ChatteringError, match="friction device 'clutch'.*peak > 1"):
        g = _guard("ida")
        for k in range(5):
            g.record(1e-5 * k, "clutch")


@pytest.mark.parametrize("solver, others", [("ida", "'dop853' or 'scipy:Radau'"), ("scipy:Radau", "'dop853'"),
                                            ("scipy:DOP853", "'scipy:Radau'"), ("dop853", "'scipy:Radau'")])
def test_silent_crossings_do_not_send_a_solver_to_itself(solver, others):
    g = _guard(solver)
    with pytest.raises(ChatteringError) as err:
        for k in range(SILENT_MIN + 1):
            g.record_silent(1e-3 * k, "clutch")
    msg = str(err.value)
    assert f"Use solver={others} (" in msg
    suggested = msg.split("Use solver=")[1].split("(")[0]
    # never the method that runs: regmech's dop853 and scipy's DOP853 are one method
    assert ("853" not in suggested) if "853" in solver else (f"'{solver}'" not in suggested)
