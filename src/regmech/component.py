"""Component base classes: parameters, flanges, roles.

A regular mechanical system is made of *masses* (``Body``), the *ground*
(``Ground``) and massless *devices* (``Device``) that join them. A device is
described by

* its **structure**: ``rows()``, a list of linear maps from its flanges'
  positions to device coordinates, ``e_r = sum_f c_rf x_f`` (the rows of
  the structure matrix of REFERENCES.md [000]);
* its **law**, by kind:

  - ``compliant``: generalised forces ``tau_r = law(e, de)``, written once
    per class with sympy-compatible expressions (``self.c`` is a symbol when
    the class template is built, a number otherwise);
  - ``rigid``: ``e_r = 0``, ``tau_r`` a constraint force (Lagrange multiplier);
  - ``position`` / ``speed``: ``e_r = ref(t)`` or ``de_r = ref(t)``;
  - ``friction``: variable structure with a mode (see ``components.friction``).

The force that a device exerts *on itself* at flange f is
``flange.tau = sum_r c_rf tau_r``; the bodies receive the opposite, so the
power a device absorbs is ``sum_r tau_r * de_r``.
"""

from __future__ import annotations

import inspect
import math
from typing import Any, ClassVar

import numpy as np

from ._frozen import frozen
from ._numbers import as_real, describe
from .errors import ParameterError, UnknownFlangeError
from .ports import DOMAINS, ROTATIONAL, TRANSLATIONAL, VARIABLE_NAMES, Flange
from .signals import Signal, as_signal
from .units import FIXED_UNITS, in_domain, variable_unit

REQUIRED = object()
#: the smallest positive normal double (2.2e-308): a "positive" or "nonzero" parameter below it is refused
TINY = float(np.finfo(float).tiny)


class Command:
    """A value that another device computes from the state of the DAE, read by a friction device's law
    (``Controller.command(key)``: a controller's output driving a clutch's or brake's normal force).

    The friction device receives it in its laws as an input ``q`` (``FrictionDevice.law_inputs``); the
    compiler evaluates it from the unknowns at every residual, Jacobian, event function and mode-logic
    call, so stick/slip sees the normal force as a function of the state."""

    __slots__ = ("device", "key")

    def __init__(self, device, key: str):
        self.device, self.key = device, key

    def __repr__(self) -> str:
        return f"{type(self.device).__name__} '{self.device.name}'.command({self.key!r})"


#: the range checks a ``Param`` can declare (its docstring)
CHECKS = ("real", "positive", "nonnegative", "nonzero", "signal", "table", "choice", "any")


class StateRead:
    """A value of the unknowns of the DAE that a signal parameter reads instead of a function of time: state
    ``key`` of device ``device`` (a causal block's output, ``regmech.blocks``), in ``unit``.

    Any parameter that takes a ``Signal`` takes one. The compiler makes the parameter an argument of the
    device's laws read from the unknowns (``compile.reads``): its value at every residual, Jacobian, event
    function and output, with the Jacobian entries ``d law / d input`` placed at the producer's column."""

    __slots__ = ("device", "key", "unit")

    def __init__(self, device, key: str, unit: str = ""):
        self.device, self.key, self.unit = device, key, unit

    def __repr__(self) -> str:
        return f"{self.device.name}.{self.key}"


