"""Variable-structure friction devices and their logical equations.

Devices: ``Clutch`` (between two flanges), ``Brake`` (flange to support),
``FrictionContact`` (translational, mass to mass or to ground), and
``BearingFriction`` (speed-dependent torque table, no normal force).

Every device keeps **one equation structure** in all modes (the "universal
equation" of REFERENCES.md [003], MSL PartialFriction): a row of the constraint
matrix ``G_f`` (its relative coordinate) and one unknown force ``lam``:

=========  ====  ===========================================
mode       code  equation
=========  ====  ===========================================
Backward   -1    ``lam = -tau_k(|w_rel|)``
Stuck       0    ``a_rel = 0`` (``lam`` = holding torque)
Forward     1    ``lam = +tau_k(|w_rel|)``
Free        2    ``lam = 0``   (normal force <= 0)
Held        3    ``lam = 0``   (zero relative speed kept by other stuck
                               devices: ``hybrid.holding``)
=========  ====  ===========================================

with the kinetic capacity ``tau_k(w) = mu(w) * cgeo * fn_max * f_normalized(t)``,
``tau0 = tau_k(0)`` and the static (break-away) capacity ``tau0_max = peak * tau0``.
Index reduction therefore runs once; only the row's equation switches.

A device states its laws here: the kinetic characteristic (``kinetic``), the
capacities (``capacities``, ``capacity_function``), the equation of each mode
(``relation``) and, for a lossy gear, the torque it can hold at rest
(``limits``, ``breakaway``). Which mode a device is in, the event functions
and the holding torques are the hybrid layer's (``regmech.hybrid``: its
``logic`` module states the MSL rules of stick and slip).
"""

from __future__ import annotations

import bisect
import math

import numpy as np

from ..component import Device, Param, read_only
from ..modes import BACKWARD, FORWARD, FREE, HELD, STUCK  # noqa: F401  (the mode codes, as before)
from ..ports import ROTATIONAL, TRANSLATIONAL
from ..component import Command, StateRead
from .heat import HEAT_UNITS, THERMAL_UNITS, DissipatesPower, ThermalMass


