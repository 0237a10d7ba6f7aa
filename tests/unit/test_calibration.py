"""The calibration harness of the accuracy contract (regmech.bench.calibration) on a closed form."""

import math

import numpy as np

import regmech as rm
from regmech.bench import calibration as C
from regmech.components import Fixed, Inertia, SpringDamper


def _oscillator():
    m = rm.Model("osc")
    f = m.add(Fixed("fixed"))
    sd = m.add(SpringDamper("sd", c=40.0, d=0.4))
    J = m.add(Inertia("J", J=1.0, phi0=1.0))
    m.connect(sd.flange_a, f.flange)
    m.connect(sd.flange_b, J.flange_a)
    return m


def _exact(grid):
    wn, z = math.sqrt(40.0), 0.4 / (2 * math.sqrt(40.0))
    wd, s = wn * math.sqrt(1 - z * z), z * wn
    e = np.exp(-s * grid)
    return {"J.phi": e * (np.cos(wd * grid) + s / wd * np.sin(wd * grid)), "J.w": -e * wn ** 2 / wd * np.sin(wd * grid)}


def test_a_cell_is_measured_against_the_closed_form_and_reported(tmp_path):
    case = C.CalCase("osc", "test", "damped oscillator", _oscillator, 3.0, 0.01, _exact)
    ref = C.reference(case, tmp_path)
    assert ref.method == "closed form" and ref.signals == ["J.phi", "J.w"]
    records = [C.run_cell(case, ref, s, 1e-4, 60.0) for s in ("ida", "auto", "rk4")]
    assert [r.status for r in records] == ["met", "met", "met"]
    assert all(0 < r.achieved <= 1e-4 and r.wall >= r.main > 0 for r in records)
    assert records[1].used in ("ida", "expm") and records[1].reason
    C.save_records(records, tmp_path / "cal.csv")
    back = C.load_records(tmp_path / "cal.csv")
    assert [(r.solver, r.status) for r in back] == [(r.solver, r.status) for r in records]
    text = C.calibration_markdown(back, [case], {"osc": ref}, {"cpu": "test"}, 60.0, 1.0, "cal.png")
    assert "| `ida` | 1 | 1 | **0** |" in text and "closed form" in text