class Param:
    """A declared parameter with a range check.

    check: ``"real"`` (finite), ``"positive"`` (> 0), ``"nonnegative"`` (>= 0),
    ``"nonzero"``, ``"signal"`` (number, Signal or callable of t),
    ``"table"`` ((n, 2) points), ``"choice"`` (one of ``choices``),
    ``"any"`` (``CHECKS``; any other is a ``ParameterError``). ``optional=True`` also admits None.

    ``unit``: the SI unit (``"N m/rad"``, ``"kg m^2"``; ``"1"`` dimensionless; for a table the units of its
    columns, ``"(rad/s, N m)"``), written for the class's default kind of flange: an instance of the
    other kind reads it translated (``unit_in``). Signatures, docstrings and error messages show it.

    A signal is stored bound to the component and the parameter
    (``signals.as_signal``): its values are checked where the solvers read
    them. ``bounds=(lo, hi)`` (None: open) is a signal's documented range,
    ``bounds_note`` the sentence an error adds to explain it. A table is
    stored as a read-only copy, so an in-place edit of it is a ``ParameterError``
    naming the component and the parameter instead of a change of a validated
    parameter behind the checks; assign a new table to change it.
    """

    def __init__(self, default=REQUIRED, check: str = "real", *, optional: bool = False,
                 unit: str = "", doc: str = "", choices: tuple = (), bounds=None, bounds_note: str = "",
                 command: bool = False):
        if check not in CHECKS:
            import difflib
            close = difflib.get_close_matches(str(check), CHECKS, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else "."
            raise ParameterError(f"Param(check={check!r}): unknown check{hint} The checks are "
                                 f"{', '.join(repr(c) for c in CHECKS)}")
        if check == "choice" and not choices:
            raise ParameterError("Param(check='choice') needs the allowed values: Param(check='choice', "
                                 "choices=('a', 'b'))")
        self.default = default
        #: a signal parameter that also takes a ``Command`` (a value computed from the state by another
        #: device, e.g. a controller driving a clutch's normal force)
        self.command = command
        self.check = check
        self.optional = optional
        self.unit = unit
        self.doc = doc
        self.choices = choices
        self.bounds = bounds
        self.bounds_note = bounds_note
        self.name = "?"
        #: the default kind of flange of the class declaring it (set by ``Component.__init_subclass__``)
        self.owner_domain: str | None = None

    def __set_name__(self, owner, name):
        self.name = name

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        return obj._values[self.name]

    def __set__(self, obj, value):
        obj._values[self.name] = self.validate(obj, value)
        obj._changed()

    def validate(self, comp, value):
        if value is None and self.optional:
            return None
        if type(value) is float and math.isfinite(value):
            # the common case, decided without the general checks below (a model may have 100,000 of them)
            chk = self.check
            if chk == "real" or (chk == "positive" and value >= TINY) or (chk == "nonnegative" and value >= 0) \
                    or (chk == "nonzero" and abs(value) >= TINY):
                return value
        where = f"{type(comp).__name__} '{comp.name}'"
        if self.check == "signal":
            if isinstance(value, StateRead):
                want = self.unit_in(getattr(comp, "domain", ROTATIONAL))
                if want and value.unit and want != value.unit:
                    raise ParameterError(
                        f"{where}: parameter '{self.name}' is in [{want}] but {value!r} is in [{value.unit}]; "
                        f"convert it with a block in between (e.g. blocks.Gain(u={value!r}, k=...) or a "
                        f"controller whose output is in [{want}])")
                return value
            if isinstance(value, Command):
                if not self.command:
                    raise ParameterError(
                        f"{where}: parameter '{self.name}' is read as a function of time and cannot take "
                        f"{value!r}, a value of the state; a controller drives a torque or force through one of "
                        f"its actuators, and a clutch's or brake's normal force (f_normalized, fn) through a "
                        f"command")
                return value
            return as_signal(value, comp, self.name, self.bounds, self.bounds_note)
        if self.check == "any":
            return value
        if self.check == "choice":
            if value not in self.choices:
                raise ParameterError(f"{where}: parameter '{self.name}' must be one of {self.choices}, got {value!r}")
            return value
        if self.check == "table":
            try:
                arr = np.asarray(value, dtype=float)
            except (TypeError, ValueError):
                arr = None
            if arr is None or arr.ndim != 2 or arr.shape[1] != 2 or len(arr) < 1 or not np.all(np.isfinite(arr)):
                raise ParameterError(f"{where}: parameter '{self.name}' must be finite (x, y) pairs, got {value!r}")
            if np.any(np.diff(arr[:, 0]) <= 0):
                raise ParameterError(f"{where}: parameter '{self.name}' needs strictly increasing x values")
            return read_only(arr, comp, self.name)
        number = as_real(value)      # any real scalar: int, float, numpy scalars (np.float32, np.int64), ...
        if number is None:
            raise ParameterError(f"{where}: parameter '{self.name}' must be a real number{self._unit(comp)}, got "
                                 f"{describe(value)}")
        if not math.isfinite(number):
            raise ParameterError(f"{where}: parameter '{self.name}' must be finite, got {value!r}")
        bad = {"positive": number <= 0, "nonnegative": number < 0, "nonzero": number == 0}.get(self.check, False)
        if bad:
            want = {"positive": "> 0", "nonnegative": ">= 0", "nonzero": "non-zero"}[self.check]
            raise ParameterError(f"{where}: parameter '{self.name}' must be {want}{self._unit(comp)}, got {value!r}")
        if self.check in ("positive", "nonzero") and abs(number) < TINY:
            # a subnormal divisor: its reciprocal overflows to inf (1 / 1e-310), so the equations turn non-finite
            size = "in magnitude " if number < 0 else ""
            raise ParameterError(f"{where}: parameter '{self.name}' = {number:g}{self._unit(comp)} is {size}below "
                                 f"{TINY:.3g}, the smallest normal double, whose reciprocal overflows; give a "
                                 f"realistic value (SI units)")
        return number

    def _unit(self, comp=None):
        unit = self.unit_in(getattr(comp, "domain", ROTATIONAL))
        return f" [{unit}]" if unit and unit != "1" else ""

    def unit_in(self, domain: str) -> str:
        """The unit in ``domain``: units are written for a class's default kind of flange, and a class
        whose kind is chosen per instance (``Spring(..., domain="translational")``) reads ``N m/rad`` as
        ``N/m`` (``units.TRANSLATIONAL_OF``)."""
        if self.owner_domain is not None and self.owner_domain != domain:
            return in_domain(self.unit, domain)
        return self.unit

    def type_text(self) -> str:
        """What the parameter takes, with its unit, as shown in signatures and docstrings."""
        kind = {"real": "float", "positive": "float > 0", "nonnegative": "float >= 0", "nonzero": "float != 0",
                "signal": "float | Signal | f(t)", "table": "(n, 2) points",
                "choice": " | ".join(repr(c) for c in self.choices), "any": "object"}.get(self.check, self.check)
        unit = f" [{self.unit}]" if self.unit and self.unit != "1" else ""
        return kind + unit + (" | None" if self.optional else "")


def read_only(value, comp=None, name: str | None = None) -> np.ndarray:
    """A read-only float copy of an array parameter (validated values cannot be edited in place); an edit in
    place is a ``ParameterError`` naming ``comp`` and the parameter ``name`` (``regmech._frozen``)."""
    owner = None if comp is None else f"{type(comp).__name__} '{comp.name}'"
    return frozen(value, owner, name)


_PARAMETER_HEADING = "Parameters (keywords, SI units)"


class _Text:
    """An annotation shown as plain text in signatures (``J: float > 0 [kg m^2]``, no quotes)."""

    def __init__(self, text: str):
        self.text = text

    def __repr__(self) -> str:
        return self.text


def _own_init_keywords(cls) -> list[inspect.Parameter]:
    """Keyword-only arguments of ``__init__`` methods that subclasses define themselves (e.g. ``Fixed``'s
    ``s0``), other than ``domain`` and ``**params``."""
    extra: list[inspect.Parameter] = []
    for klass in cls.__mro__:
        if "__init__" not in vars(klass):
            continue
        try:
            sig = inspect.signature(vars(klass)["__init__"])
        except (TypeError, ValueError):
            continue
        for p in sig.parameters.values():
            if p.kind is inspect.Parameter.KEYWORD_ONLY and p.name != "domain" and p.name not in {e.name for e in extra}:
                extra.append(p)
    return extra


def _class_signature(cls) -> inspect.Signature:
    """``Cls(name, *, p1, p2=default, ..., domain=...)`` from the Param declarations: required parameters
    first (in declaration order), then those with defaults; ``domain`` when a flange takes its kind
    from the instance."""
    P = inspect.Parameter
    params = [P("name", P.POSITIONAL_OR_KEYWORD, annotation=str)]
    specs = cls.param_specs()
    required = [n for n, s in specs.items() if s.default is REQUIRED]
    optional = [n for n, s in specs.items() if s.default is not REQUIRED]
    for n in required + optional:
        spec = specs[n]
        default = P.empty if spec.default is REQUIRED else spec.default
        params.append(P(n, P.KEYWORD_ONLY, default=default, annotation=_Text(spec.type_text())))
    taken = {p.name for p in params}
    params += [p for p in _own_init_keywords(cls) if p.name not in taken]
    if any(len(f) > 1 and f[1] is None for f in cls.flanges):
        params.append(P("domain", P.KEYWORD_ONLY, default=cls.default_domain,
                        annotation=_Text("'rotational' | 'translational'")))
    return inspect.Signature(params)


def _with_parameter_section(cls, doc: str) -> str:
    """``doc`` followed by a ``Parameters`` section listing every Param (type, unit, default, doc)."""
    specs = cls.param_specs()
    if not specs:
        return doc
    lines = ["", "", _PARAMETER_HEADING, "-" * len(_PARAMETER_HEADING)]
    switchable = any(len(f) > 1 and f[1] is None for f in cls.flanges)
    for n, spec in specs.items():
        default = "required" if spec.default is REQUIRED else f"default {spec.default!r}"
        other = spec.unit_in(TRANSLATIONAL if cls.default_domain == ROTATIONAL else ROTATIONAL)
        kind = "translational" if cls.default_domain == ROTATIONAL else "rotational"
        alt = f" ([{other}] when {kind})" if switchable and other != spec.unit else ""
        dimensionless = ", dimensionless" if spec.unit == "1" else ""
        lines.append(f"{n} : {spec.type_text()}{alt}{dimensionless}, {default}")
        if spec.doc:
            lines.append(f"    {spec.doc}")
    return inspect.cleandoc(doc) + "\n".join(lines) + "\n"


def refuse_positional(cls, args) -> None:
    """Raise the ``ParameterError`` of a call with parameters after the name given by position (a class
    with its own ``__new__`` calls this too)."""
    if len(args) > 1:
        raise ParameterError(_positional_message(cls, args))


def _positional_message(cls, args) -> str:
    """The error for ``Inertia("x", 1.0)``: the class's parameters in order and the call it probably meant."""
    sig = cls.__signature__
    names = [p for p in sig.parameters if p != "name"]
    given = args[1:]
    guess = ", ".join(f"{n}={v!r}" for n, v in zip(names, given))
    listing = ", ".join(f"{p.name}{'' if p.default is p.empty else '=' + repr(p.default)}"
                        for p in list(sig.parameters.values())[1:])
    more = "" if len(given) <= len(names) else f" ({len(given)} values given, it takes {len(names)} parameters)"
    return (f"{cls.__name__}({args[0]!r}, {', '.join(repr(a) for a in given)}): parameters are given by keyword "
            f"after the name{more}; did you mean {cls.__name__}({args[0]!r}, {guess})? {cls.__name__} takes "
            f"(name, *, {listing}) (SI units; help({cls.__name__}) describes each)")


#: instance attributes of components and subsystems, which a flange of the same name must not shadow
_OWN_ATTRIBUTES = frozenset({"name", "model", "domain", "_values", "_flanges", "parts", "links"})


class Component:
    """Base of every component. Subclasses declare ``Param`` attributes and ``flanges``.

    ``flanges`` is a tuple of (name, domain) or (name, domain, grounded_if_free).
    ``domain`` may be ``None`` in a class that takes the domain as the
    ``domain`` constructor keyword (e.g. ``Spring(..., domain="translational")``).
    """

    role: ClassVar[str] = "abstract"
    flanges: ClassVar[tuple] = ()
    default_domain: ClassVar[str] = ROTATIONAL

    def __init_subclass__(cls, **kwargs):
        """Give every component class a real signature and a parameter list in its docstring, built
        from its ``Param`` declarations (so ``help()``, IDEs and ``inspect.signature`` show them)."""
        super().__init_subclass__(**kwargs)
        for val in vars(cls).values():
            if isinstance(val, Param) and val.owner_domain is None:
                val.owner_domain = cls.default_domain
        cls.__signature__ = _class_signature(cls)
        doc = cls.__dict__.get("__doc__")
        if doc and _PARAMETER_HEADING not in doc:
            cls.__doc__ = _with_parameter_section(cls, doc)

    def __new__(cls, *args, **kwargs):
        # parameters are keywords (Inertia("J1", J=1.0)); a positional one would otherwise end in a bare
        # TypeError from __init__ that names neither the class's parameters nor their order
        refuse_positional(cls, args)
        return super().__new__(cls)

    def __init__(self, name: str, *, domain: str | None = None, **params: Any):
        if not isinstance(name, str) or not name or "." in name or name.strip() != name:
            raise ParameterError(f"{type(self).__name__}: name must be a non-empty string without '.' or spaces at the ends, got {name!r}")
        self.name = name
        self.model = None
        if domain is None:
            domain = self.default_domain
        if domain not in DOMAINS:
            raise ParameterError(f"{type(self).__name__} '{name}': domain must be one of {DOMAINS}, got {domain!r}")
        self.domain = domain
        self._values: dict[str, Any] = {}
        declared = self._declared()
        unknown = set(params) - set(declared)
        if unknown:
            raise ParameterError(
                f"{type(self).__name__} '{name}': unknown parameter(s) {sorted(unknown)}; "
                f"it takes {sorted(declared)}")
        for pname, spec in declared.items():
            if pname in params:
                value = params[pname]
            elif spec.default is REQUIRED:
                raise ParameterError(f"{type(self).__name__} '{name}': parameter '{pname}' is required{spec._unit(self)}")
            else:
                value = spec.default
            self._values[pname] = spec.validate(self, value)
        self._flanges: dict[str, Flange] = {}
        for spec in self.flanges:
            fname, fdomain = spec[0], spec[1] or domain
            grounded = bool(spec[2]) if len(spec) > 2 else False
            self._flanges[fname] = Flange(self, fname, fdomain, grounded)
        self._expose_flanges()
        self.validate()

    # -- parameters ---------------------------------------------------------
    @classmethod
    def param_specs(cls) -> dict[str, Param]:
        """The declared parameters of the class (its own and inherited), name -> ``Param``."""
        return dict(cls._declared())

    @classmethod
    def _declared(cls) -> dict[str, Param]:
        # made once per class (walking the MRO for each of 100,000 instances cost ~1.5 s); the key is
        # checked in the class's own __dict__ so that a subclass never reads its base's entry
        specs = cls.__dict__.get("_param_specs_cache")
        if specs is None:
            specs = {}
            for klass in reversed(cls.__mro__):
                for key, val in vars(klass).items():
                    if isinstance(val, Param):
                        specs[key] = val
            type.__setattr__(cls, "_param_specs_cache", specs)
        return specs

    def validate(self) -> None:
        """Cross-parameter checks; raise ParameterError naming the component."""

    def params(self) -> dict[str, Any]:
        return dict(self._values)

    def param_unit(self, name: str) -> str:
        """SI unit of parameter ``name`` for this instance's kind of flange ("" if none is declared)."""
        spec = self.param_specs().get(name)
        if spec is None:
            raise ParameterError(f"{type(self).__name__} '{self.name}' has no parameter '{name}'; "
                                 f"it takes {list(self.param_specs())}")
        return spec.unit_in(self.domain)

    # -- units of the exported signals ---------------------------------------
    #: unit of internal states whose start value is no parameter (name -> unit); a state with a start
    #: parameter takes that parameter's unit
    state_units: ClassVar[dict[str, str]] = {}

    def signal_unit(self, var: str) -> str | None:
        """SI unit of this component's signal ``<name>.<var>`` (``var`` e.g. ``w``, ``tau``, ``w_rel``,
        ``flange_a.phi``, ``power``, an internal state): from the kind of the flange or of the component
        (``units.VARIABLE_UNITS``), energies J, powers W, modes 1, internal states from their start
        parameter or ``state_units``. None when it is none of these (a subclass exporting other signals
        overrides this)."""
        head, _, tail = var.partition(".")
        if tail:
            fl = self._flanges.get(head)
            return variable_unit(tail, fl.domain) if fl is not None else None
        if var in FIXED_UNITS:
            return FIXED_UNITS[var]
        derived = getattr(self, "derived_units", None) or {}
        if var in derived:
            return derived[var]
        states = getattr(self, "states", None) or {}
        if var in states:
            if var in self.state_units:
                return self.state_units[var]
            start = states[var]
            return (self.param_unit(start) or None) if start else None
        return variable_unit(var, self.domain)

    def _changed(self):
        if self.model is not None:
            self.model._invalidate()

    # -- flanges ------------------------------------------------------------
    def get_flange(self, name: str) -> Flange:
        try:
            return self._flanges[name]
        except KeyError:
            raise UnknownFlangeError(
                f"{type(self).__name__} '{self.name}' has no flange '{name}'; "
                f"its flanges are {sorted(self._flanges)}") from None

    def _expose_flanges(self) -> None:
        """Flanges as plain instance attributes, so ``J1.flange_a`` is found at once: reaching them
        through ``__getattr__`` costs a caught AttributeError (~2.5 us), seconds for a model of
        100,000 components. A name the class or the base's own attributes use is left to
        ``__getattr__`` (never shadowed). ``self.__dict__`` is not touched: reading it would make a
        dictionary object per instance (64 bytes and one more object for the garbage collector)."""
        cls = type(self)
        for fname, fl in self._flanges.items():
            if fname not in _OWN_ATTRIBUTES and not hasattr(cls, fname):
                object.__setattr__(self, fname, fl)

    def __getattr__(self, attr: str):
        flanges = self.__dict__.get("_flanges")
        if flanges is not None and attr in flanges:
            return flanges[attr]
        if not attr.startswith("_"):
            raise UnknownFlangeError(
                f"{type(self).__name__} '{self.__dict__.get('name', '?')}' has no flange '{attr}'; "
                f"its flanges are {sorted(flanges or {})}")
        raise AttributeError(f"{type(self).__name__} object has no attribute {attr!r}")

    @property
    def flange_list(self) -> list[Flange]:
        return list(self._flanges.values())

    def var_names(self) -> tuple[str, str, str, str]:
        return VARIABLE_NAMES[self.domain]

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self._values.items())
        return f"{type(self).__name__}({self.name!r}{', ' if args else ''}{args})"


