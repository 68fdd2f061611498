"""Find, read and override scenarios; turn every validation failure into one clear line.

A scenario file must be UTF-8 TOML of at most MAX_FILE_BYTES, nested at most MAX_DEPTH deep,
with no control characters in its strings; anything else is refused with one line naming it.
"""

import copy
import difflib
import tomllib
from importlib import resources
from pathlib import Path

from pydantic import BaseModel, ValidationError

from ..arguments import optional_string, strings
from ..control.registry import CASCADES, CONTROLLERS
from ..errors import InputError
from ..signals import TERM_TYPES
from .schema import Scenario

MAX_FILE_BYTES = 16 * 2**20  # a scenario with a long table signal is a few MB
MAX_DEPTH = 16  # tables and arrays within each other; the deepest schema path is 6
_CONTROL = {chr(c) for c in range(32)} - {"\t", "\n", "\r"} | {"\x7f"}


def builtin_scenarios() -> dict[str, Path]:
    """Name -> path of every scenario shipped with the package."""
    folder = resources.files(__package__)
    return {p.name[:-5]: Path(str(p)) for p in folder.iterdir() if p.name.endswith(".toml")}


def read_scenario_file(name_or_path: str) -> tuple[dict, str]:
    """The raw TOML table of a built-in scenario name or a file path, and where it came from."""
    text, source = read_scenario_text(name_or_path)
    raw = parse_toml(text, f"scenario: {source}")
    check_raw(raw, source)
    return raw, source


def read_scenario_text(name_or_path: str) -> tuple[str, str]:
    """The text of a built-in scenario name or a file path, and where it came from."""
    shipped = builtin_scenarios()
    if name_or_path in shipped:
        path, source = shipped[name_or_path], name_or_path
    else:
        path = Path(name_or_path)
        if (resources.files(__package__) / "axis" / f"{name_or_path}.toml").is_file():
            raise InputError(
                f"scenario: '{name_or_path}' is an axis scenario, simulated against a measured "
                f"trace: emasim identify {name_or_path} --data FILE"
            )
        if path.suffix != ".toml" or not path.is_file():
            raise InputError(
                f"scenario: unknown scenario '{name_or_path}'; choose one of: "
                f"{', '.join(sorted(shipped))}, or give the path of a .toml file"
            )
        source = str(path)
    try:
        if path.stat().st_size > MAX_FILE_BYTES:
            raise InputError(f"scenario: {path} is larger than {MAX_FILE_BYTES // 2**20} MB")
        text = path.read_bytes().decode("utf-8-sig")  # a byte-order mark is fine
    except UnicodeDecodeError as err:
        raise InputError(
            f"scenario: {path} is not UTF-8 text (byte {err.start}); save it as UTF-8 TOML"
        ) from None
    except OSError as err:
        raise InputError(f"scenario: cannot read {path} ({err.strerror or err})") from None
    return text, source


