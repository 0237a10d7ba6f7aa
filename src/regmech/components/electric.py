"""Electric machines: the ``DCMotor``, two DC motors on one armature circuit
(``SeriesDCMotors``) and the map-based ``ElectricMotor``.

A machine is a massless *device* between its rotor flange and its stator
(``support``, grounded when left unconnected); the rotor inertia is an
explicit ``Inertia`` on ``flange`` (regularity rule 1), so a machine's
torque acts on a mass in every state. The armature current of a DC motor is
an internal differential state of the device, so it joins the DAE like a
body's speed; the supply voltage is a signal (number, ``Signal`` or f(t)).

The electrical side does not enter the mechanical energy audit (a motor is a
source there: the work it does on the rotor); it is exported as *derived
signals* (``Device.derived``), computed from the result after the run:

    p_el = p_mech + p_loss + d(magnetic)/dt            [W]

with ``p_el`` the electrical power drawn, ``p_mech`` the mechanical power
delivered to the rotor (``= -<name>.power``), ``p_loss`` the resistive
(or map) loss and ``magnetic`` the energy ``L i^2 / 2`` [J] stored in the
armature inductance.
"""

from __future__ import annotations

import numpy as np
import sympy

from .._frozen import frozen
from ..component import Device, Param
from ..errors import ParameterError
from ..ports import ROTATIONAL
from ._symbolic import SpeedAbove
from .heat import HEAT_UNITS, heat_signals


def signal_series(sig, t, left) -> np.ndarray:
    """Values of a bound signal at the output instants (left limits on the rows marked ``left``)."""
    return np.array([sig.value(float(tk), bool(lf)) for tk, lf in zip(t, left)], float)


class DCMotor(Device):
    """Separately excited (constant field) DC motor, armature current ``i`` as state::

        L di/dt = u(t) - R i - k w        [V]
        tau = k i                         [N m]  on ``flange`` (reaction on ``support``)

    with ``w = w_flange - w_support`` [rad/s]. ``u`` the supply voltage [V]
    (number, signal or f(t)), ``R`` [Ohm] > 0 the armature resistance, ``L``
    [H] > 0 the armature inductance (electrical time constant ``L/R``), ``k``
    [N m/A = V s/rad] > 0 the torque and back-EMF constant, ``i0`` [A] the
    start current. The rotor inertia is an ``Inertia`` on ``flange``.

    Steady state under a constant load torque ``tau_L``: ``i = tau_L / k``,
    ``w = (u - R tau_L / k) / k``; after a voltage step the current rises
    with the electrical time constant ``L/R`` (rotor held) and the speed with
    the mechanical one ``J R / k^2`` (``L`` small).

    Exports ``w`` (rotor speed relative to the stator), the state ``i`` [A],
    and derived signals ``tau`` = k i [N m], ``u`` [V], ``p_el`` = u i,
    ``p_loss`` = R i^2, ``p_mech`` = k i w [W], ``magnetic`` = L i^2 / 2 [J];
    ``p_el = p_mech + p_loss + d(magnetic)/dt`` holds exactly; ``heat_flow`` (= ``p_loss``) and the
    accumulated ``heat`` [J] as every loss element (``components.heat``).
    """

    kind = "compliant"
    is_source = True
    states = {"i": "i0"}
    flanges = (("flange", ROTATIONAL), ("support", ROTATIONAL, True))
    rel_names = {ROTATIONAL: (None, "w", None, None)}
    u = Param(check="signal", unit="V", doc="supply voltage")
    R = Param(check="positive", unit="Ohm", doc="armature resistance")
    L = Param(check="positive", unit="H", doc="armature inductance")
    k = Param(check="positive", unit="N m/A", doc="torque constant = back-EMF constant [V s/rad]")
    i0 = Param(0.0, unit="A", doc="start current")
    derived_units = {"tau": "N m", "u": "V", "p_el": "W", "p_loss": "W", "p_mech": "W", "magnetic": "J", **HEAT_UNITS}

    def rows(self):
        # e = phi_flange - phi_support: de is the rotor speed, flange.tau = -k i, so the rotor receives +k i
        return [{"flange": 1.0, "support": -1.0}]

    def laws(self, e, de):
        return [-self.k * self.i]

    def derivatives(self, e, de):
        return [(self.u - self.R * self.i - self.k * de[0]) / self.L]

    def derived(self, t, left, e, de, tau, z):
        i, w, u = z["i"], de[0], signal_series(self.u, t, left)
        return {"tau": self.k * i, "u": u, "p_el": u * i, "p_loss": self.R * i * i, "p_mech": self.k * i * w,
                "magnetic": 0.5 * self.L * i * i, **heat_signals(t, self.R * i * i)}