class Body(Component):
    """A lumped mass or inertia: all its flanges share one coordinate.

    ``mass_param`` names the parameter holding J [kg m^2] or m [kg];
    ``start_params`` the (position, velocity) start values; a start value
    given (not None) is *fixed*: initialisation keeps it and adjusts the
    others. Equation: ``J a = sum of torques on the body``.
    """

    role = "body"
    mass_param: ClassVar[str] = "J"
    start_params: ClassVar[tuple[str, str]] = ("phi0", "w0")

    @property
    def mass(self) -> float:
        return self._values[self.mass_param]

    @property
    def start(self) -> tuple[float | None, float | None]:
        return self._values[self.start_params[0]], self._values[self.start_params[1]]


class Ground(Component):
    """The ground (fixed frame) at a constant position."""

    role = "ground"
    position_param: ClassVar[str] = "phi0"

    @property
    def position(self) -> float:
        return self._values[self.position_param]


class Device(Component):
    """A massless device joining masses (see module docstring)."""

    role = "device"
    kind: ClassVar[str] = "compliant"
    #: output names of (row-0 coordinate, its rate, its acceleration, force)
    #: per domain; None entries are not exported.
    rel_names: ClassVar[dict] = {
        ROTATIONAL: ("phi_rel", "w_rel", "a_rel", "tau"),
        TRANSLATIONAL: ("s_rel", "v_rel", "a_rel", "f"),
    }
    #: internal differential states: name -> name of the start parameter (or None)
    states: ClassVar[dict[str, str | None]] = {}
    #: states that are algebraic unknowns rather than differential ones: ``derivatives()`` gives for each the
    #: residual ``f - s`` of its equation ``s = f(...)`` (the compiler writes the row ``s - f = 0``, no ``s'``)
    algebraic_states: ClassVar[tuple[str, ...]] = ()
    #: states held between sample instants: name -> (input parameter, period parameter, offset parameter); the
    #: state's rate is 0 and at every instant ``offset + k * period`` it takes the input's value
    sampled_states: ClassVar[dict[str, tuple[str, str, str]]] = {}
    #: states that say which side of one of the device's switching surfaces the run is on: name -> the surface's
    #: position in ``switching_surfaces()``; the state's rate is 0 and it is 1 on the positive side, 0 on the
    #: negative one, set at every restart (a law that jumps at the surface reads it, so no step meets the jump)
    branch_states: ClassVar[dict[str, int]] = {}
    #: states with memory, changed where a switching surface becomes positive: name -> ((surface position, increment),
    #: ...); the state's rate is 0; each time surface k crosses to g > 0 (located as an event) the state grows by
    #: its increment (a relay with hysteresis, a gear selection): the surfaces are written so that the new value
    #: puts them back below zero
    #: True for devices that feed energy in (sources): the energy audit counts
    #: their absorbed power with the opposite sign, as work of the sources
    is_source: ClassVar[bool] = False

    def device_kind(self) -> str:
        """Kind of this instance (a class may decide per instance, e.g. Shaft)."""
        return self.kind

    #: the parameters that fix the start value of the device's own coordinate (row 0, ``rel = x_b - x_a``):
    #: (its position, its speed), None where the class has none. A given value is a start equation
    #: ``rel(t0) = value`` (MSL's ``phi_rel(start=..., fixed=true)``), met with the masses' own start values by
    #: the consistent start (``CompiledSystem.project``), or refused naming the device when they contradict.
    relative_start_params: ClassVar[tuple[str | None, str | None]] = (None, None)

    def relative_starts(self) -> list[tuple[int, int, float, str]]:
        """``[(level, row, value, parameter)]``: the fixed start values given for the device's coordinate
        (level 0 its position, 1 its speed; row 0)."""
        out = []
        for level, pname in enumerate(self.relative_start_params):
            if pname is not None and self._values.get(pname) is not None:
                out.append((level, 0, float(self._values[pname]), pname))
        return out

    def rows(self) -> list[dict[str, float]]:
        """Structure rows: coefficient of each flange's position in each device coordinate."""
        return [{"flange_a": -1.0, "flange_b": 1.0}]

    def row_kinds(self) -> list[str]:
        """Kind of each row (a lossy gear has a rigid row and a friction row); default: all the device's kind."""
        return [self.device_kind()] * len(self.rows())

    # -- compliant devices: symbolic laws ----------------------------------
    def law(self, rel, rel_dot):
        """Transmitted torque/force of a one-row compliant device (sympy-compatible)."""
        raise NotImplementedError(f"{type(self).__name__} must define law(rel, rel_dot) or laws(e, de)")

    def laws(self, e, de):
        """Generalised forces of all rows; default: ``[law(e[0], de[0])]``."""
        return [self.law(e[0], de[0])]

    def derivatives(self, e, de):
        """Time derivatives of the internal ``states`` (sympy-compatible)."""
        return []

    def potential(self, e):
        """Stored energy as a function of the device coordinates (0 if none)."""
        return 0

    def switching_surfaces(self, e, de):
        """The switching surfaces of a piecewise law: ``[(g, code), ...]`` (sympy-compatible, like ``laws``).

        ``g(e, de)`` is continuous and changes sign where the law changes branch (a kink or a switch of
        the force, e.g. the contact of a backlash, ``phi_diff - b/2``); ``g > 0`` on the side where the
        device is in state ``code`` (a nonzero int such as +1 for contact at the upper side, -1 at the
        lower), and a device whose surfaces are all negative is in state 0 (open). The device only
        *states* its surfaces: the hybrid layer turns them into event functions that the solvers locate
        (so no step straddles a kink) and reports each change of state in ``Result.events`` as an
        ``Event`` of kind "contact". Default: none (a smooth law)."""
        return []

    #: the ``Event`` kind of a change of state of this device's switching surfaces: "contact" (a backlash,
    #: a stop, a gap), "limit" (a controller's output reaching or leaving its limits)
    switching_kind: ClassVar[str] = "contact"

    def switching_active(self) -> bool:
        """False when this instance's law has no kink after all (a play below ``B_EPS`` is a plain spring):
        its surfaces are then not watched. Decided per instance from the parameters."""
        return True

    # -- derived outputs: signals computed from a result, never seen by the solvers --------------
    #: extra signals ``<name>.<key>`` the device exports, key -> SI unit (e.g. a motor's electrical
    #: power ``p_el`` [W]); ``derived`` computes them
    derived_units: ClassVar[dict[str, str]] = {}

    def derived(self, t, left, e, de, tau, z) -> dict:
        """The signals of ``derived_units`` over the output instants, as numpy arrays.

        ``t`` (T,) the times, ``left`` (T,) bool: the row is the left limit at a time event (read a
        signal there with ``sig.value(t, left)``); ``e``, ``de``, ``tau`` lists (one (T,) array per row) of the device
        coordinates, their rates and the row forces; ``z`` the internal states, name -> (T,) array.
        Computed per instance after the run (numpy, tables and signals allowed): quantities that feed
        nothing back into the motion, such as the electrical power of a motor from its efficiency map.
        """
        return {}


