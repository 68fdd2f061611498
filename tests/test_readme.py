"""The examples of the README and of the docs pages its details live on run as written; the
README's statement of its two commands' times is the stored measurement; its links stay in the
project."""

import json
import re
import shlex
import tomllib
from pathlib import Path

from helpers import module_at
from typer.main import get_command
from typer.testing import CliRunner

from emasim.cli import app
from emasim.page_blocks import block_of
from emasim.scenarios.loader import read_scenario_file, validate_scenario

ROOT = Path(__file__).parents[1]
README = (ROOT / "README.md").read_text()
DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]
# The pages whose Python examples run here, in this order and in one namespace, as a reader
# runs them: the README's sections on the command line and Python moved to the guide, the
# datasheet and python-control bridge to the acceptance page.
RUNNABLE = [ROOT / "README.md", DOCS / "guide.md", DOCS / "acceptance.md"]
TEXT = "".join(page.read_text() for page in PAGES)

commands = module_at("benchmarks/readme_commands.py")


def blocks(language: str, text: str = TEXT) -> list[str]:
    """The fenced code blocks of ``text`` (the README and the docs pages) whose info string is
    ``language`` ('' for plain blocks)."""
    found, current, info = [], None, None
    for line in text.splitlines(keepends=True):
        if line.startswith("```"):
            if current is None:
                current, info = [], line[3:].strip()
            else:
                if info == language:
                    found.append("".join(current))
                current = None
        elif current is not None:
            current.append(line)
    return found


def toml_block(starting: str) -> str:
    """The one TOML block of the README and the docs whose first line starts with
    ``starting``."""
    (found,) = [b for b in blocks("toml") if b.startswith(starting)]
    return found


def test_the_scenario_example_is_valid_and_runs():
    example = toml_block("name = ")
    scenario = validate_scenario(tomllib.loads(example))
    assert scenario.sensors.rudder.accuracy_error > 0  # "bench" sensors were picked up
    assert scenario.plant.backlash.width_mm == 0.2
    assert scenario.reference.loop == "position"


def test_the_realistic_bench_options_are_valid_on_a_bench_scenario():
    options = toml_block("sensors = ")
    raw, _ = read_scenario_file("bench-step")
    for key, value in tomllib.loads(options).items():
        raw[key] = {**raw.get(key, {}), **value} if isinstance(value, dict) else value
    scenario = validate_scenario(raw)
    assert scenario.loop.position_feedback == "rudder"
    assert scenario.loop.computation_delay_s == 1e-4
    assert scenario.sensors.speed.derived and scenario.plant.load_motor.preload_Nm == 20.0


def test_the_python_examples_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__main__"}  # as a script runs them
    for page in RUNNABLE:
        for code in blocks("python", page.read_text()):
            exec(code, namespace)  # noqa: S102 - the project's own examples
    assert (tmp_path / "runs" / "wide-gap" / "result.parquet").is_file()
    assert namespace["setup"].speed.function is namespace["my_speed_law"]
    assert list(namespace["study"].table["plant.backlash.width_mm"]) == [0.05, 0.2]


def test_the_study_examples_are_valid_studies():
    """Each ``emasim study`` command of the bash blocks plans (every sample valid)."""
    from emasim.experiments.study import StudySpec, plan_study

    lines = "".join(blocks("bash")).replace("\\\n", " ").splitlines()
    studies = []
    for line in lines:
        words = shlex.split(line, comments=True)
        if len(words) > 1 and words[0].endswith("emasim") and words[1] == "study":
            studies.append(words[2:])
    assert len(studies) >= 3
    command = get_command(app).commands["study"]
    for words in studies:
        given = command.make_context("study", words).params  # parsed as the command line does
        spec = StudySpec(
            given["scenario"],
            vary=tuple(given["vary"] or ()),
            runs=given["runs"],
            seeds=given["seeds"],
            labels=tuple(given["label"] or ()),
            settings=tuple(given["setting"] or ()),
        )
        assert plan_study(spec).jobs


