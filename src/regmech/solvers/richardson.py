"""A-posteriori global error estimate of the fixed-step solvers (``euler``, ``rk4``, ``abm``, ``expm``).

The fixed-step methods have no error control of their own, so a step that
is too coarse gives a wrong answer without a word. Option ``tol`` (default
``DEFAULT_TOL`` = 1e-3; ``None`` switches the check off) bounds the
estimated global error of every ODE-form state (positions and speeds of the
independent coordinates, internal device states) by Richardson
extrapolation against a *companion run*:

* after the main run at step h, the same model is run again with steps of
  exactly 2h (``ode_driver.GroupedKnotClock``: pairs of the main steps,
  landing on every other output instant when h >= dt_out), with the same
  time events and the same stick/slip logic (events located anew: a switch
  time that moves with the step is part of the error and counts);
* at the instants both runs hit exactly (output instants, breakpoints), for
  a method of order p, ``y_2h - y_h ~ (2^p - 1) C h^p``, so the error of
  the main run is estimated as

      E_i(t) = |y_h,i(t) - y_2h,i(t)| / (r^p - 1),     r = min(2, steps(h) / steps(2h))

  (r < 2 only where segments between events are too short for a step of
  2h, which makes E larger, i.e. conservative);
* each state is measured against the largest range over the run of the
  states of its *kind* (angles, angular speeds, positions, speeds, each
  kind of internal state): the measure of the hard-case checks
  (``regmech.bench.hard``). A state that hardly moves is thus not held to
  its own tiny range (round-off alone would exceed it); a kind that does
  not move at all is measured against ``MAGNITUDE_FLOOR`` times its largest
  value, and at least ``ABSOLUTE_FLOOR`` (in the state's SI unit); a kind
  that moves by no more than ``ABSOLUTE_FLOOR`` in both runs is left out
  (``clear_at_rest``: its round-off is no error of a motion; listed in
  ``stats.extra["at_rest"]``).

``stats.error_estimate`` is ``max_i,t E_i(t) / scale_i``; when it exceeds
``tol`` the run raises ``AccuracyError`` naming the worst state's signal
and component, with a step that meets ``tol``:
``h * 0.8 * (tol / E)^(1/p)`` (h the step actually taken: a requested step
longer than the output interval is shortened to it). To tell a truncation error from a floor that
a smaller step does not lower (round-off of ``expm`` on a stretched
spectrum, a discontinuity the steps do not resolve), a refusal first runs a
third, 4h run: when ``|y_2h - y_4h|`` is not at least sqrt(2) times
``|y_h - y_2h|`` the error does not shrink with h: with an estimate below 1 %
of the range (``FLOOR_LIMIT``) that is a floor, and the message says so and suggests an
implicit adaptive solver instead; above it the steps are far from resolving
the motion (phase errors over many periods saturate), and the message asks
for a much smaller step; when it shrinks more slowly
than h^p, the observed order is used for the step suggestion.

Orders p: ``euler`` 1, ``rk4`` 4, ``abm`` 4 (its RK4 start-up is of the
same order), ``expm`` ``order_p``: its propagator is exact for the model;
its truncation error is that of holding the inputs over a step by a
polynomial of degree ``order_p - 1`` through the Gauss points, O(h^order_p)
for general smooth forcing (higher for forcing slow against the step, none
for piecewise polynomial forcing, where only round-off is left), so
``order_p`` is the guaranteed order and the estimate errs on the safe side.
Its round-off part does not shrink with h (it grows with the number of
steps); the third run identifies it.

An estimate that meets ``tol`` only through the division by ``2^p - 1``
(``tol < |y_h - y_2h|``) rests on the order p; a run at 4h then checks it,
and where the error shrinks more slowly (observed order below p - 1/2:
events located on an interpolant, inputs the steps do not resolve) the
estimate is formed with the observed order (``error_order_observed``).

A companion run at 2h that diverges (or fails otherwise) while the main run
did not means the main step is within a factor 2 of the stability limit of
the method (or of what its event logic can resolve). The error is then
estimated against a run at h/2 instead (every main step cut in two, twice
the main run's steps): ``E = |y_h - y_h/2| 2^p / (2^p - 1)``. Only when that
run fails too is the run refused without an estimate (``AccuracyError``).
The run at h/2 also decides before a refusal by the 2h estimate (when that
estimate is below 1): a run at 2h can put a fast mode outside the range where
the error goes like h^p and over-estimate, e.g. abm at h = 1e-3 on the
vehicle launch: 0.013 against 2h, 6e-5 against h/2, true 2.2e-4. Both uses
of the h/2 run are skipped for runs of more than ``HALF_STEP_MAX_STEPS``
main steps (it would cost twice the main run).

Cost: the companion takes half the steps of the main run and records
nothing but the states at the compared instants (no output rows, no
result); it reuses the compiled system (and, for ``expm``, the propagators
of each mode set). ``tol=None`` runs the bare method (what the
work-precision benchmarks time).
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import AccuracyError, SimulationError
from ..hybrid import attach
from .common import check_times, output_grid, refuse_impacts, signal_breakpoints
from .ode_driver import GridProbe, GroupedKnotClock, KnotClock, simulate_ode

#: default bound of the estimated error relative to the range of the states of a kind
DEFAULT_TOL = 1e-3
#: the suggested step aims at 0.8 of the tolerance
SAFETY = 0.8
#: a kind of state that does not move is measured against this fraction of its largest magnitude ...
MAGNITUDE_FLOOR = 1e-6
#: ... and at least against this absolute value (SI units of the state: rad, m, rad/s, m/s, ...)
ABSOLUTE_FLOOR = 1e-12
#: two runs that both keep a kind within ABSOLUTE_FLOOR of where it starts agree when they differ by at most this
#: many times its scale (``ABSOLUTE_FLOOR`` there): the sum of their ranges (``clear_at_rest``)
REST_AGREEMENT = 2.0
#: |y_2h - y_4h| / |y_h - y_2h| below this: the error does not shrink with the step
SHRINK_RATIO = math.sqrt(2.0)
#: ... but only when the estimate is below this fraction of the range (a floor); larger errors that do not
#: shrink are the pre-asymptotic range of steps that do not resolve the motion
FLOOR_LIMIT = 1e-2
#: the check at h/2 (twice the main run's steps) is made only for runs of at most this many steps: on a
#: longer run it would triple the cost of a refusal (rk4 over 1e6 steps: minutes)
HALF_STEP_MAX_STEPS = 100_000
#: steps(h) / steps(2h) below this: the segments leave no room for a doubled step
MIN_RATIO = 1.5


# ------------------------------------------------------------------------ labels
@dataclass(frozen=True)
class StateLabel:
    signal: str         # e.g. "J2.w"
    component: str      # e.g. "J2"
    kind: str           # e.g. "w"; internal states: "state:<name>"


def state_labels(c) -> list[StateLabel]:
    """Signal, component and kind of each entry of the ODE state ``u = [x_K, v_K, z]``."""
    st = c.structure
    labels = []
    for level, coords in ((0, c.Kx), (1, c.Kv)):
        for k in coords:
            node = st.coord_node[int(k)]
            if node.bodies:
                body = node.bodies[0]
                var = body.var_names()[level]
                labels.append(StateLabel(f"{body.name}.{var}", body.name, var))
            else:       # pragma: no cover - a coordinate without a body has no mass and cannot be independent
                labels.append(StateLabel(node.label(), node.label(), ("x", "v")[level]))
    for name in c.state_names:
        comp, var = name.rsplit(".", 1)
        labels.append(StateLabel(name, comp, f"state:{var}"))
    return labels


def kind_members(labels) -> list[np.ndarray]:
    """The indices of the labels of each kind of state (index arrays), in the order the kinds first appear."""
    return list(_members_of_kinds(tuple(lab.kind for lab in labels)))


@functools.lru_cache(maxsize=64)
def _members_of_kinds(kinds: tuple) -> tuple:
    """``kind_members`` of a sequence of kinds, kept: the contract asks it several times per call of the same
    model (a tenth of a millisecond each on a chain of 100 inertias); the arrays are read, never written."""
    groups: dict = {}
    for i, kind in enumerate(kinds):
        groups.setdefault(kind, []).append(i)
    members = tuple(np.array(g, dtype=np.intp) for g in groups.values())
    for m in members:
        m.flags.writeable = False       # shared by every caller of the cache
    return members


def kind_scales(labels, values: np.ndarray) -> np.ndarray:
    """Per state: the largest range over the run of the states of its kind (with the floors of the module)."""
    rng = np.ptp(values, axis=0) if len(values) else np.zeros(len(labels))
    mag = np.max(np.abs(values), axis=0) if len(values) else np.zeros(len(labels))
    scales = np.empty(len(labels))
    for members in kind_members(labels):
        scales[members] = max(float(rng[members].max()), MAGNITUDE_FLOOR * float(mag[members].max()),
                              ABSOLUTE_FLOOR)
    return scales


def kind_at_rest(range_k: float, magnitude_k: float) -> bool:
    """Whether a kind of state whose largest range over a run is ``range_k`` and largest magnitude
    ``magnitude_k`` does not move: ``range_k <= max(MAGNITUDE_FLOOR * magnitude_k, ABSOLUTE_FLOOR)``, the
    floors of ``kind_scales`` (a non-finite value moves)."""
    if not (math.isfinite(range_k) and math.isfinite(magnitude_k)):
        return False
    return range_k <= max(MAGNITUDE_FLOOR * magnitude_k, ABSOLUTE_FLOOR)


def kind_unmoved(range_k: float) -> bool:
    """Whether a kind of state whose largest range over a run is ``range_k`` did not move beyond round-off:
    ``range_k <= ABSOLUTE_FLOOR`` (1e-12 in its SI unit), whatever its magnitude (a non-finite range moves).
    Stricter than ``kind_at_rest``: a speed of 300 rad/s with a ripple of 1.8e-4 rad/s is below 1e-6 of its
    magnitude, yet a motion to be resolved."""
    return math.isfinite(range_k) and range_k <= ABSOLUTE_FLOOR


def at_rest_mask(labels, *runs: np.ndarray) -> np.ndarray:
    """Per state: True when no state of its kind moved beyond round-off (``kind_unmoved``) in any run of ``runs``
    (state matrices, one row per instant, one column per label)."""
    mask = np.zeros(len(labels), dtype=bool)
    runs = [r for r in runs if len(r)]
    if not runs or not len(labels):
        return mask
    ranges = [np.ptp(r, axis=0) for r in runs]
    for members in kind_members(labels):
        mask[members] = all(kind_unmoved(float(rng[members].max())) for rng in ranges)
    return mask


def clear_at_rest(d: np.ndarray, labels, *runs: np.ndarray) -> tuple[np.ndarray, list]:
    """``d`` (scaled differences of two runs, one column per label, scales from ``kind_scales``) with the
    columns of the kinds that moved by round-off only in every run of ``runs`` (``at_rest_mask``: at most
    ``ABSOLUTE_FLOOR``, 1e-12 SI units) set to zero where the runs agree within ``REST_AGREEMENT`` floors, and
    the signals so cleared.

    Such a kind has no range to be measured against: ``kind_scales`` gives it its floor, ``ABSOLUTE_FLOOR`` when
    its values are themselves near zero, and its round-off is then judged as if it were its motion. Calibration
    seed 9001: a stuck clutch's temperature rise (``clutch1.T``, before its heat read the stuck mode's zero
    slip) moved by 2e-14 K in each run, its pairs differed by 1e-14 to 4e-13 K, estimates of 0.01 to 0.8 "of its
    range", and the contract tightened the solver's atol to 1e-8 rtol to hold that noise (1.4 million IDA steps
    for a model plain ida runs in 0.8 s). Both runs keep the kind within 1e-12 of where it starts, so they agree
    to 2e-12 in its unit: that is the answer (it does not move), and the difference is left out. Only the
    absolute floor counts here: a kind within the relative floor of ``kind_at_rest`` (1e-6 of its magnitude)
    can be a motion to resolve (a review of this rule: a 300 rad/s shaft's ripple of 1.8e-4 rad/s, left out, came
    back 4.9 % of its range off with an estimate of 2.3e-9)."""
    cleared: list = []
    if not d.size:
        return d, cleared
    mask = at_rest_mask(labels, *runs)
    if not mask.any():
        return d, cleared
    d = d.copy()
    for i in np.flatnonzero(mask):
        col = d[:, i]
        if np.all(np.isfinite(col)) and float(col.max()) <= REST_AGREEMENT:
            d[:, i] = 0.0
            cleared.append(labels[int(i)].signal)
    return d, cleared


@dataclass
class Difference:
    value: float        # max over states and instants of |a - b| / scale
    index: int          # the state
    t: float            # the instant
    instants: int       # instants compared
    at_rest: tuple = ()     # signals of kinds at rest in both runs, left out (``clear_at_rest``)


def largest_difference(va: np.ndarray, vb: np.ndarray, scales, labels=None) -> tuple[float, int, int, tuple]:
    """``(value, instant, state, at_rest)``: the largest ``|va - vb| / scales`` of two runs' state matrices (one
    row per instant, one column per state) and where it is; a non-finite difference is ``inf`` at its first
    entry. With ``labels``, the kinds at rest in both runs are left out where the runs agree
    (``clear_at_rest``: ``at_rest`` names them). A value of 0 (the runs agree everywhere) has no worst state:
    the callers name none. The one measure of the contract's pairs (``accuracy.compare_states``) and of the
    Richardson companions (``scaled_difference``)."""
    d = np.abs(va - vb) / scales
    if not np.all(np.isfinite(d)):
        k, i = np.argwhere(~np.isfinite(d))[0]
        return math.inf, int(k), int(i), ()
    rest: list = []
    if labels:
        d, rest = clear_at_rest(d, labels, va, vb)
    k, i = np.unravel_index(int(np.argmax(d)), d.shape)
    return float(d[k, i]), int(k), int(i), tuple(rest)


def scaled_difference(a: GridProbe, b: GridProbe, scales, labels=None) -> Difference:
    """The largest difference of two runs at the instants both hit, over ``scales`` (``largest_difference``)."""
    common = sorted(set(a.samples) & set(b.samples))
    if not common:
        return Difference(math.inf, 0, math.nan, 0)
    value, k, i, rest = largest_difference(np.array([a.samples[t] for t in common]),
                                           np.array([b.samples[t] for t in common]), scales, labels)
    return Difference(value, i, float(common[k]), len(common), rest)


# -------------------------------------------------------------------- the runs
def _probe_times(model, t_start, t_end, dt_out):
    return np.union1d(output_grid(t_start, t_end, dt_out), signal_breakpoints(model, t_start, t_end) + [t_end])


def _mutable_state(obj) -> dict:
    """Copies of the arrays and sets an object keeps between calls (the friction set's engagement and
    driving sides): a companion run must neither see the main run's end state nor leave its own behind."""
    return {k: v.copy() for k, v in vars(obj).items() if isinstance(v, (np.ndarray, set))}


