"""``solver="auto"``: the method and its settings chosen from the model's structure and the accuracy asked for.

The choice (``choose``) reads a few *traits* of the compiled model
(``traits``), all cheap next to a run:

* ``linear``: every device law linear with constant coefficients, friction
  with a constant coefficient, no internal states (``expm.nonlinear_components``);
* ``floor``: the a-priori round-off bound ``eps (w_max/w_min)^2`` of the
  link spread (``accuracy.roundoff_bound``);
* ``spread``: highest over lowest local link frequency
  (``CompiledSystem.fastest_link``);
* ``modes``: for a linear model of at most ``MODAL_MAX`` independent
  coordinates, the damping ratio and frequency of every oscillating mode at
  the start (the roots of ``lambda^2 M + lambda B + C``), those up to the
  Nyquist frequency of the output grid;
* ``expm_steps(a)``: the steps ``expm`` takes: one per output interval and
  breakpoint, and at least ``EXPM_STEPS_PER_FORCING * a^-1/2`` per period of
  the fastest sinusoidal input (its forcing fit is of order 2 in the step;
  measured on chain_drive_5, 425 Hz: the contract took 23, 54, 170 and 540
  steps per period at 1e-3 .. 1e-6); ``states`` (ODE-form size) and
  ``friction`` (devices).

What decides between a stepping method (``ida``) and the exact flow
(``expm``) is how long the model oscillates: a stepping method must resolve
every period of every mode that is still above the accuracy, ``expm``
takes one step per output interval whatever the motion. A mode of damping
ratio ``zeta`` and frequency ``f`` stays above ``a`` of its amplitude for
``ln(1/a) / (2 pi zeta)`` periods, and the run holds ``span * f`` of them, so

    periods(a) = max over the modes of min(span * f, ln(1/a) / (2 pi zeta)).

The rules (measured: ``benchmarks/results/calibration.md``, "The rules of
``solver="auto"`` and the figures they come from"; summary in BENCHMARKS.md):

``expm`` is a candidate only for a linear model whose round-off bound is
within what its estimate is held to (``floor <= accuracy * FLOOR_MARGIN``,
``FLOOR_MARGIN`` = 1/3, the contract's ``FIXED_STEP_MARGIN``). Then:

1. ``expm_steps(a) <= K(a) * periods(a)`` with ``K(a) =
   EXPM_STEPS_PER_PERIOD + EXPM_STEPS_PER_DECADE * log10(1/a)`` (a stepping
   method takes more steps per period the tighter the accuracy): ``expm``
   (an undamped or lightly damped model over many periods always lands
   here: the exact flow keeps its energy, where BDF's numerical damping
   lost 3.3e-2 of the energy of a 20-inertia chain over 200 periods at its
   default settings);
2. ``floor > accuracy * NEAR_ROUNDOFF``: ``expm``, since a stepping method
   would need an rtol near the limit the link spread sets
   (``common.check_link_spread``; ida refused inertia_ratio_1e8 at 1e-6);
3. too large for the modal traits (more than ``MODAL_MAX`` coordinates):
   the test of rule 1 with the upper bound ``span * f_bound`` of the
   periods (``f_bound``: twice the fastest link's local frequency, a
   Gershgorin bound of the highest natural frequency, at most the Nyquist
   frequency of the output grid) and a step of ``ida`` that costs more the
   larger the model: ``expm_steps(a) <= K(a) * span * f_bound *
   max(1, states / EXPM_STATES_REF)``: ``expm``. Measured
   (benchmarks/results/auto_rules.md, chains of 100 and 1000 inertias with
   a 5 Hz sine drive, 1 s): at 1000 inertias expm's sparse step is about
   5x cheaper than ida's (1e-4, dt_out 1e-3: expm 0.33 s, ida 1.0 s), at
   100 inertias they cost alike and the step counts decide (1e-6, dt_out
   1e-2: the forcing needs about 2700 expm steps, ida 0.61 s, expm 1.55 s);
   train_100 (501 output steps against 164 bounded periods): expm 0.16 s,
   ida 0.45 s at 1e-6, and within 1.4x of ida at 1e-2. When ida runs
   natively the weight is
   ``min(max(1, states / EXPM_STATES_REF), (states / NATIVE_EXPM_STATES)
   ^ NATIVE_EXPM_POWER)`` instead: a native step is so cheap on models of
   a few hundred states that ida beat expm on every measured cell of the
   chains up to 100 inertias, and lost every one at 1000. The Nyquist cap
   is lifted when the fastest modes *ring* (``ringing``: the top of dg/du's
   spectrum lightly damped by rule E's test, ``damping <= EXPLICIT_DAMPING
   * oscillation``, and a link spread of at least ``STIFF_SPREAD``): local
   modes of stiff links far above the output grid, which a stepping method
   resolves while they ring whether or not the grid shows them. Measured
   (random chains and trees of 41-260 inertias 1e-3 to 10 kg
   m^2 on links of 1e2 to 1e6 N m/rad, a step or a 1-20 Hz sine torque, 1 s,
   accuracy 1e-3 and 1e-6, dt_out 1e-2 and 1e-3, each solver under the
   contract): of the cells where rule 3 had chosen ida, the test sends 20
   to expm; on four models ida had taken 1.7-4.3 s and expm takes
   0.06-0.5 s; the worst loss, 0.22 -> 1.1 s (116 states at 1e-6, dt_out
   1e-2, expm's coarse grid); in all 106 -> 87 s over the sample;
E. (between rules 2 and 3) a linear model of at least
   ``EXPLICIT_STATES_MIN`` ODE states (``EXPLICIT_STATES_MIN_LOOSE``, 200, at an
   accuracy looser than ``EXPLICIT_TIGHT``) without friction devices whose ODE
   form is the linear one (no rigid links or gears with constraints), whose
   dg/du tops out in lightly damped oscillation and whose explicit run fits
   DOP853's step budget: ``dop853``. The test reads the linear form's dg/du
   once (kept with the compiled system): its spectral bound ``rho`` and the
   split of that bound into an oscillation part (the springs: ``2 sqrt(c /
   J)`` on a chain) and a damping part (dampers, device states: ``4 d / J``
   on a chain, twice its fastest decay ``2 d / J``)
   (``ode_driver.spectral_split``). The damping must be at most
   ``EXPLICIT_DAMPING`` times the oscillation: then the fastest rates are
   oscillation that any stepping method resolves while it rings (BDF with
   several times the steps per period of an order-8 method), not decays an
   implicit method steps over. The pair's steps are bounded below by DOP853's
   step cap on ``rho`` at the pair's two tolerances (``explicit_steps``) and
   must stay within ``scipy_ivp.DEFAULT_MAX_STEPS["DOP853"]``. Measured
   (benchmarks/results/auto_rules.md, "Rule E", both under the contract):
   the 5 Hz-driven chains of 100 to 1000 inertias, dop853 0.4-1.0x the time
   of auto's former choice at 1e-3 and 0.16-0.4x at 1e-6; random trees of
   200 and 1000 inertias (lightly damped modes up to 200 Hz, all excited),
   where ida needed 6,000-20,000 steps, 0.01-0.5x; the models it turns away
   (damped chains, 30 inertias) as in the table. What it costs where it is
   wrong: a chain with one link 1,000 times stiffer than the rest (a stiff
   mode the drive does not excite, that ida's steps cross) took dop853 up to
   1.9x auto's former choice. When the explicit pair would take more than
   twice the steps of ``expm`` on an output grid fine enough for expm's first step, and
   the model is at most ``EXPM_FIRST_STATES`` states, ``expm`` runs first
   and ``dop853`` after it (rule E', ``expm_first_reason``). A refusal (the stiffness check, the contract)
   falls back to ``ida``, then ``expm`` (a refusal as stiff is where ida's
   implicit steps pay);
4. otherwise ``ida`` (the fastest solver under the contract on every
   nonlinear case measured, stiff ones included).

``K(a)`` was measured with ida's Python callbacks. When ida will run with
compiled ones (``ida_native``: numba installed, the model within what it
serves), its step is ``native_gain(states)`` times cheaper and ``K(a)`` is
divided by that -- where the periods counted are all ida must resolve
(``Traits.step_gain``: no oscillating mode above the output grid's Nyquist
frequency, which ``periods(a)`` leaves out).

When the first choice refuses (``AccuracyError`` or another
``SimulationError``), the next candidate runs: ``ida`` after ``dop853``
(which also steps aside for an option only ida takes); ``ida`` after ``expm``;
``expm`` (when a candidate), ``dop853`` (when not chosen first) and then ``scipy:Radau`` after ``ida``. The result's ``stats.solver`` is the solver
that produced it and ``stats.extra["auto_reason"]`` says why it was chosen
(and what refused before). Options that set the tolerance or the step
(``rtol``, ``atol``, ``h``, ``tol``) are refused under ``auto`` (the
accuracy sets them: name the solver to set them yourself); other options go
to the chosen solver, which must take them.
"""

