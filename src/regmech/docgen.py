"""The API reference, generated from the docstrings: ``python -m regmech.docgen [--out docs/api.md]``.

One Markdown file: every public name of ``regmech`` (``regmech.__all__``),
then the public names of the sub-packages a user imports from
(``components``, ``signals``, ``analysis``, ``units``, ``library``), each
with its signature and docstring; a class also with its public methods and
properties. Nothing is written by hand here, so the reference cannot drift
from the code: rerun it after changing a docstring (the test suite checks
that it runs and covers every name of ``regmech.__all__``).
"""

from __future__ import annotations

import argparse
import inspect
import re
import sys
from pathlib import Path

#: the sub-packages documented after ``regmech`` itself: (module, title, names or None for ``__all__``)
SECTIONS = [
    ("regmech.components", "Components", None),
    ("regmech.signals", "Signals", None),
    ("regmech.analysis", "Vibration analysis", None),
    ("regmech.units", "Units", ["DISPLAY_UNITS", "QUANTITIES", "convert", "factor", "choices", "normalise"]),
    ("regmech.sweep", "Parameter studies", ["sweep", "grid", "latin_hypercube", "scatter"]),
    ("regmech.library", "Library scenes", ["SCENES"]),
]


def _doc(obj) -> str:
    doc = inspect.getdoc(obj) or ""
    return doc.strip()


def _signature(name: str, obj) -> str:
    try:
        text = f"{name}{inspect.signature(obj)}"
    except (TypeError, ValueError):
        return name
    # sentinel defaults print with their address, which changes from run to run: the file must not
    return re.sub(r"<object object at 0x[0-9a-fA-F]+>", "<no default>", text)


def _members(cls) -> list[tuple[str, object]]:
    """Public methods and properties a class defines or inherits from regmech classes (not from object);
    a component class leaves out those of the base classes (``Component``, ``Device``, ...), which are
    documented once under ``regmech``."""
    out = []
    base_module = "regmech.component"
    for name in sorted(dir(cls)):
        if name.startswith("_"):
            continue
        owner = next((k for k in cls.__mro__ if name in vars(k)), None)
        if owner is None or not owner.__module__.startswith("regmech"):
            continue
        if owner.__module__ == base_module and cls.__module__ != base_module:
            continue
        attr = vars(owner)[name]
        if isinstance(attr, (property, staticmethod, classmethod)) or inspect.isfunction(attr):
            out.append((name, attr))
        elif hasattr(attr, "__get__") and hasattr(attr, "func"):            # functools.cached_property
            out.append((name, attr))
    return out


def _block(text: str) -> list[str]:
    """A docstring as Markdown: kept verbatim in an indented block when it has tables or literal layouts,
    else as a paragraph."""
    if not text:
        return ["*(no docstring)*", ""]
    return ["```text", text, "```", ""]


def _describe(qualname: str, obj, level: int = 3) -> list[str]:
    lines = [f"{'#' * level} `{qualname}`", ""]
    if inspect.isclass(obj) or callable(obj) and not isinstance(obj, (dict, list)):
        short = qualname.rpartition(".")[2]
        lines += ["```python", _signature(short, obj), "```", ""]
    if inspect.isclass(obj) or inspect.isroutine(obj) or inspect.ismodule(obj):
        lines += _block(_doc(obj))
    else:
        lines += ["```text", _value_text(obj), "```", ""]
    if inspect.isclass(obj) and not issubclass(obj, BaseException):
        for name, attr in _members(obj):
            if isinstance(attr, property) or hasattr(attr, "func") and not inspect.isfunction(attr):
                head = f"`{qualname}.{name}` (property)"
                doc = _doc(attr.fget if isinstance(attr, property) else attr.func)
            else:
                fn = attr.__func__ if isinstance(attr, (staticmethod, classmethod)) else attr
                head = f"`{_signature(f'{qualname}.{name}', fn).replace('(self, ', '(').replace('(self)', '()')}`"
                doc = _doc(fn)
            lines += [f"* {head}" + (":" if doc else "")]
            if doc:
                lines += ["", "  ```text"] + [f"  {ln}" if ln else "" for ln in doc.splitlines()] + ["  ```"]
            lines.append("")
    return lines


def _value_text(obj) -> str:
    if isinstance(obj, dict):
        rows = []
        for k, v in obj.items():
            if isinstance(v, dict):
                v = ", ".join(f"{a}" for a in v)
            elif callable(v):
                v = (_doc(v).splitlines() or [""])[0]
            rows.append(f"{k}: {v}")
        return "\n".join(rows)
    return repr(obj)


def _public(module) -> list[str]:
    names = getattr(module, "__all__", None)
    if names is None:
        names = [n for n in vars(module) if not n.startswith("_")]
    return list(names)


def generate() -> str:
    """The reference as Markdown text."""
    import importlib

    import regmech
    out = ["# regmech API reference", "",
           "Generated from the docstrings by `python -m regmech.docgen` (do not edit by hand; rerun it). "
           "The [tutorial](tutorial.md) shows how the pieces fit together.", ""]
    toc = ["## Contents", "", "* [regmech](#regmech)"]
    body = ["## regmech", "", _doc(regmech), ""]
    for name in regmech.__all__:
        body += _describe(f"regmech.{name}", getattr(regmech, name))
    for modname, title, names in SECTIONS:
        module = importlib.import_module(modname)
        anchor = title.lower().replace(" ", "-")
        toc.append(f"* [{title}](#{anchor}) (`{modname}`)")
        body += [f"## {title}", "", f"`{modname}`", "", _doc(module), ""]
        for name in (names or _public(module)):
            obj = getattr(module, name, None)
            if obj is None or inspect.ismodule(obj):
                continue
            body += _describe(f"{modname}.{name}", obj)
    return "\n".join(out + toc + [""] + body).rstrip() + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m regmech.docgen", description=__doc__.splitlines()[0])
    p.add_argument("--out", default="docs/api.md", help="Markdown file to write (default: docs/api.md)")
    args = p.parse_args(argv)
    path = Path(args.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = generate()
    path.write_text(text)
    print(f"{path}: {len(text.splitlines())} lines")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