class FrictionDevice(DissipatesPower, Device):
    """Base class: subclasses define ``kinetic(w_abs, t, left, q=None)`` and ``engaged``.

    Inputs from the state: a device whose laws read more than ``|w_rel|`` and ``t`` lists them in
    ``law_inputs()`` (its own temperature with a ``ThermalMass``, a controller's ``Command`` as its
    normal force); the compiler then evaluates them from the DAE's unknowns and passes their values
    as ``q`` (a float array in that order) to ``kinetic``, ``normal_force``, ``capacities``,
    ``relation`` and the capacity function, everywhere: residual, Jacobian, event functions, mode
    logic. A device without inputs is called without ``q``, as before (user subclasses keep working).
    Its own states (``friction_states``) join the DAE with the rates ``state_rates`` states, which
    may read its friction force ``lam`` and ``w_rel``.
    """

    kind = "friction"
    one_way = False   # True: only w_rel >= 0 (freewheel); no Backward mode
    coupled = False   # True: the row's force is tied to the device's own rigid row (LossyGear)
    #: the parameter holding the normal force (a signal, or a ``Command`` for classes that take one)
    _force_param: str | None = None

    # -- inputs from the state and own states (a ThermalMass; a Command as normal force) ----------------
    def law_inputs(self) -> list[tuple]:
        """What the laws read besides ``|w_rel|`` and ``t``, in the order of ``q``: ``("state", name)`` for
        one of the device's own ``friction_states``, ``("command", device, key)`` for a ``Command``."""
        out = []
        if self._values.get("thermal") is not None:
            out.append(("state", "T"))
        cmd = self._values.get(self._force_param) if self._force_param else None
        if isinstance(cmd, (Command, StateRead)):
            out.append(("command", cmd.device, cmd.key))
        return out

    def _q_index(self, what: str):
        """Position of input ``"T"`` (the temperature) or ``"command"`` in ``q``, or None."""
        for i, entry in enumerate(self.law_inputs()):
            if (entry[0] == "state" and entry[1] == what) or (entry[0] == what):
                return i
        return None

    def friction_states(self) -> dict:
        """The device's own states (name -> start value) and their units (``signal_unit``)."""
        th = self._values.get("thermal")
        return {"T": th.T0} if th is not None else {}

    def friction_state_datum(self) -> dict:
        """The datum of each own state (name -> value in its unit; 0 where absent): the solvers integrate the
        state's departure from it and the result shows the state itself. A ``ThermalMass``'s temperature is
        held as its rise over ``T_amb``: the solvers weigh a state's local error by ``rtol |y|``, and 293 K
        moving by 0.04 K held at ``rtol |T|`` is a tolerance of 7,000 times rtol of the motion (random
        drivetrain seed 30: the accuracy contract had to tighten ida from rtol 3e-6 to 6.9e-8 for it)."""
        th = self._values.get("thermal")
        return {"T": th.T_amb} if th is not None else {}

    def state_rates(self, w_rel: float, lam: float, t: float, left: bool, q):
        """Rates of ``friction_states`` and their derivatives: ``(rates, d/dw_rel, d/dlam, d/dq)`` (arrays of
        shapes (ns,), (ns,), (ns,), (ns, nq)). A ``ThermalMass``: ``dT/dt = (lam w_rel - G (T - T_amb)) / C``,
        ``lam w_rel`` the power the friction absorbs (``heat_flow``)."""
        th = self._values["thermal"]
        iT = self._q_index("T")
        dq = np.zeros((1, len(q)))
        dq[0, iT] = -th.G / th.C
        return (np.array([th.rate(lam * w_rel, q[iT])]), np.array([lam / th.C]), np.array([w_rel / th.C]), dq)

    def _fade(self, q) -> float:
        th = self._values.get("thermal")
        if th is None or q is None:
            return 1.0
        return th.factor(q[self._q_index("T")])[0]

    def law_gradient(self, mode, quadrant, w_abs, t, left, q) -> np.ndarray:
        """``d rhs / d q`` of ``relation`` (central differences of the law; the fade table's kinks and a
        command's clip make analytic slopes no more useful to Newton's iteration than these)."""
        q = np.asarray(q, float)
        out = np.zeros(len(q))
        for i in range(len(q)):
            h = 1e-8 * max(1.0, abs(q[i]))
            qp, qm = q.copy(), q.copy()
            qp[i] += h
            qm[i] -= h
            out[i] = (self.relation(mode, quadrant, w_abs, t, left, qp)[2]
                      - self.relation(mode, quadrant, w_abs, t, left, qm)[2]) / (2 * h)
        return out

    @property
    def derived_units(self):
        return THERMAL_UNITS if self._values.get("thermal") is not None else HEAT_UNITS

    def signal_unit(self, var: str):
        if var == "T" and self._values.get("thermal") is not None:
            return "K"
        return super().signal_unit(var)

    def _check_thermal(self):
        th = self._values.get("thermal")
        if th is not None and not isinstance(th, ThermalMass):
            from ..errors import ParameterError
            raise ParameterError(f"{type(self).__name__} '{self.name}': thermal must be a "
                                 f"regmech.components.heat.ThermalMass(C, G, T_amb, T0, fade), got {th!r}")

    # -- laws -------------------------------------------------------------------------------------
    def relation(self, mode, quadrant, w_abs, t, left=False, q=None):
        """Equation of a non-stuck row: ``c_own lam + c_cpl lam_cpl = rhs``; returns
        (c_own, c_cpl, rhs, d rhs / d|w_rel|)."""
        if mode == FREE or mode == HELD:
            return 1.0, 0.0, 0.0, 0.0
        tk, dk = self.kinetic(w_abs, t, left) if q is None else self.kinetic(w_abs, t, left, q)
        return 1.0, 0.0, mode * tk, mode * dk

    def kinetic(self, w_abs: float, t: float, left: bool = False, q=None) -> tuple[float, float]:
        """Kinetic capacity at relative speed ``w_abs`` >= 0 and its derivative d/dw."""
        raise NotImplementedError

    def normal_force(self, t: float, left: bool = False, q=None) -> float:
        """Engagement measure: the device is Free when this is <= 0."""
        return 1.0

    def peak_ratio(self) -> float:
        return self._values.get("peak", 1.0)

    def capacity_function(self):
        """A fast closure ``(t, left, q=None) -> (fn, tau0, tau0_max)`` with the parameters bound
        (the event functions call it at every root-finding iterate). A closure may say what it
        depends on besides constants: ``at.signals``, a tuple of the device's signals (without it,
        anything); the event functions then evaluate it once per segment when all of them are
        constant between their breakpoints (``hybrid.events``)."""
        if self.law_inputs():
            def at(t, left=False, q=None):
                tau0, tau0_max = self.capacities(t, left, q)
                return self.normal_force(t, left, q), tau0, tau0_max
            return at

        def at(t, left=False):
            tau0, tau0_max = self.capacities(t, left)
            return self.normal_force(t, left), tau0, tau0_max
        return at

    def capacities(self, t, left=False, q=None):
        tau0 = (self.kinetic(0.0, t, left) if q is None else self.kinetic(0.0, t, left, q))[0]
        return tau0, self.peak_ratio() * tau0

    def linear_law(self):
        """The device's laws in closed form when they are linear in one signal, else None.

        Returns ``(signal, fn_scale, k, peak)`` meaning: normal force ``fn = fn_scale * signal(t)``
        [N] (the device is Free when ``fn <= 0``), kinetic torque ``tau_k = k * max(fn, 0)`` at every
        relative speed (``k`` [m]: a constant friction coefficient times the geometry), capacities
        ``tau0 = tau_k`` and ``tau0_max = peak * tau0``. Compiled solvers (``solvers.ida_native``)
        evaluate the device from these numbers instead of calling its methods, so a subclass that
        states another law (it overrides a method) gets None here, and so does a device with inputs
        from the state (``law_inputs``).
        """
        return None