from __future__ import annotations

import functools
import inspect
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError, SimulationError
from .accuracy import DEFAULT_ACCURACY, roundoff_bound, simulate_with_accuracy

#: expm only when the round-off bound is at most this fraction of the accuracy (its estimate is held to it)
FLOOR_MARGIN = 1.0 / 3.0
#: ... and chosen first when the bound is above this fraction (a stepping method would need rtol near its limit)
NEAR_ROUNDOFF = 1e-2
#: expm when its steps are at most this many times the periods a stepping method must resolve
EXPM_STEPS_PER_PERIOD = 4.0
EXPM_STEPS_PER_DECADE = 2.0
#: a model too large for the modal traits: ida's step costs about states / EXPM_STATES_REF times an expm step (at
#: least once) in rule 3 (measured on the chains of benchmarks/results/auto_rules.md: alike at 200 states, expm's
#: sparse step about 5x cheaper at 2000)
EXPM_STATES_REF = 200.0
#: damped modes computed for linear models up to this many independent coordinates (the eigenvalues of the
#: companion matrix cost 0.15-0.75 s at 100 on the loaded development machine, a few ms at 40)
MODAL_MAX = 40
#: expm's steps per period of the fastest sinusoidal input at accuracy a: this times a^-1/2
EXPM_STEPS_PER_FORCING = 0.54
#: a mode with a damping ratio below this counts as lightly damped (in the reason only)
ZETA_LIGHT = 0.02
#: link spread from which a model counts as stiff (in the reason; and rule 3's ringing test, ``ringing``)
STIFF_SPREAD = 100.0
#: options that set the tolerance or the step: the accuracy sets them under auto
SETTINGS = ("rtol", "atol", "h", "tol")
#: when ida will run natively (``ida_native``: compiled callbacks), its step costs ``native_gain(states)`` times
#: less than the Python path's on which K(a) was measured: ``1 + NATIVE_GAIN / (1 + states / NATIVE_GAIN_STATES)``.
#: Measured on the 5 Hz-driven chains (CPU time under the contract, accuracy 1e-3 and 1e-6, load ~11): 10 inertias
#: (20 states) 4.2x and 5.2x, 100 inertias 1.8x and 1.9x, 1000 inertias 1.02x and 1.10x (the linear algebra, the
#: same in both, dominates a large model's step)
NATIVE_GAIN = 4.0
NATIVE_GAIN_STATES = 60.0
#: rule 3 when ida runs natively: expm when ``expm_steps(a) <= K(a) span f_bound (states / NATIVE_EXPM_STATES) ^
#: NATIVE_EXPM_POWER``. Measured (benchmarks/results/auto_rules.md, "native ida against expm"): the 5 Hz-driven
#: chains of 50 to 1000 inertias (100 to 2000 states), 1 s, dt_out 1e-2 and 1e-3, accuracy 1e-2, 1e-4, 1e-6, both
#: under the contract, interleaved: native ida was faster in every cell up to 100 inertias (1.7x to 11x: at 200
#: states its contract took 29 ms against expm's 60 ms at 1e-2, dt_out 1e-2), expm in every cell at 1000 (1.1x to
#: 3.5x); between them the cells split at about 0.4 (400 states) and 1.1 (800 states) times ``K(a) span f_bound``
#: expm steps, and a power law through those points (exponent log 10 / log 5) separates every measured cell within
#: 1.6x. ``max(1, states / EXPM_STATES_REF)`` (measured with ida's Python callbacks) sent the 100-inertia chain to
#: expm at 1e-2 to 1e-4 (2x native ida). A fit over 100 to 2000 states: larger models lean further to expm,
#: which is where they were measured to go (10,000 inertias)
NATIVE_EXPM_STATES = 760.0
NATIVE_EXPM_POWER = 1.43
#: rule E: the explicit method auto may choose for a large linear model whose spectrum tops out in lightly damped
#: oscillation, and the models it is weighed on: at least this many ODE states (below, native ida's cheap steps
#: won every measured cell: chains of 30 inertias 1.5-5x, random trees of 50 inertias 1.1-2x) ...
EXPLICIT = "dop853"
EXPLICIT_STATES_MIN = 150
#: ... and at an accuracy looser than EXPLICIT_TIGHT at least EXPLICIT_STATES_MIN_LOOSE. Measured with a bound of 400 states: at
#: 1e-3 a native ida step was cheap enough that it matched dop853 at 200-300 states (both under the contract,
#: interleaved, medians of 5: the chain of 100 inertias 10.6 against 11.7 ms, of 150 16.0 against 12.8, a train of
#: 150 cars 28.9 against 35.8, of 100 19.3 against 18.5), although random trees of 100 and 150 inertias went 4-9x
#: faster with dop853. With a bound of 200 states and a step's stages in one compiled call (``OdeProblem.stage_sweep``)
#: dop853's pair at 1e-3 took 0.71 (chain of 100), 0.51 (chain of 150), 0.16 and 0.08 (trees of 100 and 150) and
#: 0.80 (train of 100) times native ida's, and 1.05 on the train of 150 (``bench_auto_rules.py --boundary``, medians
#: of 5, interleaved, quiet machine; benchmarks/results/auto_rules.md); at 1e-4 and tighter 0.11-0.76
EXPLICIT_TIGHT = 1e-4
EXPLICIT_STATES_MIN_LOOSE = 200
#: rule E': ``expm`` before the explicit method when the explicit pair's steps are more than EXPM_FIRST_RATIO times
#: expm's, the output grid's interval at most EXPM_FIRST_H_RHO times the fastest rate's time scale 1 / rho (a
#: coarser grid made expm's first run fail its estimate and retry at a step of 2e-5 to 5e-3 s: random trees of 200,
#: 400 and 1000 inertias at dt_out 1e-2, 0.4 s, 5.5 s and 20 s against dop853's 0.05-0.2 s) and the model at most
#: EXPM_FIRST_STATES states (the tree of 1000 inertias, 2000 states, at dt_out 1e-3: expm 0.9 and 1.5 s against
#: dop853's 0.23 and 0.47 s, with about as many steps). Measured: random models for rule E (48
#: cells where it chose dop853, random chains, trees and trains of 75-600 bodies, accuracy 1e-3 and 1e-6, both
#: under the contract; expm met the accuracy in all): this rule sends 22 of them to expm, which was faster in each
#: (1.1-8.5x); of the 26 left to dop853, 18 took at most 1.06x expm's time (0.16-1.06x) and 7 1.5-4.75x (a
#: ratio of steps of 0.49 and 1.02-1.74, or a grid coarser than the bound: dt_out rho of 70-84). The margin of 2 keeps the
#: benchmark chains, where an expm step costs more than the fuzz models' (300 inertias at accuracy 1e-3, dt_out
#: 1e-2: 1.16 times expm's steps, dop853 20 ms against expm's 42 ms)
EXPM_FIRST_RATIO = 2.0
EXPM_FIRST_STATES = 1200
EXPM_FIRST_H_RHO = 10.0
#: ... and a damping bound at most this fraction of the oscillation bound (``ode_driver.spectral_split``): above
#: it the fastest rates are decays that ida steps over (a chain of 100 inertias with dampers of 100 and 3000 N m
#: s/rad, damping bound 4 d / J 2 and 60 times the oscillation bound 2 sqrt(c / J): native ida 1.3-3.7x and 37-55x
#: faster than dop853). The bound of the damping is about twice the fastest decay (2 d / J on that chain), so
#: this admits top modes of a damping ratio up to about 0.25
EXPLICIT_DAMPING = 0.5


