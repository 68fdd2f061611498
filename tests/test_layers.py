"""The package's layers (docs/architecture.md): which subpackage may import which.

Every import in every module is read from its source, the ones inside functions included, so a
late import cannot hide a cycle. A layer may import only the layers listed for it: plant and
control never import each other, sim joins them, analysis reads Results without importing sim,
and only experiments starts runs for the command line and the reports.
"""

import ast
import graphlib
from pathlib import Path

import emasim

PACKAGE = Path(emasim.__file__).parent
BASE = {
    "arguments",
    "config",
    "errors",
    "interface",
    "jit",
    "numerics",
    "signals",
    "output",
    "naming",
    "jsonio",
    "manifest",
    "numba_cache",
    "results",
    "toml_text",
    "version",
}
ALLOWED = {
    "plant": BASE,
    "control": BASE,
    "sim": BASE | {"plant", "control"},
    "scenarios": BASE | {"plant", "control", "sim"},
    "analysis": BASE | {"signals"},
    # the battery overlays the linear model (emasim.linear sits on sim and scenarios)
    "experiments": BASE | {"plant", "control", "sim", "scenarios", "analysis", "linear"},
    # it simulates through experiments (the bench's fit, the wear study of a series)
    "identification": BASE | {"plant", "control", "sim", "scenarios", "analysis", "experiments"},
}
# a saved Result draws its own plot.png; analysis never imports sim, so this makes no cycle
EXCEPTIONS = {("sim/result.py", "analysis")}


def imported_layers(path: Path) -> set[str]:
    """The top-level emasim modules or subpackages that ``path`` imports."""
    module = path.relative_to(PACKAGE).with_suffix("").parts
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolve against the module's own package
                base = list(module[: len(module) - node.level])
                target = base + (node.module.split(".") if node.module else [])
                if not target:  # "from .. import x": x is the layer
                    found.update(alias.name for alias in node.names)
                    continue
                found.add(target[0])
            elif node.module and node.module.startswith("emasim."):
                found.add(node.module.split(".")[1])
        elif isinstance(node, ast.Import):
            found.update(
                alias.name.split(".")[1] for alias in node.names if alias.name.startswith("emasim.")
            )
    return found


def test_every_layer_imports_only_the_layers_below_it():
    broken = []
    for layer, allowed in ALLOWED.items():
        for path in sorted((PACKAGE / layer).rglob("*.py")):
            name = path.relative_to(PACKAGE).as_posix()
            for other in imported_layers(path) - allowed - {layer}:
                if (name, other) not in EXCEPTIONS:
                    broken.append(f"{name} imports {other}")
    assert broken == []


def module_name(path: Path) -> str:
    parts = ("emasim", *path.relative_to(PACKAGE).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(path): path for path in PACKAGE.rglob("*.py")}


def imported_modules(path: Path) -> set[str]:
    """The emasim modules ``path`` imports, anywhere in it (``from a import b`` counts as the
    module a.b where there is one, else as a)."""
    module = module_name(path).split(".")
    package = module if path.name == "__init__.py" else module[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            source = ".".join(base + (node.module.split(".") if node.module else []))
            for alias in node.names:
                found.add(
                    f"{source}.{alias.name}" if f"{source}.{alias.name}" in MODULES else source
                )
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return (found & MODULES.keys()) - {module_name(path)}


def test_no_module_imports_one_that_imports_it_back():
    """No import cycle, however long and wherever its imports sit (a late import inside a
    function included): graphlib's topological order exists."""
    graph = {name: imported_modules(path) for name, path in MODULES.items()}
    try:
        tuple(graphlib.TopologicalSorter(graph).static_order())
    except graphlib.CycleError as err:
        raise AssertionError(f"import cycle: {' -> '.join(err.args[1])}") from None
