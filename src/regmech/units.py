"""Units of signals and parameters, and the display units a result converts to.

Every value inside regmech is SI. A signal's SI unit follows from what it
is: the across and flow variables of its flange kind (rotational ``phi``
[rad], ``w`` [rad/s], ``a`` [rad/s^2], ``tau`` [N m]; translational ``s``
[m], ``v`` [m/s], ``a`` [m/s^2], ``f`` [N]; the ``_rel`` versions of
devices alike), energies [J], powers [W], modes [1] (a dimensionless code),
and a device's internal states the unit of their start parameter
(``Component.signal_unit``). ``res.unit(name)`` returns it.

Display units are conversions on the way out only (``res.get(name,
unit="rpm")``, ``res.to_dataframe(units=...)``, ``res.to_csv(...,
units=...)``, ``res.plot(..., units=...)``). ``DISPLAY_UNITS`` lists, per
SI unit, the display units and their size in SI (``value_display =
value_SI / size``):

==========  ==========================================================
SI unit     display units (size in SI)
==========  ==========================================================
rad         deg (pi/180), rev (2 pi), mrad (1e-3)
rad/s       rpm (2 pi/60), deg/s (pi/180), rev/s (2 pi)
rad/s^2     deg/s^2 (pi/180), rpm/s (2 pi/60)
N m         kN m (1e3), N mm (1e-3)
m           mm (1e-3), cm (1e-2), km (1e3)
m/s         km/h (1/3.6), mm/s (1e-3)
m/s^2       g (9.80665), mm/s^2 (1e-3)
N           kN (1e3)
J           kJ (1e3), MJ (1e6), Wh (3600)
W           kW (1e3), hp (745.7, mechanical horsepower)
s           ms (1e-3)
==========  ==========================================================

Every SI unit is also its own display unit. Spelling variants are accepted
(``Nm``, ``N*m``, ``N.m`` for ``N m``; ``1/min`` and ``rev/min`` for
``rpm``; ``kph`` for ``km/h``; ``degree`` for ``deg``). A unit that does not
fit the signal is a ``ParameterError`` naming the signal, its unit and the
choices.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import ParameterError
from .ports import ROTATIONAL, TRANSLATIONAL

#: SI unit of the across variable, its derivatives and the flow variable, per flange kind
VARIABLE_UNITS = {
    ROTATIONAL: {"phi": "rad", "w": "rad/s", "a": "rad/s^2", "tau": "N m"},
    TRANSLATIONAL: {"s": "m", "v": "m/s", "a": "m/s^2", "f": "N"},
}
#: signals every component may export whose unit does not depend on the flange kind
FIXED_UNITS = {"kinetic": "J", "potential": "J", "power": "W", "mode": "1"}
#: a rotational unit and its translational counterpart: the units of a parameter of a class whose
#: domain is chosen per instance (``Spring(..., domain="translational")``: c in N/m instead of N m/rad)
TRANSLATIONAL_OF = {"rad": "m", "rad/s": "m/s", "rad/s^2": "m/s^2", "N m": "N", "N m/rad": "N/m",
                    "N m s/rad": "N s/m", "kg m^2": "kg"}

#: display units per SI unit: name -> size in SI (value shown = value in SI / size)
DISPLAY_UNITS: dict[str, dict[str, float]] = {
    "rad": {"rad": 1.0, "deg": math.pi / 180, "rev": 2 * math.pi, "mrad": 1e-3},
    "rad/s": {"rad/s": 1.0, "rpm": 2 * math.pi / 60, "deg/s": math.pi / 180, "rev/s": 2 * math.pi},
    "rad/s^2": {"rad/s^2": 1.0, "deg/s^2": math.pi / 180, "rpm/s": 2 * math.pi / 60},
    "N m": {"N m": 1.0, "kN m": 1e3, "N mm": 1e-3},
    "m": {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "km": 1e3},
    "m/s": {"m/s": 1.0, "km/h": 1 / 3.6, "mm/s": 1e-3},
    "m/s^2": {"m/s^2": 1.0, "g": 9.80665, "mm/s^2": 1e-3},
    "N": {"N": 1.0, "kN": 1e3},
    "J": {"J": 1.0, "kJ": 1e3, "MJ": 1e6, "Wh": 3600.0},
    "W": {"W": 1.0, "kW": 1e3, "hp": 745.69987158227022},
    "s": {"s": 1.0, "ms": 1e-3},
    "A": {"A": 1.0, "kA": 1e3, "mA": 1e-3},
    "V": {"V": 1.0, "kV": 1e3, "mV": 1e-3},
    "K": {"K": 1.0},          # temperatures (a thermal mass's T): display units are scalings, so no deg C
}
#: what a signal of each SI unit is, for axis labels ("speed [rpm]")
QUANTITIES = {"rad": "angle", "rad/s": "speed", "rad/s^2": "angular acceleration", "N m": "torque",
              "m": "position", "m/s": "velocity", "m/s^2": "acceleration", "N": "force", "J": "energy",
              "W": "power", "1": "mode", "A": "current", "V": "voltage", "s": "time", "K": "temperature"}
#: accepted spellings of the display units above
ALIASES = {"Nm": "N m", "N*m": "N m", "N.m": "N m", "kNm": "kN m", "kN*m": "kN m", "kN.m": "kN m",
           "Nmm": "N mm", "1/min": "rpm", "rev/min": "rpm", "RPM": "rpm", "kph": "km/h", "km/hr": "km/h",
           "degree": "deg", "degrees": "deg", "°": "deg", "deg/sec": "deg/s", "kgm^2": "kg m^2",
           "rad/s2": "rad/s^2", "m/s2": "m/s^2", "m/s**2": "m/s^2", "rad/s**2": "rad/s^2"}


def variable_unit(var: str, domain: str) -> str | None:
    """SI unit of a flange variable or a device's relative variable (``phi``, ``w_rel``, ``f``, ...).

    The name tells the kind where it can (``phi``/``w``/``tau`` rotational, ``s``/``v``/``f``
    translational, so a wheel contact on a rotational flange still exports its force ``f`` in N); an
    acceleration ``a`` takes the kind of ``domain``. None when the name is none of these.
    """
    base = var[:-4] if var.endswith("_rel") else var
    for dom in (ROTATIONAL, TRANSLATIONAL):
        if base != "a" and base in VARIABLE_UNITS[dom]:
            return VARIABLE_UNITS[dom][base]
    if base == "a":
        return VARIABLE_UNITS[domain]["a"]
    return None


#: the rotational unit of each translational one (a class written for translational flanges, such as
#: ``ElastoGap``, read with ``domain="rotational"``)
ROTATIONAL_OF = {v: k for k, v in TRANSLATIONAL_OF.items()}


def in_domain(unit: str, domain: str) -> str:
    """A parameter unit written for the other kind of flange, in ``domain`` (``N m/rad`` <-> ``N/m``)."""
    if domain == TRANSLATIONAL:
        return TRANSLATIONAL_OF.get(unit, unit)
    return ROTATIONAL_OF.get(unit, unit)


def normalise(unit: str) -> str:
    """The canonical spelling of a unit (``"Nm"`` -> ``"N m"``; blanks collapsed)."""
    if not isinstance(unit, str):
        return unit
    u = " ".join(unit.split())
    return ALIASES.get(u, u)


def choices(si_unit: str | None) -> list[str]:
    """The display units a signal of SI unit ``si_unit`` converts to (the SI unit first)."""
    if si_unit in DISPLAY_UNITS:
        return list(DISPLAY_UNITS[si_unit])
    return [si_unit] if si_unit else []


def factor(si_unit: str | None, display: str, signal: str = "") -> float:
    """Size of one ``display`` unit in ``si_unit`` (value_display = value_SI / factor).

    ``ParameterError`` naming ``signal``, its unit and the compatible choices when ``display`` does not
    fit (or is not in ``DISPLAY_UNITS``).
    """
    if not isinstance(display, str):
        raise ParameterError(f"{('signal ' + repr(signal)) if signal else 'a value'}: a display unit is a str such "
                             f"as 'rpm' (regmech.units.DISPLAY_UNITS), got {display!r}")
    want = normalise(display)
    if si_unit is not None and want == si_unit:
        return 1.0
    table = DISPLAY_UNITS.get(si_unit or "", {})
    if isinstance(want, str) and want in table:
        return table[want]
    what = f"signal '{signal}'" if signal else "the value"
    if si_unit is None:
        raise ParameterError(f"{what} has no known unit (its component does not declare one), so it cannot be "
                             f"shown in {display!r}; read it in SI")
    ok = choices(si_unit)
    other = [si for si, tab in DISPLAY_UNITS.items() if want in tab]
    hint = f" ({display!r} is a unit of {other[0]} signals)" if other else ""
    raise ParameterError(f"{what} is in {si_unit}, which cannot be shown in {display!r}{hint}; choose one of "
                         f"{', '.join(repr(c) for c in ok)} (regmech.units.DISPLAY_UNITS)")


def convert(values, si_unit: str | None, display: str, signal: str = ""):
    """``values`` in SI shown in ``display`` (see ``factor``)."""
    f = factor(si_unit, display, signal)
    return np.asarray(values, float) / f if f != 1.0 else np.asarray(values, float)


def signal_unit(components: dict, name: str) -> str | None:
    """SI unit of signal ``name`` of a model with ``components`` (name -> component): the longest
    component name that ``name`` starts with (``"wheel.J.w"``: part ``wheel.J``, signal ``w``) answers
    through ``Component.signal_unit``; None if no component or no unit is found."""
    parts = name.split(".")
    for i in range(len(parts) - 1, 0, -1):
        comp = components.get(".".join(parts[:i]))
        if comp is not None:
            return comp.signal_unit(".".join(parts[i:]))
    return None


def label(name: str, unit: str | None) -> str:
    """``"name [unit]"``; the bare name when dimensionless (1) or unknown."""
    return f"{name} [{unit}]" if unit and unit != "1" else name