def parse_toml(text: str, what: str) -> dict:
    """tomllib.loads with its failures (bad syntax, absurd nesting) as one InputError line."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise InputError(f"{what} is not valid TOML: {err}") from None
    except RecursionError:
        raise InputError(f"{what}: nested too deeply (at most {MAX_DEPTH} levels)") from None


def check_raw(value, source: str, path: str = "", depth: int = 0) -> None:
    """Refuse nesting deeper than MAX_DEPTH and strings with control characters (a NUL byte
    in a name would reach the file system), naming the dotted path."""
    where = path or "(top level)"
    if depth > MAX_DEPTH:
        raise InputError(f"{source}: {where}: nested too deeply (at most {MAX_DEPTH} levels)")
    if isinstance(value, str):
        bad = next((ch for ch in value if ch in _CONTROL), None)
        if bad is not None:
            raise InputError(f"{source}: {where}: control character {bad!r} in a string; remove it")
    elif isinstance(value, dict):
        for key, item in value.items():
            check_raw(key, source, where, depth + 1)
            check_raw(item, source, f"{path}.{key}" if path else str(key), depth + 1)
    elif isinstance(value, list):
        for i, item in enumerate(value):
            check_raw(item, source, f"{path}.{i}", depth + 1)


def apply_controller_choice(raw: dict, choice: str) -> None:
    """Apply ``LOOP=NAME`` (e.g. ``speed=pi``), that loop's controller with default gains, or
    the name of a cascade (``hybrid``, ``pid``) for every loop the scenario closes."""
    loop, sep, name = choice.partition("=")
    if not sep and choice in CASCADES:
        raw["controllers"] = {"cascade": choice}
        return
    if not sep or not name or not loop:
        raise InputError(
            f"--controller: expected LOOP=NAME or a cascade ({', '.join(CASCADES)}), got '{choice}'"
        )
    if loop not in CONTROLLERS:
        raise InputError(f"--controller: unknown loop '{loop}'; loops: {', '.join(CONTROLLERS)}")
    if name not in CONTROLLERS[loop]:
        other = [lp for lp, names in CONTROLLERS.items() if name in names]
        hint = f" ('{name}' is a {other[0]}-loop controller)" if other else ""
        raise InputError(
            f"--controller: unknown {loop}-loop controller '{name}'{hint}; "
            f"choose one of: {', '.join(CONTROLLERS[loop])}"
        )
    raw.setdefault("controllers", {})[loop] = {"name": name}


def setting_value(setting: str) -> tuple[str, object]:
    """``dotted.key=value`` as (key, value), the value read as TOML (number, bool, string,
    array) and a bare word as a string."""
    key, sep, text = setting.partition("=")
    parts = key.split(".")
    if not sep or not all(parts):
        raise InputError(f"--set: expected KEY=VALUE with a dotted KEY, got {setting!r}")
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        value = text
    except RecursionError:
        raise InputError(f"--set {key}: nested too deeply") from None
    check_raw(value, f"--set {key}")
    return key, value


def apply_setting(raw: dict, setting: str) -> None:
    """Apply ``dotted.key=value`` (:func:`setting_value`)."""
    key, value = setting_value(setting)
    set_key(raw, key, value, "--set")


def set_key(raw: dict, key: str, value, what: str) -> None:
    """Set the dotted ``key`` of a raw scenario table to ``value``; a section given as a preset
    name (``plant = "sea805"``) is opened up into ``{preset = ...}`` on the way, and a number
    in the key indexes a list (``load.rudder_Nm.0.value``)."""
    parts = key.split(".")
    table = raw
    for part in parts[:-1]:
        if isinstance(table, list):
            table = _item(table, part, key, what)
            continue
        child = table.setdefault(part, {})
        if isinstance(child, str):  # a preset name given as a string: open it up as a table
            child = table[part] = {"preset": child}
        if not isinstance(child, dict | list):
            raise InputError(f"{what} {key}: '{part}' is a value, not a section")
        table = child
    if isinstance(table, list):
        index = parts[-1]
        _item(table, index, key, what)
        table[int(index)] = value
    else:
        table[parts[-1]] = value


def _item(items: list, part: str, key: str, what: str):
    """``items[int(part)]``, refused in one line when ``part`` is no index of the list."""
    if not part.isdigit() or int(part) >= len(items):
        raise InputError(f"{what} {key}: '{part}' is not an index of a list of {len(items)}")
    return items[int(part)]


def load_scenario(
    name_or_path: str,
    settings: list[str] = (),
    controllers: list[str] = (),
    label: str | list[str] | None = None,
) -> Scenario:
    """Read, override and validate a scenario; raise InputError naming the field on failure.

    ``label`` runs that controller set of the comparison alone, with its gains (a list of
    several: those sets compared, in that order, each with its gains); each of
    ``controllers`` (``LOOP=NAME`` or a cascade) then replaces a loop, starting from the gains
    of the comparison's first set that uses it, else from the library's defaults. Either
    leaves a single run (no comparison); the set whose gains it took is recorded as
    ``tuning.gains_from``, and the one ``label`` chose as ``tuning.controller_set`` (the run's
    label). ``label`` and ``controllers`` together run that set with those loops replaced,
    labelled so: ``PI (speed=smc)``."""
    raw, source = read_scenario_file(name_or_path)
    choose_controllers(raw, list(controllers), label)
    for setting in settings:
        apply_setting(raw, setting)
    return validate_scenario(raw, source)


def as_scenario(
    scenario: "Scenario | str | Path",
    label: str | None = None,
    controllers: list[str] = (),
    settings: list[str] = (),
    caller: str = "emasim.run",
) -> Scenario:
    """``scenario`` itself, or the shipped scenario of that name or the TOML file at that path
    read with ``label``, ``controllers`` and ``settings`` as the command line reads
    ``--label``, ``--controller`` and ``--set`` (:func:`load_scenario`). InputError, naming
    ``caller``, for those given with a Scenario: it is read already, and for an argument of
    the wrong type."""
    label = optional_string(f"{caller}: label", label)
    controllers = strings(f"{caller}: controllers", controllers)
    settings = strings(f"{caller}: settings", settings)
    if not isinstance(scenario, Scenario | str | Path):
        raise InputError(
            f"{caller}: scenario must be a Scenario, a shipped scenario's name or a TOML "
            f"file's path, got {scenario!r}"
        )
    if isinstance(scenario, str | Path):
        return load_scenario(str(scenario), list(settings), list(controllers), label)
    if label is not None or controllers or settings:
        raise InputError(
            f"{caller}: label, controllers and settings apply to a scenario's name or path; "
            "give load_scenario(...) them for a Scenario"
        )
    return scenario


def choose_controllers(raw: dict, controllers: list[str], label: str | list[str] | None) -> None:
    """Apply ``label`` and ``controllers`` to a raw scenario table (see :func:`load_scenario`)."""
    labels = [label] if isinstance(label, str) else list(label or [])
    label = labels[0] if len(labels) == 1 else None
    if not labels and not controllers:
        return
    entries = raw.pop("compare", [])
    entries = entries if isinstance(entries, list) else []  # malformed: validation says so
    sets = {entry.get("label"): entry for entry in entries if isinstance(entry, dict)}
    if len(labels) > 1:
        raw["compare"] = _chosen_sets(sets, labels, controllers)
        return
    if not isinstance(raw.get("tuning", {}), dict):
        raise InputError("tuning: must be a table of key = value records")
    if isinstance(raw.get("controllers"), str):  # controllers = "hybrid": a cascade's name
        raw["controllers"] = {"cascade": raw["controllers"]}
    origin = []
    if label is not None:
        _check_label(sets, label)
        raw["controllers"] = copy.deepcopy(sets[label].get("controllers", {}))
        raw.setdefault("tuning", {})["controller_set"] = label
        origin.append(label)
    for choice in controllers:
        apply_controller_choice(raw, choice)
        loop, _, name = choice.partition("=")
        for set_label, entry in sets.items():
            chosen = entry.get("controllers", {})
            if not name and chosen.get("cascade") == choice:  # a cascade: that set's loops
                raw["controllers"] = copy.deepcopy(chosen)
            elif name and isinstance(chosen.get(loop), dict) and chosen[loop].get("name") == name:
                raw["controllers"][loop] = dict(chosen[loop])
            else:
                continue
            origin.append(set_label)
            break
    if origin:
        raw.setdefault("tuning", {})["gains_from"] = ", ".join(dict.fromkeys(origin))
    if label is not None and controllers:  # that set with its loops replaced: say so
        raw["tuning"]["controller_set"] = f"{label} ({', '.join(controllers)})"


def _check_label(sets: dict, label: str) -> None:
    """One InputError line where ``label`` names no set of the comparison ``sets``."""
    if label not in sets:
        known = ", ".join(map(str, sets)) or "none: the scenario compares nothing"
        raise InputError(f"--label: {label!r} is no controller set of it; choose from: {known}")


def _chosen_sets(sets: dict, labels: list[str], controllers: list[str]) -> list[dict]:
    """The comparison's entries named by ``labels`` (several), in that order."""
    if controllers:
        raise InputError(
            "--label given more than once with --controller: give one --label, whose loops "
            "--controller replaces"
        )
    twice = sorted({label for label in labels if labels.count(label) > 1})
    if twice:
        raise InputError(f"--label: {twice[0]} given twice")
    for label in labels:
        _check_label(sets, label)
    return [sets[label] for label in labels]