@dataclass
class Traits:
    linear: bool
    nonlinear: list
    floor: float
    spread: float
    modes_of: object                # () -> (k, 2) array: damping ratio, frequency [Hz]; None: unknown (lazy)
    span: float
    expm_steps: int
    states: int
    friction: int
    f_bound: float = math.inf       # an upper bound of the frequencies that count [Hz]
    f_forcing: float = 0.0          # the fastest sinusoidal input [Hz]
    ida_gain: float = 1.0           # how many times cheaper ida's step is than on the Python path (native)
    f_nyquist: float = math.inf     # the output grid's Nyquist frequency [Hz]
    spectrum: object = None         # rules E and 3: (spectral bound, oscillation, damping) [1/s] of dg/du; None: not taken
    _complete: bool = field(default=False, repr=False)
    _modes: object = field(default=False, repr=False)

    @property
    def modes(self):
        """The oscillating modes (computed on first use: the choice needs them only for some models)."""
        if self._modes is False:
            got = self.modes_of() if callable(self.modes_of) else self.modes_of
            self._modes, self._complete = got if isinstance(got, tuple) else (got, False)
        return self._modes

    def step_gain(self) -> float:
        """``ida_gain`` where the periods counted are all there are (every oscillating mode below the output
        grid's Nyquist frequency, or, without modal traits, the frequency bound below it); else 1. A mode above
        it is left out of ``periods(a)`` (expm need not resolve it), yet ida resolves it while it is excited:
        on a fixed-free undamped chain of 6 inertias over 100 slowest periods (dt_out 1 s, accuracy 1e-3),
        native ida took 134,692 steps and 238 ms, expm 261 steps and 33 ms; the Python path's K(a) hid that."""
        if self.ida_gain == 1.0:
            return 1.0
        if self.modes is not None:
            return self.ida_gain if self._complete else 1.0
        return self.ida_gain if self.f_bound < self.f_nyquist else 1.0

    def explicit_steps(self, accuracy: float) -> float:
        """The steps the explicit method's pair of runs takes at least under the contract at ``accuracy``: its
        stability cap (``scipy_ivp.stability_cap``) on the spectral bound at the pair's two tolerances, over
        the span (inf when there is no candidate)."""
        from .accuracy import RTOL_FACTOR, TIGHTEN
        from .scipy_ivp import stability_cap
        if self.spectrum is None:
            return math.inf
        rho = self.spectrum[0]
        r = accuracy * RTOL_FACTOR[EXPLICIT]
        caps = [stability_cap("DOP853", rho, r), stability_cap("DOP853", rho, r / TIGHTEN)]
        return sum(self.span / h if h else 0.0 for h in caps)

    def expm_steps_at(self, accuracy: float) -> float:
        """``expm_steps(a)`` of the module docstring."""
        return max(float(self.expm_steps),
                   self.span * self.f_forcing * EXPM_STEPS_PER_FORCING / math.sqrt(accuracy))

    def periods_bound(self) -> float:
        """An upper bound of ``periods(a)`` for any a, without the modes: span times the frequency bound."""
        return self.span * self.f_bound

    def periods(self, accuracy: float) -> float:
        """``periods(a)`` of the module docstring (0 without oscillating modes)."""
        if self.modes is None or not len(self.modes):
            return 0.0
        zeta, f = self.modes[:, 0], self.modes[:, 1]
        with np.errstate(divide="ignore"):
            lasting = np.where(zeta > 0, math.log(1.0 / accuracy) / (2 * math.pi * np.maximum(zeta, 1e-300)), np.inf)
        return float(np.max(np.minimum(self.span * f, lasting)))

    def slowest_decay(self):
        """(zeta, f) of the mode that sets ``periods`` at a tight accuracy: the least damped one."""
        k = int(np.argmin(self.modes[:, 0] - 1e-12 * self.modes[:, 1]))
        return float(self.modes[k, 0]), float(self.modes[k, 1])

    def describe(self) -> str:
        devices = f"{self.friction} friction device{'' if self.friction == 1 else 's'}"
        parts = ["linear" if self.linear else f"nonlinear ({', '.join(self.nonlinear[:2])})",
                 f"{self.states} states", devices, f"link spread {self.spread:.3g}"]
        if self.modes is not None and len(self.modes):
            parts.append(f"min damping ratio {float(np.min(self.modes[:, 0])):.2g}")
        return ", ".join(parts)