class SeriesDCMotors(Device):
    """Two DC motors on one armature circuit (one current ``i`` through both), as
    the Ward-Leonard swing drive of REFERENCES.md [004]::

        L di/dt = u(t) - R i - k_1 w_1 - k_2 w_2     [V]
        tau_1 = k_1 i,  tau_2 = k_2 i                [N m]

    ``w_j = w(flange_j) - w(support)`` [rad/s]; each torque acts on its rotor
    flange (rotor inertias are ``Inertia`` components on ``flange_1`` and
    ``flange_2``), the reactions on the common stator ``support`` (grounded
    when free). ``R`` [Ohm] > 0 and ``L`` [H] > 0 are those of the whole
    circuit (both armatures, interpoles, the generator), ``k_1``, ``k_2``
    [N m/A] > 0 the motor constants, ``u`` [V] the generator voltage, ``i0``
    [A] the start current. In steady state under total load ``tau_L`` on
    rigidly coupled rotors: ``i = tau_L / (k_1 + k_2)``,
    ``w = (u - R i) / (k_1 + k_2)``.

    Exports the state ``i`` [A], derived ``tau_1``, ``tau_2`` [N m], ``w_1``,
    ``w_2`` [rad/s], ``u`` [V], ``p_el`` = u i, ``p_loss`` = R i^2,
    ``p_mech`` = (k_1 w_1 + k_2 w_2) i [W], ``magnetic`` = L i^2 / 2 [J], ``heat_flow``, ``heat``.
    """

    kind = "compliant"
    is_source = True
    states = {"i": "i0"}
    flanges = (("flange_1", ROTATIONAL), ("flange_2", ROTATIONAL), ("support", ROTATIONAL, True))
    rel_names = {ROTATIONAL: (None, None, None, None)}
    u = Param(check="signal", unit="V", doc="supply voltage of the circuit")
    R = Param(check="positive", unit="Ohm", doc="resistance of the whole armature circuit")
    L = Param(check="positive", unit="H", doc="inductance of the whole armature circuit")
    k_1 = Param(check="positive", unit="N m/A", doc="motor constant of motor 1 [V s/rad]")
    k_2 = Param(check="positive", unit="N m/A", doc="motor constant of motor 2 [V s/rad]")
    i0 = Param(0.0, unit="A", doc="start current")
    derived_units = {"tau_1": "N m", "tau_2": "N m", "w_1": "rad/s", "w_2": "rad/s", "u": "V", "p_el": "W",
                     "p_loss": "W", "p_mech": "W", "magnetic": "J", **HEAT_UNITS}

    def rows(self):
        return [{"flange_1": 1.0, "support": -1.0}, {"flange_2": 1.0, "support": -1.0}]

    def laws(self, e, de):
        return [-self.k_1 * self.i, -self.k_2 * self.i]

    def derivatives(self, e, de):
        return [(self.u - self.R * self.i - self.k_1 * de[0] - self.k_2 * de[1]) / self.L]

    def derived(self, t, left, e, de, tau, z):
        i, u = z["i"], signal_series(self.u, t, left)
        return {"tau_1": self.k_1 * i, "tau_2": self.k_2 * i, "w_1": de[0], "w_2": de[1], "u": u, "p_el": u * i,
                "p_loss": self.R * i * i, "p_mech": (self.k_1 * de[0] + self.k_2 * de[1]) * i,
                "magnetic": 0.5 * self.L * i * i, **heat_signals(t, self.R * i * i)}


def _grid(comp, name, value) -> np.ndarray:
    """A strictly increasing, finite, non-negative 1-D grid (speeds or torques of an efficiency map)."""
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.ndim != 1 or len(arr) < 2 or not np.all(np.isfinite(arr)) or np.any(arr < 0) \
            or np.any(np.diff(arr) <= 0):
        raise ParameterError(f"ElectricMotor '{comp.name}': '{name}' must be at least two finite, non-negative, "
                             f"strictly increasing values, got {value!r}")
    return frozen(arr, f"ElectricMotor '{comp.name}'", name)