def test_the_error_examples_print_what_the_docs_say(tmp_path, monkeypatch):
    """Each ``$ emasim ...`` line of the plain code blocks, run here, prints the line below it
    (one line, exit 2). ``thesis`` is a user's folder holding a file."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "thesis").mkdir()
    (tmp_path / "thesis" / "thesis.tex").write_text("years of work")
    examples = [
        (line, following)
        for block in blocks("")
        for line, following in zip(block.splitlines(), block.splitlines()[1:], strict=False)
        if line.startswith("$ emasim ")
    ]
    assert len(examples) >= 4
    for command, expected in examples:
        result = CliRunner().invoke(app, shlex.split(command)[2:])
        assert result.exit_code == 2, command
        assert result.stderr.strip() == expected, command
    assert (tmp_path / "thesis" / "thesis.tex").read_text() == "years of work"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["thesis"]


def test_the_metric_windows_the_docs_state_are_the_codes():
    from emasim.analysis import report

    text = " ".join((DOCS / "model.md").read_text().split())
    assert (
        f"the recovery band is {100 * report.RECOVERY_FRACTION:g} % of the dip, but at least "
        f"{report.RECOVERY_FLOOR_RPM:g} rpm (speed) or {1e3 * report.RECOVERY_FLOOR_MM:g} µm"
    ) in text
    assert f"over the last {100 * report.STEADY_FRACTION:g} % of the interval after it" in text
    assert f"steady statistics from {report.BENCH_STEADY_S:g} s to the end" in text


def test_every_shell_block_of_the_readme_and_the_docs_is_valid_bash():
    """``bash -n`` on each bash block: an unquoted ``linspace(...)`` is a syntax error there."""
    import subprocess

    found = 0
    for page in PAGES:
        for code in blocks("bash", page.read_text()):
            found += 1
            check = subprocess.run(["bash", "-n"], input=code, capture_output=True, text=True)
            assert check.returncode == 0, f"{page.name}: {check.stderr}\n{code}"
    assert found >= 5


def test_every_python_block_of_the_docs_compiles():
    for page in sorted(DOCS.glob("*.md")):
        for code in blocks("python", page.read_text()):
            compile(code, page.name, "exec")


def test_the_readme_states_the_two_commands_measured_times():
    """The README's block of the two commands' times is the stored measurement rendered (a
    command that failed said so), and the stored measurement timed the README's commands as
    printed. Measure with
    ``python3 benchmarks/readme_commands.py --write`` (minutes: it runs both in a fresh
    clone); this test times nothing."""
    stored = json.loads(commands.STORE.read_text())
    assert block_of(README, commands.BLOCK) == commands.render(stored)
    printed = commands.commands(README)
    assert [stored["commands"][name]["command"] for name in commands.NAMES] == printed


def slug(heading: str) -> str:
    """A heading's anchor as the docs site (Python-Markdown's toc) and GitHub make it."""
    text = re.sub(r"[^\w\s-]", "", heading.replace("`", "")).strip().lower()
    return re.sub(r"[-\s]+", "-", text)


def anchors(page: Path) -> set[str]:
    return {
        slug(line.lstrip("#")) for line in page.read_text().splitlines() if line.startswith("#")
    }


def test_every_relative_link_of_the_readme_and_the_docs_is_a_file_of_the_project():
    """Each link without a scheme names a file inside the project (nothing beside it, such as
    ../shared), and its #anchor a heading of that page. The README stays a front page."""
    link = re.compile(r"\]\(([^)\s]+)\)")
    checked = 0
    for page in PAGES:
        for target in link.findall(page.read_text()):
            if re.match(r"[a-z]+:", target):
                continue
            path, _, anchor = target.partition("#")
            resolved = (page.parent / path).resolve() if path else page
            assert resolved.is_relative_to(ROOT.resolve()), (page.name, target)
            assert resolved.is_file(), (page.name, target)
            if anchor and resolved.suffix == ".md":
                assert anchor in anchors(resolved), (page.name, target)
            checked += 1
    assert checked >= 20
    assert "../" not in README and "shared/" not in README
    assert len(README.splitlines()) <= 250