#: a commanded normal force (f_normalized [1] or fn [N]) at most this in magnitude is zero
COMMAND_ZERO = 1e-12


def _checked_command(dev, param, value, t, upper):
    """A commanded normal force, refused when it is not finite or above ``upper`` (beyond round-off): the
    same contract as a signal's (``signals``), said with the controller's name."""
    cmd = dev._values[param]
    value = float(value)
    if not np.isfinite(value) or (upper is not None and value > upper * (1 + 1e-6)):
        from ..errors import SimulationError
        bound = "" if upper is None else f" above {upper:g}"
        raise SimulationError(
            f"{type(dev).__name__} '{dev.name}': its {param} from {cmd!r} is {value!r}{bound} at t={t:.9g}; "
            f"keep the controller's output in range (clip(u, 0, 1) in its outputs) or raise fn_max")
    # a command held at zero (clip(u, 0, 1) below its range) is zero to round-off only; its sign would
    # engage and release the device at every evaluation (chattering between Free and sliding)
    return 0.0 if abs(value) <= COMMAND_ZERO else value


class _MuMixin:
    """mu(w) from a constant ``mu``, a ``mu_table`` of (w, mu) points (w >= 0) or a ``mu_law``
    (``components.laws.Stribeck``: a closed-form law instead of a long table)."""

    mu_law = Param(None, check="any", optional=True, unit="1",
                   doc="friction law mu(|w_rel|), e.g. Stribeck(...); overrides mu and mu_table")
    thermal = Param(None, check="any", optional=True,
                    doc="heat.ThermalMass(C, G, T_amb, T0, fade): temperature state T [K] and fade mu * fade(T)")

    def _mu(self, w_abs):
        law = self._values.get("mu_law")
        if law is not None:
            return self._law_mu(law, w_abs)
        tab = self._values.get("mu_table")
        if tab is None:
            return self._values["mu"], 0.0
        ws, mus = tab[:, 0], tab[:, 1]
        if len(ws) == 1:
            return float(mus[0]), 0.0
        k = int(np.clip(np.searchsorted(ws, w_abs, side="right") - 1, 0, len(ws) - 2))
        slope = (mus[k + 1] - mus[k]) / (ws[k + 1] - ws[k])
        if w_abs >= ws[-1]:
            return float(mus[-1]), 0.0
        if w_abs <= ws[0]:
            return float(mus[0]), 0.0
        return float(mus[k] + slope * (w_abs - ws[k])), float(slope)

    def _law_mu(self, law, w_abs):
        """``law.mu(w_abs)`` checked: a law's own exception, a result that is not two finite numbers ``(mu, dmu/dw)``
        is a ``SimulationError`` naming the device and the law (a user's ``FrictionLaw`` subclass)."""
        from ..errors import RegmechError, SimulationError
        where = f"{type(self).__name__} '{self.name}': mu_law {type(law).__name__}"
        try:
            mu, dmu = law.mu(w_abs)
            mu, dmu = float(mu), float(dmu)
        except RegmechError:
            raise
        except Exception as exc:
            raise SimulationError(f"{where}: mu({w_abs!r}) raised {type(exc).__name__}: {exc}; a friction law's mu(w) "
                                  f"must return (mu, d mu / d w), two finite numbers, for every speed w >= 0") \
                from exc
        if not (math.isfinite(mu) and math.isfinite(dmu)):
            raise SimulationError(f"{where}: mu({w_abs!r}) returned ({mu!r}, {dmu!r}); a friction law must return "
                                  f"finite numbers (mu, d mu / d w) for every speed w >= 0")
        return mu, dmu

    def _constant_mu(self):
        """mu when it does not depend on the relative speed (a constant, or a one-point table), else None; None
        with a ``mu_law``, which overrides both (read as the constant ``mu``, a Stribeck clutch under a ramp
        torque never broke away on the compiled IDA path, ``linear_law``, which the default call takes)."""
        if self._values.get("mu_law") is not None:
            return None
        tab = self._values.get("mu_table")
        if tab is None:
            return float(self._values["mu"])
        return float(tab[0, 1]) if len(tab) == 1 else None

    def _states_own_law(self, base, names) -> bool:
        """True when this class overrides none of ``base``'s methods ``names`` (it keeps base's law)."""
        return all(getattr(type(self), n) is getattr(base, n) for n in names)

    def validate(self):
        from .laws import FrictionLaw
        self._check_thermal()
        law = self._values.get("mu_law")
        if law is not None and not isinstance(law, FrictionLaw):
            from ..errors import ParameterError
            raise ParameterError(f"{type(self).__name__} '{self.name}': mu_law must be a friction law "
                                 f"(regmech.components.laws.Stribeck(...)), got {law!r}")
        tab = self._values.get("mu_table")
        if tab is not None and (tab[0, 0] < 0 or np.any(tab[:, 1] < 0)):
            from ..errors import ParameterError
            raise ParameterError(f"{type(self).__name__} '{self.name}': mu_table needs w >= 0 and mu >= 0")
        if self._values.get("peak", 1.0) < 1.0:
            from ..errors import ParameterError
            raise ParameterError(f"{type(self).__name__} '{self.name}': parameter 'peak' must be >= 1 "
                                 f"(static over kinetic friction), got {self._values['peak']}")