def _restore(obj, saved: dict):
    for k, v in saved.items():
        setattr(obj, k, v.copy())


class _Isolated:
    """Runs a companion from the state the main run started from, and puts the main run's end state back."""

    def __init__(self, c, start_state):
        self.c, self.start = c, start_state

    def __enter__(self):
        c = self.c
        self.end = (c._t_right, _mutable_state(c.friction) if c.friction else None)
        if c.friction:
            _restore(c.friction, self.start)
        return self

    def __exit__(self, *exc):
        c = self.c
        c._t_right = self.end[0]
        if c.friction:
            _restore(c.friction, self.end[1])
        return False


def simulate_fixed_step(model, name, make_stepper, *, h: float, order: float, tol: float | None,
                        t_start=0.0, t_end=1.0, dt_out=None, after_main=None, floor: float = 0.0,
                        max_steps: int | None = None, **driver):
    """Run a fixed-step method and, unless ``tol`` is None, check its estimated global error.

    ``make_stepper(clock, companion)`` returns the stepper factory of
    ``simulate_ode`` whose steppers take their steps from
    ``clock(t0, knots, t_bound, h)`` (``KnotClock`` for the main run,
    ``GroupedKnotClock`` for the companions, ``companion=True``); ``order``: p
    of the module docstring; ``after_main(res)``
    completes the result's stats before any companion runs (so nothing of a
    companion reaches the result); ``floor``: an a-priori bound of an error that the companions
    cannot see because every run shares it (``expm``'s round-off floor): no estimate is below it;
    ``max_steps``: a step ``h`` that needs more steps over the run is refused before it starts
    (a fixed-step run has no other bound on its work);
    ``driver``: options of ``simulate_ode``.
    Raises ``AccuracyError`` when the estimate exceeds ``tol``.
    """
    refuse_impacts(model, name)
    t_start, t_end, dt_out = check_times(t_start, t_end, dt_out)
    needed = math.ceil(round((t_end - t_start) / h, 6))     # 0.3 / 0.1 is 2.9999999999999996
    if max_steps is not None and needed > max_steps:
        raise SimulationError(
            f"solver '{name}' on model '{model.name}': a step h = {h:.3g} s over {t_end - t_start:.6g} s takes "
            f"{needed:,} steps, more than max_steps={max_steps:,} (minutes to hours of work, and twice that "
            f"again for the error estimate). Use a larger step (tol checks that it is accurate enough), an "
            f"adaptive solver ('ida', 'scipy:DOP853'), a shorter run, or raise max_steps.")
    c = attach(model.compile())
    start_state = _mutable_state(c.friction) if c.friction else None
    times = _probe_times(model, t_start, t_end, dt_out) if tol is not None else None
    main_probe = GridProbe(times) if tol is not None else None
    # a segment's first interval: an even step count before even ones (``step_counts``), with or without a
    # companion to come (the answer does not depend on whether it is checked)
    res = simulate_ode(model, name, make_stepper(functools.partial(KnotClock, even_start=True), False), t_start,
                       t_end, dt_out, probe=main_probe, **driver)
    if after_main is not None:
        after_main(res)
    if tol is None:
        return res
    res.stats.extra["error_floor"] = floor
    t0 = time.perf_counter()

    def companion(factor):
        probe = GridProbe(times)
        if factor < 1:      # steps of h/2: every instant of the main run is hit
            clock = functools.partial(KnotClock, parts=round(1 / factor), even_start=True)
        else:
            clock = functools.partial(GroupedKnotClock, factor=factor, even_start=True)
        with _Isolated(c, start_state):
            stats = simulate_ode(model, name, make_stepper(clock, True), t_start, t_end, dt_out, probe=probe,
                                 record=False, **driver)
        return probe, stats

    # the step actually taken: h is shortened to the output interval (and around breakpoints and events)
    h = min(h, (t_end - t_start) / max(1, res.stats.steps))
    labels = state_labels(c)
    values = np.array(list(main_probe.samples.values()))
    scales = kind_scales(labels, values)
    try:
        probe2, stats2 = companion(2)
    except SimulationError as exc:
        # 2h is beyond what the method resolves (or its stability limit): estimate against h/2 instead
        half = _half_step_estimate(main_probe, companion, order, scales, labels, t_end, res.stats.steps)
        if half is None:
            raise AccuracyError(_companion_failed(name, model, h, exc), accuracy=tol, suggested_h=h / 2) from exc
        est, d, stats_h = half
        est = max(est, floor)
        _record(res.stats, tol, order, est, d, labels, stats_h, 0.5, time.perf_counter() - t0,
                error_companion="h/2 (the run at 2h failed)")
        if not est <= tol:
            raise _too_inaccurate(name, model, c, h, order, tol, est, d, None, labels,
                                  against=f"h/2 (the run at 2h failed: {first_words(exc, 160)})")
        return res
    ratio = min(2.0, res.stats.steps / max(1, stats2.steps))
    if ratio < MIN_RATIO:
        raise AccuracyError(
            f"solver '{name}' on model '{model.name}': the error of the run at h = {h:.3g} s cannot be estimated: "
            f"the segments between time events and stick/slip events are too short for a companion run at 2h "
            f"(it took {stats2.steps} steps against {res.stats.steps}; events from {_event_sources(model, c)}). "
            f"Use a step h well below the spacing of the events, an adaptive solver ('ida', 'scipy:DOP853'), or "
            f"{_SKIP}.", accuracy=tol)
    d1 = scaled_difference(main_probe, probe2, scales, labels) if labels else Difference(0.0, 0, t_end, 0)
    est = max(d1.value / (ratio ** order - 1.0), floor)
    _record(res.stats, tol, order, est, d1, labels, stats2, ratio, time.perf_counter() - t0,
            error_companion="2h")
    d2 = None
    four = False
    if est <= tol and d1.value > tol and labels:
        # the estimate meets tol only through the division by 2^p - 1: check with a run at 4h that the
        # error does shrink like h^p (events located on an interpolant or forcing the steps do not
        # resolve lower the order; measured: expm on OneWayClutch at h = 2 ms, estimate 3.8e-7 against
        # a true 1.2e-6, order 1 there)
        d2, four = _difference_at_4h(companion, probe2, scales, labels), True
        p_obs = _observed_order(d1, d2)
        if p_obs is not None and p_obs < order - 0.5:
            est = max(d1.value / (2.0 ** max(0.5, p_obs) - 1.0), floor)
            _record(res.stats, tol, order, est, d1, labels, stats2, ratio, time.perf_counter() - t0,
                    error_companion="2h, order observed against 4h", error_order_observed=p_obs)
    if not est <= tol and est < 1.0:
        # the run at 2h may lie outside the range where the error goes like h^p (a fast mode near the
        # method's stability limit at 2h but resolved at h): the run at h/2 decides before refusing
        half = _half_step_estimate(main_probe, companion, order, scales, labels, t_end, res.stats.steps)
        if half is not None and max(half[0], floor) <= tol:
            est_h, d, stats_h = half
            est_h = max(est_h, floor)
            _record(res.stats, tol, order, est_h, d, labels, stats_h, 0.5, time.perf_counter() - t0,
                    error_companion="h/2 (the estimate against 2h was not in the asymptotic range)",
                    error_estimate_2h=est)
            return res
    if not est <= tol:
        if est < 1.0 and not four:      # is the error a truncation error (shrinking like h^p)? a run at 4h tells
            d2 = _difference_at_4h(companion, probe2, scales, labels)
        raise _too_inaccurate(name, model, c, h, order, tol, est, d1, d2, labels)
    return res