def traits(model, t_start: float, t_end: float, dt_out: float) -> Traits:
    from .common import output_grid, signal_breakpoints
    from .expm import nonlinear_components
    c = model.compile()
    bad = nonlinear_components(c, t_start, t_end)
    linear = not bad and c.nz == 0
    link = c.fastest_link()
    spread = float(link[2]) if link is not None else 1.0
    bound = roundoff_bound(c)
    floor = bound[0] if bound is not None else 0.0
    f_nyquist = 0.5 / dt_out
    if not linear:
        modes_of, f_bound = None, math.inf
    elif link is None:      # no spring: nothing oscillates
        modes_of, f_bound = np.zeros((0, 2)), 0.0
    else:
        def modes_of():
            return _cached_modes(c, t_start, f_nyquist)
        # the highest natural frequency is below about twice the fastest link's local one (Gershgorin)
        f_bound = min(f_nyquist, 2.0 * link[1] / (2 * math.pi))
    steps = len(output_grid(t_start, t_end, dt_out)) - 1 + len(signal_breakpoints(model, t_start, t_end))
    states = int(c.ode_size())
    # dg/du's spectral bounds (rule E, and rule 3's ringing test) for a model too large for the modal traits
    spectrum = _cached_spectrum(c) if linear and c.mf == 0 and states > 2 * MODAL_MAX else None
    if spectrum is not None and link is not None and ringing(spectrum, spread):
        # rule 3: the fastest modes ring far above the output grid, and a stepping method resolves them while
        # they ring: the Nyquist frequency is no cap of the periods it must resolve
        f_bound = 2.0 * link[1] / (2 * math.pi)
    return Traits(linear, bad, floor, spread, modes_of, t_end - t_start, steps, states, int(c.mf),
                  f_bound=f_bound, f_forcing=_forcing_frequency(model, c),
                  ida_gain=native_gain(states) if _runs_native(c) else 1.0, f_nyquist=f_nyquist,
                  spectrum=spectrum)


