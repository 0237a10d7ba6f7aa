"""Forced harmonic response of the structural-matrix form.

An input ``u(t) = A cos(w t + phase)`` (``= Re(U e^{i w t})``, ``U = A e^{i phase}``;
note ``A sin(w t) = A cos(w t - pi/2)``) gives the steady state
``q(t) = Re(Q e^{i w t})`` with

    (C - w^2 M + i w B) Q = F(w),                                   (1)

``F = W U`` for a force input (Torque, Force), and
``F = -(K_g + i w B_g - w^2 M_g) G`` for a kinematic input with
displacement amplitude ``G`` (Position source: ``G = U``; Speed source:
``G = U / (i w)``). Every output ``y = a0.x + a1.x' + a2.x''`` of the full
coordinates ``x = T q + P g`` (``LinearModel.output``) then has the complex
amplitude ``Y = (a0 + i w a1 - w^2 a2) . (T Q + P G)``: amplitude ``|Y|``
[output unit per input unit] and phase ``arg Y`` [rad], so
``y(t) = |Y| cos(w t + arg Y)``.

Multi-harmonic excitation (an engine order spectrum) is the superposition of
(1) over the harmonics; ``order_sweep`` runs it over a range of speeds.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ParameterError, StructureError
from .table import Table


# ============================================================ the solver
class _Excitation:
    """Complex generalised force and input displacement for a set of inputs."""

    def __init__(self, lin, inputs):
        self.lin = lin
        self.inputs = _normalise_inputs(lin, inputs)

    def at(self, omega):
        lin = self.lin
        F = np.zeros(lin.n, complex)
        G = np.zeros(len(lin.full_names), complex)
        for name, amp in self.inputs.items():
            F += amp * lin.input_force(name, omega)
            G += amp * lin.input_motion(name, omega)
        return F, G


def _normalise_inputs(lin, inputs) -> dict:
    names = lin.all_inputs
    if inputs is None:
        if len(names) != 1:
            raise ParameterError(f"harmonic response: model '{lin.compiled.model.name}' has inputs {names or 'none'}; "
                                 f"name the excitation, e.g. inputs='torque' or inputs={{'torque': 10.0}}")
        inputs = names[0]
    if isinstance(inputs, str):
        inputs = {inputs: 1.0}
    out = {}
    for name, spec in dict(inputs).items():
        lin._input(name)    # raises with the list of inputs when unknown
        if isinstance(spec, tuple):
            amp, phase = spec
            spec = float(amp) * np.exp(1j * float(phase))
        spec = complex(spec)
        if not np.isfinite(spec):
            raise ParameterError(f"harmonic response: amplitude of '{name}' must be finite, got {spec!r}")
        out[name] = spec
    return out


def _solve(lin, omega, F):
    """Q of (C - w^2 M + i w B) Q = F; an error when the dynamic stiffness is singular."""
    Z = lin.C - omega ** 2 * lin.M + 1j * omega * lin.B
    where = f"{omega / (2 * np.pi):.6g} Hz"
    if sp.issparse(Z):
        try:
            lu = spla.splu(sp.csc_matrix(Z))
        except RuntimeError:
            lu = None
        if lu is not None:
            d = np.abs(lu.U.diagonal())
            if d.min() > 1e-13 * d.max():
                return lu.solve(F)
    else:
        with warnings.catch_warnings():     # singularity is checked on the pivots below, with a clear error
            warnings.simplefilter("ignore", la.LinAlgWarning)
            lu, piv = la.lu_factor(np.asarray(Z, complex), check_finite=True)
        d = np.abs(np.diag(lu))
        if d.size == 0 or d.min() > 1e-13 * d.max():
            return la.lu_solve((lu, piv), F)
    raise StructureError(
        f"harmonic response at {where}: the dynamic stiffness C - w^2 M + i w B is singular (an undamped resonance, "
        f"or a rigid-body mode at 0 Hz); add damping, move the frequency, or hold the free motion")


def _response(lin, outputs, omegas, excitation):
    maps = [lin.output(name) for name in outputs]
    Y = np.empty((len(omegas), len(maps)), complex)
    for i, w in enumerate(omegas):
        F, G = excitation.at(w)
        X = np.asarray(lin.T @ _solve(lin, w, F)).ravel() + G
        for j, om in enumerate(maps):
            Y[i, j] = om.gain(w) @ X
    return Y


# =================================================== single-frequency sweep
@dataclass
class FrequencyResponse:
    """Complex amplitudes ``values[i, j]`` of output ``outputs[j]`` at ``freqs_hz[i]``.

    ``amplitude(name)``, ``phase(name)`` [rad, cosine convention],
    ``table()``, ``to_dataframe()``, ``plot(path=None)``.
    """

    freqs_hz: np.ndarray
    outputs: list
    values: np.ndarray
    inputs: dict = field(default_factory=dict)
    #: SI unit of every output (``"rad/s"``, ``"N m"``; None when unknown) and of every input (``"N m"``)
    units: dict = field(default_factory=dict)
    input_units: dict = field(default_factory=dict)
    #: undamped natural frequencies of the linear model [Hz], rigid-body modes as 0 (modal numbering);
    #: marked in the plot; None when not computed (a model too large for all modes at once)
    natural_hz: np.ndarray | None = None
    model_name: str = ""

    def _col(self, name):
        try:
            return self.values[:, self.outputs.index(name)]
        except ValueError:
            raise KeyError(f"no output {name!r}; outputs are {self.outputs}") from None

    def amplitude(self, name: str) -> np.ndarray:
        return np.abs(self._col(name))

    def phase(self, name: str) -> np.ndarray:
        return np.angle(self._col(name))

    def __getitem__(self, name: str) -> np.ndarray:
        return self._col(name)

    def table(self) -> Table:
        parts = [c for j in range(len(self.outputs)) for c in (np.abs(self.values[:, j]), np.angle(self.values[:, j]))]
        data = np.column_stack(parts) if parts else np.zeros((len(self.freqs_hz), 0))
        cols = [c for name in self.outputs for c in (f"|{name}|", f"arg {name} [rad]")]
        return Table(data, [f"{f:.6g}" for f in self.freqs_hz], cols, title="harmonic response",
                     index_name="f [Hz]")

    def to_dataframe(self):
        return self.table().to_dataframe()

    def plot(self, path=None, ax=None, units=None):
        """Amplitude (log, one axis per output unit, labelled ``speed amplitude [rad/s per N m]``) and phase
        against frequency, the natural frequencies marked; ``units`` display units of the outputs
        (``{"w": "rpm"}``). Returns the figure."""
        from .plots import plot_frequency_response
        return plot_frequency_response(self, path=path, axes=ax, units=units)


def harmonic_response(lin, outputs, freqs_hz, inputs=None) -> FrequencyResponse:
    """Steady-state response (1) of ``outputs`` at each frequency of ``freqs_hz`` [Hz].

    ``outputs``: a name or names from ``lin.outputs()`` (``"J2.w"``,
    ``"spring.tau"``). ``inputs``: ``None`` (the model's only input, unit
    amplitude), a name (unit amplitude), or ``{name: amplitude}`` with a
    complex amplitude or an ``(amplitude, phase)`` pair; amplitudes are in
    the input's unit ([N m], [N], [rad], [rad/s], ...).
    """
    outputs = [outputs] if isinstance(outputs, str) else list(outputs)
    freqs = np.atleast_1d(np.asarray(freqs_hz, float))
    if freqs.ndim != 1 or not np.all(np.isfinite(freqs)) or np.any(freqs < 0):
        raise ParameterError("harmonic_response: freqs_hz must be finite frequencies >= 0 [Hz]")
    exc = _Excitation(lin, inputs)
    Y = _response(lin, outputs, 2 * np.pi * freqs, exc)
    return FrequencyResponse(freqs_hz=freqs, outputs=outputs, values=Y, inputs=exc.inputs,
                             units={n: output_unit(lin, n) for n in outputs},
                             input_units={n: input_unit(lin, n) for n in exc.inputs},
                             natural_hz=natural_frequencies(lin), model_name=lin.compiled.model.name)


#: the natural frequencies shown in response plots are computed up to this many coordinates (all modes,
#: dense: milliseconds at this size); above, the plots go without them
MARK_MODES_MAX = 300


def natural_frequencies(lin) -> np.ndarray | None:
    """Undamped natural frequencies [Hz] of ``lin`` (rigid-body modes 0), for marking response plots;
    None for a model above ``MARK_MODES_MAX`` coordinates or one the modal analysis refuses."""
    from ..errors import RegmechError
    from .modal import modal
    if lin.n == 0 or lin.n > MARK_MODES_MAX:
        return None
    try:
        return np.asarray(modal(lin).frequencies_hz, float)
    except RegmechError:
        return None


def output_unit(lin, name: str) -> str | None:
    """SI unit of the linear output ``name`` (``"J2.w"`` rad/s, ``"spring.tau"`` N m)."""
    from ..units import signal_unit
    return signal_unit(lin.compiled.model.components, name)


def input_unit(lin, name: str) -> str | None:
    """SI unit of the amplitude of input ``name``: a force input's torque or force (``"drive.tau"`` N m),
    a kinematic input's prescribed position or speed (``"motor.w_ref"`` rad/s)."""
    base = name.split("[")[0]
    owner, _, var = base.rpartition(".")
    comp = lin.compiled.model.components.get(owner)
    if comp is None:
        return None
    unit = comp.signal_unit(var)
    if unit is None and var in comp.param_specs():
        unit = comp.param_unit(var) or None
    return unit


