"""How long the README's two commands take on a fresh machine, measured end to end.

    python benchmarks/readme_commands.py            # measure, store readme_commands.json
    python benchmarks/readme_commands.py --write    # measure, store, rewrite the README's block
    python benchmarks/readme_commands.py --render   # rewrite the README's block from the JSON

Each command is read from the README's "Two commands" section (so it cannot drift from what a
reader copies) and run exactly as printed, with ``bash -c``, in a fresh ``git clone`` of the
current commit (never the working tree), one clone per command, with an empty cache folder
(``XDG_CACHE_HOME``: pip's cache, matplotlib's and emasim's numba cache lie under it) and no
``NUMBA_CACHE_DIR``: pip fetches and builds every package and numba compiles the core, as on
a fresh machine. The commands run one after the other, never together. The result
(seconds, exit codes, date, commit, ``nproc``, the Python ``python3`` starts, the load average
when each command started) goes to ``benchmarks/readme_commands.json``; the README states it
between ``<!-- commands:begin -->`` and ``<!-- commands:end -->``, written by :func:`render`,
and ``tests/test_readme.py`` checks the block against the stored JSON (it times nothing).

Not named ``bench_*.py``: CI runs those with ``--quick``, and this one takes minutes. Standard
library only: it needs no installed emasim, and reads ``src/emasim/page_blocks.py`` (standard
library too) from the file.
"""

import argparse
import datetime
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
STORE = ROOT / "benchmarks" / "readme_commands.json"
PAGE_BLOCKS = ROOT / "src" / "emasim" / "page_blocks.py"
BLOCK = "commands"
SECTION = "## Two commands"
NAMES = ("run", "test")  # the section's commands, in order: install and run, install and test
TIMEOUT_S = 3600


def commands(text: str) -> list[str]:
    """The one-line bash blocks of the README's "Two commands" section, in order."""
    start = text.index(f"\n{SECTION}\n")
    end = text.find("\n## ", start + 1)
    section = text[start : end if end != -1 else len(text)]
    found, lines, inside = [], [], False
    for line in section.splitlines():
        if line.startswith("```"):
            if inside:
                found.append("\n".join(lines))
            inside, lines = not inside and line[3:].strip() == "bash", []
        elif inside:
            lines.append(line)
    if len(found) != len(NAMES) or any("\n" in c for c in found):
        raise ValueError(f"{SECTION} should hold {len(NAMES)} one-line bash blocks: {found}")
    return found


def environment(cache: Path) -> dict:
    """A user's shell environment with an empty cache: no virtual environment active, no
    numba cache given, bytecode written (emasim's benchmarks drop this sandbox's
    PYTHONDONTWRITEBYTECODE the same way)."""
    drop = {"VIRTUAL_ENV", "NUMBA_CACHE_DIR", "PYTHONDONTWRITEBYTECODE", "PYTHONPATH"}
    env = {k: v for k, v in os.environ.items() if k not in drop and not k.startswith("EMASIM")}
    return {**env, "XDG_CACHE_HOME": str(cache)}


def git(*args: str, cwd: Path = ROOT) -> str:
    return subprocess.run(
        ["git", *args], cwd=cwd, check=True, capture_output=True, text=True
    ).stdout.strip()


def run_one(command: str, commit: str, scratch: Path, name: str) -> dict:
    """Clone ``commit`` into ``scratch/name``, run ``command`` there on an empty cache, time it."""
    clone, cache = scratch / name, scratch / f"{name}-cache"
    git("clone", "--quiet", "--no-checkout", str(ROOT), str(clone))
    git("checkout", "--quiet", "--detach", commit, cwd=clone)
    cache.mkdir()
    env = environment(cache)
    log = scratch / f"{name}.log"
    load = os.getloadavg()[0]
    start = time.perf_counter()
    with log.open("w") as out:
        proc = subprocess.run(
            ["bash", "-c", command],
            cwd=clone,
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
            timeout=TIMEOUT_S,
        )
    seconds = time.perf_counter() - start
    tail = log.read_text(errors="replace").splitlines()[-5:]
    print(f"{name}: {seconds:.0f} s, exit code {proc.returncode}; {' | '.join(tail)}", flush=True)
    return {
        "command": command,
        "seconds": round(seconds, 1),
        "exit_code": proc.returncode,
        "load_average_at_start": round(load, 2),
        "output_tail": tail,
    }


