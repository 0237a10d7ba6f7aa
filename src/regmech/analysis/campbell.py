"""Campbell diagram: natural frequencies and engine orders against speed.

An engine running at ``n`` [rpm] excites order ``k`` at ``f = k n / 60``
[Hz]; where that ray meets a natural frequency ``f_i`` the order drives mode
``i`` at resonance, at the speed

    n_ki = 60 f_i / k   [rpm].

``campbell(modes, orders, speed_rpm)`` finds these crossings. ``modes`` is a
``ModalResult`` (its elastic modes), an array of natural frequencies [Hz],
or, for natural frequencies that change with speed (a centrifugal pendulum,
a speed-dependent stiffness), a callable ``f(speed_rpm)`` returning either;
then the frequencies are evaluated on the speed grid and the crossings found
between grid points by linear interpolation.

The abscissa may be any shaft's speed: ``shaft="gearbox output"`` with
``ratio`` its speed per engine speed (the orders stay engine orders, so the
rays are ``f = k n_shaft / (60 ratio)`` and the resonance speeds are the
shaft's). ``operating_rpm`` (in that shaft's speed) marks the operating
point: a vertical line, and the excitation frequencies of the orders there.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError
from .table import Table


@dataclass
class CampbellDiagram:
    """``speeds_rpm`` (grid), ``natural_hz`` (grid x modes, [Hz]; the mode numbers in ``mode_numbers``),
    ``orders``, ``crossings`` (list of ``(order, mode number, frequency [Hz], speed [rpm])``).
    ``table()``, ``plot(path=None)``."""

    speeds_rpm: np.ndarray
    natural_hz: np.ndarray
    mode_numbers: list
    orders: np.ndarray
    crossings: list = field(default_factory=list)
    model_name: str = ""
    #: the shaft whose speed is the abscissa, and its speed per engine speed (the orders' reference)
    shaft: str = "engine"
    ratio: float = 1.0
    #: the operating point [rpm of ``shaft``], or None
    operating_rpm: float | None = None

    def order_hz(self, order: float, speed_rpm):
        """Frequency [Hz] of engine order ``order`` at ``speed_rpm`` of the abscissa's shaft: ``k n / (60 ratio)``."""
        return order * np.asarray(speed_rpm, float) / (60.0 * self.ratio)

    def operating_point(self) -> list:
        """``(order, frequency [Hz])`` of every order at the operating point (empty without one)."""
        if self.operating_rpm is None:
            return []
        return [(float(k), float(self.order_hz(k, self.operating_rpm))) for k in self.orders]

    def table(self) -> Table:
        data = np.array([[o, m, f, n] for o, m, f, n in self.crossings], float).reshape(-1, 4)
        return Table(data, [f"order {o:g} x mode {m}" for o, m, _, _ in self.crossings],
                     ["order", "mode", "f [Hz]", "speed [rpm]"], title="resonance speeds (order meets mode)",
                     index_name="crossing")

    def __str__(self) -> str:
        return str(self.table())

    def plot(self, path=None, ax=None):
        """Natural frequencies (horizontal lines, labelled with mode number and frequency), the order rays
        ``f = k n / 60`` (labelled ``order k``) and the crossings (circles, with their speed in rpm), against
        speed [rpm] and frequency [Hz]. Returns the figure."""
        from .plots import plot_campbell
        return plot_campbell(self, path=path, ax=ax)


def _frequencies(modes) -> tuple[np.ndarray, list]:
    """Elastic natural frequencies [Hz] and their mode numbers from a ModalResult or an array."""
    if hasattr(modes, "frequencies_hz") and hasattr(modes, "rigid"):
        f = np.asarray(modes.frequencies_hz, float)
        keep = ~np.asarray(modes.rigid, bool)
        return f[keep], [int(i) + 1 for i in np.nonzero(keep)[0]]
    try:
        f = np.atleast_1d(np.asarray(modes, float))
    except (TypeError, ValueError):
        raise ParameterError(f"campbell: modes must be a ModalResult, natural frequencies [Hz] or a callable "
                             f"speed_rpm -> either; got {type(modes).__name__}") from None
    if f.ndim != 1 or not np.all(np.isfinite(f)) or np.any(f < 0):
        raise ParameterError("campbell: natural frequencies must be finite and >= 0 [Hz]")
    keep = f > 0
    return f[keep], [int(i) + 1 for i in np.nonzero(keep)[0]]


