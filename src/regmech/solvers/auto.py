"""``solver="auto"``: the method and its settings chosen from the model's structure and the accuracy asked for.

The choice (``choose``) reads a few *traits* of the compiled model
(``traits``), all cheap next to a run:

* ``linear``: every device law linear with constant coefficients, friction
  with a constant coefficient, no internal states (``expm.nonlinear_components``);
* ``floor``: for a linear model, the a-priori round-off floor of ``expm``,
  ``eps (w_max/w_min)^2`` of the link spread (``expm.roundoff_floor``);
* ``spread``: highest over lowest local link frequency
  (``CompiledSystem.fastest_link``);
* ``zeta_min`` and ``periods``: for a linear model of at most
  ``MODAL_MAX`` coordinates, the smallest damping ratio of its oscillating
  modes at the start and the number of periods of the slowest lightly
  damped one (``zeta < ZETA_LIGHT``) over the run;
* ``states`` (ODE-form size) and ``friction`` (friction devices).

The rules (measured, see BENCHMARKS.md, "Calibration of the accuracy
contract", which lists the figures each rule comes from):

1. linear, ``floor <= accuracy * FLOOR_MARGIN``, and lightly damped over
   many periods (``zeta_min < ZETA_LIGHT`` and ``periods > PERIODS_MANY``):
   ``expm``: exact flow between events, no numerical damping or phase drift;
   the implicit multistep methods damp such oscillations (BDF's energy loss
   over 200 periods of an undamped chain is 3e-2 at the default settings).
2. linear, floor as in 1, and ``states >= EXPM_STATES`` or ``accuracy <=
   EXPM_ACCURACY``: ``expm`` (its cost hardly grows with the accuracy).
3. otherwise ``ida``, except a small smooth model (``states <=
   SMALL_STATES``, ``spread < STIFF_SPREAD``) at ``accuracy <=
   DOP853_ACCURACY``: ``scipy:DOP853`` (high order; never chosen for a
   stiff model, where an explicit method is held at its stability limit).

When the first choice refuses (``AccuracyError`` or another
``SimulationError``), the next candidate (``ida`` after the others) runs;
the result's ``stats.solver`` is the solver that produced it and
``stats.extra["auto_reason"]`` says why it was chosen (and what refused
before). Options that set the tolerance or the step (``rtol``, ``atol``,
``h``, ``tol``) are refused under ``auto`` (the accuracy sets them: name
the solver to set them yourself); other options go to the chosen solver,
which must take them.
"""

from __future__ import annotations

import inspect
import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError, SimulationError
from .accuracy import DEFAULT_ACCURACY, simulate_with_accuracy

#: expm only when its round-off floor is at most this fraction of the accuracy
FLOOR_MARGIN = 0.1
#: a mode with a damping ratio below this is lightly damped ...
ZETA_LIGHT = 0.02
#: ... and a run over more periods of it than this goes to expm
PERIODS_MANY = 20.0
#: linear models of at least this many ODE states go to expm
EXPM_STATES = 40
#: linear models at this accuracy or tighter go to expm
EXPM_ACCURACY = 1e-5
#: models up to this many states (and not stiff) may go to DOP853 at tight accuracy
SMALL_STATES = 20
#: link spread from which a model counts as stiff (no explicit method)
STIFF_SPREAD = 100.0
#: DOP853 for small smooth models at this accuracy or tighter
DOP853_ACCURACY = 1e-6
#: damped modes computed for linear models up to this many independent coordinates
MODAL_MAX = 100
#: options that set the tolerance or the step: the accuracy sets them under auto
SETTINGS = ("rtol", "atol", "h", "tol")


@dataclass
class Traits:
    linear: bool
    nonlinear: list
    floor: float | None
    spread: float
    fastest: str
    zeta_min: float | None
    periods: float | None
    states: int
    friction: int

    def describe(self) -> str:
        parts = ["linear" if self.linear else f"nonlinear ({', '.join(self.nonlinear[:2])})",
                 f"{self.states} states", f"{self.friction} friction devices", f"link spread {self.spread:.3g}"]
        if self.zeta_min is not None:
            parts.append(f"min damping ratio {self.zeta_min:.2g}")
        if self.periods:
            parts.append(f"{self.periods:.3g} periods of its slowest lightly damped mode")
        return ", ".join(parts)


def traits(model, t_start: float, t_end: float) -> Traits:
    from .expm import nonlinear_components, roundoff_floor
    c = model.compile()
    bad = nonlinear_components(c, t_start, t_end)
    linear = not bad and c.nz == 0
    link = c.fastest_link()
    spread = float(link[2]) if link is not None else 1.0
    fastest = f"{type(link[0]).__name__} '{link[0].name}'" if link is not None else ""
    floor = None
    if linear:
        fl = roundoff_floor(c)
        floor = float(fl[0]) if fl is not None else 0.0
    zeta, periods = (None, None)
    if linear:
        zeta, periods = _damping(c, t_start, t_end)
    return Traits(linear, bad, floor, spread, fastest, zeta, periods, int(c.ode_size()), int(c.mf))