def _cached_spectrum(c):
    """Rule E's ``(bound, oscillation, damping)`` of the linear form's dg/du (``ode_driver.spectral_bound``,
    ``spectral_split``), kept with the compiled system (dg/du is constant; dropped with the system on any change
    of the model): 0.3-2 ms from 200 to 20,000 states. None when the ODE form is not the linear one (rigid
    links or gears with constraints: the general form's right-hand side, several times dearer a call)."""
    if "_auto_spectrum" not in c.__dict__:
        c._auto_spectrum = _spectrum(c)
    return c._auto_spectrum


def _spectrum(c):
    from ..compile.odeform import ode_form
    from .ode_driver import spectral_bound, spectral_split
    try:
        form = ode_form(c)
        if not form.linear:
            return None
        J = form.jacobian()
        rho = spectral_bound(J.tocsc(), c)
        osc, damp = spectral_split(J, c)
    except Exception:       # noqa: BLE001 - a model the linear form cannot hold is simply no candidate
        return None
    if not (math.isfinite(rho) and rho > 0):
        return None
    return float(rho), float(osc), float(damp)


def native_gain(states: int) -> float:
    """How many times cheaper a native ida step is than a Python-path one (``NATIVE_GAIN``)."""
    return 1.0 + NATIVE_GAIN / (1.0 + states / NATIVE_GAIN_STATES)


def _runs_native(c) -> bool:
    """Whether ida under auto will run with compiled callbacks (``_native_default``): numba and SUNDIALS'
    libraries there and the model within what the native path serves."""
    from .ida import choose_linsolver
    from .ida_native import eligible
    try:
        return eligible(c, choose_linsolver(c)[0]) is None
    except Exception:       # noqa: BLE001 - a model the check cannot judge simply runs as if not native
        return False


def _forcing_frequency(model, c=None) -> float:
    """The highest frequency [Hz] of the model's sinusoidal inputs (0 without). With the compiled system ``c``,
    the model's signal objects are found once and kept with it (a change of a parameter drops it, like
    ``_cached_modes``); their frequencies are read at every call (the library's signals are fixed when made, a user's own
    Signal subclass may not be). The
    pass over every component's values cost 0.2 ms on a chain of 100 inertias, at every default call."""
    from .common import model_signals
    signals = model_signals(model, c)
    f = 0.0
    for val in signals:
        f = max(f, abs(float(getattr(val, "freq_hz", 0.0) or 0.0)))
    return f


#: modal traits kept per compiled system (a change of the model drops the compiled system, ``Model._invalidate``)
MODES_KEPT = 8


def _cached_modes(c, t_start, f_max):
    """``_modes``, kept with the compiled system for its next runs: the linear form and its eigenvalues cost
    2-5 ms on small models (``linearize``'s sparse set-up), 30-60 % of a default call that then runs ida
    natively in 3-6 ms (inertia_ratio_1e8 at 1e-4, the chain of 10 inertias at 1e-3); the system is dropped on
    any change of a parameter or a connection, so what is kept is never stale."""
    kept = c.__dict__.setdefault("_auto_modes", {})
    key = (float(t_start), float(f_max))
    if key not in kept:
        if len(kept) >= MODES_KEPT:
            kept.pop(next(iter(kept)))
        kept[key] = _modes(c, t_start, f_max)
    return kept[key]


