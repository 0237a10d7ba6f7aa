"""The base of causal blocks: outputs as unknowns of the DAE, inputs as signal parameters.

A block is a massless compliant ``Device`` that exerts no force: its rows (a sensor's) have the law 0, so it
absorbs no power and changes no motion. Each output ``o`` is one of its states, listed in
``Device.algebraic_states``: the compiler adds the unknown ``o`` and the row ``o - f_o(...) = 0``, where
``f_o`` (``output_laws``) is written with sympy from the block's rows ``e``/``de``, its other states, its
parameters and its inputs. An output with its own dynamics (a ``Lag``'s) is a differential state instead,
``do/dt = rate`` (``dynamic_outputs``). An input is a signal parameter: a number, a ``Signal``, a callable of
``t`` or another block's output ``<block>.y`` (a ``component.StateRead``), read from the unknowns by the
compiler (``compile.reads``); so is every signal parameter of every other component (``DCMotor(u=pi.y)``).

Discontinuities, chosen per block:

* kinks of a continuous output (``Saturation``, the limits of ``PI``/``PID``, ``Min``/``Max``): switching
  surfaces (``switching_surfaces``), located as events (kind "limit") where the solver restarts; the law
  itself is evaluated on both sides (it is continuous);
* jumps (``Compare``, ``Switch``, the stops of a limited ``Integrator``): the branch is a state of rate 0
  (``Device.branch_states``) set at every restart from the side of its surface, so no step meets the jump
  (events of kind "switch"/"limit");
* memory (``Hysteresis``, ``ShiftSchedule``): a latch state (``Device.latch_states``) that changes where its
  surface becomes positive (events of kind "latch");
* sampling (``SampleHold``): time events at the sample instants, where the held state takes its input;
* kinks of a ``Table1D``: left to the step-size control (the output is continuous).

An algebraic loop (outputs that depend on each other at the same instant through direct feedthrough) is
refused by name when the model is compiled (``compile.reads``); a ``Lag``, ``Integrator`` or ``SampleHold``
in the loop breaks it. The models with blocks run on IDA's Python path (``solvers.ida``); explicit and expm
solvers refuse them by name.
"""

from __future__ import annotations

from typing import ClassVar

import sympy

from ..component import Device, Param, StateRead
from ..errors import ParameterError
from ..ports import ROTATIONAL, TRANSLATIONAL

#: a limit left open (None) is held as this value: finite, so the switching surfaces stay finite numbers
OPEN = 1e300


class Output:
    """Descriptor of a block output: ``block.<name>`` is a ``StateRead`` of the output, to give to any
    parameter that takes a signal."""

    def __init__(self, unit: str = ""):
        self.unit = unit
        self.name = "?"

    def __set_name__(self, owner, name):
        self.name = name

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        unit = obj.output_unit(self.name) if hasattr(obj, "output_unit") else self.unit
        return StateRead(obj, self.name, unit)


def Input(unit: str = "", doc: str = "", default=None):
    """A block input: a signal parameter (number, Signal, f(t) or a block output); None means unconnected."""
    return Param(default, check="signal", optional=True, unit=unit, doc=doc)


def clip(v, lo, hi):
    """``min(max(v, lo), hi)`` as a ``Piecewise`` (exact, and finite with ``lo``/``hi`` = -/+ ``OPEN``)."""
    return sympy.Piecewise((hi, v > hi), (lo, v < lo), (v, True))


class Block(Device):
    """Base of causal blocks (see the module docstring).

    Subclasses declare ``outputs`` (name -> unit, algebraic), ``dynamic_outputs`` (name -> start parameter,
    differential), ``internal`` (name -> start parameter, differential states) and write
    ``output_laws(e, de)`` (output name -> expression) and ``rates(e, de)`` (name -> rate of each
    differential state). Inputs are ``Input`` parameters; outputs ``Output`` attributes.
    """

    kind = "compliant"
    flanges = ()
    rel_names = {ROTATIONAL: (None, None, None, None), TRANSLATIONAL: (None, None, None, None)}
    #: algebraic outputs: name -> unit
    outputs: ClassVar[dict[str, str]] = {}
    #: differential outputs: name -> start parameter
    dynamic_outputs: ClassVar[dict[str, str | None]] = {}
    #: internal differential states: name -> start parameter
    internal: ClassVar[dict[str, str | None]] = {}
    switching_kind = "limit"

    def __init_subclass__(cls, **kwargs):
        cls.states = {**cls.internal, **cls.dynamic_outputs, **{o: None for o in cls.outputs}}
        cls.algebraic_states = tuple(cls.outputs)
        for name in list(cls.outputs) + list(cls.dynamic_outputs):
            if not isinstance(cls.__dict__.get(name), Output):
                out = Output(cls.outputs.get(name, ""))
                out.__set_name__(cls, name)
                setattr(cls, name, out)
        cls.state_units = {**getattr(cls, "state_units", {}), **{o: u for o, u in cls.outputs.items() if u}}
        super().__init_subclass__(**kwargs)

    def validate(self):
        for name, spec in self.param_specs().items():
            if spec.check == "signal" and self._values.get(name) is None:
                raise ParameterError(
                    f"{type(self).__name__} '{self.name}': input '{name}' is not connected; give it "
                    f"{name}=<block>.y (another block's output), a number or a signal")
        self.check_block()

    def check_block(self) -> None:
        """Cross-parameter checks of a subclass (ParameterError naming the block and the fix)."""

    def output_unit(self, name: str) -> str:
        return type(self).outputs.get(name, "")

    # -- the device -------------------------------------------------------------------------------
    def rows(self):
        return []

    def laws(self, e, de):
        return [0] * len(e)

    def output_laws(self, e, de) -> dict:
        raise NotImplementedError

    def rates(self, e, de) -> dict:
        return {}

    def derivatives(self, e, de):
        # ``self`` is the compiler's symbolic stand-in here: class attributes are read through it
        outputs = self.outputs
        rates = self.rates(e, de)
        outs = self.output_laws(e, de) if outputs else {}
        res = []
        for s in self.states:
            if s in outputs:
                res.append(outs[s] - getattr(self, s))          # algebraic: the residual f - s
            else:
                res.append(rates[s])
        return res


class Sensor(Block):
    """A block reading a flange: one row ``e = x(flange) - x(flange_ref)`` with law 0 (``flange_ref``
    grounded when free), ``de`` its rate."""

    flanges = (("flange", None), ("flange_ref", None, True))

    def rows(self):
        return [{"flange": 1.0, "flange_ref": -1.0}]


__all__ = ["Block", "Sensor", "Input", "Output", "OPEN", "clip"]
