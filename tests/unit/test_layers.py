"""The layers of the package, checked on the source's imports.

    components -> Model -> structure/ -> compile/ -> hybrid/ -> solvers/ -> analysis/, bench/, cli, ...

Each layer imports only itself and the layers above it in this list; compile/, hybrid/ and
solvers/ never import a component or block module (a solver never knows a component class). The core
modules (errors, ports, units, signals, mode codes, the component base, results, reports) are shared by all and
import no layer. ``model.py`` is the user's facade: it reaches the layers below it only inside
its methods (``Model.compile``, ``Model.simulate``), never when it is imported.

Imports are read with ``ast`` from the files, so nothing is imported or run.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src" / "regmech"

#: the layers' order, top (imported by the others) first; a unit is a subpackage or a top-level module
LAYERS = [
    {"components", "blocks"},
    {"model"},
    {"structure"},
    {"compile"},
    {"hybrid"},
    {"solvers"},
    {"analysis", "bench", "study", "cli", "scene", "sweep", "library", "draw", "docgen", "__root__"},
]
CORE = {"errors", "_numbers", "_frozen", "_portable", "ports", "modes", "units", "signals", "component", "result",
        "report", "io", "plotting", "data"}
NEVER_COMPONENTS = {"compile", "hybrid", "solvers"}
RANK = {unit: i for i, layer in enumerate(LAYERS) for unit in layer}


def unit_of(module: str) -> str:
    """``regmech.solvers.ida`` -> ``solvers``; ``regmech`` itself (its ``__init__``) -> ``__root__``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__root__"


def imports_of(source: str, module: str, is_package: bool):
    """(target module, line, inside a function) of every import of ``regmech`` in ``source``."""
    package = module if is_package else module.rpartition(".")[0]
    out = []

    def visit(node, in_function):
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            if isinstance(child, ast.Import):
                out.extend((a.name, child.lineno, in_function) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = package.split(".")[: len(package.split(".")) - (child.level - 1)]
                    target = ".".join(base + ([child.module] if child.module else []))
                else:
                    target = child.module or ""
                if child.module is None or target == "regmech":
                    # ``from . import x`` / ``from regmech import x``: x may be a module of its own
                    for a in child.names:
                        sub = f"{target}.{a.name}"
                        root = SRC.parent.joinpath(*sub.split("."))
                        known = root.with_suffix(".py").exists() or root.is_dir()
                        out.append((sub if known else target, child.lineno, in_function))
                else:
                    out.append((target, child.lineno, in_function))
            visit(child, inner)

    visit(ast.parse(source), False)
    return [(t, line, f) for t, line, f in out if t == "regmech" or t.startswith("regmech.")]


def violations(source: str, module: str, is_package: bool = False) -> list[str]:
    """What the imports of ``module`` (its ``source``) break of the layer rules."""
    own = unit_of(module)
    bad = []
    for target, line, in_function in imports_of(source, module, is_package):
        dep = unit_of(target)
        if dep == own or dep in CORE:
            continue
        where = f"{module} line {line} imports {target}"
        if own in CORE:
            bad.append(f"{where}: a core module imports no layer")
        elif own == "model":
            if not in_function:
                bad.append(f"{where} when it is imported: the Model facade reaches the layers only in its methods")
        elif own in NEVER_COMPONENTS and dep in ("components", "blocks"):
            bad.append(f"{where}: {own}/ never imports a component or block module (the hybrid layer holds the mode "
                       f"logic)")
        elif own in RANK and dep in RANK and RANK[dep] > RANK[own]:
            bad.append(f"{where}: {own} imports {dep}, a layer below it")
        elif own in RANK and dep not in RANK:
            bad.append(f"{where}: {dep} is in no layer of this test; place it in LAYERS or CORE")
    return bad


def source_modules():
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC.parent).with_suffix("")
        is_package = rel.name == "__init__"
        module = ".".join(rel.parts[:-1] if is_package else rel.parts)
        yield path, module, is_package


def test_every_module_is_placed():
    units = {unit_of(module) for _, module, _ in source_modules()}
    assert units <= set(RANK) | CORE, f"modules in no layer: {sorted(units - set(RANK) - CORE)}"
    assert (SRC / "hybrid").is_dir()


def test_imports_follow_the_layers():
    bad = []
    for path, module, is_package in source_modules():
        bad += violations(path.read_text(encoding="utf-8"), module, is_package)
    assert not bad, "imports against the layers:\n" + "\n".join(bad)


@pytest.mark.parametrize("module, source, broken", [
    ("regmech.compile.system", "from ..components.friction import FrictionSet", True),
    ("regmech.compile.system", "def f():\n    from regmech.components import Clutch", True),
    ("regmech.solvers.ida", "from ..components import friction", True),
    ("regmech.solvers.auto", "from ..blocks import PI", True),
    ("regmech.blocks.base", "from ..compile.reads import settle", True),
    ("regmech.hybrid.logic", "from ..solvers.ida import simulate_ida", True),
    ("regmech.compile.system", "from ..hybrid import attach", True),
    ("regmech.structure.system", "from .. import compile", True),
    ("regmech.errors", "from .solvers import SOLVERS", True),
    ("regmech.model", "from .solvers import simulate", True),
    ("regmech.model", "def simulate():\n    from .solvers import simulate", False),
    ("regmech.solvers.ida", "from ..hybrid import FrictionSet\nfrom ..compile.outputs import Trajectory", False),
    ("regmech.hybrid.events", "from ..compile.friction_rows import FrictionRows\nfrom ..modes import STUCK", False),
    ("regmech.structure.reduction", "from ..components.elastic import Shaft", False),
])
def test_the_check_sees_a_broken_rule(module, source, broken):
    assert bool(violations(source, module)) == broken, violations(source, module)
