"""The accuracy contract: ``simulate(model, t_end, ..., accuracy=a)`` returns a run whose estimated global
error is at most ``a``, or raises ``AccuracyError``.

What is bounded. The *state signals* of the result: the position and the
speed of every mass (``J.phi``, ``J.w``; ``m.s``, ``m.v``) and the internal
states of devices, at the output instants. Each is measured against the
largest range over the run of the signals of its *kind* (angles, angular
speeds, positions, speeds, each kind of internal state), the measure of the
fixed-step estimate (``richardson.kind_scales``, with its floors for a kind
that does not move)::

    estimate = max over signals i and output instants t of |e_i(t)| / range(kind of i)

A kind that moves by round-off only (its range at most ``ABSOLUTE_FLOOR``,
1e-12 in its SI unit, in both runs of a pair) has no range to be relative
to: the runs then agree within 2e-12 of it, which is the answer (it does
not move), so the kind is left out of the estimate
(``richardson.clear_at_rest``) and named in ``stats.extra["at_rest"]``; nor
does it scale the pair's atol (``motion_scale``). A kind that moves by more
in either run is judged as any other, against its floor of ``1e-6`` of its
magnitude where its range is smaller.

Signals that jump at a mode change (friction torques, accelerations) are
not compared point by point: a switch-time error of 1e-9 s would show as an
O(1) difference there. The switch times of the friction events are checked
separately: the companion runs must take the same path through the modes
(the same changes, device by device, in the same order), and each event of
the result gets ``Event.t_error``, the difference of its switch time between
the runs; ``stats.extra["event_time_error"]`` is the largest. One exception,
for adaptive pairs: a round trip of a device's mode (a -> b -> a) lasting at
most ``GRAZE_FRACTION`` of the run, seen by one run only (a grazing stick of
a few microseconds, found by one tolerance and missed by the next), is left
to the state signals, which show its effect on the motion as they show a
grazing contact's; ``stats.extra["grazing"]`` lists such trips. Likewise a
hard stop's rebound series whose impacts the runs count differently (its
ever weaker tail is resolved to a depth that follows the tolerance) is one
change per series, matched at its first impact (``match_events``).

How it is estimated, per family of solver:

* **Adaptive solvers** (``ida``, ``scipy:*``, ``dopri5``, ``dop853``, ``convolution`` without ``h``):
  a pair of runs at ``rtol = r`` and ``r / TIGHTEN`` (atol scaled alike),
  and the *tighter* one is returned, with ``PAIR_FACTOR`` (2) times the
  scaled maximum difference of the pair as its estimate. Under tolerance
  proportionality (global error ``~ C r^alpha`` with ``alpha`` near 1) the
  difference is about ``(1 - TIGHTEN^-alpha)`` times the loose run's error,
  i.e. roughly ``TIGHTEN^alpha - 1`` (9 for alpha = 1) times the returned
  run's: a conservative bound, which stays a bound as long as tightening the
  tolerance ten-fold at least divides the error by 1.5. The factor 2 covers
  pairs whose errors partly cancel in their difference: on fuzz seed 97 of
  the random calibration (a wheel's road contact sticking and slipping 14
  times, its contact patch ringing at 110 Hz) ida's pair at 3e-6 / 3e-7
  differed by 9.9e-5 of the range, and the returned run was 1.3e-4 off a
  reference that four methods agree on to 1e-7 (accuracy 1e-4 asked): the
  errors fell only 3-fold from one rtol to the next. The first ``r`` is
  ``accuracy * RTOL_FACTOR[solver]``, times ``(accuracy / 1e-3) **
  RTOL_SLOPE`` below 1e-3 for ida on its native path, whose error grows
  faster than its tolerance shrinks and whose runs cost little more when
  tighter (``first_rtol``; measured, see BENCHMARKS.md, calibration), or
  the user's ``rtol``; ``atol = ATOL_RATIO * r`` (or the
  user's ratio), scaled down to the motion when its smallest range of a kind
  is below ``ATOL_RESCALE`` (``motion_scale``; an atol made for a motion
  of 1 would hold a motion of 1e-5 to errors near atol): the tight run gets
  the scaled atol, and the first run, made with the unscaled one, stays the
  pair's loose run unless the pair misses the accuracy, when it is repeated
  with the scaled atol (a looser atol leaves the loose run less accurate as
  a rule, so its difference is as a rule the larger bound; the calibration
  measures it; ida makes each run once, ``atol_rescale=False``,
  instead of repeating it scaled itself). A state far larger than the
  range of its kind (a speed of 5.8 m/s moving by 0.0036 m/s) has a local
  tolerance ``rtol |y|`` far above the same rtol of the measure, and its
  error is then left to the steps, not to the tolerance: the tight rtol is
  capped at ``MAGNITUDE_REACH * accuracy / ratio`` (``magnitude_ratio``,
  kinds at rest left out) and the first run is made again at the cap
  (``stats.extra["rtol_cap"]`` names the state). When the estimate exceeds the
  accuracy, ``r`` is scaled by ``SAFETY * accuracy / estimate`` (when that
  is no tighter than ``r / TIGHTEN``, the tight run becomes the loose run of
  the next pair and only one new run is made), at most ``MAX_ATTEMPTS``
  pairs.
* **Fixed-step solvers** (``euler``, ``rk4``, ``abm``, ``expm``,
  ``convolution`` with ``h``): their Richardson estimate
  (``regmech.solvers.richardson``) held to ``accuracy / FIXED_STEP_MARGIN``
  (an estimate against 2h is no bound where the error does not fall steadily
  with h, e.g. around events; richardson also checks the order against a
  run at 4h when the estimate passes only through the division by
  ``2^p - 1``); without ``h`` a first step from the output interval and,
  for the explicit methods, ``STABLE_FRACTION`` of their stability limit on
  the fastest link; a refusal that suggests a step
  (``AccuracyError.suggested_h``) is retried with it, at most
  ``MAX_ATTEMPTS`` runs, and never beyond ``MAX_FIXED_STEPS`` steps.

A run whose companion takes another path through the modes is retried
tighter; if the paths still differ at the last attempt the run is refused
naming the device. Both families share one more limit: the round-off of
the stiffest link puts up to ``eps (w_max/w_min)^2`` of the range on any
answer (``roundoff_bound``), the same in both runs of a pair, so no
difference shows it: no estimate is reported below it, an accuracy below it
is refused before any run, and the pair's rtol never goes below the limit
of ``common.check_link_spread``. Every refusal names the worst signal (or
the stiffest link), its component, the estimate, the instant and what would
meet the accuracy.

``stats`` of a run made with ``accuracy=``: ``error_estimate``; in
``extra``: ``error_signal``, ``error_component``, ``error_t``,
``accuracy``, ``attempts``, ``estimate_time`` (time of every run but the
returned one), ``settings`` (rtol/atol or h the run ended with),
``error_method``, ``error_floor`` (the round-off bound, with links),
``rtol_cap`` (the state that capped the rtol, when one did),
``event_time_error`` (with events), ``grazing`` (round trips left to the
states, when any), ``at_rest`` (signals of the kinds at rest left out, when
any); ``wall_time`` counts every run,
``extra["wall_time_main"]`` the returned one alone.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections import defaultdict

import numpy as np

from ..errors import AccuracyError, ParameterError, SimulationError
from .common import check_times, output_grid, spread_rtol_floor
from .richardson import StateLabel, kind_at_rest, kind_members, kind_scales, kind_unmoved, largest_difference

#: the accuracy of ``solver="auto"`` when none is given: 1e-3 of the range of the signals of a kind
DEFAULT_ACCURACY = 1e-3
#: loosest accuracy accepted (beyond it the estimate itself, a difference of two runs, means little)
MAX_ACCURACY = 0.1
#: pairs of runs (adaptive) or runs (fixed step) before a refusal
MAX_ATTEMPTS = 3
#: the tight run of a pair has ``rtol / TIGHTEN``
TIGHTEN = 10.0
#: a retry aims at this fraction of the accuracy
SAFETY = 0.5
#: an adaptive pair's estimate is this many times the scaled difference of its two runs (module docstring)
PAIR_FACTOR = 2.0
#: no adaptive run below this rtol (double precision leaves nothing to gain; the solvers' own checks
#: refuse much earlier on stretched spectra)
RTOL_MIN = 1e-13
#: a fixed-step run that would need more steps is refused instead of run (an hour of euler)
MAX_FIXED_STEPS = 500_000
#: solvers estimated by Richardson extrapolation of their fixed steps
FIXED_STEP = ("euler", "rk4", "abm", "expm")
#: the first rtol of the pair is ``accuracy * RTOL_FACTOR[solver]``: measured (calibration in BENCHMARKS.md)
RTOL_FACTOR = {"ida": 0.03, "scipy:Radau": 0.5, "scipy:DOP853": 0.1, "scipy:RK45": 0.04, "scipy:RK23": 0.04,
               "scipy:BDF": 0.01, "scipy:LSODA": 0.03, "convolution": 0.003}
#: regmech's own Dormand-Prince integrators take the steps of scipy's (``dopri``; tests/unit/test_dopri.py), so
#: scipy's calibration is theirs
RTOL_FACTOR.update({"dopri5": RTOL_FACTOR["scipy:RK45"], "dop853": RTOL_FACTOR["scipy:DOP853"]})
#: ... times ``(accuracy / RTOL_ANCHOR) ** RTOL_SLOPE`` below RTOL_ANCHOR for ida on its native path
#: (``native_served``): its global error grows faster than its tolerance shrinks (``error ~ C rtol^alpha``; the
#: calibration of BENCHMARKS.md, 24 cases and 100 random drivetrains, first pair at 0.03 a: median estimate over
#: a 0.054, 0.074, 0.079, 0.107, 0.208 at a = 1e-2 .. 1e-6, alpha = 0.85), so at tight accuracies the first pair
#: misses more often and a third run is made (CoupledClutches at 1e-6: 3e-8 / 3e-9 estimated 1.2e-6, 1e-8 / 1e-9
#: 1.5e-7). A native run's time changes little with rtol (events and set-up dominate: CoupledClutches 3.5 ms at
#: 3e-5, 5.0 ms at 3e-10), so a tighter pair costs less than a third run there. Measured side by side, slope 0.15
#: against none (load 4-6, medians of 3): native cells at 1e-6 0.43x-1.35x, geometric mean 0.86 (CoupledClutches
#: 0.71, one pair instead of two); at 1e-4 and 1e-5 0.98x-1.26x (the price: no retry saved there); on the Python
#: path much dearer (vehicle_launch at 1e-5 3.5x, one_way_clutch at 1e-4 1.85x: stiff nonlinear steps) and above
#: the anchor a looser first pair retried more (auto at 1e-2: 3 of 24 cases against 1), so neither is done
RTOL_SLOPE = 0.15
RTOL_ANCHOR = 1e-3
#: atol = ATOL_RATIO * rtol (the solvers' default) for a motion of magnitude 1 or more; for a smaller one
#: (the smallest range of a kind of state signal that moves, ``motion_scale``, below ATOL_RESCALE after the
#: first run) the pair is run with atol scaled down to it, but not below ATOL_SCALE_MIN times
ATOL_RATIO = 1e-2
ATOL_RESCALE = 0.1
ATOL_SCALE_MIN = 1e-6
#: the tight run's relative tolerance times the largest ratio of a state's magnitude to the range of its kind
#: (``magnitude_ratio``) is held to this fraction of the accuracy: the solvers weigh a state's local error by
#: ``rtol |y|``, so a speed of 5.8 m/s whose kind moves by 0.0036 m/s (fuzz seed 80130: a 490 kg mass leaving a
#: stiff gap) had a tolerance of 4.8e-3 of the range at rtol 3e-6 while 1e-3 was asked; its pair (3e-5 / 3e-6)
#: differed by 4.9e-4 and the tight run was 5.4e-3 off, the error set by the steps across the contact, not by
#: the tolerance (the same 4.9e-3 and 5.4e-3 at 3e-5 and 3e-6). Capped at 0.5 a / 1600: 3.1e-7, error 1.7e-5
MAGNITUDE_REACH = 0.5
#: the Richardson estimate of a fixed-step run must be below accuracy / FIXED_STEP_MARGIN: against a run at
#: 2h it is no bound where the error does not fall steadily with h (events; measured: expm on OneWayClutch
#: at h = 2 ms, estimate 3.8e-7, true 1.2e-6, while the run at 2h was nearer the truth)
FIXED_STEP_MARGIN = 3.0
#: first fixed step of an explicit method: this fraction of its stability limit on the fastest link (so that
#: the companion at 2h is still at half the limit: at 0.5, rk4's 2h run sat on the limit and the estimate
#: on stretched_1e3 was 6 times below the true error)
STABLE_FRACTION = 0.25
#: switch instants closer than this (relative to max(1, |t|)) are one change of a device (round-off pairs)
SAME_INSTANT = 1e-9
#: a round trip of a friction mode seen by one run of an adaptive pair only, lasting at most this fraction of
#: the run's span, is judged by the state signals (``match_events``, ``graze_span``): the OneWayClutch hard
#: case grazes a stick for 4 us at t = 1.5 s, which ida saw at rtol 3e-8, 3e-10 and 3e-11 but not at 3e-9,
#: so that two pairs were rejected at accuracy 1e-6 and the third ran at 3e-11 (793 ms, error 2.2e-9)
GRAZE_FRACTION = 1e-4


def check_accuracy(accuracy) -> float:
    """``accuracy`` as a float in (0, MAX_ACCURACY]; ``ParameterError`` otherwise (numpy scalars accepted)."""
    ok = isinstance(accuracy, (int, float, np.integer, np.floating)) and not isinstance(accuracy, (bool, np.bool_))
    if ok:
        value = float(accuracy)
        if math.isfinite(value) and 0.0 < value <= MAX_ACCURACY:
            return value
    raise ParameterError(
        f"simulate(): accuracy (the bound of the estimated global error of every state signal, relative to the "
        f"range of the signals of its kind) must be a number in (0, {MAX_ACCURACY:g}], e.g. 1e-4; got "
        f"{accuracy!r}")


def first_rtol(solver: str, accuracy: float, native: bool = False) -> float:
    """The rtol of the first (looser) run of an adaptive solver's pair: ``accuracy * RTOL_FACTOR[solver]``, times
    ``(accuracy / RTOL_ANCHOR) ** RTOL_SLOPE`` below the anchor for ida on its native path (``native``)."""
    r = accuracy * RTOL_FACTOR.get(solver, 0.01)
    if native and solver == "ida" and accuracy < RTOL_ANCHOR:
        r *= (accuracy / RTOL_ANCHOR) ** RTOL_SLOPE
    return r


def native_served(solver: str, c, options: dict) -> bool:
    """Whether the runs of ``solver`` with ``options`` go through ida's compiled callbacks (``ida_native``)."""
    if solver != "ida" or not options.get("native"):
        return False
    from .ida import choose_linsolver
    from .ida_native import eligible, libraries
    if isinstance(libraries(), str):
        return False
    try:
        linsolver = options.get("linsolver") or choose_linsolver(c, options.get("dense_max", 60))[0]
        return eligible(c, linsolver) is None
    except Exception:       # noqa: BLE001 - a model the check cannot judge runs as if not native
        return False