def _modes(c, t_start, f_max):
    """``(modes, complete)``: (damping ratio, frequency [Hz]) of the oscillating modes of a linear model at its
    start up to ``f_max``, and whether that is all of them; None when the model is too large or the linear form
    cannot be had."""
    from ..compile.linear import linearize
    try:
        lin = linearize(c, t=t_start)
    except Exception:       # noqa: BLE001 - a model the linear form cannot hold simply gets no modal traits
        return None
    n = lin.M.shape[0]
    if n == 0:
        return np.zeros((0, 2))
    if n > MODAL_MAX:
        return None
    M, B, C = (np.asarray(X.todense() if hasattr(X, "todense") else X, float) for X in (lin.M, lin.B, lin.C))
    try:
        Minv = np.linalg.inv(M)
    except np.linalg.LinAlgError:
        return None
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ C, -Minv @ B]])
    with np.errstate(all="ignore"):
        lam = np.linalg.eigvals(A)
    if not np.all(np.isfinite(lam)):
        return None
    # oscillating: a complex pair whose frequency is not round-off of a rigid-body (zero) root
    osc = lam[lam.imag > 1e-6 * float(np.max(np.abs(lam), initial=0.0))]
    zeta = np.maximum(0.0, -osc.real / np.abs(osc))       # an undamped root's real part is round-off of either sign
    f = osc.imag / (2 * math.pi)
    keep = f <= f_max
    return np.column_stack([zeta[keep], f[keep]]), bool(np.all(keep))


def steps_per_period(accuracy: float, ida_gain: float = 1.0) -> float:
    """``K(a)``: expm's output steps per period a stepping method must resolve, at which the two cost alike
    (divided by ``ida_gain`` when ida's steps are that much cheaper: the native path)."""
    return (EXPM_STEPS_PER_PERIOD + EXPM_STEPS_PER_DECADE * math.log10(1.0 / accuracy)) / ida_gain


def large_model_bound(tr: Traits, accuracy: float) -> float:
    """Rule 3's bound of expm's steps for a model without modal traits: ``K(a) * span * f_bound * w``, with
    ``w = max(1, states / EXPM_STATES_REF)`` (ida's Python callbacks) or, when ida runs natively, ``w =
    min(that, (states / NATIVE_EXPM_STATES) ^ NATIVE_EXPM_POWER)`` (``native_size_weight``). Unlike rule 1's
    native gain (``Traits.step_gain``), not withheld when ``f_bound`` is capped at the output grid's Nyquist
    frequency: on the sine-driven chain of tests/unit/test_auto.py (fastest links near 160 Hz, output every
    10 ms, 100 and 200 inertias) native ida took 82-206 ms against expm's 148-1541 ms at 1e-2 to 1e-6. Not
    measured: a large, lightly damped model with modes far above that frequency (ida resolves them while they
    ring; rule 1 covers the small ones). Those whose fastest modes ring, of stiff links (``ringing``), get
    ``f_bound`` without that cap (``traits``)."""
    weight = max(1.0, tr.states / EXPM_STATES_REF)
    if tr.ida_gain > 1.0:
        weight = min(weight, native_size_weight(tr.states))
    return steps_per_period(accuracy) * tr.periods_bound() * weight


def native_size_weight(states: int) -> float:
    """Rule 3's weight of a native ida step against an expm step for a model of ``states`` ODE states:
    ``(states / NATIVE_EXPM_STATES) ^ NATIVE_EXPM_POWER``."""
    return (states / NATIVE_EXPM_STATES) ** NATIVE_EXPM_POWER


#: what each candidate of ``choose`` is, for the reason of a fallback
METHODS = {"ida": "variable-order BDF with events located by root finding",
           EXPLICIT: "an explicit Runge-Kutta method of order 8 (Dormand-Prince)",
           "expm": "the exact flow of the linear model",
           "scipy:Radau": "an implicit Runge-Kutta method"}


