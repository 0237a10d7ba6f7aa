"""Helpers of the hard-case suite (CI-sized versions of ``regmech.bench.hard``).

Runs are bounded by a *work budget* (evaluations of the model equations,
``regmech.bench.guard.work_budget``) rather than by the clock, so a solver
that would crawl for hours fails the same way on any machine. Each case's
model and answer are built once per session and shared by the solvers.
"""

import functools

from regmech.bench.hard import CI, get_case, run_case

#: evaluations of the model equations allowed per run (the passing runs need far fewer)
BUDGET = 60_000


@functools.lru_cache(maxsize=None)
def _built(key):
    case = get_case(key)
    return case, case.build(CI)


def outcome(key, solver, budget=BUDGET):
    """Run ``solver`` on the CI-sized hard case ``key``; returns a ``HardOutcome``."""
    case, built = _built(key)
    return run_case(case, solver, CI, limit=None, built=built, max_calls=budget)


def assert_passes(out):
    assert out.verdict == "pass", f"{out.case} / {out.solver}: {out.verdict}: {out.reason}"
