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
    """A fixed-step run whose estimated global error exceeds its tolerance ``tol``
    (``regmech.solvers.richardson``): the answer would be wrong, so none is returned."""


class RegularityWarning(UserWarning):
    """Legal but questionable model (e.g. a stretched spectrum, Position 2)."""
