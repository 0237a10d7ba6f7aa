"""Parameter studies: ``sweep`` and the sampling helpers (see ``regmech.sweep``).

Modules: ``sampling`` (grids, Latin hypercube, scatter), ``worker`` (one run,
the recipe shipped to workers), ``executors`` (serial, process pool, Dask),
``store`` (incremental CSV/Parquet, resume), ``table`` (the result table),
``outputs`` (signal summaries), ``run`` (the study loop), ``cli``.
"""

from .outputs import SignalSummary, scene_defaults
from .run import sweep
from .sampling import grid, latin_hypercube, scatter

__all__ = ["sweep", "grid", "latin_hypercube", "scatter", "SignalSummary", "scene_defaults"]
