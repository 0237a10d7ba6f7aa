"""Ready-made models and scenes (each uses only the public API).

``regmech.library.first()`` builds MSL's Rotational.Examples.First, and so on;
``SCENES`` maps scene names to builder functions.
"""

from .msl import coupled_clutches, first

SCENES = {
    "first": first,
}

try:
    SCENES["coupled_clutches"] = coupled_clutches
except NameError:  # pragma: no cover
    pass

__all__ = ["SCENES", "first", "coupled_clutches"]