class Subsystem(Component):
    """A reusable assembly of components with exposed flanges (a Modelica sub-model).

    Subclasses declare ``Param`` attributes and implement ``build(self)``, in
    which ``self.part(component)`` adds a part (named locally) and
    ``self.link(a, b)`` connects two of its flanges; ``ports`` maps each
    exposed flange name to ``"part.flange"``. Added to a model, the parts
    become ``"<subsystem>.<part>"`` (so results read ``res["wheel.tyre.f"]``)
    and the subsystem's flanges *are* the parts' flanges.
    """

    role = "subsystem"
    ports: ClassVar[dict[str, str]] = {}

    def __init__(self, name: str, **params):
        super().__init__(name, **params)
        self.parts: dict[str, Component] = {}
        self.links: list[tuple] = []
        self.build()
        for port, target in self.ports.items():
            pname, _, fname = target.partition(".")
            if pname not in self.parts:
                raise ParameterError(f"{type(self).__name__} '{name}': port '{port}' refers to unknown part '{pname}'")
            self._flanges[port] = self.parts[pname].get_flange(fname)
        self._expose_flanges()

    def build(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def part(self, component: Component) -> Component:
        if component.name in self.parts:
            raise ParameterError(f"{type(self).__name__} '{self.name}': two parts named '{component.name}'")
        self.parts[component.name] = component
        return component

    def link(self, a: Flange, b: Flange) -> None:
        self.links.append((a, b))


def bound_value(comp: Component, name: str):
    """Numeric value of a parameter or a Signal (callers evaluate signals)."""
    return comp._values[name]


def signal_params(cls) -> list[str]:
    return [n for n, p in cls.param_specs().items() if p.check == "signal"]


def numeric_params(cls) -> list[str]:
    return [n for n, p in cls.param_specs().items()
            if p.check in ("real", "positive", "nonnegative", "nonzero")]


__all__ = ["Param", "Command", "StateRead", "Component", "Body", "Ground", "Device", "Subsystem", "REQUIRED", "Signal", "read_only",
           "ROTATIONAL", "TRANSLATIONAL"]
