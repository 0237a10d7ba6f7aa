"""The documentation runs: every ```python block of docs/tutorial.md, in order, in one namespace; the API
reference generator covers every public name."""

import re
import warnings
from pathlib import Path

import pytest

import regmech as rm

DOCS = Path(__file__).resolve().parents[2] / "docs"


def python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


@pytest.mark.slow
def test_tutorial_code_runs(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib").use("Agg")
    pytest.importorskip("pandas")
    blocks = python_blocks((DOCS / "tutorial.md").read_text())
    assert len(blocks) >= 15
    monkeypatch.chdir(tmp_path)                       # the tutorial writes its files to the current folder
    ns = {"__name__": "__tutorial__"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rm.RegularityWarning)
        for i, code in enumerate(blocks, start=1):
            try:
                exec(compile(code, f"docs/tutorial.md block {i}", "exec"), ns)
            except Exception as exc:                   # say which block failed
                raise AssertionError(f"block {i} of docs/tutorial.md failed:\n{code}") from exc
    for name in ("motor_and_load_scheme.png", "motor_and_load.png", "clutch_lockup.png", "launch_campbell.png",
                 "motor_and_load.mat"):
        assert (tmp_path / name).stat().st_size > 0
    import matplotlib.pyplot as plt
    plt.close("all")


def test_api_reference_generator_covers_every_public_name(tmp_path, capsys):
    from regmech import docgen
    from regmech import analysis, components, signals
    out = tmp_path / "api.md"
    assert docgen.main(["--out", str(out)]) == 0
    text = out.read_text()
    headings = set(re.findall(r"^### `([^`]+)`", text, flags=re.M))
    for name in rm.__all__:
        assert f"regmech.{name}" in headings, name
    for module, prefix in ((components, "regmech.components"), (signals, "regmech.signals"),
                           (analysis, "regmech.analysis")):
        for name in module.__all__:
            assert f"{prefix}.{name}" in headings, name
    # signatures and docstrings are there, with units
    assert "Inertia(name: str, *, J: float > 0 [kg m^2]" in text
    assert "* `regmech.Result.plot(" in text and "* `regmech.Model.draw(" in text
    assert "moment of inertia" in text


def test_committed_api_reference_lists_every_public_name():
    text = (DOCS / "api.md").read_text()
    for name in rm.__all__:
        assert f"### `regmech.{name}`" in text, f"docs/api.md lacks regmech.{name}: run python -m regmech.docgen"


def test_api_reference_is_reproducible(tmp_path):
    from regmech import docgen
    a, b = docgen.generate(), docgen.generate()
    assert a == b
    assert not re.search(r" at 0x[0-9a-fA-F]{6,}", a)          # no object addresses in the text