def choose(tr: Traits, accuracy: float) -> list[tuple[str, str]]:
    """Candidates ``[(solver, reason), ...]`` in order (module docstring, rules 1-3)."""
    out = []
    expm_ok = tr.linear and tr.floor <= FLOOR_MARGIN * accuracy
    explicit = explicit_reason(tr, accuracy)
    k = steps_per_period(accuracy, tr.step_gain() if expm_ok else 1.0)
    # the modes only where they can decide (their eigenvalues cost about as much as a short run)
    steps = tr.expm_steps_at(accuracy)
    periods = tr.periods(accuracy) if expm_ok and steps <= k * tr.periods_bound() else 0.0
    if expm_ok and tr.modes is not None and periods > 0 and steps <= k * periods:
        zeta, f = tr.slowest_decay()
        kind = "lightly damped" if zeta < ZETA_LIGHT else "damped"
        out.append(("expm", f"linear and oscillating over {periods:.3g} periods at accuracy {accuracy:g} ({kind}: "
                            f"damping ratio {zeta:.2g} at {f:.3g} Hz): the exact flow takes about {steps:.0f} "
                            f"steps and keeps amplitude and phase"))
    elif expm_ok and tr.floor > NEAR_ROUNDOFF * accuracy:
        out.append(("expm", f"linear, its round-off bound {tr.floor:.2g} within {1 / NEAR_ROUNDOFF:g}x of the "
                            f"accuracy {accuracy:g}: a stepping method would need an rtol near the limit of the link "
                            f"spread {tr.spread:.3g}"))
    elif explicit is not None:
        fewer = expm_first_reason(tr, accuracy) if expm_ok else None
        if fewer is not None:
            out.append(("expm", fewer))      # rule E': fewer exact steps on a fine grid, the explicit method next
        out.append((EXPLICIT, explicit))     # else rule 3's expm comes after its refusal, behind ida (below)
    # rule 3, only when rules 1, 2 and E chose nothing
    if not out and expm_ok and tr.modes is None and tr.periods_bound() > 0 \
            and steps <= large_model_bound(tr, accuracy):
        out.append(("expm", f"linear with {tr.states} states (too many for the modal traits) at accuracy "
                            f"{accuracy:g}: the exact flow takes about {steps:.0f} steps, against at most "
                            f"{tr.periods_bound():.3g} periods (up to {tr.f_bound:.3g} Hz) a stepping method must "
                            f"resolve, each of its steps costing more the larger the model"
                            + (" (with compiled callbacks too)" if tr.ida_gain > 1.0 else "")
                            + ("; its fastest modes are lightly damped ones of links stiffer than the rest, which a "
                               "stepping method resolves while they ring, above the output grid too"
                               if tr.f_bound > tr.f_nyquist else "")))
    why = "nonlinear" if not tr.linear else (
        f"linear, oscillating over {periods:.3g} periods at accuracy {accuracy:g} against about {steps:.0f} expm "
        f"steps" if periods > 0 else "linear")
    if expm_ok and tr.modes is None and tr.periods_bound() > 0:
        why = (f"linear with {tr.states} states, about {steps:.0f} expm steps against at most "
               f"{tr.periods_bound():.3g} periods (up to {tr.f_bound:.3g} Hz): more steps than the periods repay")
    if tr.linear and not expm_ok:
        why += f" (round-off bound {tr.floor:.2g} too close to the accuracy for expm)"
    if tr.spread >= STIFF_SPREAD:
        why += f", stiff (link spread {tr.spread:.3g})"
    native = (f"; its compiled callbacks make a step about {tr.ida_gain:.2g}x cheaper" if tr.ida_gain > 1.0
              else "")
    out.append(("ida", f"{why}: variable-order BDF with events located by root finding{native}"))
    if expm_ok and not any(solver == "expm" for solver, _ in out):
        out.append(("expm", "linear, after ida refused: the exact flow"))
    # the last resort after expm and ida refused too (the hard case inertia_ratio_1e8 at accuracy 1e-6: both hit
    # the round-off floor of its 3e4 link spread, Radau's collocation met it with an estimate of 2.7e-7)
    if not any(solver == EXPLICIT for solver, _ in out):
        # ida's own refusal of an accuracy it cannot reach names DOP853: an order-8 method whose events are located
        # on its own steps, refused at once by its up-front stiffness check where the model is stiff for it (a
        # fuzz run, seed 90019: a mass rattling in a 1e9 N/m end stop, ida refused 1e-3 after three pairs,
        # Radau then took 38.6 s, DOP853 12.5 s)
        out.append((EXPLICIT, "after ida refused: an explicit method of order 8 that locates events on its own "
                              "steps (refused at once where the model is stiff for it)"))
    out.append(("scipy:Radau", "after ida refused: an implicit Runge-Kutta method"))
    return out


def ringing(spectrum, spread: float) -> bool:
    """Rule 3's test (module docstring): the top of dg/du's spectrum is lightly damped oscillation (``damping <=
    EXPLICIT_DAMPING * oscillation``, rule E's test) and the links spread by at least ``STIFF_SPREAD``, so that the
    fastest modes are local ones of stiff links, far above the rest."""
    _, osc, damp = spectrum
    return damp <= EXPLICIT_DAMPING * osc and spread >= STIFF_SPREAD


def explicit_reason(tr: Traits, accuracy: float):
    """Rule E's reason to run the explicit method first, or None (module docstring)."""
    if tr.spectrum is None or tr.states < EXPLICIT_STATES_MIN:
        return None
    from .scipy_ivp import DEFAULT_MAX_STEPS
    rho, osc, damp = tr.spectrum
    if damp > EXPLICIT_DAMPING * osc:
        return None
    if accuracy > EXPLICIT_TIGHT and tr.states < EXPLICIT_STATES_MIN_LOOSE:
        return None
    steps = tr.explicit_steps(accuracy)
    if not steps <= DEFAULT_MAX_STEPS["DOP853"]:
        return None
    return (f"linear with {tr.states} states, no friction device, its fastest rates lightly damped oscillation "
            f"(bounds: frequency {osc:.3g} 1/s, damping {damp:.3g} 1/s): a stepping method resolves it while it "
            f"rings, and DOP853's steps (about {steps:.0f} for the pair of runs at accuracy {accuracy:g}) cost "
            f"a few passes over the states each")