def _difference_at_4h(companion, probe2, scales, labels=None):
    """The scaled difference between the runs at 2h and 4h (None when the run at 4h fails)."""
    try:
        probe4, _ = companion(4)
    except SimulationError:
        return None
    return scaled_difference(probe2, probe4, scales, labels)


def _observed_order(d1, d2):
    """log2(|y_2h - y_4h| / |y_h - y_2h|), or None when it cannot be formed."""
    if d2 is None or not (math.isfinite(d2.value) and d2.value > 0 and d1.value > 0):
        return None
    return math.log2(d2.value / d1.value)


def _half_step_estimate(main_probe, companion, order, scales, labels, t_end, main_steps):
    """``(E, difference, stats)`` against a run at h/2 (every main step cut in two):
    ``E = |y_h - y_h/2| 2^p / (2^p - 1)``; None when that run fails or the main run is too long for it."""
    if main_steps > HALF_STEP_MAX_STEPS:
        return None
    try:
        probe_half, stats_half = companion(0.5)
    except SimulationError:
        return None
    d = scaled_difference(main_probe, probe_half, scales, labels) if labels else Difference(0.0, 0, t_end, 0)
    return d.value * 2.0 ** order / (2.0 ** order - 1.0), d, stats_half


def _record(st, tol, order, est, d, labels, stats_c, ratio, elapsed, **more):
    """The estimate into the main run's stats; ``wall_time`` = the main run + all companions so far."""
    st.error_estimate = est
    st.wall_time = st.extra.setdefault("wall_time_main", st.wall_time) + elapsed
    named = bool(labels) and d.value > 0.0         # no worst signal where the runs agree everywhere
    st.extra.update({"error_tol": tol, "error_order": order, "error_signal": labels[d.index].signal if named
                     else "", "error_component": labels[d.index].component if named else "", "error_t": d.t,
                     "companion_steps": stats_c.steps,
                     "companion_rhs_calls": stats_c.rhs_calls, "companion_ratio": ratio,
                     "error_estimate_time": elapsed,
                     # the mode changes of the companion behind the estimate (compared by solvers.accuracy)
                     "companion_events": stats_c.extra.get("event_list", []), **more})
    if d.at_rest:
        st.extra["at_rest"] = list(d.at_rest)
    else:
        st.extra.pop("at_rest", None)      # an earlier companion's, not this estimate's


