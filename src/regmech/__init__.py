"""regmech: dynamics of drivetrains and other regular mechanical systems.

>>> import regmech as rm
>>> from regmech.components import Fixed, Inertia, Spring, Torque
>>> m = rm.Model("two_inertias")
"""

from . import signals
from .component import Body, Component, Device, Ground, Param, Subsystem
from .errors import (AccuracyError, ChatteringError, ModelError, ParameterError, RegmechError, RegularityError,
                     RegularityWarning, SimulationError, SimulationTimeout, StructureError,
                     UnknownFlangeError, UnknownSignalError)
from .model import Model
from .io import load_result
from .result import Event, Result, Stats
from .scene import Scene

__version__ = "0.1.0"

__all__ = [
    "Model", "Scene", "Result", "Event", "Stats", "signals", "load_result",
    "Component", "Body", "Ground", "Device", "Param", "Subsystem",
    "RegmechError", "ParameterError", "ModelError", "UnknownFlangeError", "RegularityError",
    "UnknownSignalError", "StructureError", "SimulationError", "SimulationTimeout", "ChatteringError",
    "AccuracyError", "RegularityWarning",
]


def __getattr__(name):
    # heavier sub-packages load on first use
    if name in ("analysis", "components", "solvers", "structure", "compile", "bench", "library"):
        import importlib
        return importlib.import_module(f".{name}", __name__)
    if name in ("sweep", "latin_hypercube", "scatter", "grid"):
        # regmech.sweep is a callable module (rm.sweep(...) runs a study), the helpers live in it
        import importlib
        module = importlib.import_module(".sweep", __name__)
        return module if name == "sweep" else getattr(module, name)
    raise AttributeError(f"module 'regmech' has no attribute {name!r}")