def expm_first_reason(tr: Traits, accuracy: float):
    """Rule E''s reason to run ``expm`` before the explicit method, or None: a model of at most
    ``EXPM_FIRST_STATES`` states whose explicit pair takes more than ``EXPM_FIRST_RATIO`` times expm's steps
    (``explicit_steps`` against ``expm_steps_at``) on an output grid fine enough for expm's first step
    (``dt_out * rho <= EXPM_FIRST_H_RHO``)."""
    rho = tr.spectrum[0]
    dt_out = 0.5 / tr.f_nyquist
    dop, exact = tr.explicit_steps(accuracy), tr.expm_steps_at(accuracy)
    if tr.states > EXPM_FIRST_STATES or dop <= EXPM_FIRST_RATIO * exact or dt_out * rho > EXPM_FIRST_H_RHO:
        return None
    return (f"linear with {tr.states} states, its fastest rates lightly damped oscillation: the exact flow takes "
            f"about {exact:.0f} steps on the output grid (every {dt_out:.3g} s, {dt_out * rho:.2g} times the fastest "
            f"rate's time scale), fewer than the about {dop:.0f} of DOP853's stability cap for the pair of runs")


@functools.lru_cache(maxsize=64)
def _accepted(fn) -> set:
    sig = inspect.signature(fn)
    from .options import TIME_ARGUMENTS      # taken by every registered solver (max_points, timeout_s, ...)
    return {p.name for p in sig.parameters.values()
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)} | set(TIME_ARGUMENTS)


def _native_default(solver: str, options: dict) -> dict:
    """The chosen solver's options, with IDA's compiled callbacks (``native=True``, ``solvers.ida_native``)
    when the user left ``native`` unset and numba and SUNDIALS' libraries are there: the same method and
    tolerances without Python in IDA's loop (10-20x less time on small models); a model the native path
    cannot serve runs the usual path (``stats.extra["native"]`` says why)."""
    if solver != "ida" or "native" in options:
        return options
    from .ida_native import libraries
    if isinstance(libraries(), str):
        return options
    return {**options, "native": True}


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
    tr = traits(model, t_start, t_end, dt_out)
    candidates = choose(tr, accuracy)
    c = model.compile()
    if getattr(c, "dae_only", False):
        # algebraic, sampled or branch device states (causal blocks): only the DAE solver holds them, so its own
        # refusal is the answer (the ODE-form fallbacks would refuse the model itself)
        candidates = [cand for cand in candidates if cand[0] == "ida"]
    analysis = time.perf_counter() - t0
    refused = []
    for i, (solver, reason) in enumerate(candidates):
        fn = SOLVERS[solver]
        # ``native`` says how ida runs; a fallback to another method (expm, Radau) simply runs without it
        run_given = {k: v for k, v in options.items() if k != "native" or solver == "ida"}
        unknown = sorted(set(run_given) - _accepted(fn))
        if unknown and solver == EXPLICIT:
            continue        # options of the other candidates (ida's): rule E steps aside rather than refuse them
        if unknown and refused:
            # a fallback that cannot take the options (dop853's first_step, not ida's): the refusal that led here
            exc = refused[-1][1]
            raise type(exc)(f"{exc} (solver='auto' could not fall back to '{solver}': it does not take option(s) "
                            f"{unknown}; name a solver to run with them)",
                            **(exc.fields() if hasattr(exc, "fields") else {})) from exc
        if unknown:
            from .options import unknown_message      # with the closest names, when there are
            raise ParameterError(f"simulate(): option(s) {unknown} are not options of '{solver}', which "
                                 f"solver='auto' chose ({reason}); name the solver that takes them. "
                                 f"{unknown_message(solver, fn.options, unknown)}")
        run_options = _native_default(solver, run_given)
        try:
            res = simulate_with_accuracy(model, solver, fn, t_start, t_end, dt_out, accuracy, run_options)
        except SimulationError as exc:
            refused.append((solver, exc))
            if i + 1 < len(candidates):
                continue
            if len(refused) > 1:
                first = refused[0]
                raise type(exc)(f"{exc} (solver='auto' tried '{first[0]}' first, which refused: "
                                f"{' '.join(str(first[1]).split())[:300]})",
                                **(exc.fields() if hasattr(exc, "fields") else {})) \
                    from (exc.__cause__ if exc.__cause__ is not None else exc)     # e.g. the user's own exception
            raise
        st = res.stats
        elapsed = time.perf_counter() - t0
        st.wall_time = max(st.wall_time, elapsed)
        st.extra["estimate_time"] = max(0.0, elapsed - st.extra.get("wall_time_main", st.wall_time))
        text = f"{solver}: {reason} ({tr.describe()})"
        if refused:
            # the reason says that this solver ran because the first choice refused, and why that one was
            # chosen; this solver's own rule-3 reason would read as if it had been preferred
            first, first_reason = candidates[0]
            tried = "; ".join(f"'{s}' refused{' first' if k == 0 else ''}: {' '.join(str(e).split())[:200]}"
                              for k, (s, e) in enumerate(refused))
            text = (f"{solver} as a fallback: solver='auto' chose '{first}' ({first_reason}); {tried}; "
                    f"'{solver}' ran instead ({METHODS.get(solver, solver)}) ({tr.describe()})")
        st.extra.update(auto_reason=text, auto_time=analysis)
        return res
    raise AssertionError("unreachable")     # pragma: no cover - the list always ends with ida