def _damping(c, t_start, t_end):
    """(smallest damping ratio of the oscillating modes, periods of the slowest lightly damped one over the run)
    of a linear model at its start (None, None when too large or without oscillating modes)."""
    from ..compile.linear import linearize
    try:
        lin = linearize(c, t=t_start)
    except Exception:       # noqa: BLE001 - a model the linear form cannot hold simply gets no damping trait
        return None, None
    n = lin.M.shape[0]
    if n == 0 or n > MODAL_MAX:
        return None, None
    M = np.asarray(lin.M.todense() if hasattr(lin.M, "todense") else lin.M, float)
    B = np.asarray(lin.B.todense() if hasattr(lin.B, "todense") else lin.B, float)
    C = np.asarray(lin.C.todense() if hasattr(lin.C, "todense") else lin.C, float)
    try:
        Minv = np.linalg.inv(M)
    except np.linalg.LinAlgError:
        return None, None
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ C, -Minv @ B]])
    with np.errstate(all="ignore"):
        lam = np.linalg.eigvals(A)
    # oscillating: a complex pair whose frequency is not round-off of a rigid-body (zero) root
    osc = lam[lam.imag > 1e-6 * float(np.max(np.abs(lam), initial=0.0))]
    if not len(osc):
        return None, None
    mag = np.abs(osc)
    zeta = np.maximum(0.0, -osc.real / mag)       # an undamped root's real part is round-off of either sign
    light = zeta < ZETA_LIGHT
    periods = float((t_end - t_start) * np.min(osc.imag[light]) / (2 * math.pi)) if light.any() else 0.0
    return float(np.min(zeta)), periods


def choose(tr: Traits, accuracy: float) -> list[tuple[str, str]]:
    """Candidates ``[(solver, reason), ...]`` in order (module docstring, rules 1-3)."""
    out = []
    expm_ok = tr.linear and tr.floor is not None and tr.floor <= FLOOR_MARGIN * accuracy
    if expm_ok and tr.zeta_min is not None and tr.zeta_min < ZETA_LIGHT and (tr.periods or 0) > PERIODS_MANY:
        out.append(("expm", f"linear and lightly damped (damping ratio {tr.zeta_min:.2g}) over {tr.periods:.3g} "
                            f"periods: the exact flow keeps amplitude and phase"))
    elif expm_ok and tr.states >= EXPM_STATES:
        out.append(("expm", f"linear with {tr.states} states: the matrix exponential's cost hardly grows with "
                            f"the accuracy"))
    elif expm_ok and accuracy <= EXPM_ACCURACY:
        out.append(("expm", f"linear at accuracy {accuracy:g}: the exact flow reaches it at the output step"))
    elif tr.states <= SMALL_STATES and tr.spread < STIFF_SPREAD and accuracy <= DOP853_ACCURACY:
        out.append(("scipy:DOP853", f"small ({tr.states} states) and not stiff (link spread {tr.spread:.3g}) at "
                                    f"accuracy {accuracy:g}: a high-order explicit method"))
    if not out or out[0][0] != "ida":
        why = "nonlinear" if not tr.linear else "linear"
        if tr.spread >= STIFF_SPREAD:
            why += f", stiff (link spread {tr.spread:.3g})"
        out.append(("ida", f"{why}: variable-order BDF with events located by root finding"))
    return out


def _accepted(fn) -> set:
    sig = inspect.signature(fn)
    return {p.name for p in sig.parameters.values() if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}


def simulate_auto(model, t_start, t_end, dt_out, accuracy, options):
    from . import SOLVERS
    from .common import check_times
    t_start, t_end, dt_out = check_times(t_start, t_end, dt_out)
    given = [k for k in SETTINGS if k in options]
    if given:
        raise ParameterError(
            f"simulate(): {', '.join(given)} set the tolerance or step of one solver, but solver='auto' chooses "
            f"the solver and its settings from accuracy= (the bound of the global error, default "
            f"{DEFAULT_ACCURACY:g}). Ask for accuracy=..., or name the solver to set them yourself, e.g. "
            f"solver='ida', rtol=1e-8.")
    if accuracy is None:
        accuracy = DEFAULT_ACCURACY
    model.compile()         # compiling is not part of the choice (nor of any run's wall time)
    t0 = time.perf_counter()
    tr = traits(model, t_start, t_end)
    candidates = choose(tr, accuracy)
    analysis = time.perf_counter() - t0
    refused = []
    for i, (solver, reason) in enumerate(candidates):
        fn = SOLVERS[solver]
        unknown = sorted(set(options) - _accepted(fn))
        if unknown:
            raise ParameterError(f"simulate(): option(s) {unknown} are not options of '{solver}', which "
                                 f"solver='auto' chose ({reason}); name the solver that takes them")
        try:
            res = simulate_with_accuracy(model, solver, fn, t_start, t_end, dt_out, accuracy, options)
        except SimulationError as exc:
            refused.append((solver, exc))
            if i + 1 < len(candidates):
                continue
            if len(refused) > 1:
                first = refused[0]
                raise type(exc)(f"{exc} (solver='auto' tried '{first[0]}' first, which refused: "
                                f"{' '.join(str(first[1]).split())[:300]})",
                                **(exc.fields() if hasattr(exc, "fields") else {})) from exc
            raise
        st = res.stats
        elapsed = time.perf_counter() - t0
        st.wall_time = max(st.wall_time, elapsed)
        st.extra["estimate_time"] = max(0.0, elapsed - st.extra.get("wall_time_main", st.wall_time))
        text = f"{solver}: {reason} ({tr.describe()})"
        if refused:
            text += "; " + "; ".join(f"'{s}' refused first: {' '.join(str(e).split())[:200]}" for s, e in refused)
        st.extra.update(auto_reason=text, auto_time=analysis)
        return res
    raise AssertionError("unreachable")     # pragma: no cover - the list always ends with ida