# ===================================================== multi-harmonic input
@dataclass
class MultiHarmonicResponse:
    """Steady state under a sum of harmonics.

    ``freqs_hz`` (per harmonic), ``input_amplitudes`` (complex, per
    harmonic), ``values[h, j]`` complex amplitude of output j from harmonic
    h; ``time_series(t)`` the superposed steady state ``sum_h Re(Y_h e^{i w_h t})``;
    ``peak(name)`` the largest ``|y(t)|`` over a common period.
    """

    freqs_hz: np.ndarray
    input_amplitudes: np.ndarray
    outputs: list
    values: np.ndarray
    input_name: str
    period: float | None = None
    units: dict = field(default_factory=dict)
    input_unit: str | None = None
    #: the orders (``base_hz`` given) or None (frequencies)
    orders: np.ndarray | None = None

    def time_series(self, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, float))
        ph = np.exp(1j * 2 * np.pi * np.outer(t, self.freqs_hz))
        return (ph @ self.values).real

    def _grid(self, per_cycle: int = 64) -> np.ndarray:
        period = self.period or 1.0 / max(float(np.min(self.freqs_hz[self.freqs_hz > 0], initial=1.0)), 1e-300)
        npts = int(min(200000, max(256, per_cycle * np.max(self.freqs_hz, initial=1.0) * period)))
        return np.linspace(0.0, period, npts, endpoint=False)

    def peak(self, name: str) -> float:
        j = self.outputs.index(name)
        return float(np.abs(self.time_series(self._grid())[:, j]).max())

    def table(self) -> Table:
        data = np.column_stack([self.freqs_hz, np.abs(self.input_amplitudes)] +
                               [c for j in range(len(self.outputs))
                                for c in (np.abs(self.values[:, j]), np.angle(self.values[:, j]))])
        cols = ["f [Hz]", "|input|"] + [c for name in self.outputs for c in (f"|{name}|", f"arg {name} [rad]")]
        return Table(data, [f"h{i + 1}" for i in range(len(self.freqs_hz))], cols,
                     title=f"multi-harmonic response to {self.input_name}", index_name="harmonic")

    def plot(self, path=None, units=None):
        """Amplitude of each harmonic's contribution (bars) and the superposed steady state over one
        period, labelled with the outputs' units. Returns the figure."""
        from .plots import plot_multi_harmonic
        return plot_multi_harmonic(self, path=path, units=units)


