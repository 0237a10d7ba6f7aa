"""The calibration harness of the accuracy contract (regmech.bench.calibration) on a closed form."""

import math

import numpy as np
import pytest

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


def test_random_calibration_runs_and_reports_a_fuzz_model(tmp_path):
    """The random part of the calibration (``bench_calibration.py --random N``): a fuzz model as a case, its
    reference cached under a key that carries the model's source, one cell run and judged, the report."""
    from regmech.bench import calibration as C
    cases = C.random_cases(1, 7)
    assert cases[0].key.startswith("fuzz_7_") and cases[0].group == "random"
    csv_path = tmp_path / "random.csv"
    recs = C.run_random(cases, csv_path, limit=120.0, cache_dir=tmp_path / "cache", log=lambda m: None,
                        cells=(("ida", 1e-2),))
    assert [(r.solver, r.accuracy) for r in recs] == [("ida", 1e-2)]
    assert recs[0].status == "met" and recs[0].achieved <= 1e-2
    again = C.run_random(cases, csv_path, cache_dir=tmp_path / "cache", log=lambda m: None, cells=(("ida", 1e-2),))
    assert [(r.case, r.solver, r.status) for r in again] == [(r.case, r.solver, r.status) for r in recs]  # resumed
    md = C.random_markdown(recs, cases, {}, 120.0, 0.0, "test", cache_dir=tmp_path / "cache")
    assert "| `ida` | 1e-02 | 1 | 1 | **0** |" in md and "None." in md


def test_a_verdict_beyond_the_accuracy_within_the_references_resolution_is_unresolved():
    from regmech.bench.calibration import verdict
    assert verdict(9e-5, 1e-4, 1e-9) == "met"
    assert verdict(1.3e-4, 1e-4, 1.1e-7) == "broken"
    # fuzz seed 72: rotational speeds at rest, round-off against the measure's floor; the references differ by
    # 1.1e-4 in that measure, so an error of 1.1e-4 at accuracy 1e-4 cannot be judged
    assert verdict(1.1e-4, 1e-4, 1.1e-4) == "unresolved"
    assert verdict(1.1e-4, 1e-4, float("nan")) == "broken"          # no cross-check: judged against the reference


def test_the_judge_measures_a_kind_at_rest_as_the_contract_does():
    """``_measure`` (a run against the reference) leaves out a kind at rest in both where they agree within its
    floor, as the contract's estimate does (``richardson.clear_at_rest``); a real difference stays."""
    from regmech.solvers.richardson import StateLabel
    labels = [StateLabel("J.w", "J", "w"), StateLabel("clutch.T", "clutch", "state:T")]
    t = np.linspace(0.0, 1.0, 11)
    ref = np.column_stack([np.sin(t), np.zeros_like(t)])
    run = np.column_stack([np.sin(t) + 1e-6, 4e-13 * t])
    value, signal = C._measure(run, ref, labels)
    assert signal == "J.w" and value == pytest.approx(1e-6 / np.ptp(ref[:, 0]))
    run[:, 1] = 1e-9 * t
    value, signal = C._measure(run, ref, labels)
    assert signal == "clutch.T" and value > 100
    # a ripple of 5e-4 on a large speed is a motion, not rest: a run that misses it is measured (a review's case)
    ref[:, 0] = 300.0 + 5e-4 * np.sin(7 * t)
    run[:, 0], run[:, 1] = 300.0, 0.0
    value, signal = C._measure(run, ref, labels)
    assert signal == "J.w" and value == pytest.approx(np.max(np.abs(run[:, 0] - ref[:, 0])) / np.ptp(ref[:, 0]))