def _orders(orders) -> np.ndarray:
    try:
        items = np.ravel(orders).tolist() if isinstance(orders, np.ndarray) else (
            [orders] if np.isscalar(orders) else list(orders))
        return np.array([o[0] if isinstance(o, (tuple, list)) else o for o in items], float)
    except (TypeError, ValueError, IndexError):
        return np.array([np.nan])


def campbell(modes, orders, speed_rpm=(500.0, 6000.0), n_speeds: int = 200, model_name: str = "", *,
             shaft: str = "engine", ratio: float = 1.0, operating_rpm=None) -> CampbellDiagram:
    """Campbell diagram of ``modes`` (see the module docstring) and engine ``orders`` (numbers, or
    ``(order, amplitude, phase)`` tuples as ``order_sweep`` takes them) over ``speed_rpm`` (``(low, high)``
    [rpm] or the grid itself) of the shaft ``shaft``, whose speed is ``ratio`` times the engine's (a callable
    ``modes`` is called with that shaft's speed); ``operating_rpm`` marks the operating point."""
    if isinstance(ratio, bool) or not isinstance(ratio, (int, float, np.floating)) or not np.isfinite(ratio) \
            or ratio == 0:
        raise ParameterError(f"campbell: ratio is the shaft's speed per engine speed, a finite non-zero number "
                             f"(a gear ratio's inverse), got {ratio!r}")
    ratio = abs(float(ratio))
    if operating_rpm is not None and (isinstance(operating_rpm, bool) or not isinstance(
            operating_rpm, (int, float, np.floating)) or not np.isfinite(operating_rpm) or operating_rpm < 0):
        raise ParameterError(f"campbell: operating_rpm is the operating speed of shaft '{shaft}' [rpm], a finite "
                             f"number >= 0, got {operating_rpm!r}")
    ords = _orders(orders)
    if ords.size == 0 or not np.all(np.isfinite(ords)) or np.any(ords <= 0):
        raise ParameterError(f"campbell: orders must be positive numbers (e.g. [1, 2, 4]), got {orders!r}")
    grid = np.asarray(speed_rpm, float).ravel()
    if grid.size == 2:
        grid = np.linspace(grid[0], grid[1], max(2, int(n_speeds)))
    if grid.size < 2 or not np.all(np.isfinite(grid)) or np.any(grid < 0) or np.any(np.diff(grid) <= 0):
        raise ParameterError("campbell: speed_rpm is (low, high) with 0 <= low < high [rpm], or an increasing grid")
    if callable(modes) and not hasattr(modes, "frequencies_hz"):
        rows = [_frequencies(modes(float(s))) for s in grid]
        numbers = rows[0][1]
        if any(r[1] != numbers for r in rows):
            raise ParameterError("campbell: the callable must return the same elastic modes at every speed "
                                 "(their count changed along the grid)")
        nat = np.array([r[0] for r in rows]).reshape(len(grid), len(numbers))
    else:
        f, numbers = _frequencies(modes)
        nat = np.tile(f, (len(grid), 1))
    crossings = []
    for k in ords:
        ray = k * grid / (60.0 * ratio)
        for j, m in enumerate(numbers):
            g = ray - nat[:, j]
            for i in np.nonzero((g[:-1] <= 0) & (g[1:] > 0) | (g[:-1] < 0) & (g[1:] >= 0))[0]:
                w = -g[i] / (g[i + 1] - g[i])
                n = grid[i] + w * (grid[i + 1] - grid[i])
                crossings.append((float(k), m, float(k * n / (60.0 * ratio)), float(n)))
    crossings.sort(key=lambda c: c[3])
    return CampbellDiagram(grid, nat, numbers, ords, crossings, model_name, str(shaft), ratio,
                           None if operating_rpm is None else float(operating_rpm))
