"""The package's layers (docs/architecture.md): which subpackage may import which.

Every import in every module is read from its source, the ones inside functions included, so a
late import cannot hide a cycle. A layer may import only the layers listed for it: plant and
control never import each other, sim joins them, analysis reads Results without importing sim,
and only experiments starts runs for the command line and the reports.
"""

import ast
from pathlib import Path

import emasim

PACKAGE = Path(emasim.__file__).parent
BASE = {"config", "errors", "interface", "jit", "numerics", "signals", "output", "numba_cache"}
ALLOWED = {
    "plant": BASE,
    "control": BASE,
    "sim": BASE | {"plant", "control"},
    "scenarios": BASE | {"plant", "control", "sim"},
    "analysis": BASE | {"signals"},
    "experiments": BASE | {"plant", "control", "sim", "scenarios", "analysis"},
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
            for other in imported_layers(path) - allowed - {layer, "__version__"}:
                if (name, other) not in EXCEPTIONS:
                    broken.append(f"{name} imports {other}")
    assert broken == []
