"""Analyses of the structural-matrix form ``M q'' + B q' + C q = W u`` (``Model.linearize``).

* ``modal(lin, k=None, sigma=0.0)``: natural frequencies [Hz], mass-normalised
  mode shapes, damped eigenvalues and damping ratios (``.damped``), shapes per
  mass (``.table()``);
* ``sensitivities(modal_result)``: d f / d p for every inertia and stiffness;
* ``harmonic_response(lin, outputs, freqs_hz, inputs)``: amplitude and phase;
  ``multi_harmonic_response`` and ``order_sweep`` for engine-order spectra;
* ``campbell(modes, orders, speed_rpm)``: natural frequencies and engine orders against speed,
  the resonance speeds where they cross (``ModalResult.campbell``, ``OrderSweep.campbell``);
* ``Table``: the labelled tables these return (``.to_dataframe()`` with pandas).
"""

from .campbell import CampbellDiagram, campbell
from .harmonic import (FrequencyResponse, MultiHarmonicResponse, OrderSweep, harmonic_response,
                       multi_harmonic_response, order_sweep)
from .modal import DampedModes, ModalResult, damped_modes, modal
from .sensitivity import Sensitivities, sensitivities
from .table import Table

__all__ = [
    "modal", "damped_modes", "ModalResult", "DampedModes",
    "sensitivities", "Sensitivities",
    "harmonic_response", "multi_harmonic_response", "order_sweep",
    "FrequencyResponse", "MultiHarmonicResponse", "OrderSweep",
    "campbell", "CampbellDiagram",
    "Table",
]