class Clutch(_MuMixin, FrictionDevice):
    """Friction clutch (MSL Clutch): ``w_rel = w_b - w_a``, ``tau = flange_b.tau``,
    ``fn = fn_max * f_normalized(t)`` [N], kinetic torque ``mu(|w_rel|) cgeo fn``.

    ``f_normalized`` <= 1; values <= 0 disengage the clutch (mode Free), as in
    MSL, whose own CoupledClutches drives it with a sine down to -1. A value
    above 1 (beyond round-off) is refused: raise ``fn_max`` instead."""

    mu = Param(0.5, check="nonnegative", unit="1", doc="kinetic friction coefficient (ignored with mu_table)")
    mu_table = Param(None, check="table", optional=True, unit="(rad/s, 1)", doc="(w_rel [rad/s], mu) points for w_rel >= 0")
    peak = Param(1.0, check="positive", unit="1", doc="static over kinetic friction at w = 0 (>= 1)")
    cgeo = Param(1.0, check="nonnegative", unit="m", doc="geometry constant (effective radius x surfaces)")
    fn_max = Param(check="nonnegative", unit="N", doc="maximum normal force")
    f_normalized = Param(1.0, check="signal", bounds=(None, 1.0), unit="1", command=True,
                         doc="normalised normal force, <= 1 (<= 0: disengaged); a signal of t or a controller's "
                             "command (Controller.command)",
                         bounds_note="; the normal force is fn_max * f_normalized, so 1 is the full force fn_max and "
                                     "values <= 0 disengage the device (mode Free). Raise fn_max for a larger force")
    w_rel_start = Param(None, optional=True, unit="rad/s",
                        doc="start value of the relative speed w_rel = w_b - w_a (Brake: w_flange - w_support), "
                            "fixed when given")
    relative_start_params = (None, "w_rel_start")
    flanges = (("flange_a", ROTATIONAL), ("flange_b", ROTATIONAL))
    _force_param = "f_normalized"

    def normal_force(self, t, left=False, q=None):
        if q is not None:
            i = self._q_index("command")
            if i is not None:
                return self.fn_max * _checked_command(self, "f_normalized", q[i], t, 1.0)
        return self.fn_max * self.f_normalized.value(t, left)

    def kinetic(self, w_abs, t, left=False, q=None):
        fn = max(self.normal_force(t, left, q), 0.0)
        mu, dmu = self._mu(w_abs)
        fade = self._fade(q)        # 1.0 without a thermal mass: the products below are then bit for bit as before
        return fade * (mu * self.cgeo * fn), fade * (dmu * self.cgeo * fn)

    def capacity_function(self):
        if self.law_inputs():
            return FrictionDevice.capacity_function(self)
        sig, fn_max, k0, peak = self.f_normalized, self.fn_max, self._mu(0.0)[0] * self.cgeo, self.peak

        def at(t, left=False):
            fn = fn_max * sig.value(t, left)
            tau0 = k0 * fn if fn > 0 else 0.0
            return fn, tau0, peak * tau0
        at.signals = (sig,)
        return at

    #: the methods whose formulas ``linear_law`` restates
    _LAW = ("kinetic", "normal_force", "capacity_function", "capacities", "relation", "peak_ratio", "_mu")

    def linear_law(self):
        mu = self._constant_mu()
        if mu is None or self.one_way or self.law_inputs() or not self._states_own_law(Clutch, self._LAW):
            return None
        return self.f_normalized, float(self.fn_max), mu * float(self.cgeo), float(self.peak)