def envelope(w, tau_max: float, p_max: float):
    """Available torque magnitude at speed ``w`` [N m]: ``tau_max`` up to the base speed
    ``w_base = p_max / tau_max``, the power limit ``p_max / |w|`` above (numpy or sympy)."""
    w_base = p_max / tau_max
    if isinstance(w, sympy.Basic) or isinstance(w_base, sympy.Basic):
        return tau_max * w_base / SpeedAbove(w, w_base)
    return tau_max * w_base / np.maximum(w_base, np.abs(w))


def bilinear(xs, ys, table, x, y) -> np.ndarray:
    """Bilinear interpolation of ``table[i, j]`` given at ``(xs[i], ys[j])`` (increasing grids), held at
    the edges beyond them. Written out (not scipy's interpolator, whose code path, and so the last bit of
    the answer, depends on the arrays' flags, which a pickle round trip changes)."""
    x = np.clip(np.asarray(x, float), xs[0], xs[-1])
    y = np.clip(np.asarray(y, float), ys[0], ys[-1])
    i = np.clip(np.searchsorted(xs, x, side="right") - 1, 0, len(xs) - 2)
    j = np.clip(np.searchsorted(ys, y, side="right") - 1, 0, len(ys) - 2)
    a = (x - xs[i]) / (xs[i + 1] - xs[i])
    b = (y - ys[j]) / (ys[j + 1] - ys[j])
    return ((1 - a) * (1 - b) * table[i, j] + a * (1 - b) * table[i + 1, j]
            + (1 - a) * b * table[i, j + 1] + a * b * table[i + 1, j + 1])