def multi_harmonic_response(lin, outputs, harmonics, input=None, base_hz: float | None = None) -> MultiHarmonicResponse:
    """Response to ``u(t) = sum_h A_h cos(w_h t + phase_h)`` on one input.

    ``harmonics``: list of ``(order or frequency, amplitude, phase)``; with
    ``base_hz`` (e.g. the crankshaft speed in rev/s) the first entry is an
    order and ``f_h = order * base_hz``, otherwise a frequency [Hz].
    """
    outputs = [outputs] if isinstance(outputs, str) else list(outputs)
    name = _single_input(lin, input)
    spec = _harmonics(harmonics)
    freqs = spec[:, 0] * (base_hz if base_hz is not None else 1.0)
    amps = spec[:, 1] * np.exp(1j * spec[:, 2])
    exc = _Excitation(lin, {name: 1.0})
    Y = _response(lin, outputs, 2 * np.pi * freqs, exc) * amps[:, None]
    period = _common_period(spec[:, 0], base_hz) if base_hz else None
    return MultiHarmonicResponse(freqs, amps, outputs, Y, name, period,
                                 units={n: output_unit(lin, n) for n in outputs}, input_unit=input_unit(lin, name),
                                 orders=spec[:, 0] if base_hz is not None else None)


@dataclass
class OrderSweep:
    """Engine-order response over a speed range.

    ``speeds_hz`` (base speed, rev/s), ``orders``, ``amplitude[s, h, j]``
    (amplitude of output j from order h at speed s), ``peak[s, j]`` (largest
    ``|y(t)|`` of the superposed orders over a cycle).
    """

    speeds_hz: np.ndarray
    orders: np.ndarray
    outputs: list
    amplitude: np.ndarray
    peak: np.ndarray
    units: dict = field(default_factory=dict)
    input_name: str = ""
    input_unit: str | None = None
    #: undamped natural frequencies [Hz] (rigid 0), as ``FrequencyResponse.natural_hz``
    natural_hz: np.ndarray | None = None
    model_name: str = ""

    @property
    def speeds_rpm(self) -> np.ndarray:
        return self.speeds_hz * 60.0

    def resonance_speeds(self) -> list:
        """(order, mode number, natural frequency [Hz], speed [rpm]) where an order meets a natural
        frequency inside the speed range: ``speed = 60 f / order``."""
        out = []
        if self.natural_hz is None:
            return out
        lo, hi = float(self.speeds_rpm.min()), float(self.speeds_rpm.max())
        for order in self.orders:
            if order <= 0:
                continue
            for i, f in enumerate(self.natural_hz):
                rpm = 60.0 * f / order
                if f > 0 and lo <= rpm <= hi:
                    out.append((float(order), i + 1, float(f), float(rpm)))
        return out

    def campbell(self, modes=None):
        """The Campbell diagram of this sweep's orders and speed range (``analysis.campbell``); ``modes``
        defaults to the natural frequencies found with the sweep."""
        from .campbell import campbell
        return campbell(self.natural_hz if modes is None else modes, self.orders,
                        (float(self.speeds_rpm.min()), float(self.speeds_rpm.max())), model_name=self.model_name)

    def plot(self, path=None, units=None):
        """Amplitude of each order and of their sum against speed [rpm], one axis per output labelled with
        its unit, the speeds where an order meets a natural frequency marked. Returns the figure."""
        from .plots import plot_order_sweep
        return plot_order_sweep(self, path=path, units=units)