class OneWayClutch(Clutch):
    """One-way clutch (MSL OneWayClutch): a freewheel in parallel with a clutch, one
    constraint torque only. ``w_rel = w_b - w_a >= 0`` always: when ``w_rel`` reaches 0
    the freewheel locks (Stuck) and holds any negative torque; it releases forward when
    the holding torque exceeds ``peak * tau0`` (engaged) or a tiny threshold
    ``1e-4 * mu(0) * cgeo * fn_max`` (disengaged). Engaged (f_normalized > 0) and
    sliding, it transmits ``mu(w_rel) cgeo fn``; disengaged and sliding, nothing (Free).
    Start with ``w_rel >= 0``."""

    one_way = True
    EPS0 = 1e-4

    def capacities(self, t, left=False, q=None):
        tau0, tau0_max = super().capacities(t, left, q)
        if self.normal_force(t, left, q) <= 0:
            return 0.0, self.EPS0 * self._mu(0.0)[0] * self.cgeo * self.fn_max
        return tau0, max(self.peak, 1.0 + self.EPS0) * tau0

    def capacity_function(self):
        return FrictionDevice.capacity_function(self)

    #: the methods whose formulas ``one_way_law`` restates
    _ONE_WAY_LAW = Clutch._LAW + ("capacities",)

    def one_way_law(self):
        """``linear_law`` of the one-way clutch (compiled solvers, ``solvers._native_friction``):
        ``(signal, fn_scale, k, peak, free_capacity)``, ``peak`` at least ``1 + EPS0`` and
        ``free_capacity = EPS0 k fn_max`` [N m] the freewheel's hold when disengaged (``capacities``);
        None for a speed-dependent mu, inputs from the state, or a subclass that states another law."""
        mu = self._constant_mu()
        if mu is None or self.law_inputs() or not self._states_own_law(OneWayClutch, self._ONE_WAY_LAW):
            return None
        k = mu * float(self.cgeo)
        return (self.f_normalized, float(self.fn_max), k, max(float(self.peak), 1.0 + self.EPS0),
                self.EPS0 * k * float(self.fn_max))


class Brake(Clutch):
    """Brake (MSL Brake): friction between ``flange`` and ``support`` (grounded when free);
    ``w_rel = w_flange - w_support``."""

    flanges = (("flange", ROTATIONAL), ("support", ROTATIONAL, True))

    def rows(self):
        return [{"support": -1.0, "flange": 1.0}]


