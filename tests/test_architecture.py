"""docs/architecture.md stays true: its table of elements is the plant's, and its worked
example's file list is every source file that names the gear mesh."""

import re
from pathlib import Path

from emasim.page_blocks import block_of
from emasim.plant import actuator as A

ROOT = Path(__file__).parents[1]
PAGE = (ROOT / "docs" / "architecture.md").read_text()
SOURCE = ROOT / "src" / "emasim"
# what names the example's element: its section, its states and parameters, its model
NAMES = re.compile(r"gear_mesh|GearMesh|GEAR_MESH|screw_angle_rad|screw_inertia_kgm2")


def test_the_element_table_is_the_plants_elements_with_their_modules():
    rows = re.findall(r"^\| `(\w+)` \| `([\w/.]+)` \|", block_of(PAGE, "elements"), re.M)
    assert [name for name, _ in rows] == [e.name for e in A.ELEMENTS]
    for name, path in rows:  # the module declares the element of that name
        assert re.search(rf'^    "{name}",$', (SOURCE / path).read_text(), re.M), (name, path)


def test_the_examples_files_are_every_source_file_that_names_the_element():
    listed = set(re.findall(r"`(src/[\w/.]+)`", block_of(PAGE, "example-files")))
    assert listed and all((ROOT / path).is_file() for path in listed)
    naming = {
        str(path.relative_to(ROOT))
        for path in SOURCE.rglob("*.py")
        if NAMES.search(path.read_text())
    }
    assert naming == listed