def is_fixed_step(solver: str, options: dict) -> bool:
    return solver in FIXED_STEP or (solver == "convolution" and options.get("h") is not None)


# ------------------------------------------------------------------------------ the measure
def result_state_labels(c) -> list[StateLabel]:
    """Signal, component and kind of every state signal of a result: position and speed of each mass (one
    body per coordinate: bodies joined rigidly share it), then each internal state."""
    return [lab for lab, _ in _state_signals(c)]


def state_columns(c) -> np.ndarray:
    """The column of ``y`` (a trajectory's ``Y``) holding each state signal of ``result_state_labels(c)``,
    in its order: the position ``x_k`` and the speed ``v_k`` of the body's coordinate, the internal state
    ``z_j`` (the outputs' own recipes, ``compile.outputs``, read the same columns)."""
    return np.array([col for _, col in _state_signals(c)], dtype=np.intp)


def _state_signals(c) -> tuple:
    """``(StateLabel, column of y)`` per state signal of a compiled system, kept with it (fixed by its
    structure; 0.4 ms on a chain of 100 inertias, asked twice by every call with ``accuracy``)."""
    got = c.__dict__.get("_contract_state_signals")
    if got is None:
        got = c._contract_state_signals = tuple(_find_state_signals(c))
    return got


def _find_state_signals(c) -> list:
    st = c.structure
    out = []
    for level, cols in ((0, c.ix), (1, c.iv)):
        for k, node in enumerate(st.coord_node):
            if node.bodies:
                body = node.bodies[0]
                var = body.var_names()[level]
                out.append((StateLabel(f"{body.name}.{var}", body.name, var), int(cols[k])))
    for j, name in enumerate(c.state_names):
        comp, var = name.rsplit(".", 1)
        out.append((StateLabel(name, comp, f"state:{var}"), int(c.iz[j])))
    return out


