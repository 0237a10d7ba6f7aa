"""Every script of examples/ runs as a user runs it (``python examples/NAME.py``, a fresh process) and
writes its figure: a PNG named after the script, non-empty, that matplotlib reads back as an image."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
SCRIPTS = sorted(p for p in EXAMPLES.glob("*.py") if not p.name.startswith("_"))


def test_the_gallery_has_at_least_twelve_examples():
    assert len(SCRIPTS) >= 12, [p.name for p in SCRIPTS]


@pytest.mark.slow
@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.stem)
def test_example_runs_and_writes_its_figure(script, tmp_path):
    plt = pytest.importorskip("matplotlib.pyplot")
    pytest.importorskip("pandas")
    doc = script.read_text().split('"""')[1]
    assert doc.strip(), f"{script.name} has no docstring"
    out = tmp_path / "figures"
    env = dict(os.environ, MPLBACKEND="Agg", REGMECH_EXAMPLES_OUT=str(out))
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, f"{script.name} failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-4000:]}"
    figure = out / f"{script.stem}.png"
    assert figure.is_file(), f"{script.name} wrote {sorted(p.name for p in out.glob('*'))}, not {figure.name}"
    assert figure.stat().st_size > 10_000
    image = plt.imread(figure)
    assert image.shape[0] > 200 and image.shape[1] > 200
    assert image[..., :3].std() > 0.01                 # not a blank canvas
    assert not (tmp_path / "out").exists()             # the folder given was used, not the default
    gallery = os.environ.get("REGMECH_GALLERY_FIGURES")
    if gallery:                 # CI: the documentation build then finds the figures made (docs/gallery.py)
        Path(gallery).mkdir(parents=True, exist_ok=True)
        for png in out.glob("*.png"):
            shutil.copy(png, Path(gallery) / png.name)