class FrictionContact(_MuMixin, FrictionDevice):
    """Translational Coulomb contact between ``flange_a`` and ``flange_b`` (a Fixed
    for a contact with the ground): ``f = mu(|v_rel|) * fn(t)`` [N], static ``peak`` times that.

    Sign convention (as every two-flange device): ``v_rel = v_b - v_a`` [m/s], the mode is
    Forward (+1) while ``v_rel > 0``, Backward (-1) while ``v_rel < 0``, and ``f = flange_b.f``
    is the force the contact applies to ``flange_b``'s side, opposing ``v_rel``. So the mode names
    the direction of the *relative* motion, and which way a block slides in the world depends on
    the side the ground is on: a block ``M`` moving in +s on a floor reads Forward with
    ``connect(floor.flange, c.flange_a); connect(c.flange_b, M.flange_a)`` (``v_rel = v_M``) and
    Backward with the flanges swapped (``v_rel = -v_M``); the physics is the same::

        floor = m.add(Fixed("floor", domain="translational"))
        c = m.add(FrictionContact("c", mu=0.3, fn=9.81 * 2.0))
        M = m.add(Mass("M", m=2.0, v0=1.0))
        m.connect(floor.flange, c.flange_a)      # the ground on flange_a
        m.connect(c.flange_b, M.flange_a)        # v_rel = v_M: mode Forward (+1) while M slides in +s
    """

    mu = Param(0.5, check="nonnegative", unit="1", doc="kinetic friction coefficient (ignored with mu_table)")
    mu_table = Param(None, check="table", optional=True, unit="(m/s, 1)", doc="(v_rel [m/s], mu) points for v_rel >= 0")
    peak = Param(1.0, check="positive", unit="1", doc="static over kinetic friction")
    fn = Param(check="signal", unit="N", command=True,
               doc="normal force (number, signal or callable, or a controller's command)")
    w_rel_start = Param(None, optional=True, unit="m/s",
                        doc="start value of the relative speed v_rel = v_b - v_a, fixed when given")
    relative_start_params = (None, "w_rel_start")
    flanges = (("flange_a", TRANSLATIONAL), ("flange_b", TRANSLATIONAL))
    default_domain = TRANSLATIONAL
    _force_param = "fn"

    def normal_force(self, t, left=False, q=None):
        if q is not None:
            i = self._q_index("command")
            if i is not None:
                return _checked_command(self, "fn", q[i], t, None)
        return self.fn.value(t, left)

    def kinetic(self, w_abs, t, left=False, q=None):
        fn = max(self.normal_force(t, left, q), 0.0)
        mu, dmu = self._mu(w_abs)
        fade = self._fade(q)
        return fade * (mu * fn), fade * (dmu * fn)

    _LAW = ("kinetic", "normal_force", "capacity_function", "capacities", "relation", "peak_ratio", "_mu")

    def linear_law(self):
        mu = self._constant_mu()
        if mu is None or self.law_inputs() or not self._states_own_law(FrictionContact, self._LAW):
            return None
        return self.fn, 1.0, mu, float(self.peak_ratio())


class BearingFriction(FrictionDevice):
    """Bearing friction (MSL BearingFriction) between ``flange`` and ``support``:
    kinetic torque from ``tau_table`` of (w [rad/s], tau [N m]) for w >= 0,
    break-away torque ``peak * tau_table(0)``."""

    tau_table = Param(check="table", unit="(rad/s, N m)", doc="(w >= 0, friction torque) points")
    peak = Param(1.0, check="positive", unit="1", doc="break-away over kinetic torque at w = 0")
    thermal = Param(None, check="any", optional=True,
                    doc="heat.ThermalMass(C, G, T_amb, T0, fade): temperature state T [K], torque * fade(T)")
    flanges = (("flange", ROTATIONAL), ("support", ROTATIONAL, True))

    def rows(self):
        return [{"support": -1.0, "flange": 1.0}]

    def validate(self):
        self._check_thermal()
        # a negative friction torque would drive the motion it should resist (and the stuck test
        # tau0_max - |lam| would fail from the start)
        tab = self._values.get("tau_table")
        if tab is not None and (tab[0, 0] < 0 or np.any(tab[:, 1] < 0)):
            from ..errors import ParameterError
            raise ParameterError(f"BearingFriction '{self.name}': tau_table needs speeds w >= 0 and friction "
                                 f"torques >= 0 (the friction opposes the motion in either direction)")
        if self._values.get("peak", 1.0) < 1.0:
            from ..errors import ParameterError
            raise ParameterError(f"BearingFriction '{self.name}': parameter 'peak' must be >= 1 "
                                 f"(break-away over kinetic torque), got {self._values['peak']}")

    def kinetic(self, w_abs, t, left=False, q=None):
        tab = self.tau_table
        ws, ts = tab[:, 0], tab[:, 1]
        f = self._fade(q)
        if len(ws) == 1 or w_abs <= ws[0]:
            return f * float(ts[0]), 0.0
        if w_abs >= ws[-1]:
            return f * float(ts[-1]), 0.0
        k = int(np.searchsorted(ws, w_abs, side="right") - 1)
        slope = (ts[k + 1] - ts[k]) / (ws[k + 1] - ws[k])
        return f * float(ts[k] + slope * (w_abs - ws[k])), f * float(slope)

    #: the methods whose formulas ``linear_law`` restates
    _LAW = ("kinetic", "normal_force", "capacity_function", "capacities", "relation", "peak_ratio")

    def linear_law(self):
        """A torque that does not vary with speed (a ``tau_table`` of one torque) in closed form:
        ``(Constant(1), 1, tau, peak)``, always engaged. None for a speed-dependent table, a thermal state, or
        a subclass that states another law."""
        from ..signals import Constant
        torques = self.tau_table[:, 1]
        own = all(getattr(type(self), n) is getattr(BearingFriction, n) for n in self._LAW)
        if self.law_inputs() or np.ptp(torques) != 0.0 or not own:
            return None
        return Constant(1.0), 1.0, float(torques[0]), float(self.peak)