def grid_rows(t: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Index of each grid instant in a result's time axis: the last row at that instant (the right limit
    after an event); every solver lands on the output instants."""
    tol = 1e-11 * np.maximum(1.0, np.abs(grid))
    k = np.searchsorted(t, grid + tol, side="right") - 1
    return np.clip(k, 0, len(t) - 1)


def state_matrix(res, labels, grid, columns=None) -> np.ndarray:
    """The state signals of ``res`` at the grid instants, one column per label. ``columns``
    (``state_columns`` of the compiled system that made ``res``): read from the stored rows directly,
    without building each signal over the whole run (a tenth of a millisecond per signal on small
    models, which the contract paid for both runs of every pair)."""
    rows = grid_rows(np.asarray(res.t, float), grid)
    if not labels:
        return np.zeros((len(grid), 0))
    traj = getattr(res, "_traj", None)
    Y = getattr(traj, "Y", None)
    if columns is not None and isinstance(Y, np.ndarray) and Y.ndim == 2 and len(columns) == len(labels):
        return np.array(Y[rows][:, columns], dtype=float)
    return np.column_stack([np.asarray(res[lab.signal], float)[rows] for lab in labels])


@dataclasses.dataclass
class Estimate:
    value: float            # max |a - b| / scale
    signal: str
    component: str
    kind: str
    t: float
    at_rest: tuple = ()     # signals of kinds at rest in both runs, left out (``richardson.clear_at_rest``)


def compare_runs(a, b, labels, grid, columns=None) -> Estimate:
    """Scaled largest difference of the state signals of two results (scales from ``b``)."""
    if not labels:
        return Estimate(0.0, "", "", "", float(grid[-1]))
    return compare_states(state_matrix(a, labels, grid, columns), state_matrix(b, labels, grid, columns), labels,
                          grid)


def compare_states(va, vb, labels, grid) -> Estimate:
    """``compare_runs`` on the state matrices (``state_matrix``) of the two runs."""
    if not labels:
        return Estimate(0.0, "", "", "", float(grid[-1]))
    value, k, i, rest = largest_difference(va, vb, kind_scales(labels, vb), labels)
    if not value > 0.0:
        # the runs agree everywhere (or every kind is at rest): no signal is the worst one, none is named
        return Estimate(0.0, "", "", "", float(grid[-1]), rest)
    lab = labels[i]
    return Estimate(value, lab.signal, lab.component, lab.kind, float(grid[k]), rest)


# ------------------------------------------------------------------------------ events
def net_changes(events) -> list[tuple[float, str, int, int, list[int]]]:
    """Mode changes ``(t, component, old, new, indices)`` with the changes of one device at one instant (to
    ``SAME_INSTANT``) merged into one (a Free -> Forward -> Stuck pair 1e-15 s apart is one Free -> Stuck;
    a change undone at once disappears); ``indices``: the events of the list merged into it."""
    out: list = []
    last: dict = {}
    for i, ev in enumerate(events):
        if ev.kind in ("contact", "limit", "flow", "switch", "latch"):
            # contacts of piecewise laws (and controllers' limits) are compared through the signals they shape: a
            # grazing touch seen by one run and not the other changes the motion by less than the tolerances
            continue
        j = last.get(ev.component)
        if j is not None and out[j] is not None:
            t0, comp, old, new, idx = out[j]
            if abs(ev.t - t0) <= SAME_INSTANT * max(1.0, abs(t0)):
                out[j] = (t0, comp, old, ev.new_mode, idx + [i])
                continue
        last[ev.component] = len(out)
        out.append((float(ev.t), ev.component, int(ev.old_mode), int(ev.new_mode), [i]))
    return [e for e in out if e[2] != e[3]]


@dataclasses.dataclass
class EventMatch:
    same_path: bool
    t_error: list            # per event of ``b``: |t_a - t_b| of its match (None: merged away or grazing)
    max_error: float | None
    devices: list            # devices whose changes differ between the runs
    #: brief round trips of a mode seen by one run of the pair only, ``(device, t, duration)``, judged by the
    #: state signals they shape (``graze_span`` of ``match_events``)
    grazing: list = dataclasses.field(default_factory=list)


def _path(seq) -> list:
    return [(e[2], e[3]) for e in seq]


def _without_trips(seq, span: float) -> tuple[list, list]:
    """``seq`` (one device's ``net_changes``) without its round trips ``a -> b -> a`` that last at most
    ``span`` seconds, and the trips removed ``(t, duration)``."""
    out, trips = [], []
    for e in seq:
        if out and out[-1][2] == e[3] and out[-1][3] == e[2] and e[0] - out[-1][0] <= span:
            first = out.pop()
            trips.append((first[0], e[0] - first[0]))
            continue
        out.append(e)
    return out, trips


def _without_bounce_repeats(seq, events) -> tuple[list, list]:
    """``seq`` (one device's ``net_changes``) with each series of impacts on one side (consecutive ``"impact"``
    events with the same (old, new): a rebound series of a ``HardStop``) kept as its first impact, and the instants
    of the repeats removed."""
    out, repeats = [], []
    for e in seq:
        if out and (out[-1][2], out[-1][3]) == (e[2], e[3]) and events[e[4][0]].kind == "impact" \
                and events[out[-1][4][0]].kind == "impact":
            repeats.append(e[0])
            continue
        out.append(e)
    return out, repeats


def match_events(events_a, events_b, graze_span: float | None = None) -> EventMatch:
    """Compare the mode changes of two runs, device by device (``net_changes``): the same sequence of
    (old, new) per device is the same path, and the k-th changes of a device are matched.

    ``graze_span`` [s]: where the sequences of a device differ, its round trips ``a -> b -> a`` of at most
    this duration are taken out of both runs and the rest compared. A grazing touch of zero slip (a
    one-way clutch's stick of 4 us at t = 1.5 s in the OneWayClutch hard case, 2 -> 0 -> 2) is seen by
    one tolerance and missed by the next, while its effect on the motion is within both runs'
    tolerances: the pair's state signals judge it, as they judge a grazing contact (the trips are listed
    in ``grazing``). A trip that changes the motion by more than the accuracy shows in those signals.

    Likewise a rebound series of a hard stop (impacts on one side, each with ``e^2`` of the energy of the one
    before) is one change per series where the runs count its impacts differently: the tail of the series, ever
    shorter and weaker rebounds until the Zeno rule holds the contact, is resolved to a depth that follows the
    tolerance (a fuzz run, seed 90076: a servo-driven inertia rattling in a stop with e = 0.4, 11 and 12
    impacts in its first series at ida's rtol 3e-7 and 3e-8, every pair rejected and the default call refused),
    while the motion of the two runs agrees to 2.6e-5 of the range; the series' first impacts are matched in time
    and the state signals judge the rest (the repeats are listed in ``grazing`` with duration 0)."""
    na, nb = net_changes(events_a), net_changes(events_b)
    per_a, per_b = defaultdict(list), defaultdict(list)
    for e in na:
        per_a[e[1]].append(e)
    for e in nb:
        per_b[e[1]].append(e)
    differ, grazing = [], []
    for comp in sorted(set(per_a) | set(per_b)):
        if _path(per_a[comp]) == _path(per_b[comp]):
            continue
        if graze_span is not None and graze_span > 0:
            (sa, ta), (sb, tb) = _without_trips(per_a[comp], graze_span), _without_trips(per_b[comp], graze_span)
            if _path(sa) == _path(sb):
                per_a[comp], per_b[comp] = sa, sb
                grazing += [(comp, t, d) for t, d in ta + tb]
                continue
            (ra, qa), (rb, qb) = _without_bounce_repeats(sa, events_a), _without_bounce_repeats(sb, events_b)
            if _path(ra) == _path(rb):
                per_a[comp], per_b[comp] = ra, rb
                grazing += [(comp, t, d) for t, d in ta + tb] + [(comp, t, 0.0) for t in qa + qb]
                continue
        differ.append(comp)
    t_error: list = [None] * len(events_b)
    worst = None
    if not differ:
        for comp, seq_b in per_b.items():
            for ea, eb in zip(per_a[comp], seq_b):
                dt = abs(ea[0] - eb[0])
                worst = dt if worst is None else max(worst, dt)
                for i in eb[4]:
                    t_error[i] = dt
    return EventMatch(not differ, t_error, worst, differ, sorted(grazing, key=lambda g: g[1]))


def _path_text(events, device, n=4) -> str:
    from ..result import MODE_NAMES
    seq = [e for e in net_changes(events) if e[1] == device]
    shown = ", ".join(f"{MODE_NAMES.get(e[2], e[2])}->{MODE_NAMES.get(e[3], e[3])} at {e[0]:.6g} s" for e in seq[:n])
    more = f" and {len(seq) - n} more" if len(seq) > n else ""
    return f"{len(seq)} change(s): {shown or 'none'}{more}"


# ------------------------------------------------------------------------------ the contract
def simulate_with_accuracy(model, solver: str, fn, t_start, t_end, dt_out, accuracy: float, options: dict):
    """Run ``solver`` (its registered function ``fn``) under the contract of the module docstring."""
    t_start, t_end, dt_out = check_times(t_start, t_end, dt_out)
    options = dict(options)
    if "tol" in options:
        raise ParameterError(f"solver '{solver}': give either accuracy= (the contract) or tol= (the bare "
                             f"Richardson check of a fixed-step run), not both; accuracy sets tol")
    tc = time.perf_counter()
    c = model.compile()
    compile_time = time.perf_counter() - tc
    t0 = time.perf_counter()
    floor = roundoff_bound(c)
    if floor is not None and floor[0] > accuracy:
        bound, dev, w, ratio = floor
        raise AccuracyError(
            f"accuracy {accuracy:g} with solver '{solver}' on model '{model.name}': the round-off of the stiffest "
            f"link, {type(dev).__name__} '{dev.name}' (local mode {w / 2 / math.pi:.3g} Hz, {ratio:.3g} times "
            f"faster than the softest), may put up to eps * {ratio:.3g}^2 = {bound:.2g} of the range on the answer "
            f"whatever the solver and its settings, and no pair of runs can see it (both carry it). Make that link "
            f"rigid (Shaft(stiffness=None)) or let rm.Scene(band_hz=...) do it, or ask for a looser accuracy.",
            component=dev.name, estimate=bound, accuracy=accuracy)
    if is_fixed_step(solver, options):
        res = _fixed_step(model, solver, fn, t_start, t_end, dt_out, accuracy, options)
    else:
        res = _adaptive(model, solver, fn, t_start, t_end, dt_out, accuracy, options)
    total = time.perf_counter() - t0
    st = res.stats
    if floor is not None:
        st.extra["error_floor"] = floor[0]
        if st.error_estimate is not None and st.error_estimate < floor[0]:
            st.error_estimate = floor[0]
    main = st.extra.get("wall_time_main", st.wall_time)
    st.extra["wall_time_main"] = main
    st.extra["estimate_time"] = max(0.0, total - main)
    st.wall_time = max(st.wall_time, total)
    st.compile_time = max(st.compile_time, compile_time)
    return res


def roundoff_bound(c):
    """``(bound, device, omega, ratio)``: the a-priori bound ``eps (w_max/w_min)^2`` of the error that the
    round-off of the stiffest link puts on any answer (relative to the range; measured 0.01 to 0.25 of it on
    the stretched chains of the hard cases, ``expm.roundoff_floor``), None without links. Two runs of a
    pair share it, so their difference cannot show it: no estimate is reported below it."""
    floor = spread_rtol_floor(c)
    if floor is None:
        return None
    rmin, dev, w, ratio = floor
    return float(np.finfo(float).eps * ratio ** 2), dev, w, ratio


def _run_or_explain(fn, model, solver, accuracy, what, **kw):
    """One run of the contract; a failure of a run the contract asked for says so (same error class)."""
    try:
        return fn(model, **kw)
    except AccuracyError as exc:
        fields = exc.fields()
        fields["accuracy"] = accuracy
        raise AccuracyError(f"accuracy {accuracy:g} with solver '{solver}': the run at rtol={kw.get('rtol', 0):.3g} "
                            f"refused: {exc}", **fields) from exc
    except SimulationError as exc:
        if what is None:
            raise
        cls = type(exc)
        try:
            new = cls(f"accuracy {accuracy:g} with solver '{solver}': the run at {what} failed: {exc}")
        except TypeError:       # pragma: no cover - an error class with another constructor
            raise exc
        raise new from exc


def _settings_text(settings: dict) -> str:
    return ", ".join(f"{k}={v:.3g}" for k, v in settings.items())


def _adaptive(model, solver, fn, t_start, t_end, dt_out, accuracy, options):
    rtol0 = options.pop("rtol", None)
    atol0 = options.pop("atol", None)
    if rtol0 is not None and not (isinstance(rtol0, (int, float)) and not isinstance(rtol0, bool) and rtol0 > 0):
        raise ParameterError(f"solver '{solver}': rtol must be a positive number, got {rtol0!r}")
    c = model.compile()
    r = float(rtol0) if rtol0 is not None else first_rtol(solver, accuracy, native_served(solver, c, options))
    # the stiffest link's round-off bounds the useful rtol (common.check_link_spread): the pair never goes
    # below it; an accuracy that would need a tighter one is refused naming the link
    floor = spread_rtol_floor(c) if options.get("stiff_check", True) else None
    r_floor = floor[0] * 1.000001 if floor is not None else 0.0
    r = max(r, TIGHTEN * r_floor)
    bound = roundoff_bound(c)
    round_off = bound[0] if bound is not None else 0.0
    # atol follows rtol: the solvers' default ratio 1e-2, or the ratio the user gave
    atol_ratio = ATOL_RATIO if atol0 is None else np.asarray(atol0, float) / r
    labels = result_state_labels(c)
    columns = state_columns(c)
    grid = output_grid(t_start, t_end, dt_out)
    graze = GRAZE_FRACTION * (t_end - t_start)

    def states(res):
        return state_matrix(res, labels, grid, columns)

    def run(rt, first=False, **extra):
        at = atol_ratio * rt
        at = float(at) if np.ndim(at) == 0 else at
        what = None if first else f"rtol={rt:.3g} (the contract tightened it)"
        return _run_or_explain(fn, model, solver, accuracy, what, t_start=t_start, t_end=t_end, dt_out=dt_out,
                               rtol=rt, atol=at, **options, **extra)

    # ida repeats a run whose motion is small for its atol (``ida._rescaled_atol``); the contract scales its
    # pair's atol to the motion itself (``motion_scale``, below), so every run is made once: a kind that ida would
    # rescale (magnitude below 1/30 of a motion of 1) has a range below ATOL_RESCALE, where a pair that misses
    # repeats it scaled (measured: the benchmark chain of 100 inertias at accuracy 1e-3 took three IDA runs,
    # 4.2, 5.8 and 9.7 ms, the first of them ida's own repeat). Once the contract has scaled atol to the smallest
    # range s of a kind that moves, ida would repeat a run only for a kind of magnitude below s/30 (a moving kind's
    # magnitude is at least half its range, s/2): a kind at rest, which the estimate leaves out. Such repeats
    # resolved round-off: calibration seed 9001's stuck clutch temperature (2e-14 K) had the device states' atol
    # scaled by 1e-6, and its tight runs took 12,439 to 464,587 IDA steps where unscaled ones took 700 to 1,900
    once = {"atol_rescale": False} if solver == "ida" and atol0 is None and "atol_rescale" not in options else {}
    options.update(once)
    loose = run(r, first=True)
    v_loose = states(loose)
    # a state far larger than the range of its kind: its tolerance (rtol |y|) must be held below the accuracy in
    # the contract's measure, else the pair's difference is no bound (MAGNITUDE_REACH); the first run is made
    # again at the capped rtol (its own rtol left that state's error to chance)
    magnitude = magnitude_ratio(labels, v_loose)
    r_cap = max(TIGHTEN * MAGNITUDE_REACH * accuracy / magnitude[0], TIGHTEN * r_floor)
    capped = None
    if r > r_cap * 1.000001:
        capped = f"rtol capped for {magnitude[1]} ({magnitude[0]:.3g} times the range of its kind)"
        r = r_cap
        loose = run(r, first=True)
        v_loose = states(loose)
    # the atol of the loose run when it is not the pair's (a small motion, below): the run is kept as the pair's
    # loose run until its comparison fails, then repeated with the pair's atol
    loose_atol = None
    if atol0 is None:
        scale = motion_scale(loose, labels, grid, v_loose)
        if scale < ATOL_RESCALE:
            # a small motion: the default atol (for a motion of about 1) would hold every state's error near
            # atol, far above the accuracy relative to the motion; the pair's runs get atol scaled to it. The
            # loose run is not repeated at once: its larger atol leaves it less accurate as a rule, so its
            # difference from the tight run is as a rule the larger bound of the tight run's error (measured
            # before: the benchmark chain of 100 inertias at accuracy 1e-3 took three ida runs, 10, 9 and
            # 10 ms, the second of them the repeat)
            loose_atol = ATOL_RATIO * r
            atol_ratio = ATOL_RATIO * scale
    history = []
    attempts = 0
    while True:
        attempts += 1
        r_tight = r / TIGHTEN
        if r_tight < max(RTOL_MIN, r_floor):
            raise AccuracyError(_out_of_reach(solver, model, accuracy, history, r_tight, floor), accuracy=accuracy,
                                **_worst_fields(history, floor))
        tight = run(r_tight)
        v_tight = states(tight)
        est, ev = _pair_estimate(v_loose, v_tight, loose, tight, labels, grid, round_off, graze)
        if loose_atol is not None and not (est.value <= accuracy and ev.same_path):
            # the pair with the unscaled loose run missed: the loose run again with the pair's atol, against
            # the same tight run (what the retry below needs: a pair whose difference follows the tolerance)
            loose_atol = None
            loose = run(r)
            v_loose = states(loose)
            est, ev = _pair_estimate(v_loose, v_tight, loose, tight, labels, grid, round_off, graze)
        history.append((r, est, ev))
        if est.value <= accuracy and ev.same_path:
            break
        if attempts >= MAX_ATTEMPTS:
            raise _adaptive_refusal(solver, model, accuracy, history, tight, loose)
        if not ev.same_path or not math.isfinite(est.value) or est.value <= 0:
            r_new = r_tight
        else:
            r_new = r * SAFETY * accuracy / est.value
        lowest = max(RTOL_MIN, r_floor)
        if r_new / TIGHTEN < lowest:
            # as tight as double precision or the link spread allows: the last pair that can be run (a retry
            # aimed below it once ran its loose run at rtol 2e-15, which the solver refused as the user's rtol)
            r_new = TIGHTEN * lowest
            if r_new >= r:
                raise AccuracyError(_out_of_reach(solver, model, accuracy, history, r_new / TIGHTEN, floor),
                                    accuracy=accuracy, **_worst_fields(history, floor))
        if r_new >= r_tight:
            loose, v_loose, r = tight, v_tight, r_tight
        else:
            r = r_new
            loose = run(r)
            v_loose = states(loose)
    settings = {"rtol": r_tight}
    at = atol_ratio * r_tight
    settings["atol"] = float(at) if np.ndim(at) == 0 else float(np.max(at))
    looser = (f"rtol={r:.3g} ({TIGHTEN:g} times looser)" if loose_atol is None else
              f"rtol={r:.3g} and atol={loose_atol:.3g} ({TIGHTEN:g} times looser, with the atol of a motion of 1)")
    _record(tight, accuracy, est, attempts, settings,
            f"{PAIR_FACTOR:g} times the difference from a run at {looser}, a conservative bound under tolerance "
            f"proportionality")
    _record_events(tight, ev)
    if capped:
        tight.stats.extra["rtol_cap"] = capped
    return tight


def _pair_estimate(v_loose, v_tight, loose, tight, labels, grid, round_off, graze_span=None):
    """``(Estimate, EventMatch)`` of a pair: ``PAIR_FACTOR`` times the scaled difference of its state signals
    (never below the round-off bound) and the comparison of its friction events (round trips up to
    ``graze_span`` seen by one run only judged by the signals, ``match_events``)."""
    est = compare_states(v_loose, v_tight, labels, grid)
    est = dataclasses.replace(est, value=PAIR_FACTOR * est.value)
    if est.value < round_off:
        est = dataclasses.replace(est, value=round_off)
    return est, match_events(loose.events, tight.events, graze_span)


def magnitude_ratio(labels, values) -> tuple[float, str]:
    """The largest ratio, over the state signals of kinds that move, of a signal's largest magnitude to the
    range of its kind (``richardson.kind_scales``), at least 1, with the signal: how much larger a relative
    tolerance's ``rtol |y|`` is than the same rtol of the contract's measure. A kind that does not move (its
    range at the measure's floor) is left out: the solvers keep a state at rest to round-off."""
    if not labels or not len(values):
        return 1.0, ""
    rng = np.ptp(values, axis=0)
    mag = np.max(np.abs(values), axis=0)
    best, signal = 1.0, ""
    for members in kind_members(labels):
        r_k, m_k = float(rng[members].max()), float(mag[members].max())
        if not (math.isfinite(r_k) and math.isfinite(m_k)) or kind_at_rest(r_k, m_k):
            continue
        i = members[int(np.argmax(mag[members]))]
        if m_k / r_k > best:
            best, signal = m_k / r_k, labels[i].signal
    return best, signal


def motion_scale(res, labels, grid, values=None) -> float:
    """The smallest range over the run among the kinds of state signal that move (``ATOL_SCALE_MIN`` at
    least, 1 at most): the magnitude the absolute tolerance of the contract's runs is scaled to.
    ``values``: the run's ``state_matrix``, when already at hand.

    A kind that moves by round-off only (``richardson.kind_unmoved``: at most 1e-12 SI units) is no motion, as
    in the estimate (``clear_at_rest``): counted, the round-off of a stuck clutch's temperature rise (2e-14 K,
    calibration seed 9001, before its heat read the stuck mode's zero slip) set the scale to its floor and the
    contract's atol to 1e-8 times its rtol, and IDA took 1.4 million steps where 349 did."""
    if not labels:
        return 1.0
    values = state_matrix(res, labels, grid) if values is None else values
    rng = np.ptp(values, axis=0)
    moving = []
    for members in kind_members(labels):
        r_k = float(rng[members].max())
        if r_k > 0 and math.isfinite(r_k) and not kind_unmoved(r_k):
            moving.append(r_k)
    return float(np.clip(min(moving), ATOL_SCALE_MIN, 1.0)) if moving else 1.0


def _record(res, accuracy, est: Estimate, attempts, settings, method):
    st = res.stats
    st.error_estimate = est.value
    st.extra.update({"accuracy": accuracy, "error_signal": est.signal, "error_component": est.component,
                     "error_t": est.t, "attempts": attempts, "settings": settings, "error_method": method})
    if est.at_rest:
        st.extra["at_rest"] = list(est.at_rest)


def _record_events(res, ev: EventMatch):
    if ev.grazing:
        res.stats.extra["grazing"] = [{"component": comp, "t": t, "duration": d} for comp, t, d in ev.grazing]
    if not res.events:
        return
    res.events[:] = [dataclasses.replace(e, t_error=dt) if dt is not None else e
                     for e, dt in zip(res.events, ev.t_error)]
    res.stats.extra["event_time_error"] = ev.max_error


def _worst_fields(history, floor=None) -> dict:
    if not history:
        return {"component": floor[1].name} if floor is not None else {}
    est = history[-1][1]
    return dict(signal=est.signal or None, component=est.component or None, estimate=est.value, t=est.t)


def _out_of_reach(solver, model, accuracy, history, r_tight, floor=None) -> str:
    tried = "; ".join(f"rtol {r:.2g}: estimate {e.value:.2g}" for r, e, _ in history) or "none"
    worst = ""
    if history and history[-1][1].signal:
        est = history[-1][1]
        worst = (f" The worst signal so far is {est.signal} of '{est.component}' (estimate {est.value:.2g} at "
                 f"t = {est.t:.6g} s).")
    if floor is not None and r_tight < floor[0] * 1.01:
        rmin, dev, w, ratio = floor
        return (f"accuracy {accuracy:g} with solver '{solver}' on model '{model.name}' would need rtol below "
                f"{rmin:.2g}, where the round-off of the stiffest link, {type(dev).__name__} '{dev.name}' "
                f"(local mode {w / 2 / math.pi:.3g} Hz, {ratio:.3g} times faster than the softest), swamps the "
                f"answer (pairs so far: {tried}).{worst} Make that link rigid (Shaft(stiffness=None)) or let "
                f"rm.Scene(band_hz=...) do it, or ask for a looser accuracy.")
    return (f"accuracy {accuracy:g} with solver '{solver}' on model '{model.name}' would need rtol below "
            f"{r_tight:.2g}, beyond what double precision resolves (pairs so far: {tried}).{worst} Ask for a "
            f"looser accuracy, or use solver='expm' for a linear model.")


def _adaptive_refusal(solver, model, accuracy, history, tight, loose) -> AccuracyError:
    r, est, ev = history[-1]
    tried = "; ".join(f"rtol {rr:.2g}/{rr / TIGHTEN:.2g}: {e.value:.2g}" + ("" if m.same_path else " (paths differ)")
                      for rr, e, m in history)
    if not ev.same_path:
        dev = ev.devices[0]
        text = (f"accuracy {accuracy:g} with solver '{solver}' on model '{model.name}': the mode changes of "
                f"'{dev}' differ between the runs at rtol {r:.2g} ({_path_text(loose.events, dev)}) and "
                f"{r / TIGHTEN:.2g} ({_path_text(tight.events, dev)}), even after {len(history)} tightenings: "
                f"its switching is decided by differences near the round-off or by a grazing contact (a speed "
                f"that just touches zero), so no tolerance settles it. Make the engagement decisive (a clear "
                f"margin in the normal force or torque), or run a solver explicitly without accuracy= and judge "
                f"the event yourself. (Pairs tried: {tried}.)")
        return AccuracyError(text, component=dev, estimate=est.value, t=est.t, accuracy=accuracy,
                             signal=f"{dev}.mode")
    text = (f"accuracy {accuracy:g} with solver '{solver}' on model '{model.name}': estimated error "
            f"{est.value:.2g} of {est.signal} of '{est.component}' (relative to the range of the {est.kind} "
            f"signals, worst at t = {est.t:.6g} s) after {len(history)} pairs of runs ({tried}). "
            f"{_remedy(model, solver, accuracy, history)}")
    return AccuracyError(text, signal=est.signal, component=est.component, estimate=est.value, t=est.t,
                         accuracy=accuracy)


def _remedy(model, solver, accuracy, history) -> str:
    """What would meet the accuracy, from how the estimate moved with the tolerance."""
    c = model.compile()
    vals = [e.value for _, e, _ in history]
    shrinking = len(vals) >= 2 and vals[-1] < 0.5 * vals[0]
    link = c.fastest_link()
    stiff = ""
    if link is not None and link[2] >= 1e3:
        dev, w, ratio = link
        stiff = (f" The stiffest link, {type(dev).__name__} '{dev.name}', is {ratio:.3g} times faster than the "
                 f"softest: making it rigid (Shaft(stiffness=None)) or rm.Scene(band_hz=...) removes its "
                 f"round-off, which may be what holds the estimate up.")
    if shrinking:
        return (f"The estimate shrinks with the tolerance, so a looser accuracy (about {vals[-1] * 2:.1g}) is "
                f"within reach, or a higher-order solver (solver='scipy:DOP853' for small non-stiff models, "
                f"'expm' for linear ones) reaches {accuracy:g} sooner.{stiff}")
    return (f"The estimate does not shrink with the tolerance: {accuracy:g} is out of reach of '{solver}' on "
            f"this model (round-off, or a discontinuity that is not declared as an event). Ask for a looser "
            f"accuracy or try another solver ('expm' for a linear model, 'scipy:Radau').{stiff}")


# ------------------------------------------------------------------------------ fixed steps
def first_fixed_step(model, solver, t_start, t_end, dt_out) -> float:
    """The first step of a contract run without ``h``: the output interval, and for an explicit method at
    most ``STABLE_FRACTION`` of its stability limit on the fastest link (the error estimate then picks
    the step that meets the accuracy)."""
    from .explicit import ABMStepper, EulerStepper, RK4Stepper
    bound = {"euler": EulerStepper, "rk4": RK4Stepper, "abm": ABMStepper}.get(solver)
    h = float(dt_out)
    if bound is not None:
        link = model.compile().fastest_link()
        if link is not None and link[1] > 0:
            h = min(h, STABLE_FRACTION * bound.stability_bound / link[1])
    return h


def _fixed_step(model, solver, fn, t_start, t_end, dt_out, accuracy, options):
    h = options.pop("h", None)
    if h is None:
        h = first_fixed_step(model, solver, t_start, t_end, dt_out)
    elif not (isinstance(h, (int, float)) and not isinstance(h, bool) and math.isfinite(h) and h > 0):
        raise ParameterError(f"solver '{solver}': the step h must be a positive number [s], got {h!r}")
    span = t_end - t_start
    tried = []
    attempt = 0
    while True:
        attempt += 1
        steps = span / h
        if steps > MAX_FIXED_STEPS:
            fields = tried[-1][1].fields() if tried else {}
            fields.update(accuracy=accuracy, suggested_h=h)
            why = ""
            if fields.get("signal"):
                why = f" (worst signal {fields['signal']} of '{fields['component']}')"
            else:
                link = model.compile().fastest_link()
                if link is not None:
                    fields["component"] = link[0].name
                    why = (f" (the stability limit on the fastest link, {type(link[0]).__name__} '{link[0].name}', "
                           f"{link[1] / 2 / math.pi:.3g} Hz)")
            raise AccuracyError(
                f"accuracy {accuracy:g} with solver '{solver}' on model '{model.name}' needs a step of about "
                f"{h:.3g} s{why}, {steps:.3g} steps for the run, more than {MAX_FIXED_STEPS:,} (steps tried: "
                f"{_tried_text(tried)}). Use an adaptive solver ('ida', 'scipy:DOP853'), 'expm' for a linear "
                f"model, or a looser accuracy.", **fields)
        try:
            res = fn(model, t_start=t_start, t_end=t_end, dt_out=dt_out, h=h, tol=accuracy / FIXED_STEP_MARGIN,
                     **options)
            companion = res.stats.extra.pop("companion_events", None)
            ev = match_events(companion, res.events) if companion is not None else None
            if ev is not None and not ev.same_path:
                dev = ev.devices[0]
                raise AccuracyError(
                    f"accuracy {accuracy:g} with solver '{solver}' on model '{model.name}': the mode changes of "
                    f"'{dev}' differ between the run at h = {h:.3g} s ({_path_text(res.events, dev)}) and its "
                    f"companion ({_path_text(companion, dev)}): the steps do not resolve its switching. Use a "
                    f"smaller step h or an adaptive solver ('ida', 'scipy:DOP853').", component=dev,
                    signal=f"{dev}.mode", estimate=res.stats.error_estimate, accuracy=accuracy, suggested_h=h / 2)
            break
        except AccuracyError as exc:
            tried.append((h, exc))
            new_h = exc.suggested_h
            if new_h is None or attempt >= MAX_ATTEMPTS:
                fields = exc.fields()
                fields["accuracy"] = accuracy
                raise AccuracyError(
                    f"accuracy {accuracy:g} with solver '{solver}' (its Richardson estimate held to "
                    f"1/{FIXED_STEP_MARGIN:g} of it, tol = {accuracy / FIXED_STEP_MARGIN:.3g}; {attempt} run(s), "
                    f"steps tried: {_tried_text(tried)}): {exc}", **fields) from exc
            h = min(float(new_h), 0.9 * h)      # the suggestion is a bound; always make progress
    st = res.stats
    est = Estimate(float(st.error_estimate), st.extra.get("error_signal", ""), st.extra.get("error_component", ""),
                   "", float(st.extra.get("error_t", float("nan"))))
    _record(res, accuracy, est, attempt, {"h": float(st.extra.get("h", h))},
            f"Richardson extrapolation against a run at {st.extra.get('error_companion', '2h')}")
    if ev is not None:
        _record_events(res, ev)
    return res


def _tried_text(tried) -> str:
    return ", ".join(f"{h:.3g} s" + (f" (estimate {e.estimate:.2g})" if e.estimate is not None else "")
                     for h, e in tried) or "none"


__all__ = ["DEFAULT_ACCURACY", "check_accuracy", "simulate_with_accuracy", "compare_runs", "compare_states",
           "match_events", "result_state_labels", "state_columns", "RTOL_FACTOR", "TIGHTEN", "MAX_ATTEMPTS"]
