"""Data files shipped with regmech.

``msl/`` holds reference trajectories of eight Modelica Standard Library 4.1 examples
(``Modelica.Mechanics.Rotational.Examples``), computed by Dymola with DASSL at tolerance 1e-6;
their source and licence are in ``msl/README.md``. The tests, ``regmech demo`` and the
work-precision runs compare regmech's trajectories with them.

The files are package data: they are found the same way in a source checkout, an editable
install and an installed wheel, with nothing outside the package.
"""

from __future__ import annotations

import os
from pathlib import Path

#: folder of the MSL reference CSV files inside the installed package
MSL_DIR = Path(__file__).resolve().parent / "msl"


def msl_dir() -> Path:
    """Folder of the MSL reference trajectories: ``$REGMECH_MSL_REFERENCE`` when set (a user's own
    reference files, e.g. from another MSL version), else the files shipped in this package."""
    env = os.environ.get("REGMECH_MSL_REFERENCE")
    return Path(env) if env else MSL_DIR