def order_sweep(lin, outputs, orders, speeds_hz, input=None) -> OrderSweep:
    """Run ``multi_harmonic_response`` with ``base_hz`` over every speed of ``speeds_hz`` [rev/s]."""
    outputs = [outputs] if isinstance(outputs, str) else list(outputs)
    speeds = np.atleast_1d(np.asarray(speeds_hz, float))
    if not np.all(np.isfinite(speeds)) or np.any(speeds <= 0):
        raise ParameterError("order_sweep: speeds_hz must be positive [rev/s]")
    spec = _harmonics(orders)
    amp = np.empty((len(speeds), len(spec), len(outputs)))
    peak = np.empty((len(speeds), len(outputs)))
    for i, s in enumerate(speeds):
        r = multi_harmonic_response(lin, outputs, spec, input=input, base_hz=s)
        amp[i] = np.abs(r.values)
        ts = r.time_series(r._grid())
        peak[i] = np.abs(ts).max(axis=0)
    name = _single_input(lin, input)
    return OrderSweep(speeds, spec[:, 0], outputs, amp, peak, units={n: output_unit(lin, n) for n in outputs},
                      input_name=name, input_unit=input_unit(lin, name), natural_hz=natural_frequencies(lin),
                      model_name=lin.compiled.model.name)


def _single_input(lin, input):
    names = lin.all_inputs
    if input is None:
        if len(names) != 1:
            raise ParameterError(f"model '{lin.compiled.model.name}' has inputs {names or 'none'}; name the one "
                                 f"that carries the harmonics (input='...')")
        return names[0]
    kind, j = lin._input(input)
    return (lin.input_names if kind == "force" else lin.kinematic_names)[j]


def _harmonics(harmonics) -> np.ndarray:
    try:
        spec = np.array([tuple(h) + (0.0,) * (3 - len(tuple(h))) for h in harmonics], float)
    except (TypeError, ValueError):
        spec = None
    if spec is None or spec.ndim != 2 or spec.shape[1] != 3 or len(spec) == 0 or not np.all(np.isfinite(spec)) \
            or np.any(spec[:, 0] < 0):
        raise ParameterError("harmonics must be a list of (order or frequency >= 0, amplitude, phase [rad]) tuples")
    return spec


def _common_period(orders, base_hz) -> float:
    """Period [s] after which all orders repeat (orders as fractions with denominators up to 12)."""
    den = 1
    for o in orders:
        den = np.lcm(den, Fraction(float(o)).limit_denominator(12).denominator)
    return float(den) / base_hz
