"""``regmech modes``: the command prints the modes and writes tables and plots."""

import numpy as np
import pytest

from regmech.analysis.cli import modes_main


def test_modes_command_on_msl_first(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    assert modes_main(["first", "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    f = np.sqrt(1e4 * (1 / 12.0 + 1 / 2.0)) / (2 * np.pi)
    assert f"{f:.6g}" in text            # the elastic mode, 12.1557 Hz
    assert "inertia3" in text and "damping ratio" in text
    for name in ("modes.csv", "mode_shapes.csv", "mode_shapes.png", "response.png"):
        assert (tmp_path / name).stat().st_size > 0
    rows = (tmp_path / "modes.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[2].startswith("mode 2,")


def test_modes_command_with_friction_modes_and_errors(capsys):
    assert modes_main(["coupled_clutches", "--mode", "clutch1=Stuck", "--k", "2"]) == 0
    assert "J1" in capsys.readouterr().out
    assert modes_main(["no_such_scene"]) == 2
    assert "unknown scene" in capsys.readouterr().err
    assert modes_main(["coupled_clutches", "--mode", "clutch9=Stuck"]) == 2
    assert "not a friction device" in capsys.readouterr().err
