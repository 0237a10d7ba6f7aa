"""The repository stands alone: nothing in it reads a path outside it, and the MSL reference
trajectories it compares with ship inside the package (``regmech/data/msl``), so a fresh clone
or an installed wheel runs the tests and ``regmech demo`` with nothing beside it."""

from __future__ import annotations

import re
import subprocess
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CHECKED = ("src", "tests", "library", "benchmarks")
# written in two pieces so that this file does not match itself
OUTSIDE = (".." + "/shared", "shared" + "/reference", "shared" + "/notes")


def tracked_files() -> list[Path]:
    """The files git tracks under the checked folders (every file there when git is absent, as in an sdist)."""
    try:
        out = subprocess.run(["git", "ls-files", "-z", *CHECKED], cwd=ROOT, capture_output=True, check=True)
        names = [n for n in out.stdout.decode().split("\0") if n]
    except (OSError, subprocess.CalledProcessError):
        names = [str(p.relative_to(ROOT)) for d in CHECKED for p in (ROOT / d).rglob("*") if p.is_file()]
    return [ROOT / n for n in names]


def outside_references(paths, root: Path = ROOT) -> list[str]:
    """``file:line: text`` of every line of ``paths`` that names a folder beside the repository."""
    bad = []
    for path in paths:
        if path.suffix in {".csv", ".png", ".npz", ".pkl"} or not path.is_file():
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        for n, line in enumerate(text.splitlines(), 1):
            if any(s in line for s in OUTSIDE):
                bad.append(f"{path.relative_to(root)}:{n}: {line.strip()[:100]}")
    return bad


def test_no_file_reads_a_path_outside_the_repository():
    bad = outside_references(tracked_files())
    assert not bad, "paths outside the repository:\n" + "\n".join(bad)


def test_the_scan_finds_an_outside_path(tmp_path):
    (tmp_path / "a.py").write_text("x = 1\nREF = ROOT / '" + OUTSIDE[0] + "/reference/msl'\n")
    (tmp_path / "b.py").write_text("REF = Path('" + OUTSIDE[1] + "/msl')\n")
    (tmp_path / "c.py").write_text("REF = ROOT / 'src' / 'regmech' / 'data' / 'msl'\n")
    found = outside_references(sorted(tmp_path.iterdir()), tmp_path)
    assert [f.split(":")[:2] for f in found] == [["a.py", "2"], ["b.py", "1"]]


def test_msl_reference_ships_as_package_data(monkeypatch):
    from regmech.data import MSL_DIR, msl_dir
    monkeypatch.delenv("REGMECH_MSL_REFERENCE", raising=False)
    assert msl_dir() == MSL_DIR
    assert MSL_DIR.is_relative_to(ROOT / "src" / "regmech") or "site-packages" in str(MSL_DIR)
    files = sorted(p.name for p in MSL_DIR.glob("*.csv"))
    assert files == ["Backlash.csv", "CoupledClutches.csv", "First.csv", "LossyGearDemo1.csv",
                     "LossyGearDemo2.csv", "LossyGearDemo3.csv", "OneWayClutch.csv", "OneWayClutchDisengaged.csv"]
    readme = (MSL_DIR / "README.md").read_text(encoding="utf-8")
    assert "MAP-LIB_ReferenceResults" in readme and "BSD 3-Clause" in readme
    # the wheel carries them: pyproject declares the folder's CSV files and README as package data
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]
    assert "regmech.data" in config["packages"]
    assert set(config["package-data"]["regmech.data"]) >= {"msl/*.csv", "msl/README.md"}


def test_demo_prints_its_msl_deviations(capsys, monkeypatch):
    """``regmech demo`` compares First with the shipped reference and prints the deviations (inside the MSL
    tube, 2e-3); with no reference beside the repository it used to skip the comparison without a word."""
    from regmech.cli import _compare_reference
    from regmech.library import first
    monkeypatch.delenv("REGMECH_MSL_REFERENCE", raising=False)
    res = first().simulate(1.0, dt_out=5e-4, solver="ida", rtol=1e-8)
    _compare_reference("first", res)
    out = capsys.readouterr().out
    assert "max abs deviation from the MSL reference" in out, out
    values = [float(v) for v in re.findall(r"\b(?:inertia3\.w|damper\.w_rel) ([0-9.e+-]+)", out)]
    assert len(values) == 2 and all(0 <= v < 2e-3 for v in values), out


def test_demo_says_when_a_chosen_reference_folder_lacks_the_file(capsys, monkeypatch, tmp_path):
    from regmech.cli import _compare_reference
    from regmech.library import first
    monkeypatch.setenv("REGMECH_MSL_REFERENCE", str(tmp_path))
    res = first().simulate(0.1, dt_out=1e-3, solver="ida")
    _compare_reference("first", res)
    assert "no MSL comparison" in capsys.readouterr().out


@pytest.mark.parametrize("name", ["First.csv", "CoupledClutches.csv"])
def test_bench_reads_the_shipped_reference(name, monkeypatch):
    from regmech.bench import msl
    monkeypatch.delenv("REGMECH_MSL_REFERENCE", raising=False)
    msl._CACHE.clear()
    cols = msl.load(name)
    assert cols is not None and cols["time"][0] == 0.0 and len(cols) >= 5


#: wording about the history of the code's making (written in pieces so that this file does not match itself)
HISTORY = re.compile(r"\b(" + "sess" + r"ion[ -]\d|" + "iss" + r"ue \d|" + "help" + r"er's)", re.I)


def history_wording(paths, root: Path = ROOT) -> list[str]:
    """``file:line: text`` of every line of ``paths`` that speaks of the making rather than of the software."""
    bad = []
    for path in paths:
        if path.suffix in {".csv", ".png", ".npz", ".pkl"} or not path.is_file():
            continue
        for n, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
            if HISTORY.search(line):
                bad.append(f"{path.relative_to(root)}:{n}: {line.strip()[:100]}")
    return bad


def test_the_code_speaks_of_itself_not_of_its_making():
    files = tracked_files()
    assert not [f for f in files if "sess" + "ion" in f.name.lower()], "file names after a working session"
    bad = history_wording(files)
    assert not bad, "history wording:\n" + "\n".join(bad)


def test_the_wording_scan_finds_history(tmp_path):
    (tmp_path / "a.py").write_text("# fixed in " + "sess" + "ion 12\nx = 1  # the pytest session fixture\n")
    (tmp_path / "b.py").write_text('"""See ' + "iss" + 'ue 15."""\n')
    found = history_wording(sorted(tmp_path.iterdir()), tmp_path)
    assert [f.split(":")[:2] for f in found] == [["a.py", "1"], ["b.py", "1"]]
