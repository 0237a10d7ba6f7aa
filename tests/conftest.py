import os
from pathlib import Path

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")

ROOT = Path(__file__).resolve().parents[1]

#: the MSL reference trajectories, shipped in the package (src/regmech/data/msl, with their source and licence)
REFERENCE = ROOT / "src" / "regmech" / "data" / "msl"


@pytest.fixture
def reference_dir():
    """The repository's MSL reference folder (never one outside the repository)."""
    if not (REFERENCE / "First.csv").is_file():
        pytest.fail(f"MSL reference data missing from the repository: {REFERENCE}")
    return REFERENCE