def validate_scenario(raw: dict, source: str = "scenario") -> Scenario:
    """Validate a raw scenario table, turning pydantic's errors into one InputError."""
    try:
        return Scenario.model_validate(raw)
    except ValidationError as err:
        raise InputError(f"{source}: " + "; ".join(describe_errors(err))) from None
    except ValueError as err:  # raised by preset resolution before field validation
        raise InputError(f"{source}: {err}") from None


def describe_errors(err: ValidationError, root: type[BaseModel] | None = None) -> list[str]:
    """One 'dotted.path: what is wrong (allowed ...)' line per pydantic error of the model
    ``root`` (a Scenario by default)."""
    lines = []
    for e in err.errors(include_url=False):
        loc = [str(part) for part in e["loc"] if not _is_union_tag(part)]
        path = ".".join(loc)
        prefix = f"{path}: " if path else ""
        if e["type"] == "extra_forbidden":
            allowed = _allowed_keys(loc[:-1], root or Scenario)
            close = difflib.get_close_matches(loc[-1], allowed, n=1) if loc else []
            hint = f"; did you mean '{close[0]}'?" if close else ""
            keys = f"; allowed: {', '.join(allowed)}" if allowed else ""
            lines.append(f"{prefix}unknown key{hint}{keys}")
        else:
            msg = e["msg"].removeprefix("Value error, ")
            got = e.get("input")
            shown = "" if isinstance(got, dict | list) else f" (got {got!r})"
            lines.append(f"{prefix}{msg}{shown}")
    return lines


UNION_TAGS = TERM_TYPES | {name for names in CONTROLLERS.values() for name in names}


def _is_union_tag(part) -> bool:
    """pydantic puts a union member's tag (a signal type such as 'step', a controller name
    such as 'pi') into the location; leave it out."""
    return isinstance(part, str) and part in UNION_TAGS


def _allowed_keys(loc: list[str], root: type[BaseModel]) -> list[str]:
    """The field names of the model at a location inside ``root`` (best effort)."""
    model: type[BaseModel] | None = root
    for part in loc:
        if model is None or part.isdigit():
            continue
        field = model.model_fields.get(part)
        if field is None:
            return []
        model = _model_of(field.annotation)
    return list(model.model_fields) if model is not None else []


def _model_of(annotation) -> type[BaseModel] | None:
    """The BaseModel class inside an annotation like ``X``, ``X | None`` or ``list[X]``."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in getattr(annotation, "__args__", ()):
        found = _model_of(arg)
        if found is not None:
            return found
    return None