class LossyGear(FrictionDevice):
    """Gear with mesh efficiency and bearing friction, stuck or rolling (MSL LossyGear).

    Kinematics ``phi_a - phi_s = ratio (phi_b - phi_s)`` (a rigid row, mesh force
    ``lam_g``) and a friction row on ``w_a = w_flange_a - w_support`` whose force is
    the loss torque ``tau_loss`` acting at flange_a: ``flange_a.tau = lam_g + tau_loss =
    tau_a``, ``flange_b.tau = -ratio (tau_a - tau_loss)``.

    ``loss_table`` rows ``(|w_a|, eta_mf1, eta_mf2, |tau_bf1|, |tau_bf2|)``: mesh
    efficiency when flange_a drives (1) or flange_b drives (2), and the resultant
    bearing friction with respect to flange_a. Rolling forward (``w_a > 0``):
    ``tau_loss = (1 - eta_mf1) tau_a + tau_bf1`` when ``tau_eta = tau_a - tau_bf_a >= 0``
    (flange_a drives) else ``(1 - 1/eta_mf2) tau_a + tau_bf2``; backward mirrored.
    Since ``tau_a`` contains ``tau_loss`` the row is linear in both multipliers. Stuck
    (``w_a = 0``): the loss torque holds the gear while it lies between the values at
    ``w = 0+`` and ``0-``; beyond them it starts rolling. The driving side changes at
    an event where ``tau_eta`` crosses zero (``res.events``: kind "driving side", see
    ``hybrid.gears`` for how the side is decided). An ideal table ``[[0, 1, 1, 0, 0]]``
    keeps the gear in mode Free (``tau_loss = 0``).
    """

    coupled = True
    ratio = Param(check="nonzero", unit="1", doc="transmission ratio phi_a/phi_b")
    loss_table = Param([[0.0, 1.0, 1.0, 0.0, 0.0]], check="any", unit="(rad/s, 1, 1, N m, N m)", doc="(|w_a|, eta_mf1, eta_mf2, tau_bf1, tau_bf2) rows")
    flanges = (("flange_a", ROTATIONAL), ("flange_b", ROTATIONAL), ("support", ROTATIONAL, True))
    rel_names = {ROTATIONAL: (None, None, None, None)}

    def validate(self):
        from ..errors import ParameterError
        try:
            tab = np.atleast_2d(np.asarray(self._values["loss_table"], dtype=float))
        except (TypeError, ValueError):
            tab = None
        if tab is None or tab.ndim != 2 or tab.shape[1] != 5 or not np.all(np.isfinite(tab)):
            raise ParameterError(f"LossyGear '{self.name}': loss_table must be rows (|w_a|, eta_mf1, eta_mf2, "
                                 f"tau_bf1, tau_bf2), got {self._values['loss_table']!r}")
        if np.any(tab[:, 1:3] <= 0) or np.any(tab[:, 1:3] > 1) or np.any(np.diff(tab[:, 0]) <= 0) or tab[0, 0] < 0:
            raise ParameterError(f"LossyGear '{self.name}': efficiencies must lie in (0, 1] and speeds increase from >= 0")
        tab = read_only(tab, self, "loss_table")   # the validated table, not the caller's (editable) array
        self._values["loss_table"] = tab
        self._table = tab
        # the lookup's plain floats (``_interp``), made with the table: a new table gets new ones
        self._interp_xs = [float(x) for x in tab[:, 0]]
        self._interp_rows = [tuple(float(v) for v in row[1:5]) for row in tab]
        self._interp_last = None
        self.ideal = bool(np.allclose(tab, [[0.0, 1.0, 1.0, 0.0, 0.0]], rtol=0, atol=1e-15) and len(tab) == 1)
        self._zero = self._interp(0.0)

    def rows(self):
        r = self.ratio
        return [{"flange_a": 1.0, "flange_b": -r, "support": r - 1.0}, {"flange_a": 1.0, "support": -1.0}]

    def capacity_function(self):
        # no normal force; its limits depend on the mesh force (see limits / breakaway)
        return lambda t, left=False: (1.0, 0.0, 0.0)

    def row_kinds(self):
        return ["rigid", "friction"]

    def _interp(self, w_abs):
        """The table's row at ``|w|`` (linear between its speeds, constant beyond them) as ``(eta1, eta2, bf1,
        bf2, bf_a)``. Plain floats and a bisection, and the last answer kept: the mode logic and the friction rows
        ask for the same speed several times per residual call, and four ``np.interp`` calls a time were a
        quarter of a run of fuzz seed 60016 once its kernels stopped dominating."""
        last = self._interp_last
        if last is not None and last[0] == w_abs:
            return last[1]
        xs, rows = self._interp_xs, self._interp_rows
        i = bisect.bisect_right(xs, w_abs)
        if i == 0:
            eta1, eta2, bf1, bf2 = rows[0]
        elif i == len(xs):
            eta1, eta2, bf1, bf2 = rows[-1]
        else:
            f = (w_abs - xs[i - 1]) / (xs[i] - xs[i - 1])
            eta1, eta2, bf1, bf2 = (lo + f * (hi - lo) for lo, hi in zip(rows[i - 1], rows[i]))
        out = self._coefficients(eta1, eta2, bf1, bf2)
        self._interp_last = (w_abs, out)
        return out

    @staticmethod
    def _coefficients(eta1, eta2, bf1, bf2):
        bf1, bf2 = abs(bf1), abs(bf2)
        if abs(eta1 - 1.0) < 1e-15 and abs(eta2 - 1.0) < 1e-15:
            bf_a = bf1 / 2.0        # the split between the sides is arbitrary (MSL does the same)
        else:
            bf_a = (bf1 - bf2) / (eta1 - 1.0 / eta2)
        return eta1, eta2, bf1, bf2, bf_a

    @staticmethod
    def _quadrant_loss(mode, q, coeffs):
        """tau_loss = k * tau_a + b for rolling ``mode`` and driving side ``q``."""
        eta1, eta2, bf1, bf2, _ = coeffs
        if mode == FORWARD:
            return (1.0 - eta1, bf1) if q > 0 else (1.0 - 1.0 / eta2, bf2)
        return (1.0 - 1.0 / eta2, -bf2) if q > 0 else (1.0 - eta1, -bf1)

    def relation(self, mode, quadrant, w_abs, t, left=False, q=None):
        if mode == FREE or mode == HELD:
            return 1.0, 0.0, 0.0, 0.0
        k, b = self._quadrant_loss(mode, quadrant, self._interp(w_abs))
        # tau_loss = k (lam_g + tau_loss) + b  ->  (1 - k) tau_loss - k lam_g = b
        return 1.0 - k, -k, b, 0.0

    def limits(self, sa, lam_g):
        """(tauLossMax_p, tauLossMin_m) [N m]: the loss torque the gear can hold at w = 0 under the
        loss torque ``sa`` and mesh force ``lam_g``."""
        eta1, eta2, bf1, bf2, bf_a = self._zero
        tau_a = lam_g + sa
        hi = (1 - eta1) * tau_a + bf1 if tau_a - bf_a > 0 else (1 - 1 / eta2) * tau_a + bf2
        lo = (1 - 1 / eta2) * tau_a - bf2 if tau_a + bf_a > 0 else (1 - eta1) * tau_a - bf1
        return hi, lo

    def breakaway(self, sa, lam_g):
        """FORWARD/BACKWARD when the loss torque ``sa`` leaves ``limits`` (beyond round-off), else 0."""
        hi, lo = self.limits(sa, lam_g)
        scale = 1e-12 * max(1.0, abs(sa), abs(lam_g))
        if sa > hi + scale:
            return FORWARD
        if sa < lo - scale:
            return BACKWARD
        return 0

    def tau_eta(self, mode, w_abs, tau_loss, lam_g):
        """``tau_eta`` [N m] of a rolling gear: ``tau_a - tau_bf_a`` forward, ``tau_a + tau_bf_a``
        backward, with ``tau_bf_a`` at the current speed ``w_abs`` (the torque at which the two
        loss laws of the direction give the same loss). Its sign is the quadrant (``relation``)."""
        bf_a = self._interp(w_abs)[4]
        tau_a = lam_g + tau_loss
        return tau_a - bf_a if mode == FORWARD else tau_a + bf_a

    @staticmethod
    def driving_flange(mode, quadrant):
        """+1 when flange_a drives (power flows from flange_a through the gear to flange_b), -1 when
        flange_b drives: forward, quadrant +1 is the efficiency eta_mf1 (flange_a drives); backward,
        quadrant +1 is eta_mf2 (flange_b drives)."""
        return int(mode) * int(quadrant)