class ElectricMotor(Device):
    """Map-based traction machine (motor and generator), torque by command::

        tau = command(t) * T_env(w)                                      [N m]
        T_env(w) = tau_max                 for |w| <= w_base = p_max / tau_max
                 = p_max / |w|             above (power limit)
        p_mech = tau w                                                   [W]
        p_el = p_mech / eta(|w|, |tau|)    motoring   (p_mech >= 0)
             = p_mech * eta_gen(|w|, |tau|) generating (p_mech < 0, regeneration)

    ``w = w_flange - w_support`` [rad/s]; the torque acts on ``flange`` (the
    rotor ``Inertia``), its reaction on ``support`` (grounded when free).
    ``command`` in [-1, 1] (signal; negative brakes: in the generator quadrants
    when the rotor turns forward) is the fraction of the available torque, as
    an inverter's torque demand; ``tau_max`` [N m] > 0, ``p_max`` [W] > 0.
    The efficiency map ``eta`` (values in (0, 1]) is a table over
    ``eta_speeds`` [rad/s] (rows) and ``eta_torques`` [N m] (columns), both
    non-negative and increasing, interpolated bilinearly and held beyond its
    edges; ``eta_gen`` (same grid, optional) is the generator map, ``eta``
    when not given; with no map the machine is lossless (``p_el = p_mech``).

    The map acts on the electrical side only: the shaft torque is what the
    command asks within the envelope, so losses do not feed back into the
    motion and ``p_el`` is a derived signal (``p_el``, ``p_loss = p_el - p_mech``
    [W], ``tau`` [N m], ``w_base`` rad/s as a parameter). The envelope's corner
    at ``w_base`` is a kink (continuous torque, a jump in its slope), which
    IDA steps over without an event. ``heat_flow`` (= ``p_loss``) and ``heat``
    [J] as every loss element.

    Driven by a controller instead of a time signal: a ``Controller`` whose
    actuator law is ``command * envelope(w, tau_max, p_max)`` with the
    command from its loop (``control.Driver`` does this for a speed profile);
    an ``ElectricMotor``'s ``efficiency(w, tau, generating)`` turns that
    actuator's torque and speed into the electrical side after the run.
    """

    kind = "compliant"
    is_source = True
    flanges = (("flange", ROTATIONAL), ("support", ROTATIONAL, True))
    rel_names = {ROTATIONAL: (None, "w", None, None)}
    command = Param(0.0, check="signal", unit="1", doc="torque demand as a fraction of the envelope, -1..1",
                    bounds=(-1.0, 1.0), bounds_note="the command is a fraction of the available torque")
    tau_max = Param(check="positive", unit="N m", doc="peak torque up to the base speed")
    p_max = Param(check="positive", unit="W", doc="peak power (the envelope above the base speed)")
    eta_speeds = Param(None, check="any", optional=True, unit="rad/s", doc="speed grid of the efficiency map")
    eta_torques = Param(None, check="any", optional=True, unit="N m", doc="torque grid of the efficiency map")
    eta = Param(None, check="any", optional=True, unit="1", doc="motor efficiency, shape (speeds, torques)")
    eta_gen = Param(None, check="any", optional=True, unit="1", doc="generator efficiency (default: eta)")
    derived_units = {"tau": "N m", "p_mech": "W", "p_el": "W", "p_loss": "W", "efficiency": "1", **HEAT_UNITS}

    @property
    def w_base(self) -> float:
        """Base speed [rad/s]: where the torque limit meets the power limit."""
        return self.p_max / self.tau_max

    def validate(self):
        given = [n for n in ("eta_speeds", "eta_torques", "eta") if self._values[n] is not None]
        if given and len(given) < 3:
            raise ParameterError(f"ElectricMotor '{self.name}': an efficiency map needs eta_speeds, eta_torques and "
                                 f"eta together; got only {given}")
        if self._values["eta_gen"] is not None and not given:
            raise ParameterError(f"ElectricMotor '{self.name}': eta_gen needs the grid eta_speeds, eta_torques "
                                 f"(and eta) as well")
        if not given:
            return
        ws = _grid(self, "eta_speeds", self._values["eta_speeds"])
        ts = _grid(self, "eta_torques", self._values["eta_torques"])
        self._values["eta_speeds"], self._values["eta_torques"] = ws, ts
        for name in ("eta", "eta_gen"):
            val = self._values[name]
            if val is None:
                continue
            try:
                arr = np.array(val, dtype=float)
            except (TypeError, ValueError):
                arr = None
            if arr is None or arr.shape != (len(ws), len(ts)) or not np.all(np.isfinite(arr)) \
                    or np.any(arr <= 0) or np.any(arr > 1):
                raise ParameterError(f"ElectricMotor '{self.name}': '{name}' must be a table of efficiencies in "
                                     f"(0, 1] of shape (len(eta_speeds), len(eta_torques)) = ({len(ws)}, {len(ts)}), "
                                     f"got {val!r}")
            self._values[name] = frozen(arr, f"ElectricMotor '{self.name}'", name)

    def rows(self):
        # e = phi_support - phi_flange (as Torque): flange.tau = -tau, the rotor receives +tau
        return [{"support": 1.0, "flange": -1.0}]

    def law(self, rel, rel_dot):
        return self.command * envelope(-rel_dot, self.tau_max, self.p_max)

    def efficiency(self, w, tau, generating) -> np.ndarray:
        """Efficiency at speeds ``w`` and torques ``tau`` (arrays) from the motor or generator map
        (bilinear, held beyond the grid); 1 without a map."""
        w, tau = np.abs(np.asarray(w, float)), np.abs(np.asarray(tau, float))
        if self.eta is None:
            return np.ones(np.broadcast(w, tau).shape)
        ws, ts = self.eta_speeds, self.eta_torques
        motor = bilinear(ws, ts, self.eta, w, tau)
        gen = motor if self.eta_gen is None else bilinear(ws, ts, self.eta_gen, w, tau)
        return np.where(generating, gen, motor)

    def derived(self, t, left, e, de, tau, z):
        w = -de[0]
        torque = np.asarray(tau[0], float)
        p_mech = torque * w
        generating = p_mech < 0
        eta = self.efficiency(w, torque, generating)
        p_el = np.where(generating, p_mech * eta, p_mech / eta)
        return {"tau": torque, "p_mech": p_mech, "p_el": p_el, "p_loss": p_el - p_mech, "efficiency": eta,
                **heat_signals(t, p_el - p_mech)}


__all__ = ["DCMotor", "SeriesDCMotors", "ElectricMotor", "envelope", "SpeedAbove"]
