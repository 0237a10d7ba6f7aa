"""``FrictionSet``: the compiled friction rows with their mode logic, as every solver drives them."""

from __future__ import annotations

from ..compile.friction_rows import FrictionRows
from .chatter import ChatterGuard
from .events import EventFunctions
from .gears import GearSides
from .holding import Holding
from .impacts import Impacts
from .logic import ModeLogic


class FrictionSet(ModeLogic, EventFunctions, Holding, Impacts, GearSides, FrictionRows):
    """All friction rows of a compiled system with their event functions and mode logic.

    The rows' equations (residual, Jacobian weights, KKT relations) are ``FrictionRows``
    (``compile``); this class adds what a solver needs at and between events: ``event_values``
    (``events``), ``settle`` (``logic``, with ``holding`` and ``gears``) and ``chatter_guard``.
    Made from the compiled rows by ``attach``; it shares their state.
    """

    @classmethod
    def from_rows(cls, rows: FrictionRows) -> "FrictionSet":
        fs = cls.__new__(cls)
        fs.__dict__.update(rows.__dict__)
        fs._setup_impacts()
        fs._setup_events()
        fs._flips = set()
        fs._law_memo = {}         # ModeLogic._law (per settle)
        return fs

    def chatter_guard(self, window=None, count=50, solver=None):
        return ChatterGuard(1e-6 if window is None else window, count, self.devices, solver)
