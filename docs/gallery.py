"""The examples gallery: ``docs/gallery.md`` from the docstrings of ``examples/*.py``, and their figures.

    python docs/gallery.py            # write docs/gallery.md and run every example into docs/figures/
    python docs/gallery.py --page     # write docs/gallery.md only

The page lists every script of ``examples/`` with its docstring, the command that runs it and the
figures it writes (``docs/figures/<name>*.png``, made by running the script; the folder is not kept in
git). ``.ci/docs`` runs this before ``mkdocs build --strict``, which fails on a figure that is missing.
"""

from __future__ import annotations

import argparse
import ast
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
FIGURES = ROOT / "docs" / "figures"
PAGE = ROOT / "docs" / "gallery.md"

INTRO = """# Examples gallery

Each script in `examples/` is short, runs in a few seconds and writes its figure into the folder given by
`--out DIR` (or the environment variable `REGMECH_EXAMPLES_OUT`; default `out/`):

```bash
pip install ".[plot,pandas]"
python examples/msl_first.py --out out
```

The test suite runs every script (`tests/examples/test_examples.py`). This page is generated from the
scripts' docstrings by `python docs/gallery.py`, which also makes the figures.
"""


#: the order of the page: MSL examples, library scenes, models built here, analysis, studies (others after)
ORDER = ["msl_first", "msl_coupled_clutches", "msl_one_way_clutch", "msl_lossy_gear", "msl_backlash", "brake",
         "vehicle_launch", "six_speed_car", "dct_car", "excavator_swing", "electric_car_cycle", "slip_control",
         "full_vehicle", "modal_analysis", "clutch_capacity_study"]


def scripts() -> list[Path]:
    found = [p for p in EXAMPLES.glob("*.py") if not p.name.startswith("_")]
    return sorted(found, key=lambda p: (ORDER.index(p.stem) if p.stem in ORDER else len(ORDER), p.stem))


def figures_of(script: Path) -> list[str]:
    """The PNG names a script writes: every ``<stem>...png`` its text mentions."""
    return sorted(set(re.findall(rf"\b({re.escape(script.stem)}[a-z_]*\.png)", script.read_text())))


def section(script: Path) -> str:
    doc = ast.get_docstring(ast.parse(script.read_text())) or ""
    first, _, body = doc.partition("\n")
    title, _, lead = first.rstrip(".").partition(":")
    usage = ("python examples/", "(DIR:")               # the usage lines: the page gives its own command
    text = "\n".join(ln for ln in body.strip().splitlines() if not ln.strip().startswith(usage)).strip()
    images = "\n\n".join(f"![{name}](figures/{name})" for name in figures_of(script))
    lead = lead.strip()
    lead = f"*{lead[0].upper()}{lead[1:]}.*\n\n" if lead else ""
    return (f"## {title.strip()} {{#{script.stem}}}\n\n{lead}{text}\n\n"
            f"```bash\npython examples/{script.name} --out out\n```\n\n{images}\n")


def page() -> str:
    return INTRO + "\n" + "\n".join(section(s) for s in scripts())


def make_figures() -> None:
    FIGURES.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, MPLBACKEND="Agg", REGMECH_EXAMPLES_OUT=str(FIGURES))
    for script in scripts():
        if all((FIGURES / n).exists() and (FIGURES / n).stat().st_mtime > script.stat().st_mtime
               for n in figures_of(script)):
            continue                                   # up to date
        print(f"running {script.name}", flush=True)
        subprocess.run([sys.executable, str(script)], env=env, check=True, stdout=subprocess.DEVNULL)
    for extra in FIGURES.glob("*.csv"):                # a study's table is not part of the site
        extra.unlink()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--page", action="store_true", help="write docs/gallery.md only, run no example")
    args = ap.parse_args(argv)
    PAGE.write_text(page())
    if not args.page:
        make_figures()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
