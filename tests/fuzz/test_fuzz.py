"""Property-based reliability suite: random regular drivetrains (``regmech.bench.fuzz``) drawn by
hypothesis, one test per group of component families, each model run on ida and scipy:DOP853 at rtol
1e-8, on ida at rtol 1e-10 as the reference, and on expm when it is linear between friction events.

Property: no finding (``regmech.bench.fuzz.evaluate``): no exception that is not a regmech error, no
NaN/inf, the power balance and the energy books close, no friction or loss element supplies power,
every pair of returned runs agrees within the sum of their claims, every run within its work budget
(a count of equation evaluations, the same on every machine). A regmech error (a refusal) is allowed. The prescribed motions are smooth in the family groups;
``test_random_rough_references_are_refused_or_consistent`` draws speed jumps and position corners.

The CI set is a fixed list of seeds per group (``cases()``): each model is ``generate(random.Random(seed),
...)``, the same on every machine, every hypothesis version and whatever else the test run imports. (It was
drawn by hypothesis, derandomized, until that turned out to depend on the run: hypothesis mixes constants
found in the loaded modules' source into its draws -- about 5 % of them --, so collecting two more test
modules changed the models of two groups, and a fresh virtual environment with another hypothesis version
would have drawn others again.) ``FUZZ_HYPOTHESIS=N`` runs the same property on N models per group drawn by
hypothesis instead (exploration; a finding prints its model as a script, ``FUZZ_SHRINK=1`` shrinks it first).
Long runs with a report: ``benchmarks/fuzz.py``.
"""

import os
import random

import pytest

hypothesis = pytest.importorskip("hypothesis")

from hypothesis import HealthCheck, Phase, given, settings, strategies as st  # noqa: E402

from regmech.bench.fuzz import RUNS, evaluate, generate  # noqa: E402

# long-running (over 2 s on 2 cores): left out of the fast lane, pytest -m 'not slow'
pytestmark = pytest.mark.slow

#: the CI set of runs: the answer-tolerance pair, the ida reference, expm (the DOP853 reference at rtol
#: 1e-11 is for the long runs of ``benchmarks/fuzz.py``: it is the slowest run by far)
CI_RUNS = tuple(r for r in RUNS if r[0] != "dop853_ref")
#: equation evaluations per run (a run beyond it is a finding of kind "budget")
MAX_CALLS = 300_000
#: the budget of a seed whose open finding is its budget (``OPEN``): a third of ``MAX_CALLS`` shows such a
#: defect and keeps the CI subset nearer its 3 minutes (seed 4004 spent 58-67 s reaching 300,000)
MAX_CALLS_OPEN = 100_000
_budget = [MAX_CALLS]
#: the relative error at which the CI subset reads the heats for the finite check (``finite_check``): at the runs'
#: own (rtol 1e-10 for ida's reference) the quadrature re-integrated most output intervals, 73 of vehicle-4002's
#: 92 s (profiled); the long runs (``benchmarks/fuzz.py``) read them at the runs' own
INTEGRAL_TOL = 1e-6
SOURCES = ["torque", "force", "speed", "position"]
GROUPS = {
    "links": ["spring", "damper", "spring_damper", "shaft_rigid", "shaft_elastic", "backlash", "elasto_backlash"],
    "gears": ["ideal_gear", "lossy_gear", "planetary", "lossy_planetary", "differential",
              "limited_slip_differential", "spring_damper"],
    "friction": ["clutch", "brake", "one_way_clutch", "bearing_friction", "friction_contact", "spring_damper"],
    "vehicle": ["wheel", "magic_formula_wheel", "road_load", "engine", "shaft_elastic", "clutch"],
    "rough": ["spring_damper", "shaft_rigid", "clutch", "differential"],
    "electric": ["dc_motor", "electric_motor", "pi_control", "spring_damper", "shaft_elastic", "ideal_gear", "clutch"],
    # drivetrain components: end stops, gaps, speed-dependent loads, Stribeck clutches and brakes,
    # LinearBrake, VehicleLoad, Gearbox, TorqueConverter
    "driveline": ["end_stop", "elasto_gap", "speed_load", "stribeck_clutch", "linear_brake", "vehicle_load",
                  "gearbox", "torque_converter", "spring_damper"],
    # rigid impacts (HardStop, LinearHardStop) and friction elements with a thermal mass and fade
    "impacts": ["hard_stop", "thermal_friction", "spring_damper", "clutch", "ideal_gear"],
}
EXAMPLES = {"links": 10, "gears": 10, "friction": 10, "vehicle": 8, "rough": 4, "electric": 8, "driveline": 8,
            "impacts": 6}
