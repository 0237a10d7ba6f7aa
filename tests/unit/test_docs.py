"""The documentation runs and stays whole: every ```python block of each user-guide chapter (in order, one
namespace per chapter) and of the README; the API reference pages name every public name; the gallery
page lists every example; relative links between the pages point at files that exist."""

import importlib
import re
import sys
import warnings
from pathlib import Path

import pytest

import regmech as rm

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"


def python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


PAGES = sorted((DOCS / "guide").glob("*.md")) + [DOCS / "index.md", ROOT / "README.md"]
CHAPTERS = [p for p in PAGES if python_blocks(p.read_text())]     # the pages with code


def test_the_guide_has_its_chapters_with_code():
    names = {p.stem for p in CHAPTERS}
    assert {"getting-started", "building-models", "components", "results", "stick-slip", "solvers", "vibration",
            "studies", "control", "writing-components", "README"} <= names
    assert sum(len(python_blocks(p.read_text())) for p in CHAPTERS) >= 40


@pytest.mark.slow
@pytest.mark.parametrize("page", CHAPTERS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_code_of_the_page_runs(page, tmp_path, monkeypatch):
    pytest.importorskip("matplotlib").use("Agg")
    pytest.importorskip("pandas")
    blocks = python_blocks(page.read_text())
    monkeypatch.chdir(tmp_path)                       # the pages write their files to the current folder
    ns = {"__name__": "__doc_page__"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rm.RegularityWarning)
        for i, code in enumerate(blocks, start=1):
            try:
                exec(compile(code, f"{page.name} block {i}", "exec"), ns)
            except Exception as exc:                   # say which block failed
                raise AssertionError(f"block {i} of {page.name} failed:\n{code}") from exc
    if page.name == "getting-started.md":
        for name in ("motor_and_load_scheme.png", "motor_and_load.png", "clutch_lockup.png", "motor_and_load.mat"):
            assert (tmp_path / name).stat().st_size > 0
    import matplotlib.pyplot as plt
    plt.close("all")


def _documented() -> set[str]:
    """Every name the API reference pages document: a ``::: name`` line, and for a module every name
    of its ``__all__``."""
    names = set()
    for page in (DOCS / "reference").glob("*.md"):
        for target in re.findall(r"^::: *([\w.]+)", page.read_text(), flags=re.M):
            names.add(target)
            try:
                module = importlib.import_module(target)
            except ImportError:
                continue
            names.update(f"{target}.{n}" for n in getattr(module, "__all__", ()))
    return names


def test_api_reference_pages_name_every_public_name():
    from regmech import analysis, components, signals
    documented = _documented()
    for name in rm.__all__:
        assert f"regmech.{name}" in documented, f"docs/reference lacks regmech.{name}"
    for module in (components, signals, analysis):
        for name in module.__all__:
            assert f"{module.__name__}.{name}" in documented, f"docs/reference lacks {module.__name__}.{name}"
    from regmech.library import SCENES
    for scene, build in SCENES.items():
        assert any(d.endswith(f".{build.__name__}") for d in documented), f"docs/reference lacks scene {scene}"


def test_gallery_page_lists_every_example_and_is_up_to_date():
    sys.path.insert(0, str(DOCS))
    try:
        gallery = importlib.import_module("gallery")
    finally:
        sys.path.remove(str(DOCS))
    text = (DOCS / "gallery.md").read_text()
    assert text == gallery.page(), "docs/gallery.md is stale: run python docs/gallery.py --page"
    for script in (ROOT / "examples").glob("*.py"):
        assert f"python examples/{script.name}" in text
        assert gallery.figures_of(script), f"{script.name} names no figure <stem>.png"


@pytest.mark.parametrize("page", sorted(DOCS.rglob("*.md")) + [ROOT / "README.md"],
                         ids=lambda p: p.relative_to(ROOT).as_posix())
def test_relative_links_point_at_files(page):
    prose = re.sub(r"^```.*?^```", "", page.read_text(), flags=re.S | re.M)    # code is not links
    prose = re.sub(r"`[^`]*`", "", prose)
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", prose):
        if re.match(r"[a-z]+:", target) or target.startswith("figures/"):   # other sites; figures made by
            continue                                                          # docs/gallery.py
        assert (page.parent / target).exists(), f"{page.name} links to {target}, which does not exist"


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


def test_api_reference_is_reproducible(tmp_path):
    from regmech import docgen
    a, b = docgen.generate(), docgen.generate()
    assert a == b
    assert not re.search(r" at 0x[0-9a-fA-F]{6,}", a)          # no object addresses in the text