def measure() -> dict:
    commit = git("rev-parse", "HEAD")
    scratch = Path(tempfile.mkdtemp(prefix="emasim-readme-commands-"))
    try:
        python = subprocess.run(
            ["python3", "-c", "import platform; print(platform.python_version())"],
            env=environment(scratch),
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        runs = {
            name: run_one(command, commit, scratch, name)
            for name, command in zip(NAMES, commands(README.read_text()), strict=True)
        }
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return {
        "date": datetime.datetime.now(datetime.UTC).date().isoformat(),
        "commit": commit,
        "nproc": len(os.sched_getaffinity(0)),
        "python": python,
        "platform": sys.platform,
        "commands": runs,
    }


def outcome(run: dict) -> str:
    """'' for a command that succeeded; else what failed, from pytest's summary line when the
    output has one."""
    if run["exit_code"] == 0:
        return ""
    failed = re.search(r"(\d+) (failed|errors?)\b", " ".join(run["output_tail"]))
    count = failed and int(failed.group(1))
    what = f"{count} test{'s' if count != 1 else ''} failed" if failed else "it failed"
    return f"; exit code {run['exit_code']}: {what} at that commit"


def minutes(seconds: float) -> str:
    """'about 1.5 min' (to the half minute below 10 min, then to the minute)."""
    value = seconds / 60
    value = round(2 * value) / 2 if value < 10 else round(value)
    return f"about {max(value, 0.5):g} min"


def render(stored: dict) -> str:
    """The README's text between the markers (emasim.page_blocks' rule), wrapped as the
    README's prose is."""
    run, test = (stored["commands"][name] for name in NAMES)
    loads = [stored["commands"][name]["load_average_at_start"] for name in NAMES]
    busy = max(loads) >= 1
    text = (
        f"Measured on {stored['date']} at commit `{stored['commit'][:10]}`, each command in a "
        "fresh clone with empty pip and numba caches (pip fetches every package and builds "
        f"emasim, numba compiles the core): the first took {minutes(run['seconds'])} "
        f"({run['seconds']:.0f} s{outcome(run)}), the second {minutes(test['seconds'])} "
        f"({test['seconds']:.0f} s{outcome(test)}), on this project's {stored['nproc']}-core "
        f"machine with Python {stored['python']}. "
        + (
            "That machine was busy with other work as they started (load average "
            if busy
            else "That machine was otherwise idle as they started (load average "
        )
        + " and ".join(f"{load:g}" for load in loads)
        + ("), so a quiet machine of that size takes less." if busy else ").")
        + " `benchmarks/readme_commands.py` measures again."
    )
    return textwrap.fill(text, 96, break_on_hyphens=False, break_long_words=False)


def write_readme(stored: dict) -> None:
    spec = importlib.util.spec_from_file_location("page_blocks", PAGE_BLOCKS)
    page_blocks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(page_blocks)
    page_blocks.write_block(README, BLOCK, render(stored))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--write", action="store_true", help="also rewrite the README's block")
    group.add_argument("--render", action="store_true", help="only rewrite it from the JSON")
    args = parser.parse_args()
    if not args.render:
        stored = measure()
        STORE.write_text(json.dumps(stored, indent=1) + "\n")
        print(f"wrote {STORE}")
    if args.write or args.render:
        write_readme(json.loads(STORE.read_text()))
        print(f"rewrote the block of {README}")
    failed = [n for n, r in json.loads(STORE.read_text())["commands"].items() if r["exit_code"]]
    if failed:
        sys.exit(f"failed: {', '.join(failed)} (the README's block says so)")


if __name__ == "__main__":
    main()