#: hypothesis' examples per group when exploring (``FUZZ_HYPOTHESIS``); 0: the fixed seeds only
EXPLORE = int(os.environ.get("FUZZ_HYPOTHESIS", "0") or 0)


#: the first CI seed of each group (a block of its own: groups never share a model)
SEED_BASE = {"links": 1000, "gears": 2000, "friction": 3000, "vehicle": 4000, "rough": 5000, "electric": 6000,
             "driveline": 9000, "impacts": 9500}


#: seeds of the CI set with findings that are still open (strict xfail: a fix turns them into failures to
#: unmark); each is listed in benchmarks/results/fuzz.md's open causes
OPEN: dict[int, str] = {}
# 4004 (IDA needed 362,268 evaluations on two wheels of one hub with a position servo and a
# sliding clutch) was fixed by the dummy's reflected inertia and the algebraic unknowns' tolerance
# (``structure.system._reflected_mass``, ``solvers.ida._atol_vector``): 4,152 evaluations


def cases():
    """The CI models: ``EXAMPLES[group]`` seeds of each group from ``SEED_BASE[group]``, open findings marked."""
    out = []
    for group in GROUPS:
        for seed in range(SEED_BASE[group], SEED_BASE[group] + EXAMPLES[group]):
            marks = [pytest.mark.xfail(strict=True, reason=OPEN[seed])] if seed in OPEN else []
            out.append(pytest.param(group, seed, marks=marks, id=f"{group}-{seed}"))
    return out


def _check(rng, group, references="smooth", require=(), sources=SOURCES):
    spec = generate(rng, families=GROUPS[group] + sources, n_steps=rng.randint(1, 4), name=f"fuzz_{group}",
                    references=references, require=require)
    verdict = evaluate(spec, runs=CI_RUNS, max_calls=_budget[0], integral_tol=INTEGRAL_TOL)
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
    return settings(max_examples=max(EXPLORE, 1), deadline=None, database=None, phases=phases,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.filter_too_much])


def _explore(fn):
    """The hypothesis version of a group's test: skipped unless ``FUZZ_HYPOTHESIS`` asks for it."""
    return pytest.mark.skipif(not EXPLORE, reason="exploration: set FUZZ_HYPOTHESIS=N")(fn)


def _electric(rng):
    # rotational sources only: the machines and loops are rotational, and a Force on a free Mass drew the
    # fuzz runs' known range-accuracy shortfall (a speed varying little about a large value; seed 160 of
    # benchmarks/results/fuzz.md), which has nothing to do with these families
    _check(rng, "electric", require=[rng.choice(["dc_motor", "electric_motor", "pi_control"])],
           sources=["torque", "speed", "position"])


def _rough(rng):
    _check(rng, "rough", references="rough", require=[rng.choice(["speed", "position"])])


def _impacts(rng):
    # every model has a hard stop; every other one a friction element heating with fade too
    _check(rng, "impacts", require=["hard_stop"] + (["thermal_friction"] if rng.random() < 0.5 else []))


CHECKS = {group: (lambda rng, group=group: _check(rng, group)) for group in GROUPS}
CHECKS.update(electric=_electric, rough=_rough, impacts=_impacts)


@pytest.mark.parametrize("group, seed", cases())
def test_random_drivetrains(group, seed):
    """The property on the CI model of ``seed`` in ``group`` (``CHECKS``)."""
    _budget[0] = MAX_CALLS_OPEN if seed in OPEN else MAX_CALLS
    try:
        CHECKS[group](random.Random(seed))
    finally:
        _budget[0] = MAX_CALLS


@_explore
@pytest.mark.parametrize("group", sorted(CHECKS))
def test_hypothesis_exploration(group):
    """The property on models drawn by hypothesis (``FUZZ_HYPOTHESIS=N`` per group)."""
    @_settings(group)
    @given(rng=st.randoms(use_true_random=False))
    def run(rng):
        CHECKS[group](rng)
    run()
