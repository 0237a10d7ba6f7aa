"""Benchmarks: work-precision of the solvers on ready-made scenes, and the hard cases.

* ``scenes``: the benchmark scenes (library scene, parameters, horizon,
  compared signals, tolerance and step ladders, MSL file);
* ``metrics``: the error metrics, defined once (max relative error over the
  output grid, final-value error, switch-time error);
* ``reference``: tight reference solutions, cross-checked by a second
  method, cached on disk by a hash of what they depend on;
* ``runner`` / ``workprecision``: timed runs (median of repeats, compile
  timed apart), failures recorded, per-run time limit; ``report``: CSV,
  Markdown, log-log plots; ``cli``: ``regmech bench``;
* ``hard``: the hard-case suite (stretched spectra, extreme parameters,
  stick/slip, long horizons, discontinuous inputs) with analytic answers;
* ``fuzz``: random regular drivetrains of every component family and the
  reliability checks run on each (``tests/fuzz``, ``benchmarks/fuzz.py``).
"""

from .metrics import Errors, Trace, compare, sample, switch_time_error, trace_of
from .scenes import BenchScene, all_scenes, quick_scenes, select

__all__ = ["Errors", "Trace", "compare", "sample", "switch_time_error", "trace_of", "BenchScene", "all_scenes",
           "quick_scenes", "select"]
