"""Property-based reliability suite: random regular drivetrains (``regmech.bench.fuzz``) drawn by
hypothesis, one test per group of component families, each model run on ida and scipy:DOP853 at rtol
1e-8, on ida at rtol 1e-10 as the reference, and on expm when it is linear between friction events.

Property: no finding (``regmech.bench.fuzz.evaluate``): no exception that is not a regmech error, no
NaN/inf, the power balance and the energy books close, no friction or loss element supplies power,
every pair of returned runs agrees within the sum of their claims, every run within its work budget
(a count of equation evaluations, the same on every machine). A regmech error (a refusal) is allowed. The prescribed motions are smooth in the family groups;
``test_random_rough_references_are_refused_or_consistent`` draws speed jumps and position corners.

Derandomized with a fixed number of examples per group (``EXAMPLES``) so that the suite is the same
on every run and stays within its time budget in CI; a long campaign is ``benchmarks/fuzz.py``. A
failure prints the model as a standalone script (``FUZZ_SHRINK=1`` lets hypothesis shrink it first).
"""

import pytest

hypothesis = pytest.importorskip("hypothesis")
import os  # noqa: E402

from hypothesis import HealthCheck, Phase, given, settings, strategies as st  # noqa: E402

from regmech.bench.fuzz import RUNS, evaluate, generate  # noqa: E402

#: the CI set of runs: the answer-tolerance pair, the ida reference, expm (the DOP853 reference at rtol
#: 1e-11 is the campaign's: it is the slowest run by far)
CI_RUNS = tuple(r for r in RUNS if r[0] != "dop853_ref")
#: equation evaluations per run (a run beyond it is a finding of kind "budget")
MAX_CALLS = 300_000
SOURCES = ["torque", "force", "speed", "position"]
GROUPS = {
    "links": ["spring", "damper", "spring_damper", "shaft_rigid", "shaft_elastic", "backlash", "elasto_backlash"],
    "gears": ["ideal_gear", "lossy_gear", "planetary", "lossy_planetary", "differential",
              "limited_slip_differential", "spring_damper"],
    "friction": ["clutch", "brake", "one_way_clutch", "bearing_friction", "friction_contact", "spring_damper"],
    "vehicle": ["wheel", "magic_formula_wheel", "road_load", "engine", "shaft_elastic", "clutch"],
    "rough": ["spring_damper", "shaft_rigid", "clutch", "differential"],
}
EXAMPLES = {"links": 10, "gears": 10, "friction": 10, "vehicle": 8, "rough": 4}


def _check(rng, group, references="smooth", require=()):
    spec = generate(rng, families=GROUPS[group] + SOURCES, n_steps=rng.randint(1, 4), name=f"fuzz_{group}",
                    references=references, require=require)
    verdict = evaluate(spec, runs=CI_RUNS, max_calls=MAX_CALLS)
    if verdict.status == "finding":
        lines = [f"{f.kind} [{f.run}] {f.detail}" for f in verdict.findings]
        pytest.fail("findings on a generated model:\n  " + "\n  ".join(lines) + "\n\nreproducer:\n"
                    + spec.script("ida", rtol=1e-8), pytrace=False)


def _settings(group):
    # no shrinking by default: one simulation set costs seconds, so shrinking a failure takes many
    # minutes; the failure prints its model as a script anyway (FUZZ_SHRINK=1 shrinks it to a minimal one)
    phases = [Phase.explicit, Phase.reuse, Phase.generate]
    if os.environ.get("FUZZ_SHRINK"):
        phases.append(Phase.shrink)
    return settings(max_examples=EXAMPLES[group], derandomize=True, deadline=None, database=None, phases=phases,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.filter_too_much])


@_settings("links")
@given(rng=st.randoms(use_true_random=False))
def test_random_links_and_sources(rng):
    _check(rng, "links")


@_settings("gears")
@given(rng=st.randoms(use_true_random=False))
def test_random_gear_trains(rng):
    _check(rng, "gears")


@_settings("friction")
@given(rng=st.randoms(use_true_random=False))
def test_random_friction_drivetrains(rng):
    _check(rng, "friction")


@_settings("vehicle")
@given(rng=st.randoms(use_true_random=False))
def test_random_vehicles(rng):
    _check(rng, "vehicle")


@_settings("rough")
@given(rng=st.randoms(use_true_random=False))
def test_random_rough_references_are_refused_or_consistent(rng):
    _check(rng, "rough", references="rough", require=[rng.choice(["speed", "position"])])