def first_words(exc, n=None):
    """An exception's message on one line (at most ``n`` characters)."""
    text = " ".join(str(exc).split())
    return text if n is None or len(text) <= n else text[: n - 3] + "..."


# ---------------------------------------------------------------------- messages
_SKIP = "pass tol=None to skip the estimate (and take the answer unchecked)"


def _event_sources(model, c) -> str:
    """The components whose events cut the run: friction devices, then components with time signals."""
    from ..signals import Signal
    names = [d.name for d in c.friction.devices] if c.friction else []
    names += [comp.name for comp in model.components.values()
              if any(isinstance(v, Signal) for v in comp._values.values())]
    return ", ".join(f"'{n}'" for n in names[:6]) or "none"


def _companion_failed(name, model, h, exc) -> str:
    first = first_words(exc)
    return (f"solver '{name}' on model '{model.name}': the companion run at step 2h = {2 * h:.3g} s that estimates "
            f"the error of the run at h = {h:.3g} s failed, so the step h is within a factor 2 of the stability "
            f"limit of the method (or of what it resolves) and its answer cannot be trusted. Use a step h <= "
            f"{h / 2:.3g} s, or a stiff (implicit) solver: 'ida', 'scipy:Radau', 'scipy:BDF'; or {_SKIP}. The "
            f"companion run reported: {first}")


