import os
from pathlib import Path

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")

ROOT = Path(__file__).resolve().parents[1]


def _find_reference():
    for cand in (ROOT.parent / "shared" / "reference" / "msl", ROOT / "shared" / "reference" / "msl"):
        if cand.is_dir():
            return cand
    return None


REFERENCE = _find_reference()


@pytest.fixture
def reference_dir():
    if REFERENCE is None:
        pytest.fail("reference data ../shared/reference/msl not found next to the repository")
    return REFERENCE
