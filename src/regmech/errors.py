"""Errors and warnings of regmech.

Every error names the component(s) involved and says how to fix the model;
nothing in regmech returns NaNs silently.
"""


class RegmechError(Exception):
    """Base class of every error raised by regmech."""


class ParameterError(RegmechError, ValueError):
    """A component parameter is missing, of the wrong type or out of range."""


class ModelError(RegmechError):
    """The model is assembled wrongly (names, flanges, connections)."""


class UnknownFlangeError(ModelError, AttributeError):
    """A flange (or attribute) that the component does not have."""


class UnknownSignalError(RegmechError, KeyError):
    """A signal name that a ``Result`` does not have (also a ``KeyError``, as a missing key of a mapping is)."""

    def __str__(self):
        # KeyError's str() is the repr of its argument (quotes, escaped newlines): show the message as written
        return str(self.args[0]) if self.args else ""


class RegularityError(ModelError):
    """The model breaks a rule of the regular mechanical system."""


class StructureError(ModelError):
    """Structurally or numerically singular, over- or under-determined equations."""


class SimulationError(RegmechError):
    """A solver failed, or the solution stopped being trustworthy."""


class ChatteringError(SimulationError):
    """A variable-structure device changed mode too often in a short time."""


class SimulationTimeout(SimulationError):
    """A run stopped by its wall-clock limit (``simulate(..., timeout_s=...)``, ``sweep(..., timeout_s=...)``)."""


class AccuracyError(SimulationError):
    """A run whose estimated global error exceeds the accuracy asked for (``accuracy=``, or ``tol`` of a
    fixed-step solver): the answer would be wrong, so none is returned.

    Besides the message, the refusal carries what a program needs to react (each None when not known):
    ``signal`` and ``component`` (the worst signal and its component), ``estimate`` (its estimated error
    relative to the range of the signals of its kind), ``t`` [s] (where), ``accuracy`` (the bound asked
    for) and ``suggested_h`` [s] (a fixed step expected to meet it; ``regmech.solvers.richardson``).
    """

    FIELDS = ("signal", "component", "estimate", "t", "accuracy", "suggested_h")

    def __init__(self, message="", **fields):
        unknown = set(fields) - set(self.FIELDS)
        if unknown:
            raise TypeError(f"AccuracyError: unknown fields {sorted(unknown)}")
        super().__init__(message)
        for name in self.FIELDS:
            setattr(self, name, fields.get(name))

    def fields(self) -> dict:
        return {name: getattr(self, name) for name in self.FIELDS}

    def __reduce__(self):
        # keep the fields across pickling (parallel sweeps send errors between processes)
        return (_rebuild_accuracy_error, (type(self), str(self), self.fields()))


def _rebuild_accuracy_error(cls, message, fields):
    return cls(message, **fields)


class RegularityWarning(UserWarning):
    """Legal but questionable model (e.g. a stretched spectrum, Position 2)."""