def _too_inaccurate(name, model, c, h, order, tol, est, d1, d2, labels, against="2h") -> AccuracyError:
    """The refusal: its message, and ``suggested_h``, a step expected to meet ``tol`` (h/4 where the steps are
    far from resolving the motion and the message asks for a much smaller one; None for a floor)."""
    lab = labels[d1.index]
    fields = dict(signal=lab.signal, component=lab.component, estimate=est, t=d1.t, accuracy=tol)
    head = (f"solver '{name}' on model '{model.name}': estimated error {est:.2g} of {lab.signal} of "
            f"'{lab.component}' exceeds tol = {tol:g} at step h = {h:.3g} s.")
    how = (f"(Error relative to the range of the {lab.kind} states, worst at t = {d1.t:.6g} s; Richardson "
           f"estimate against a run at {against}, order {order:g}; see regmech.solvers.richardson.)")
    if not est < 1.0:
        return AccuracyError(
            f"{head} The error is as large as the motion itself: the step does not resolve the solution at "
            f"all (it may be beyond the stability limit of the method). Use a much smaller step, or a stiff "
            f"(implicit) solver: 'ida', 'scipy:Radau', 'scipy:BDF'; or {_SKIP}. {how}"
            f"{c.stiffness_hint(always=True)}", suggested_h=h / 4, **fields)
    if d2 is not None and math.isfinite(d2.value) and d2.value < SHRINK_RATIO * d1.value \
            and est >= FLOOR_LIMIT:
        # large differences that do not follow h^p: the steps are far from resolving the motion (phase
        # errors over many periods saturate at the size of the motion), not a floor
        return AccuracyError(
            f"{head} The runs at h, 2h and 4h differ by {d1.value:.2g} and {d2.value:.2g} of the range: "
            f"the steps are far from resolving the motion over this run (a long horizon accumulates phase "
            f"error), so the error does not yet shrink like h^{order:g}. Use a much smaller step or an adaptive "
            f"solver; or {_SKIP}. {how}{c.stiffness_hint(always=True)}", suggested_h=h / 4, **fields)
    if d2 is not None and math.isfinite(d2.value) and d2.value < SHRINK_RATIO * d1.value:
        return AccuracyError(
            f"{head} The error does not shrink with the step, so a smaller step will not help: use an "
            f"implicit adaptive solver, 'scipy:Radau', 'scipy:BDF' or 'ida'; or {_SKIP}. The difference "
            f"between the runs at 2h and 4h, {d2.value:.2g}, is not larger than that between h and 2h, "
            f"{d1.value:.2g}: a round-off floor or a discontinuity the steps do not resolve. {how}"
            f"{c.stiffness_hint()}", **fields)
    p = order
    observed = ""
    if d2 is not None and math.isfinite(d2.value) and d2.value > 0 and d1.value > 0:
        p_obs = math.log2(d2.value / d1.value)
        if p_obs < order - 0.5:
            p = max(0.5, p_obs)
            est = d1.value / (2.0 ** p - 1.0)
            observed = f" (the error shrinks like h^{p_obs:.2g} here, slower than the order {order:g} of the method)"
        elif p_obs > order + 0.5:
            # faster than the guaranteed order (expm under forcing slow against the step: up to 2 order_p, see
            # above): the step is chosen with the observed order, at most twice the guaranteed one. With the
            # guaranteed order 2 the default call on a 1,000-inertia chain at accuracy 1e-6 went from h = 0.01
            # to 4.1e-4 s and an estimate of 2.9e-10 (the error went as h^4 there), 2,500 steps for 1e-6
            p = min(p_obs, 2.0 * order)
            observed = f" (the error shrinks like h^{p_obs:.2g} here, faster than the guaranteed order {order:g})"
    h_new = h * SAFETY * (tol / est) ** (1.0 / p)
    return AccuracyError(f"{head} Use a step h <= {h_new:.3g} s, or an adaptive solver; or {_SKIP}{observed}. {how}",
                         suggested_h=h_new, **fields)


__all__ = ["simulate_fixed_step", "state_labels", "kind_scales", "DEFAULT_TOL"]
