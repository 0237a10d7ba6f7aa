"""Friction laws for the friction devices (``Clutch``, ``Brake``, ``OneWayClutch``,
``FrictionContact``, ``LinearBrake``): ``mu_law=Stribeck(...)``.

A law is a small object with ``mu(w) -> (mu, d mu / d w)`` for the relative speed ``w >= 0``
(rad/s, or m/s for a translational device). The friction devices call it where they would
interpolate ``mu_table``: the kinetic torque is ``mu(|w_rel|) * cgeo * fn`` and the stuck device
breaks away at ``peak * mu(0) * cgeo * fn``.

Why a closed form: the Stribeck curve as a ``mu_table`` needs many points to look smooth, and
every point is a kink the integrator has to step through (measured: a 4,001-point table ran
at 5.3 s against 1.2 s for 50 points at rtol 1e-8). The closed form is smooth for ``w > 0``.
"""

from __future__ import annotations

import math

from .._numbers import as_real
from ..errors import ParameterError


class FrictionLaw:
    """Base of the friction laws: ``mu(w_abs) -> (mu, dmu/dw)`` for ``w_abs >= 0``."""

    def mu(self, w_abs: float) -> tuple[float, float]:  # pragma: no cover - abstract
        raise NotImplementedError


def _number(name: str, value, check: str) -> float:
    x = as_real(value)
    ok = x is not None and math.isfinite(x) and {"nonnegative": x is not None and x >= 0,
                                                  "positive": x is not None and x > 0,
                                                  "exponent": x is not None and 1 <= x <= 8}[check]
    if not ok:
        want = {"nonnegative": "a finite number >= 0", "positive": "a finite number > 0",
                "exponent": "a number in [1, 8]"}[check]
        raise ParameterError(f"Stribeck: parameter '{name}' must be {want}, got {value!r}")
    return float(x)


class Stribeck(FrictionLaw):
    """Stribeck friction: exponential decay from static to kinetic friction plus a viscous part::

        mu(w) = mu_k + (mu_s - mu_k) * exp(-(w / w_s)^delta) + mu_v * w       (w = |w_rel| >= 0)

    ``mu_s`` static coefficient (at w = 0) [-], ``mu_k`` kinetic (Coulomb) coefficient [-],
    ``w_s`` Stribeck speed [rad/s or m/s] > 0 (where the excess has fallen to 1/e),
    ``mu_v`` viscous coefficient [s/rad or s/m] >= 0, ``delta`` shape exponent in [1, 8]
    (1 exponential, 2 Gaussian). With ``mu_s > mu_k`` the friction falls after break-away, so a
    device that has broken loose accelerates away (the stick-slip of a drive with a Stribeck
    characteristic). Use it with ``peak = 1``: the break-away coefficient is ``mu(0) = mu_s``.
    """

    def __init__(self, mu_s: float, mu_k: float, w_s: float, mu_v: float = 0.0, delta: float = 1.0):
        self.mu_s = _number("mu_s", mu_s, "nonnegative")
        self.mu_k = _number("mu_k", mu_k, "nonnegative")
        self.w_s = _number("w_s", w_s, "positive")
        self.mu_v = _number("mu_v", mu_v, "nonnegative")
        self.delta = _number("delta", delta, "exponent")
        if self.w_s < 1e-300:
            raise ParameterError(f"Stribeck: w_s = {w_s!r} is too small to divide by; give a realistic Stribeck speed")

    def mu(self, w_abs: float) -> tuple[float, float]:
        x = w_abs / self.w_s
        decay = math.exp(-(x ** self.delta))
        mu = self.mu_k + (self.mu_s - self.mu_k) * decay + self.mu_v * w_abs
        if self.delta == 1.0:
            dx = 1.0
        else:
            dx = self.delta * x ** (self.delta - 1.0)
        dmu = -(self.mu_s - self.mu_k) * decay * dx / self.w_s + self.mu_v
        return mu, dmu

    def __repr__(self) -> str:
        return (f"Stribeck(mu_s={self.mu_s!r}, mu_k={self.mu_k!r}, w_s={self.w_s!r}, mu_v={self.mu_v!r}, "
                f"delta={self.delta!r})")

    def __eq__(self, other) -> bool:
        return type(other) is type(self) and vars(self) == vars(other)

    __hash__ = None


__all__ = ["FrictionLaw", "Stribeck"]
