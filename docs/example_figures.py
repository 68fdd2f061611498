"""The examples gallery's figures (docs/examples/*.png), drawn by the examples themselves.

    python docs/example_figures.py   # run each script of examples/ in a fresh folder, as a
                                     # user does, its figures written into docs/examples/

Run it after changing an example or what it draws; ``tests/test_examples.py`` checks that
each example writes the figures that docs/examples.md shows. Standard library only.
"""

import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "examples"


def main() -> None:
    for script in sorted((ROOT / "examples").glob("*.py")):
        print(f"{script.name} -> {FIGURES.relative_to(ROOT)}/", flush=True)
        with tempfile.TemporaryDirectory() as folder:
            subprocess.run([sys.executable, str(script), str(FIGURES)], cwd=folder, check=True)


if __name__ == "__main__":
    main()
